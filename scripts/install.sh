#!/usr/bin/env bash
# Creates .venv (if absent) and installs the project with the given extras.
# torch is pinned to the local CPU build through constraints.txt: an unpinned
# torch (pulled in by stable-baselines3) would fetch several GB of CUDA wheels.
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-agents,rendering}"
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
.venv/bin/python -m pip install --quiet --upgrade pip >/dev/null 2>&1 || true
.venv/bin/python -m pip install --quiet -c constraints.txt torch==2.13.0
.venv/bin/python -m pip install --quiet -c constraints.txt -e ".[${extras}]"
