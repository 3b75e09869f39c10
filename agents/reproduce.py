"""``python -m agents.reproduce``: the command lives in :mod:`agents.commands.reproduce`."""

from agents.commands.reproduce import main

if __name__ == "__main__":
    raise SystemExit(main())
