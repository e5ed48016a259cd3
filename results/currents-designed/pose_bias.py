"""Pose noise alone (or no noise) on a designed trajectory: the output error's error before and
after the pose-noise correction and the correction's shift, per platform parameter (x 1e4), cutoff
3.5 Hz. Run from the repository root: PYTHONPATH=src:. python
results/currents-designed/pose_bias.py ROBOT REPEAT pose|none SEEDS (e.g. eight-craft 4 pose 0,1,2)."""
import sys, tempfile
from pathlib import Path
import jax; jax.config.update("jax_enable_x64", True)
import numpy as np
from tests.identify import winch_sim
from benchmarks.currents import ROBOTS, PLATFORM, truth_vector
from cdprid.identify import identify_currents
from cdprid.io import read_dataset
name, rep_n, kind = sys.argv[1], int(sys.argv[2]), sys.argv[3]
seeds = [int(s) for s in sys.argv[4].split(",")]
csv = "results/currents-designed/" + ("eight" if name == "eight-craft" else "six") + "-trajectory.csv"
path = winch_sim.path_from_csv(csv, repeat=rep_n)
robot, tau_ref = ROBOTS[name]
noise = dict(noise_pos=0.0, noise_rot=0.0, noise_A=0.0, noise_len=0.0)
if kind == "pose": noise.update(noise_pos=2e-4, noise_rot=3e-4)
x = truth_vector(10)
for seed in seeds:
    with tempfile.TemporaryDirectory() as tmp:
        sim = winch_sim.simulate(robot, PLATFORM, seed=seed, duration=path.duration, tau_ref=tau_ref, path=path, **noise)
        ds = read_dataset(winch_sim.write(Path(tmp) / "s", robot, sim), require_tensions=False)
        r = identify_currents(ds, reference="drive:1", bound=False, estimator="oe", params={"cutoff_hz": 3.5})
        sh = r.compared.get("pose_shift")
        sh = np.zeros_like(r.theta) if sh is None else sh
        unc = r.theta + sh
        print(f"{name} x{rep_n} {kind} seed {seed}: (param: uncorrected error, shift, corrected error) x1e4 " + "; ".join(
            f"{n} {1e4*(unc[k]-x[k]):+.1f} {1e4*sh[k]:+.1f} {1e4*(r.theta[k]-x[k]):+.1f}" for k, n in enumerate(r.names[:10]) if n in ("mxG", "mzG", "Ixx", "Ixy", "Iyy")), flush=True)
