#!/usr/bin/env bash
# Set up .venv with the test extras and run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test
echo "[test] running the test suite"
.venv/bin/python -m pytest -q -p no:cacheprovider "$@"
