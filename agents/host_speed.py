"""``python -m agents.host_speed``: the command lives in :mod:`agents.commands.host_speed`."""

from agents.commands.host_speed import main

if __name__ == "__main__":
    raise SystemExit(main())
