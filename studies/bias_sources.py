"""Where identify's second-order bias comes from: one noise source at a time (issue 24).

Two measurements on the benchmark robots of ``benchmarks/efficiency.py`` (``rich`` orbits,
26 s, 3 deg rotations):

* ``--mode bias``: antithetic pairs (each recording and its twin with every noise sample
  negated, :func:`efficiency._mirrored`) with only the chosen noise sources on; the pair means'
  average minus the truth is the bias, printed in % of the truth with its Monte-Carlo standard
  error. With tension noise alone the estimate is linear in the noise given the weights, so
  a bias there is a deterministic mismatch of the model, not noise.
* ``--mode mismatch``: noise-free data, ordinary least squares at a fixed cutoff: the rms of
  the residual ``F[W tau] - A theta_true`` per wrench row and the estimate's error, i.e. what
  the matched filtering leaves on exact data.

Run against another revision's code with ``PYTHONPATH=<worktree>/src``. Examples::

    python -m studies.bias_sources --robot eight --noise ten --pairs 3
    python -m studies.bias_sources --robot eight --noise ori --pairs 15 --weighting none
    python -m studies.bias_sources --robot eight --mode mismatch --cutoff 2
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

NOISE = {"pos": (3e-4, 0.0, 0.0), "ori": (0.0, 3e-4, 0.0), "ten": (0.0, 0.0, 0.5),
         "all": (3e-4, 3e-4, 0.5)}
PRINCIPAL = {"m": 0, "mzG": 3, "Ixx": 4, "Iyy": 7, "Izz": 9}


def _setup(robot_name: str):
    import jax

    jax.config.update("jax_enable_x64", True)
    from benchmarks import efficiency

    from cdprid.model import preset

    robot, truth, tau_ref = efficiency._case(robot_name)
    traj = preset("rich", robot, duration=26.0, rotation_amplitude=0.05)
    return efficiency, robot, truth, tau_ref, traj


def _identify(sim, tmp: Path, name: str, params: dict, weighting: str):
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset
    from cdprid.simulation import write_simulation

    ds = read_dataset(write_simulation(sim, tmp / name))
    return identify_dataset(ds, differentiator="euler-filtfilt", params=params,
                            weighting=weighting, bound=False)


def bias(args) -> None:
    from cdprid.simulation import SensorNoise, simulate

    efficiency, robot, truth, tau_ref, traj = _setup(args.robot)
    pos, ori, ten = NOISE[args.noise]
    noise = SensorNoise(pos, ori, ten, length_m=0.0)
    clean = simulate(robot, traj, truth, noise=SensorNoise(0.0, 0.0, 0.0, length_m=0.0),
                     seed=0, tau_ref=tau_ref)
    params = {} if args.cutoff is None else {"cutoff_hz": args.cutoff}
    means = []
    with tempfile.TemporaryDirectory() as tmp:
        for s in range(args.pairs):
            sim = simulate(robot, traj, truth, noise=noise, seed=args.seed0 + s, tau_ref=tau_ref)
            xs = [np.asarray(_identify(d, Path(tmp), f"{s}-{k}", params, args.weighting)
                             .result.x) for k, d in enumerate((sim, efficiency._mirrored(sim,
                                                                                         clean)))]
            means.append(0.5 * (xs[0] + xs[1]))
    means = np.array(means)
    t = np.asarray(truth.vector("full"))
    b = means.mean(axis=0) - t
    se = means.std(axis=0, ddof=1) / np.sqrt(len(means)) if len(means) > 1 else 0 * b
    print(f"{args.robot}, noise {args.noise}, weighting {args.weighting}, cutoff "
          f"{args.cutoff or 'from the data'}, {args.pairs} antithetic pairs: bias % of the truth")
    for name, i in PRINCIPAL.items():
        print(f"  {name:4s} {100 * b[i] / abs(t[i]):+7.3f} +- {100 * se[i] / abs(t[i]):.3f}")


def mismatch(args) -> None:
    from cdprid.simulation import SensorNoise, simulate

    _, robot, truth, tau_ref, traj = _setup(args.robot)
    sim = simulate(robot, traj, truth, noise=SensorNoise(0.0, 0.0, 0.0, length_m=0.0), seed=0,
                   tau_ref=tau_ref)
    with tempfile.TemporaryDirectory() as tmp:
        rep = _identify(sim, Path(tmp), "nf", {"cutoff_hz": args.cutoff or 4.0}, "none")
    reg, n = rep.regression, len(rep.regression.t)
    A, y = (np.asarray(v) for v in reg.wrench_block(0, n))
    th = np.asarray(truth.vector("full"))
    r = y - A @ th
    err = (np.asarray(rep.result.x) - th) / np.abs(th)
    print(f"{args.robot}, noise-free, OLS at {args.cutoff or 4.0:g} Hz")
    print("  residual rms per row (N, N, N, N m, N m, N m):",
          " ".join(f"{v:.1e}" for v in np.sqrt(np.mean(r ** 2, axis=0))))
    print("  inertia torque rms (N m):",
          " ".join(f"{v:.1e}" for v in np.sqrt(np.mean((A[:, 3:, 4:] @ th[4:]) ** 2, axis=0))))
    print("  error % of the truth:",
          " ".join(f"{k} {100 * err[i]:+.3f}" for k, i in PRINCIPAL.items()))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", choices=("six", "eight", "craft8"), default="eight")
    ap.add_argument("--mode", choices=("bias", "mismatch"), default="bias")
    ap.add_argument("--noise", choices=tuple(NOISE), default="all")
    ap.add_argument("--pairs", type=int, default=15)
    ap.add_argument("--seed0", type=int, default=7000)
    ap.add_argument("--weighting", choices=("eiv", "none"), default="eiv")
    ap.add_argument("--cutoff", type=float, default=None,
                    help="fixed cutoff, Hz (default: chosen from the data; mismatch: 4 Hz)")
    args = ap.parse_args(argv)
    if args.pairs < 1:
        ap.error("--pairs must be >= 1")
    (bias if args.mode == "bias" else mismatch)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
