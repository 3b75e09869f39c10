#!/usr/bin/env bash
# Creates .venv (if absent), installs the project with the given extras, then compiles
# the numba kernels once (numba's disk cache), so that no first run waits for them.
# torch is pinned to the local CPU build through constraints.txt: an unpinned torch
# (pulled in by stable-baselines3) would fetch several GB of CUDA wheels.
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-agents,rendering}"
started=$SECONDS
if [ ! -x .venv/bin/python ]; then
  echo "install: creating .venv"
  python3 -m venv .venv
fi
.venv/bin/python -m pip install --quiet --upgrade pip >/dev/null 2>&1 || true
echo "install: torch (CPU build) and the project with extras [${extras}] ..."
.venv/bin/python -m pip install --progress-bar off -q -c constraints.txt torch==2.13.0
.venv/bin/python -m pip install --progress-bar off -q -c constraints.txt -e ".[${extras}]"
echo "install: packages done in $((SECONDS - started)) s; compiling the kernels ..."
.venv/bin/python -m trailer_env --compile
echo "install: done in $((SECONDS - started)) s"
