"""``python -m agents.main``: the command lives in :mod:`agents.commands.main`."""

from agents.commands.main import main

if __name__ == "__main__":
    raise SystemExit(main())
