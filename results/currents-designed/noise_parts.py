"""The simulator's noises one at a time on a designed trajectory (results/currents-designed.md,
"Which estimator, and the output error on the designs"): per seed the output error's and the
corrected least squares' mass and m s_G errors (and the m s_G error per component, % of
|m s_G|) and the cutoff used.

Run from the repository root:
    PYTHONPATH=. python results/currents-designed/noise_parts.py REPEAT A-B KIND [ROBOT]
REPEAT the design's repetitions, A-B the seeds (B excluded), KIND none | current | pose (position
and rotation) | pos (position, 0.2 mm) | pos2 (position, 0.4 mm) | rot | len | all, ROBOT
eight-craft (default) or six-suspended; CUTOFF=HZ in the environment fixes the cutoff.
"""
import sys, tempfile
from pathlib import Path
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
from tests.identify import winch_sim
from benchmarks.currents import ROBOTS, PLATFORM, truth_vector
from cdprid.identify import identify_currents
from cdprid.io import read_dataset

rep_n, seeds, kind = int(sys.argv[1]), sys.argv[2], sys.argv[3]
name = sys.argv[4] if len(sys.argv) > 4 else "eight-craft"
csv = str(Path(__file__).resolve().parent) + "/" + ("eight" if name == "eight-craft" else "six") + "-trajectory.csv"
path = winch_sim.path_from_csv(csv, repeat=rep_n)
robot, tau_ref = ROBOTS[name]
noise = dict(noise_pos=0.0, noise_rot=0.0, noise_A=0.0, noise_len=0.0)
if kind in ("current", "all"): noise["noise_A"] = 0.03
if kind in ("pose", "all"): noise.update(noise_pos=2e-4, noise_rot=3e-4)
if kind in ("len", "all"): noise["noise_len"] = 5e-5
if kind == "pos": noise["noise_pos"] = 2e-4
if kind == "pos2": noise["noise_pos"] = 4e-4
if kind == "rot": noise["noise_rot"] = 3e-4
x = truth_vector(10)
a, b = map(int, seeds.split("-"))
for seed in range(a, b):
    with tempfile.TemporaryDirectory() as tmp:
        sim = winch_sim.simulate(robot, PLATFORM, seed=seed, duration=path.duration,
                                 tau_ref=tau_ref, path=path, **noise)
        ds = read_dataset(winch_sim.write(Path(tmp) / "s", robot, sim), require_tensions=False)
        r = identify_currents(ds, reference="drive:1", bound=False, estimator="oe",
                              params=({"cutoff_hz": float(__import__("os").environ["CUTOFF"])} if "CUTOFF" in __import__("os").environ else None))
        c = r.compared
        ms = lambda th: np.linalg.norm(th[1:4] - x[1:4]) / np.linalg.norm(x[1:4])
        print(f"{name} x{rep_n} {kind} fc {r.params.get('cutoff_hz')} seed {seed}: oe mass {100*(r.theta[0]/x[0]-1):+.3f} % "
              f"(std {100*r.std[0]/x[0]:.3f} %) msG {100*ms(r.theta):.2f} % ({np.array2string(100*(r.theta[1:4]-x[1:4])/np.linalg.norm(x[1:4]), precision=2)}); cls mass "
              f"{100*(c['cls_theta'][0]/x[0]-1):+.3f} % msG {100*ms(c['cls_theta']):.2f} %",
              flush=True)
