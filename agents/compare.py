"""``python -m agents.compare``: the command lives in :mod:`agents.commands.compare`."""

from agents.commands.compare import main

if __name__ == "__main__":
    raise SystemExit(main())
