"""``python -m agents.evaluate``: the command lives in :mod:`agents.commands.evaluate`."""

from agents.commands.evaluate import main

if __name__ == "__main__":
    raise SystemExit(main())
