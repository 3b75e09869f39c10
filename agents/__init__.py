"""Baselines, oracles and stable-baselines3 agents for the trailer_env scenes, in layers.

Each subpackage owns one concern and imports only from the layers below it (enforced
by ``tests/test_layers.py``):

1. :mod:`agents.commands`: the command-line programs, argument parsing only
   (``python -m agents.train``, ``agents.evaluate``, ``agents.certify``,
   ``agents.imitate``, ``agents.report``, ``agents.main``);
2. :mod:`agents.training`: SB3 and RLlib training, imitation (DAgger), hyperparameter
   files, callbacks;
3. :mod:`agents.evaluation`: seeded batched rollouts, metrics, tables, pictures;
4. :mod:`agents.policies`: baselines, loaded models and the registry
   (:func:`agents.policies.load_policy`);
5. :mod:`agents.oracles`: the planner, the feasibility screen and certification;
6. :mod:`agents.artifacts`: every file name and format, safe loading, cards, the
   shipped models;
7. :mod:`agents.seeds` (every seed range) and :mod:`agents.envs` (building envs and
   the scene table's look-ups).

Committed models live in ``agents/models/`` with their cards (``*.json``),
observation statistics (``*_vecnormalize.json``) and learning curves (``*.csv``);
committed certificates in ``agents/certificates/``.
"""
