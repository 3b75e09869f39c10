"""``python -m agents.shac``: the command lives in :mod:`agents.commands.shac`."""

from agents.commands.shac import main

if __name__ == "__main__":
    raise SystemExit(main())
