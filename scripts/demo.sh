#!/usr/bin/env bash
# One command on a fresh machine: install, then run the main job on the default convoy.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh agents,rendering
.venv/bin/python -m agents.main "$@"
