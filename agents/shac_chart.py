"""``python -m agents.shac_chart``: the command lives in :mod:`agents.commands.shac_chart`."""

from agents.commands.shac_chart import main

if __name__ == "__main__":
    raise SystemExit(main())
