"""``python -m agents.select``: the command lives in :mod:`agents.commands.select`."""

from agents.commands.select import main

if __name__ == "__main__":
    raise SystemExit(main())
