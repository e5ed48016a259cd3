#!/usr/bin/env bash
# Execute the notebooks (nbclient) and write rendered copies, with their outputs, to
# results/notebooks/; the figures they save go to results/. The committed notebooks stay
# without outputs.
# Usage: bash scripts/notebooks.sh [--fast] [NAME_PREFIX ...]   e.g. bash scripts/notebooks.sh 01 05
#   --fast   sets CDPRID_FAST=1 (lighter runs, as the test suite does)
# Without ../shared (or $CDPRID_SHARED), 02 regenerates its dataset with the simulator and 06
# (the real recording) says it has nothing to run.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${PYTHON:-}" ]; then
  # the notebook runner (nbclient, ipykernel) is the `notebooks` extra: install it if missing
  if ! { [ -x .venv/bin/python ] && .venv/bin/python -c "import nbclient, ipykernel" 2>/dev/null; }; then
    bash scripts/setup.sh notebooks
  fi
fi
PY=${PYTHON:-.venv/bin/python}
[ -x "$PY" ] || PY=python3
export MPLBACKEND=Agg
if [ "${1:-}" = "--fast" ]; then export CDPRID_FAST=1; shift; fi
if [ -z "${CDPRID_SHARED:-}" ] && [ -d ../shared/datasets ]; then
  CDPRID_SHARED="$(cd ../shared && pwd)"; export CDPRID_SHARED
fi
"$PY" - "$@" <<'PYEOF'
import os
import sys
import time
from pathlib import Path

import nbclient
import nbformat

root = Path.cwd()
out = root / "results" / "notebooks"
out.mkdir(parents=True, exist_ok=True)
shared = os.environ.get("CDPRID_SHARED")
have_shared = bool(shared) and Path(shared, "datasets").is_dir()
wanted = sys.argv[1:]
failed = []
for path in sorted((root / "notebooks").glob("*.ipynb")):
    if wanted and not any(path.name.startswith(w) for w in wanted):
        continue
    nb = nbformat.read(path, as_version=4)
    src = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
    needs = "shared" in src and ("find_shared" in src or "../shared" in src) \
        and "if shared:" not in src and "if SHARED is not None:" not in src
    if needs and not have_shared:
        print(f"[notebooks] skip {path.name}: it reads the shared datasets and ../shared is "
              "absent (set CDPRID_SHARED)")
        continue
    t0 = time.perf_counter()
    client = nbclient.NotebookClient(nb, timeout=1800, kernel_name="python3",
                                     resources={"metadata": {"path": str(path.parent)}})
    try:
        client.execute()
        status = "ok"
    except Exception as exc:  # noqa: BLE001 - report and go on with the others
        status = f"FAILED ({type(exc).__name__})"
        failed.append(path.name)
    nbformat.write(nb, out / path.name)
    print(f"[notebooks] {path.name}: {status} in {time.perf_counter() - t0:.0f} s -> "
          f"{(out / path.name).relative_to(root)}")
    try:
        from nbconvert import HTMLExporter
    except ImportError:
        continue
    html, _ = HTMLExporter().from_notebook_node(nb)
    (out / path.with_suffix(".html").name).write_text(html, encoding="utf-8")
if failed:
    sys.exit(f"[notebooks] failed: {', '.join(failed)}")
PYEOF
