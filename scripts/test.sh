#!/usr/bin/env bash
# One command on a fresh machine: install what the tests need, then run them.
# Extra arguments go to pytest (e.g. `-m slow` for the long checks).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh dev,agents,rendering,rllib,torchrl,docs,tune
# The site test (tests/docs/test_site.py) opens every page in Debian's headless Chromium.
if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then
  if command -v apt-get >/dev/null 2>&1; then
    sudo=""
    if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
    echo "installing chromium and chromium-driver (apt-get) for the site test ..."
    $sudo apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium chromium-driver >/dev/null
    echo "installed: $(chromium --version)"
  else
    echo "no chromium and no apt-get: tests/docs/test_site.py will be skipped" >&2
  fi
fi
export SDL_VIDEODRIVER=dummy SDL_AUDIODRIVER=dummy MPLBACKEND=Agg NO_MKDOCS_2_WARNING=1
.venv/bin/python -m ruff check .
.venv/bin/python -m ruff format --check .
.venv/bin/python -m mypy
.venv/bin/python -m mkdocs build --strict --quiet --site-dir site
.venv/bin/python -m pytest -m "not slow" -q "$@"
