"""Every file the agents read or write: names, formats and safe loading (the bottom layer).

* :mod:`~agents.artifacts.paths`: the names of a model's card, statistics, curve and
  checkpoints;
* :mod:`~agents.artifacts.records`: the base of the typed JSON documents below
  (frozen dataclasses read field by field, refused naming the field);
* :mod:`~agents.artifacts.cards`: model cards and run records (``ModelCard``);
* :mod:`~agents.artifacts.results`: the results document and the metrics summary
  (``ResultsDocument``, ``Summary``);
* :mod:`~agents.artifacts.stats`: observation statistics as JSON (``NormalizationStats``;
  legacy pickles only when trusted);
* :mod:`~agents.artifacts.sb3_zip`: stable-baselines3 zips loaded without unpickling;
* :mod:`~agents.artifacts.rllib_files`: an RLlib run's pickle-free policy export;
* :mod:`~agents.artifacts.curves`: learning curves (``evaluations.csv``);
* :mod:`~agents.artifacts.certificates`: certificates of a scene's ceiling (the typed
  :class:`~agents.artifacts.certificates.Certificate` record);
* :mod:`~agents.artifacts.action_records`: a certificate's action records in one archive;
* :mod:`~agents.artifacts.run_folder`: a training's run folder;
* :mod:`~agents.artifacts.shipped`: the models shipped in the package;
* :mod:`~agents.artifacts.files`: atomic, link-refusing writes, bounded JSON reads and
  the run folder's lock (every writer and reader above uses it);
* :mod:`~agents.artifacts.limits`: the bounds every command checks before any work
  (its docstring holds the table).

What is safe to load, and what is not:

* ``<model>_vecnormalize.json`` (observation-normalisation statistics): plain JSON
  numbers, always safe. The former ``<model>_vecnormalize.pkl`` was a pickle.
* An SB3 model zip: its weights (``*.pth``) are read by ``torch.load(weights_only=True)``,
  which refuses anything but tensors and plain containers. Its ``data`` entry is
  JSON, but SB3 stores some values in it as base64 *cloudpickle* (entries holding a
  ``:serialized:`` key: the spaces, the policy class, schedules, buffers' classes);
  SB3 would unpickle them. :func:`~agents.artifacts.sb3_zip.safe_custom_objects`
  replaces every such entry (SB3's ``custom_objects``) with a value built here: the
  spaces of the environment the model will act in (after checking the saved shapes,
  read from the entry's plain-text description), the algorithm's ``MlpPolicy``, and
  the hyperparameter file's schedules, so nothing of the file is unpickled. An entry
  it does not know is refused. Only ``trust_pickle=True`` (``--trust-pickle``) lets
  SB3 unpickle.
* SAC/TD3 replay buffers (``*_replay_buffer_*.pkl``) and legacy ``*_vecnormalize.pkl``
  files are pickles: loaded only with ``trust_pickle=True``.
* RLlib checkpoints: a pickle-free export (``policy_weights.pt``, tensors only, and
  ``policy_card.json``) beside RLlib's own pickled files, which are read only with
  ``trust_pickle=True``.
"""
