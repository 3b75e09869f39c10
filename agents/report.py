"""``python -m agents.report``: the command lives in :mod:`agents.commands.report`."""

from agents.commands.report import main

if __name__ == "__main__":
    raise SystemExit(main())
