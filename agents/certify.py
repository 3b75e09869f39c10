"""``python -m agents.certify``: the command lives in :mod:`agents.commands.certify`."""

from agents.commands.certify import main

if __name__ == "__main__":
    raise SystemExit(main())
