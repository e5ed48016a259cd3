"""The Monte Carlo of ``benchmarks/currents.py --trajectory ... --compare`` with one of the
simulator's noises switched off (results/currents-designed.md, "Iyy and the drive intervals
over 60 seeds"): which noise the drive intervals' std deficit comes from.

Run from the repository root:
    PYTHONPATH=. python results/currents-designed/noise_coverage.py ROBOT SEEDS KIND DUMP
ROBOT six-suspended | eight-craft, SEEDS the number of seeds (0 ..), KIND all | nopose
(position and rotation noise off) | nopos | norot | nolen (encoder noise off) | nocur, DUMP
the JSON-lines file of ``--dump`` (appended to).
"""
import functools
import sys
from pathlib import Path

import benchmarks.currents as bc
from tests.identify import winch_sim

name, seeds, kind, dump = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
off = {"all": {}, "nopose": dict(noise_pos=0.0, noise_rot=0.0), "nopos": dict(noise_pos=0.0),
       "norot": dict(noise_rot=0.0), "nolen": dict(noise_len=0.0),
       "nocur": dict(noise_A=0.0)}[kind]
# the noise draws of a seed stay the same (the simulator draws them whatever their level)
winch_sim.simulate = functools.partial(winch_sim.simulate, **off)
csv = Path(bc.__file__).resolve().parents[1] / "results/currents-designed" / (
    ("eight" if name == "eight-craft" else "six") + "-trajectory.csv")
path = winch_sim.path_from_csv(str(csv))
bc.compare(name, seeds, path.duration, lambda lines: None, path=path, dump=dump)
