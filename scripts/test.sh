#!/usr/bin/env bash
# One command on a fresh machine: install what the tests need, then run them.
# Extra arguments go to pytest (e.g. `-m slow` for the long checks).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh dev,agents,rendering,rllib,torchrl
export SDL_VIDEODRIVER=dummy SDL_AUDIODRIVER=dummy MPLBACKEND=Agg
.venv/bin/python -m ruff check .
.venv/bin/python -m mypy
.venv/bin/python -m pytest -m "not slow" -q "$@"
