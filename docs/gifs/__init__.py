"""Animated GIFs of every environment for the documentation site (``python -m docs.gifs``).

Each environment page shows two episodes of the same seeded start: the committed agent and
the zero action. :mod:`docs.gifs.command` writes them to ``docs/img/``.
"""
