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
# pip's lines, one per package fetched and shortened, show that it is moving (a fresh
# install takes a minute or two); pip's errors (stderr) still reach the terminal in full,
# and with pipefail a failing pip fails the install.
pip_install() {
  .venv/bin/python -m pip install --progress-bar off -c constraints.txt "$@" |
    while IFS= read -r line; do
      case "$line" in
        Collecting* | "Installing collected"*) echo "install: [$((SECONDS - started)) s] ${line:0:90}" ;;
      esac
    done
}
echo "install: torch (CPU build) and the project with extras [${extras}] ..."
pip_install torch==2.13.0
pip_install -e ".[${extras}]"
echo "install: packages done in $((SECONDS - started)) s; compiling the kernels ..."
.venv/bin/python -m trailer_env --compile
echo "install: done in $((SECONDS - started)) s"
