"""Monte-Carlo coverage of identify's default std (HAC) vs eq. 20, on three robot geometries.

For each robot: ``--reps`` noisy simulations (rich orbits with 3 deg rotations, 0.3 mm /
0.3 mrad (``--orientation-noise``) / 0.5 N noise, the seed varies), identified with the default options of ``cdprid identify``
(model auto -> full, euler-filtfilt with matched filter, HAC std). Reported per parameter:
the RMS of the z-score ``(estimate - truth) / std`` for the HAC std and for eq. 20's i.i.d.
std, and the coverage of the nominal 95 % interval.

Run: ``PYTHONPATH=src python -m benchmarks.coverage [--reps 20]`` -> ``results/coverage.md``.
"""

from __future__ import annotations

import argparse
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from cdprid.identify import identify_dataset  # noqa: E402
from cdprid.io import read_dataset  # noqa: E402
from cdprid.model import (  # noqa: E402
    EIGHT_REDUNDANT,
    PARAMETER_NAMES,
    SIX_SUSPENDED,
    InertialParameters,
    craft_like_robot,
    craft_like_truth,
    preset,  # noqa: E402
    robot_from_dict,  # noqa: E402
)
from cdprid.simulation import SensorNoise, simulate, write_simulation  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


SMALL = InertialParameters(4.5, np.array([0.01, -0.005, -0.04]), np.diag([0.03, 0.035, 0.05]))


READING = [
    "## Reading", "",
    "* The tables above are from the command at the top (the weighting and orientation noise "
    "it names). The points below were measured in wave 2 with ordinary least squares and no "
    "orientation noise; results/efficiency.md compares the weightings with orientation noise.",
    "* Eq. 20 understates the spread of m 3-6 times (coverage 21-29 %): the filtered residuals "
    "are correlated over ~2 s (HAC bandwidth ~180 samples). It overstates the spread of the "
    "first moments and inertia (RMS z 0.4-0.9) because one pooled sigma_rho serves force and "
    "moment rows of very different noise. The HAC sandwich corrects both.",
    "* The default HAC std is the Bartlett sandwich with Andrews' AR(1) bandwidth and a "
    "jackknife (leave-one-window-out) leverage adjustment of each window's score "
    "(docs/uncertainty.md). Variants measured side by side on the same fits (one-off script "
    "patching the pipeline, not kept; 16 seeds x 3 "
    "robots, worst per-parameter RMS z / max |z|): plain Bartlett 1.55 / 3.91 (the previous "
    "default); with the fixed-b factor 1/(1-b+b^2/3) 1.49 / 3.76; bandwidth x2 1.88 / 4.89 "
    "(worse: the residual scores sum to zero, so longer windows shrink the meat); bandwidth "
    "floored at 2x the score autocorrelation's zero crossing 1.55 / 3.91 (never binding); "
    "Quadratic-Spectral kernel with Andrews' QS bandwidth 1.56 / 3.91; AR(1)-prewhitened "
    "Bartlett 0.73 / 1.84 (far too conservative: RMS z 0.4-0.7); leverage-adjusted windows "
    "1.36 / 3.45 on six-suspended, 1.07 / 2.50 on eight-redundant (chosen).",
    "* With 24 runs per robot an RMS z has a sampling error of about +-0.15 and a coverage "
    "+-4 %. With the chosen std, RMS z is at most 1.24 on the two non-CRAFT robots (m 1.20 and "
    "0.98; every m s_G <= 1.22; max |z| 3.45) and 1.56 for Iyy on the CRAFT-like robot (the "
    "other 9 parameters <= 1.20). The goal RMS <= 1.2 for every parameter is met within the "
    "sampling error except CRAFT-like Iyy, whose z has mean -0.27 and standard deviation "
    "1.54 over the same seeds: spread, not bias (the Iyy std is still ~1.5x too small there, "
    "or one heavy-tailed run); not yet fixed.",
    "* CRAFT-like Iyy, investigated again (perf session, one-off scripts, not kept; 12 seeds "
    "1000-1011 of the same data unless said). Default std: Iyy RMS z 1.51 (Iyz 1.30, Izz 1.22). "
    "(1) Bandwidth: an Andrews AR(1) bandwidth per parameter, on that parameter's own influence "
    "series (B s_t)_i, gives 115-160 samples for most parameters and 230-460 for Iyz/Izz (common "
    "bandwidth 115-125); Iyy RMS z 1.51 (unchanged), Iyz 1.25, Izz 1.18. The common bandwidth x2: "
    "Iyy 1.48. Not the bandwidth. (2) Trim 2 s instead of 1 s: Iyy 1.36 but Iyz 1.65: not edge "
    "transients. (3) Noise-free data on the same trajectory: Iyy error 0.0005 (0.02 std): no "
    "deterministic bias. (4) Tension noise alone (8 seeds): Iyy RMS z 1.67, mean z -1.16; "
    "position noise alone: Iyy 0.71 (but mzG 1.92, mean +1.88: position noise is an errors-in- "
    "variables bias of mzG, hidden by the tension noise at these levels). The Iyy excess comes "
    "with the tension noise, for which least squares is unbiased (the regressor is noise-free "
    "there), and these seeds' Iyy errors are mostly negative (z per seed -2.3, -3.4, -0.9, -1.2, "
    "0.9, -0.2, -1.4, -1.5, -0.9, -1.5, -0.1, -0.4), while the spread of the error (sd 0.025) "
    "equals the mean reported std (0.026). (5) Exact std by Monte Carlo over 300 tension-noise "
    "draws with the regressor fixed (seed 1000): the HAC std of one record is 0.65-1.74 times the "
    "exact value depending on the parameter and robot (CRAFT-like Iyy 0.91). Reading: the excess "
    "is the scatter of the HAC std estimated from one 24 s record (about +-30 %) meeting a run of "
    "same-sign errors in these seeds, not a bias; longer records (more Bartlett windows) shrink "
    "that scatter. Not fixed; no variant measured so far lowers Iyy without inflating others.",
    "",
]


