#!/usr/bin/env bash
# Set up .venv with the test extras and run the test suite.
# Locally: the default selection (slow Monte-Carlo tests deselected, < 10 min on 2 cores).
# In CI (CI=true): the slow tests run too. Extra arguments are passed to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test,cluster
# NumPy's OpenBLAS single-threaded, as the cdprid executable runs it: its spinning worker
# threads take the cores XLA needs when the machine is shared (results/benchmarks.md).
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
SEL=()
if [ "${CI:-}" = "true" ]; then SEL=(-m "slow or not slow"); fi
echo "[test] running the test suite ${SEL[*]:-(slow tests deselected)}"
.venv/bin/python -m pytest -q -p no:cacheprovider "${SEL[@]}" "$@"
