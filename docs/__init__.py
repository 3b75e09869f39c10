"""The documentation's sources that are code: ``docs.figures`` draws the thesis pictures.

A package so that ``python -m docs.figures`` runs from the repository root; it is not
installed (``[tool.setuptools]`` ships only ``dynamics``, ``trailer_env`` and ``agents``).
"""
