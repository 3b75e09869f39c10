"""``python -m agents.gains``: the command lives in :mod:`agents.commands.gains`."""

from agents.commands.gains import main

if __name__ == "__main__":
    raise SystemExit(main())
