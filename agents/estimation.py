"""``python -m agents.estimation``: the command lives in :mod:`agents.commands.estimation`."""

from agents.commands.estimation import main

if __name__ == "__main__":
    raise SystemExit(main())
