"""One look at report.html: the example dataset's diagnosis rendered by headless Chromium.

Usage: python -m benchmarks.report_example  -> results/report_example.png (the top of the page)
and results/report_example.md (the command and commit that made it).

Runs ``cdprid example`` and ``cdprid diagnose --report`` in a temporary folder, then
``chromium --headless --screenshot`` of ``report.html`` (Debian's ``chromium``).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CDPRID = [sys.executable, "-m", "cdprid"]


def main() -> int:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("needs chromium (apt-get install chromium)")
    out = ROOT / "results" / "report_example.png"
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        subprocess.run(CDPRID + ["example", "--out", "example"], check=True, cwd=t)
        subprocess.run(CDPRID + ["diagnose", "example", "--quiet", "--report", "report"],
                       check=True, cwd=t)
        subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu",
                        "--disable-quic", "--no-first-run", "--disable-background-networking",
                        "--disable-component-update", "--disable-sync", "--hide-scrollbars",
                        f"--user-data-dir={t / 'profile'}", f"--screenshot={out}",
                        "--window-size=1100,1500", (t / "report" / "report.html").as_uri()],
                       check=True, capture_output=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    (ROOT / "results" / "report_example.md").write_text(
        "# report.html of the example dataset\n\n"
        f"`results/report_example.png`: made by `python -m benchmarks.report_example` at commit "
        f"{commit}: `cdprid example --out example`, `cdprid diagnose example --report report`, "
        "then `chromium --headless --screenshot --window-size=1100,1500` of "
        "`report/report.html` (the top of the page).\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
