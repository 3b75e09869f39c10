"""``python -m agents.across_n``: the command lives in :mod:`agents.commands.across_n`."""

from agents.commands.across_n import main

if __name__ == "__main__":
    raise SystemExit(main())
