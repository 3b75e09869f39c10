"""``python -m agents.ladder``: the command lives in :mod:`agents.commands.ladder`."""

from agents.commands.ladder import main

if __name__ == "__main__":
    raise SystemExit(main())
