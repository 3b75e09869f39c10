"""``python -m agents.gradients``: the command lives in :mod:`agents.commands.gradients`."""

from agents.commands.gradients import main

if __name__ == "__main__":
    raise SystemExit(main())
