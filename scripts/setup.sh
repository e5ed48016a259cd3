#!/usr/bin/env bash
# Create .venv (if needed) and install cdprid with the given extras. Usage: scripts/setup.sh [EXTRAS]
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating virtual environment .venv"
  "$PY" -m venv .venv
fi
EXTRAS=${1:-}
SPEC="."
[ -n "$EXTRAS" ] && SPEC=".[$EXTRAS]"
echo "[setup] installing cdprid ($SPEC) and its dependencies"
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e "$SPEC"
