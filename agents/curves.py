"""``python -m agents.curves``: the command lives in :mod:`agents.commands.curves`."""

from agents.commands.curves import main

if __name__ == "__main__":
    raise SystemExit(main())
