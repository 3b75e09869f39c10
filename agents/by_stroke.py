"""``python -m agents.by_stroke``: the command lives in :mod:`agents.commands.by_stroke`."""

from agents.commands.by_stroke import main

if __name__ == "__main__":
    raise SystemExit(main())
