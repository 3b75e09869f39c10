"""The command-line programs (argument parsing only; the work is in the layers below).

``python -m agents.<name>`` runs ``agents.commands.<name>``'s ``main`` (``agents/<name>.py``
imports it): the main job, ``train``, ``evaluate``, ``certify``, ``imitate``, ``shac``,
``report``, ``tune``, ``curves``, ``reproduce`` and the analyses ``across_n``, ``gains``,
``estimation``, ``gradients``, ``by_stroke``, ``rl_from_reward``, ``time_to_ceiling``,
``ladder`` and ``shac_chart`` (their computations in :mod:`agents.evaluation`);
``host_speed`` (the machine's speed that every card records); ``agents.model_files`` runs
:mod:`agents.commands.convert_stats`. Their shared options, number and range parsers are
:mod:`agents.commands.options`.
"""
