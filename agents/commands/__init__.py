"""The command-line programs (argument parsing only; the work is in the layers below).

``python -m agents.train``, ``agents.evaluate``, ``agents.certify``, ``agents.imitate``,
``agents.report``, ``agents.main`` and ``agents.model_files`` run these modules' ``main``.
"""
