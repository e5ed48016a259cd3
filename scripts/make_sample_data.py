"""Regenerate the package sample dataset src/cdprid/data/sample8_* (run from the repository root).

    PYTHONPATH=src python scripts/make_sample_data.py

An 8-cable suspended robot that is not the CRAFT-like one (3.0 m x 2.2 m frame at 2.3 m,
0.2 m x 0.16 m x 0.12 m platform, 6.3 kg), the ``rich`` trajectory preset with a 0.15 rad
rotation, 20 s, pose at 50 Hz, tensions at 100 Hz on their own clock, default sensor noise
(0.2 mm, 0.5 N), seed 7. The CSVs are written with 10 significant digits (far below the noise)
to keep the package small; meta.toml holds the truth and the settings.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

from cdprid.data import SAMPLE_ROBOT, SAMPLE_SETTINGS  # noqa: E402
from cdprid.model import robot_from_dict  # noqa: E402
from cdprid.model import preset  # noqa: E402
from cdprid.simulation import simulate, write_simulation  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src" / "cdprid" / "data"


def main() -> int:
    s = SAMPLE_SETTINGS
    robot = robot_from_dict(SAMPLE_ROBOT, source="cdprid.data.SAMPLE_ROBOT")
    traj = preset(s["trajectory"], robot, duration=s["duration_s"],
                  rotation_amplitude=s["rotation_amplitude_rad"])
    res = simulate(robot, traj, rate_pose=s["rate_pose_hz"], rate_tension=s["rate_tension_hz"],
                   seed=s["seed"])
    with tempfile.TemporaryDirectory() as tmp:
        d = write_simulation(res, Path(tmp) / "ds")
        for name in ("robot.toml", "meta.toml"):
            (OUT / f"sample8_{name}").write_text((d / name).read_text())
        for name in ("pose.csv", "tensions.csv"):
            lines = (d / name).read_text().splitlines()
            vals = np.loadtxt(d / name, delimiter=",", skiprows=1)
            with open(OUT / f"sample8_{name}", "w", encoding="utf-8") as fh:
                fh.write(lines[0] + "\n")
                np.savetxt(fh, vals, delimiter=",", fmt="%.10g")
    for f in sorted(OUT.glob("sample8_*")):
        print(f"wrote {f.relative_to(ROOT)} ({f.stat().st_size / 1024:.0f} KB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
