"""Baselines and stable-baselines3 agents for the trailer_env scenes.

Modules (one concept each):

* :mod:`agents.baselines`: zero, random, LQR and heading baselines as batched policies;
* :mod:`agents.policies`: the registry (a baseline by name, a saved model by path or stem);
* :mod:`agents.envs`: environment construction (native batches, the SB3 adapter) and the
  scene table's look-ups (ids, scene names, headline metric, baselines);
* :mod:`agents.metrics`: seeded batched rollouts and the safety metrics;
* :mod:`agents.config`: rl-zoo3 hyperparameter files (``agents/hyperparams/*.yml``) and
  :class:`~agents.config.TrainConfig`, the record behind ``config.json`` and the cards;
* :mod:`agents.run_folder`: a training's run folder (default name, refusals, overwrite);
* :mod:`agents.callbacks`: periodic evaluation during training (learning curves);
* :mod:`agents.plots`: learning curves, margin histograms, rendered frames, episode videos;
* :mod:`agents.model_files`: model file names, cards and export; loading without pickles
  (JSON statistics, safe SB3 loads);
* :mod:`agents.rllib_backend`: distributed PPO on Ray RLlib (``train --backend rllib``);
* :mod:`agents.cli`: the command-line options and number parsers the commands share;
* commands: :mod:`agents.train`, :mod:`agents.evaluate`, :mod:`agents.report` and the
  main job :mod:`agents.main`.

Committed models live in ``agents/models/`` with their cards (``*.json``),
observation statistics (``*_vecnormalize.json``) and learning curves (``*.csv``).
"""
