#!/usr/bin/env bash
# Set up .venv and run the main job: simulate a CRAFT-like dataset and identify it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
OUT=${CDPRID_DEMO_DIR:-$(mktemp -d)/cdprid-demo}
CDPRID=.venv/bin/cdprid
echo "[demo] 1/3 simulating the paper's four orbits on a CRAFT-like robot -> $OUT/paper-orbits"
$CDPRID simulate --preset paper-orbits --seed 1 --out "$OUT/paper-orbits"
echo "[demo] 2/3 identifying the paper's 4 parameters (Euler + zero-phase 4 Hz, matched filter)"
$CDPRID identify "$OUT/paper-orbits" --json "$OUT/identify-euler.json"
echo "[demo] 3/3 the same with the paper's SIHD-2 cascade"
$CDPRID identify "$OUT/paper-orbits" --differentiator sihd2-cascade --json "$OUT/identify-sihd.json"
echo "[demo] done: outputs in $OUT"
