"""``python -m agents.time_to_ceiling``: the command lives in
:mod:`agents.commands.time_to_ceiling`."""

from agents.commands.time_to_ceiling import main

if __name__ == "__main__":
    raise SystemExit(main())