def cases():
    """(name, robot, truth, pretension) of the three geometries."""
    return [
        ("six-suspended (6 cables, 4.5 kg)", robot_from_dict(SIX_SUSPENDED, source="six"),
         SMALL, 25.0),
        ("eight-redundant (8 cables, 4.5 kg)", robot_from_dict(EIGHT_REDUNDANT, source="eight"),
         SMALL, 40.0),
        ("craft-like (8 cables, 9.88 kg)", craft_like_robot(), craft_like_truth(), 25.0),
    ]


def run_case(robot, truth, tau_ref, reps, workdir, orientation_rad=3e-4, weighting="none"):
    traj = preset("rich", robot, duration=26.0, rotation_amplitude=0.05)
    z, zi, models, warns = [], [], set(), 0
    for seed in range(reps):
        sim = simulate(robot, traj, truth, noise=SensorNoise(
            position_m=3e-4, tension_N=0.5, orientation_rad=orientation_rad),
            seed=1000 + seed, tau_ref=tau_ref)
        d = write_simulation(sim, Path(workdir) / f"s{seed}", overwrite=True)
        rep = identify_dataset(read_dataset(d), weighting=weighting, bound=False)
        models.add(rep.model)
        warns += len(rep.warnings)
        x = np.asarray(truth.vector(rep.model))
        z.append((rep.result.x - x) / rep.result.std)
        zi.append((rep.result.x - x) / rep.result.std_iid)
    return np.array(z), np.array(zi), models, warns


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--out", default=str(ROOT / "results" / "coverage.md"))
    ap.add_argument("--orientation-noise", type=float, default=3e-4,
                    help="orientation noise std per axis, rad (issue 24: 0.3 mrad; 0 = none)")
    ap.add_argument("--weighting", default="none", help="identify's --weighting")
    args = ap.parse_args(argv)
    t0 = time.time()
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    lines = ["# Coverage of identify's std (HAC, the default) vs eq. 20", "",
             f"Generated by `PYTHONPATH=src python -m benchmarks.coverage --reps {args.reps} "
             f"--orientation-noise {args.orientation_noise:g} --weighting {args.weighting}` at "
             f"commit `{commit}` on {platform.machine()}, Python {platform.python_version()}; "
             f"{time.strftime('%Y-%m-%d %H:%M')}.", "",
             "Each robot: the `rich` preset shortened to 26 s, 3 deg rotations, 0.3 mm / "
             f"{1e3 * args.orientation_noise:g} mrad / 0.5 N noise, `identify` options model "
             f"auto, euler-filtfilt + matched filter, weighting {args.weighting}. "
             "z = (estimate - truth) / std. Goal: RMS(z) <= 1.2 for every parameter; coverage "
             "of the nominal 95 % interval near 95 %.", ""]
    names = PARAMETER_NAMES["full"]
    with tempfile.TemporaryDirectory() as wd:
        for label, robot, truth, tau_ref in cases():
            z, zi, models, warns = run_case(robot, truth, tau_ref, args.reps, wd,
                                            args.orientation_noise, args.weighting)
            lines += [f"## {label}", "",
                      f"models used: {', '.join(sorted(models))}; warnings over {args.reps} "
                      f"runs: {warns}", "",
                      "| parameter | RMS z (HAC) | max abs z (HAC) | 95 % coverage (HAC) "
                      "| RMS z (eq. 20) | 95 % coverage (eq. 20) |",
                      "|---|---:|---:|---:|---:|---:|"]
            for i, n in enumerate(names[: z.shape[1]]):
                lines.append(
                    f"| {n} | {np.sqrt(np.mean(z[:, i] ** 2)):.2f} | {np.abs(z[:, i]).max():.2f} "
                    f"| {100 * np.mean(np.abs(z[:, i]) < 1.96):.0f} % "
                    f"| {np.sqrt(np.mean(zi[:, i] ** 2)):.2f} "
                    f"| {100 * np.mean(np.abs(zi[:, i]) < 1.96):.0f} % |")
            lines.append("")
            print("\n".join(lines[-(z.shape[1] + 6):]), flush=True)
    lines += READING
    lines.append(f"Run time: {time.time() - t0:.0f} s.")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
