#!/usr/bin/env bash
# Set up .venv with the test extras and run the test suite.
# Locally: the default selection (slow Monte-Carlo tests deselected, < 10 min on 2 cores).
# In CI (CI=true): the slow tests run too. Extra arguments are passed to pytest (and then one
# pytest process runs exactly what they name).
#
# Without arguments the suite runs as one pytest process per test folder (tests/<subpackage>/,
# and each top-level test file), two at a time (below): a single process that had compiled the
# whole suite's XLA programs died in XLA:CPU's compiler (segfault in backend_compile_and_load,
# tests/identify/test_online.py, CI 2026-11-27, twice at the same test) while the same tests
# pass in a fresh process. Each folder's process starts from a clean JAX state; the exit code
# is 0 only when every folder passed.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test,cluster
# NumPy's OpenBLAS single-threaded, as the cdprid executable runs it: its spinning worker
# threads take the cores XLA needs when the machine is shared (results/benchmarks.md).
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
SEL=()
if [ "${CI:-}" = "true" ]; then
  SEL=(-m "slow or not slow")
  # CI compiles as users run cdprid; locally tests/conftest.py asks XLA for little optimization
  # (compiling is most of the suite's time; the README's "How long")
  export JAX_DISABLE_MOST_OPTIMIZATIONS="${JAX_DISABLE_MOST_OPTIMIZATIONS:-0}"
fi
echo "[test] running the test suite ${SEL[*]:-(slow tests deselected)}"
PYTEST=(.venv/bin/python -m pytest -q -p no:cacheprovider "${SEL[@]}")
if [ "$#" -gt 0 ]; then
  exec "${PYTEST[@]}" "$@"
fi

GROUPS_=()
for d in tests/*/; do
  d="${d%/}"
  case "$(basename "$d")" in _*|__pycache__) continue ;; esac
  if compgen -G "$d/test_*.py" >/dev/null || compgen -G "$d/**/test_*.py" >/dev/null; then
    GROUPS_+=("$d")
  fi
done
for f in tests/test_*.py; do GROUPS_+=("$f"); done

# Two folders at a time (CDPRID_TEST_JOBS, default: the number of cores, at most 4): each
# pytest process spends most of its time in XLA's single-threaded compiler, so a second process
# uses the second core (26 min -> see the README's "How long"). The heaviest folders start
# first; each folder's output is printed whole when it ends, in the order they end, with its
# wall and CPU seconds (CPU: what to compare on a shared machine) and the sum at the end.
JOBS="${CDPRID_TEST_JOBS:-$(nproc 2>/dev/null || echo 2)}"
if [ "$JOBS" -gt 4 ]; then JOBS=4; fi
if [ "$JOBS" -lt 1 ]; then JOBS=1; fi
HEAVY=(tests/identify tests/diagnosis tests/core tests/excitation tests/io tests/tuning tests/cli
       tests/effects)  # by seconds, 2026-11-28 15:25 (a whole run at load 5-9)
ORDERED=()
for h in "${HEAVY[@]}"; do
  for g in "${GROUPS_[@]}"; do [ "$g" = "$h" ] && ORDERED+=("$g"); done
done
for g in "${GROUPS_[@]}"; do
  case " ${HEAVY[*]} " in *" $g "*) ;; *) ORDERED+=("$g") ;; esac
done
LOGS="$(mktemp -d)"
trap 'rm -rf "$LOGS"' EXIT
export LOGS
run_one() {
  local g="$1" key rc s
  key="$(echo "$g" | tr '/.' '__')"
  local sel=() cpu TIMEFORMAT='%U %S'
  if [ "${CI:-}" = "true" ]; then sel=(-m "slow or not slow"); fi
  s=$SECONDS
  set +e
  # bash's time keyword: the folder's CPU seconds (user + sys of the pytest process and the
  # commands it starts), which say more than wall seconds on a shared machine
  { time .venv/bin/python -m pytest -q -p no:cacheprovider "${sel[@]}" "$g" \
      > "$LOGS/$key.log" 2>&1 ; } 2> "$LOGS/$key.time"
  rc=$?
  set -e
  echo "$rc" > "$LOGS/$key.rc"
  cpu="$(awk '{printf "%.0f", $1 + $2}' "$LOGS/$key.time" 2>/dev/null || echo '?')"
  echo "$cpu" > "$LOGS/$key.cpu"
  if command -v flock >/dev/null 2>&1; then
    { echo "[test] $g ($((SECONDS - s)) s, $cpu CPU s, exit $rc)"; cat "$LOGS/$key.log"; } \
      | flock "$LOGS/.lock" cat
  else
    echo "[test] $g ($((SECONDS - s)) s, $cpu CPU s, exit $rc)"; cat "$LOGS/$key.log"
  fi
  return 0  # the folder's exit code is in $LOGS/$key.rc, read below
}
export -f run_one

start=$SECONDS
printf '%s\n' "${ORDERED[@]}" | xargs -P "$JOBS" -I{} bash -c 'run_one "$@"' _ {} || true
failed=()
cpu_all=0
for g in "${ORDERED[@]}"; do
  key="$(echo "$g" | tr '/.' '__')"
  cpu_all=$((cpu_all + $(cat "$LOGS/$key.cpu" 2>/dev/null || echo 0)))
  rc="$(cat "$LOGS/$key.rc" 2>/dev/null || echo missing)"
  # 5: nothing collected (a folder whose tests are all deselected) is not a failure
  if [ "$rc" != "0" ] && [ "$rc" != "5" ]; then
    failed+=("$g (exit $rc)")
  fi
done
echo "[test] ${#GROUPS_[@]} folders in $((SECONDS - start)) s ($JOBS at a time; $cpu_all CPU s in all)"
if [ "${#failed[@]}" -gt 0 ]; then
  echo "[test] FAILED: ${failed[*]}"
  exit 1
fi
echo "[test] all passed"
