"""``python -m agents.model_files``: the command lives in :mod:`agents.commands.convert_stats`."""

from agents.commands.convert_stats import main

if __name__ == "__main__":
    raise SystemExit(main())
