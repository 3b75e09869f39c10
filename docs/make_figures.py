"""Old name of ``python -m docs.figures``, kept so that ``python docs/make_figures.py`` still runs.

Run from the repository root::

    python docs/make_figures.py [--out docs/img] [--quick]

The pictures, their numbers and the command live in the package ``docs/figures/``.
"""

from __future__ import annotations

import sys
from pathlib import Path

if __name__ == "__main__":
    # Run as a script, Python puts docs/ on sys.path, not the root that holds the package.
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from docs.figures.command import main

    main(sys.argv[1:])
