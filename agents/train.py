"""``python -m agents.train``: the command lives in :mod:`agents.commands.train`."""

from agents.commands.train import main

if __name__ == "__main__":
    raise SystemExit(main())
