"""``cdprid tune``: tune a differentiator's parameters for a noise level.

The noise level comes from ``--noise-std M`` or is estimated from a dataset
(``--dataset DIR``, robust 4th differences; no ground truth needed).  The
training signal is the benchmark circle (R 0.3 m, 0.25 Hz, 52 s at the
dataset's rate or 100 Hz) or, with ``--train-signal dataset``, the dataset's
own smoothed trajectory.  Output: a JSON whose ``params`` (or the whole
file) can be passed to ``cdprid differentiate --params`` and
``cdprid identify --differentiator NAME --params``.
"""

from __future__ import annotations

import json
import math
import sys

__all__ = ["add_parser"]


def _run(args) -> int:
    from . import tuning as T

    say = (lambda s: None) if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    if (args.dataset is None) == (args.noise_std is None):
        raise ValueError("give exactly one of --dataset DIR or --noise-std M.")
    if args.seeds < 1 or args.seeds > 64:
        raise ValueError(f"--seeds must be between 1 and 64, got {args.seeds}.")
    if args.max_steps < 0:
        raise ValueError(f"--max-steps must be >= 0, got {args.max_steps}.")
    if not (0.0 <= args.weight <= 1.0):
        raise ValueError(f"--weight must lie in [0, 1], got {args.weight}.")
    if not (math.isfinite(args.duration) and args.duration >= 5.0):
        raise ValueError(f"--duration must be at least 5 s, got {args.duration}.")
    known = (*T.SIHD_METHODS, *T.BASELINE_GRIDS)
    if args.method not in known:
        raise ValueError(f"cannot tune method {args.method!r}; choose one of {', '.join(known)}.")
    if args.json:
        from .outputs import check_output

        check_output(args.json, force=args.force, flag="--json")
        check_output(_figure_path(args.json), force=args.force, flag="--json")
    if args.train_signal is None:
        args.train_signal = "dataset" if args.dataset is not None else "circle"
    dt = 0.01
    signal = None
    if args.dataset is not None:
        from .io import read_dataset

        ds = read_dataset(args.dataset)
        noise = T.noise_from_dataset(ds)
        say(f"estimated position noise of {args.dataset}: {noise * 1e3:.4g} mm")
        if args.train_signal == "dataset":
            signal = T.dataset_signal(ds)
        else:
            from .io import align

            dt = float(align(ds).dt)
    else:
        noise = float(args.noise_std)
        if not (math.isfinite(noise) and noise > 0):
            raise ValueError(
                f"--noise-std must be a positive number of metres, got {args.noise_std}.")
        if noise > 0.05:
            raise ValueError(f"--noise-std is in metres; {noise:g} m is implausibly large.")
        if args.train_signal == "dataset":
            raise ValueError("--train-signal dataset needs --dataset DIR.")
    if signal is None:
        signal = T.circle_signal(dt=dt, duration=args.duration)
    S = args.seeds
    kw = dict(signal=signal, train_seeds=range(S), test_seeds=range(1000, 1000 + max(S, 4)),
              progress=say)
    if args.method in T.SIHD_METHODS:
        res = T.tune(args.method, noise, objective=args.objective, weight=args.weight,
                     max_steps=args.max_steps, zeta_min=args.zeta_min, **kw)
    else:
        if args.objective != "accel":
            raise ValueError("baselines are tuned on the acceleration objective only.")
        res = T.tune_baseline(args.method, noise, **kw)
    out = res.as_json()
    resp = T.acceleration_response(res.method, res.params, dt=float(signal.dt))
    out["frequency_response"] = resp.as_json()
    warns = []
    if not resp.ok:
        warns.append(f"the tuned {res.method} resonates: acceleration gain up to "
                     f"{max(resp.gain_max_below, resp.gain_max_above):.3g} (bounds "
                     f"{T.GAIN_MAX_BELOW:g} below {resp.bandwidth_hz:.3g} Hz, {T.GAIN_MAX_ABOVE:g} "
                     "above): its small training RMSE does not hold on other motions.")
    out["warnings"] = warns
    print(f"{res.method}: noise {noise * 1e3:.4g} mm, train RMSE {res.train_rmse:.4g}, "
          f"held-out RMSE {res.test_rmse:.4g}, paper gains {res.paper_rmse:.4g} m/s^2 "
          f"(tuning {res.wall_s:.1f} s wall, {res.cpu_s:.1f} s CPU)")
    print("params: " + json.dumps(res.params))
    print(resp.summary())
    for w in warns:
        print(f"warning: {w}", file=sys.stderr)
    if args.json:
        from .outputs import write_json
        from .report.tuning import plot_response

        print(f"wrote {write_json(args.json, out, force=args.force)}")
        print(f"wrote {plot_response(resp, _figure_path(args.json), res.method, force=args.force)}")
    return 0


def _figure_path(json_path):
    from pathlib import Path

    p = Path(json_path)
    return p.with_name(p.stem + ".response.png")


def add_parser(sub) -> None:
    """Register ``cdprid tune``."""
    from . import cli_types as V  # option validators (cdprid.cli_types)
    p = sub.add_parser(
        "tune", help="tune a differentiator's parameters for the data's noise level",
        description="Tune SIHD gains by gradient through the scan (or a baseline's "
        "hyperparameter by grid search) on noise realisations of a training signal at the "
        "given or estimated position-noise level; report held-out RMSE vs the paper gains.")
    p.add_argument("--dataset", type=V.existing_dir,
                   help="estimate the position noise from this dataset (spec v1)")
    p.add_argument("--noise-std", type=V.positive_float, default=None, help="position noise std, m")
    p.add_argument("--method", default="sihd2-cascade",
                   help="sihd2-cascade (default), sihd3, sihd4, sihd5, or a baseline: "
                   "euler-filtfilt, euler-butter-causal, savgol, kalman, rts, levant")
    p.add_argument("--objective", choices=["accel", "params", "mix"], default="accel",
                   help="acceleration RMSE (default), identified-parameter error, or a mix")
    p.add_argument("--weight", type=V.float_in(0.0, 1.0), default=0.5,
                   help="weight of the parameter term in mix")
    p.add_argument("--train-signal", choices=["circle", "dataset"], default=None,
                   help="the dataset's smoothed trajectory (default with --dataset) or the "
                   "benchmark circle (default with --noise-std)")
    p.add_argument("--seeds", type=V.positive_int, default=4,
                   help="noise realisations used for tuning")
    p.add_argument("--max-steps", type=V.positive_int, default=60,
                   help="BFGS iterations (SIHD methods)")
    p.add_argument("--zeta-min", type=V.nonneg_float, default=None,
                   help="damping floor of SIHD-N root pairs (default of cdprid.tuning)")
    p.add_argument("--duration", type=V.positive_float, default=52.0,
                   help="training circle length, s")
    p.add_argument("--json", help="write the result JSON here (with its acceleration frequency "
                   "response; the figure <stem>.response.png is written beside it)")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_run)
