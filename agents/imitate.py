"""``python -m agents.imitate``: the command lives in :mod:`agents.commands.imitate`."""

from agents.commands.imitate import main

if __name__ == "__main__":
    raise SystemExit(main())
