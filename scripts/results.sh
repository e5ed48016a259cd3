#!/usr/bin/env bash
# Regenerate every table and figure in results/ (one command). Usage: bash scripts/results.sh [--quick]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh dev
PY=.venv/bin/python
QUICK=${1:-}
run() { echo "[results] $*"; "$PY" "$@"; }
run benchmarks/differentiators.py ${QUICK:+--quick}
[ -f benchmarks/paper_replication.py ] && run benchmarks/paper_replication.py
run benchmarks/diagnosis.py --seeds "$([ -n "$QUICK" ] && echo 1 || echo 3)"
run benchmarks/excitation.py
[ -f benchmarks/tuning.py ] && run benchmarks/tuning.py ${QUICK:+--quick}
[ -f benchmarks/online.py ] && run benchmarks/online.py
run benchmarks/speed.py
[ -f benchmarks/real_uacdpr.py ] && run benchmarks/real_uacdpr.py
run benchmarks/make_index.py
echo "[results] done: see results/README.md"
