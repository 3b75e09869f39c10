"""``python -m docs.gifs [--out DIR] [--only ID ...]``: see :mod:`docs.gifs.command`."""

import sys

from docs.gifs.command import main

main(sys.argv[1:])
