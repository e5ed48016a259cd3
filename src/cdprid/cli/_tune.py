"""``cdprid tune``: tune a differentiator's parameters for a noise level.

The noise level comes from ``--noise-std M`` or is estimated from a dataset
(``--dataset DIR``, robust 4th differences; no ground truth needed).  The
training signals are, by default, the dataset's own smoothed trajectory when
``--dataset`` is given, else a family of ramped orbits (0.1-0.8 Hz, several
radii and planes, :data:`cdprid.tuning.TRAIN_FAMILY`); ``--train-signal circle``
is the old benchmark circle (R 0.3 m, 0.25 Hz).  The tuning is constrained so
that the acceleration frequency response stays within stated bounds up to a
stated bandwidth (``--bandwidth``, default from the training signals' content)
and has no resonance above it; the result is verified on a dense frequency grid
and a held-out family of trajectories.  Output: a JSON whose ``params`` (or the
whole file) can be passed to ``cdprid differentiate --params`` and
``cdprid identify --differentiator NAME --params``.
"""

from __future__ import annotations

import json
import math
import sys

from cdprid.base import InputError

__all__ = ["configure"]


def _run(args) -> int:
    import cdprid.tuning as T

    say = (lambda s: None) if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    if (args.dataset is None) == (args.noise_std is None):
        raise InputError("give exactly one of --dataset DIR or --noise-std M.")
    if args.seeds < 1 or args.seeds > 64:
        raise InputError(f"--seeds must be between 1 and 64, got {args.seeds}.")
    if args.max_steps < 0:
        raise InputError(f"--max-steps must be >= 0, got {args.max_steps}.")
    if not (0.0 <= args.weight <= 1.0):
        raise InputError(f"--weight must lie in [0, 1], got {args.weight}.")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration >= 5.0):
        raise InputError(f"--duration must be at least 5 s, got {args.duration}.")
    known = (*T.SIHD_METHODS, *T.BASELINE_GRIDS)
    if args.method not in known:
        raise InputError(f"cannot tune method {args.method!r}; choose one of {', '.join(known)}.")
    if args.json:
        from cdprid.base import check_output
        from cdprid.io import dataset_inputs

        inputs = dataset_inputs(args.dataset) if args.dataset is not None else []
        check_output(args.json, force=args.force, flag="--json", inputs=inputs)
        check_output(_figure_path(args.json), force=args.force, flag="--json", inputs=inputs)
    if args.train_signal is None:
        args.train_signal = "dataset" if args.dataset is not None else "family"
    if args.train_signal == "dataset" and args.dataset is None:
        raise InputError("--train-signal dataset needs --dataset DIR.")
    _check_bounds_options(args)
    dt = 0.01
    signals = None
    if args.dataset is not None:
        from cdprid.io import align, read_dataset

        ds = read_dataset(args.dataset)
        noise = T.noise_from_dataset(ds)
        say(f"estimated position noise of {args.dataset}: {noise * 1e3:.4g} mm")
        if args.train_signal == "dataset":
            signals = [T.dataset_signal(ds)]
        dt = float(align(ds).dt)
    else:
        noise = float(args.noise_std)
        if not (math.isfinite(noise) and noise > 0):
            raise InputError(
                f"--noise-std must be a positive number of metres, got {args.noise_std}.")
        if noise > 0.05:
            raise InputError(f"--noise-std is in metres; {noise:g} m is implausibly large.")
    if args.bandwidth is not None and args.bandwidth > 0.45 / dt:
        raise InputError(f"--bandwidth {args.bandwidth:g} Hz is above 0.45 x the sampling rate "
                         f"({0.45 / dt:g} Hz).")
    if signals is None:
        signals = ([T.circle_signal(dt=dt, duration=args.duration or 52.0)]
                   if args.train_signal == "circle"
                   else T.trajectory_family("train", dt, args.duration or 25.0))
    bw = args.bandwidth if args.bandwidth is not None else T.content_bandwidth(signals)
    bounds = T.ResponseBounds(bw, args.gain_tol, args.phase_max, T.GAIN_MAX_BELOW,
                              args.gain_max_above)
    say(f"stated bandwidth {bw:g} Hz ("
        + ("--bandwidth" if args.bandwidth is not None else
           "99 % of the training accelerations' energy")
        + f"); bounds |gain - 1| <= {bounds.gain_tol:g}, |phase| <= {bounds.phase_max_deg:g} "
        f"deg below it, gain <= {bounds.gain_max_above:g} above it")
    S = args.seeds
    kw = dict(signals=signals, train_seeds=range(S), test_seeds=range(1000, 1000 + max(S, 4)),
              progress=say, bounds=bounds, constrain=not args.no_constraint,
              heldout=T.trajectory_family("heldout", dt, args.duration or 25.0))
    if args.method in T.SIHD_METHODS:
        res = T.tune(args.method, noise, objective=args.objective, weight=args.weight,
                     max_steps=args.max_steps, zeta_min=args.zeta_min, **kw)
    else:
        if args.objective != "accel":
            raise InputError("baselines are tuned on the acceleration objective only.")
        res = T.tune_baseline(args.method, noise, **kw)
    out = res.as_json()
    out["bandwidth_source"] = ("--bandwidth" if args.bandwidth is not None else
                               "99 % of the training accelerations' energy (rounded up to "
                               "0.05 Hz)")
    resp = res.response
    warns = out["warnings"]
    print(f"{res.method}: noise {noise * 1e3:.4g} mm, train RMSE {res.train_rmse:.4g}, "
          f"held-out seeds RMSE {res.test_rmse:.4g}, held-out trajectories RMSE "
          f"{out['heldout_rmse']:.4g}, paper gains {res.paper_rmse:.4g} m/s^2 "
          f"(tuning {res.wall_s:.1f} s wall, {res.cpu_s:.1f} s CPU)")
    print("params: " + json.dumps(res.params))
    print(resp.summary())
    for w in warns:
        print(f"warning: {w}", file=sys.stderr)
    if args.json:
        from cdprid.base import write_json
        from cdprid.report import plot_response

        print(f"wrote {write_json(args.json, out, force=args.force)}")
        print(f"wrote {plot_response(resp, _figure_path(args.json), res.method, force=args.force)}")
    return 0


