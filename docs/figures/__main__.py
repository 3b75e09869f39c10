"""``python -m docs.figures [--out DIR] [--quick]``: see :mod:`docs.figures.command`."""

import sys

from docs.figures.command import main

main(sys.argv[1:])
