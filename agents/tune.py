"""``python -m agents.tune``: the command lives in :mod:`agents.commands.tune`."""

from agents.commands.tune import main

if __name__ == "__main__":
    raise SystemExit(main())