def _check_bounds_options(args) -> None:
    """One-sentence errors for the response-bound options, before any work."""
    if args.bandwidth is not None and not (math.isfinite(args.bandwidth)
                                           and args.bandwidth >= 0.05):
        raise InputError(f"--bandwidth must be at least 0.05 Hz, got {args.bandwidth:g}.")
    if not (0 < args.gain_tol < 0.5):
        raise InputError(f"--gain-tol must lie in (0, 0.5), got {args.gain_tol:g}.")
    if not (0 < args.phase_max <= 90):
        raise InputError(f"--phase-max must lie in (0, 90] deg, got {args.phase_max:g}.")
    if not (args.gain_max_above >= 1.0):
        raise InputError(f"--gain-max-above must be at least 1, got {args.gain_max_above:g}.")


def _figure_path(json_path):
    from pathlib import Path

    p = Path(json_path)
    return p.with_name(p.stem + ".response.png")


def configure(p) -> None:
    """Give the ``tune`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)

    p.description = ("Tune SIHD gains by gradient through the scan (or a baseline's "
                     "hyperparameter by grid search) on noise realisations of a training signal "
                     "at the given or estimated position-noise level; report held-out RMSE vs "
                     "the paper gains.")
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
    p.add_argument("--train-signal", choices=["family", "circle", "dataset"], default=None,
                   help="the dataset's smoothed trajectory (default with --dataset), a family "
                   "of ramped orbits 0.1-0.8 Hz with several radii and planes (default with "
                   "--noise-std), or the benchmark circle R 0.3 m 0.25 Hz")
    p.add_argument("--bandwidth", type=V.positive_float, default=None,
                   help="stated bandwidth B, Hz: the acceleration gain stays within "
                   "--gain-tol of 1 and the phase within --phase-max up to B (default: the "
                   "frequency below which 99 %% of the training accelerations' energy lies, "
                   "rounded up to 0.05 Hz)")
    p.add_argument("--gain-tol", type=V.positive_float, default=0.05,
                   help="|gain - 1| bound up to the bandwidth (default 0.05)")
    p.add_argument("--phase-max", type=V.positive_float, default=30.0,
                   help="|phase| bound up to the bandwidth, deg (default 30)")
    p.add_argument("--gain-max-above", type=V.positive_float, default=1.05,
                   help="gain bound above the bandwidth: no resonance (default 1.05)")
    p.add_argument("--no-constraint", action="store_true",
                   help="tune without the response penalty (alpha free); the response is "
                   "still verified and reported")
    p.add_argument("--seeds", type=V.positive_int, default=4,
                   help="noise realisations used for tuning")
    p.add_argument("--max-steps", type=V.positive_int, default=60,
                   help="BFGS iterations (SIHD methods)")
    p.add_argument("--zeta-min", type=V.nonneg_float, default=None,
                   help="damping floor of SIHD-N root pairs (default of cdprid.tuning._tuning)")
    p.add_argument("--duration", type=V.duration_up_to(
                       V.TUNE_MAX_S, "every noise realisation of the signal is held in memory"),
                   default=None,
                   help="length of the training circle (default 52 s) or of each family and "
                   "held-out trajectory (default 25 s), s")
    p.add_argument("--json", help="write the result JSON here (with its acceleration frequency "
                   "response; the figure <stem>.response.png is written beside it)")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(func=_run)
