"""``python -m agents.mismatch``: the command lives in :mod:`agents.commands.mismatch`."""

from agents.commands.mismatch import main

if __name__ == "__main__":
    raise SystemExit(main())
