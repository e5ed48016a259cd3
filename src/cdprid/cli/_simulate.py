"""The ``cdprid simulate`` subcommand: write a synthetic spec-v1 dataset.

Usage::

    cdprid simulate --out DIR [--trajectory FILE | --preset NAME] [--robot ROBOT.toml]
                    [--effect NAME --param key=value ...] [--seed N] [--noise-pos M]
                    [--noise-tension N] [--noise-rot RAD] [--rate-pose HZ]
                    [--rate-tension HZ] [--duration S] [--lengths] [--noise-length M]
                    [--force]

``--effect`` may be repeated; the ``--param`` options after an ``--effect`` belong to it,
e.g. ``--effect tension_gain --param cable=3 --param gain=1.05``; vectors as
``displacement_m=0.01,0,-0.02`` or ``displacement_m=[0.01,0,-0.02]``.
"""

from __future__ import annotations

import argparse
import time

from cdprid.base import InputError

__all__ = ["configure", "run"]


class _Ordered(argparse.Action):
    """Collect --effect and --param in command-line order into one list."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = list(getattr(namespace, self.dest, None) or [])
        items.append((self.const, values))
        setattr(namespace, self.dest, items)


def _group_effects(items):
    from cdprid.effects import parse_effect

    groups: list = []
    for kind, value in items or []:
        if kind == "effect":
            groups.append((value, []))
        else:
            if not groups:
                raise InputError(
                    f"--param {value} comes before any --effect; put it after the "
                    "--effect it belongs to."
                )
            groups[-1][1].append(value)
    return [parse_effect(name, pairs) for name, pairs in groups]


def run(args) -> int:
    """Run ``cdprid simulate`` with parsed arguments (see :func:`configure`)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from pathlib import Path

    import numpy as np

    from cdprid.base import UserError, input_clash
    from cdprid.io import load_trajectory_csv
    from cdprid.model import craft_like_robot, load_robot, preset
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    start = time.perf_counter()
    out = args.out
    clash = input_clash(out, [args.robot, args.trajectory])
    if clash is not None:
        raise UserError(f"--out {out}: {clash}; choose another output folder.")

    if not args.force:
        clash = [
            f
            for f in ("robot.toml", "pose.csv", "tensions.csv", "meta.toml", "lengths.csv")
            if (Path(out) / f).exists()
        ]
        if clash:
            raise FileExistsError(
                f"{out}: already holds {', '.join(clash)}; refusing to overwrite (use --force)."
            )
    effects = _group_effects(args.effect_items)
    robot = load_robot(args.robot) if args.robot else craft_like_robot()
    if args.trajectory and args.preset:
        raise InputError("give either --trajectory or --preset, not both.")
    if args.duration is not None and not args.duration > 0:
        raise InputError(f"--duration must be a positive number of seconds, got {args.duration}.")
    if args.trajectory:
        traj = load_trajectory_csv(args.trajectory)
        if args.duration is not None:
            if args.duration < traj.t_end - traj.t_start:
                keep = np.asarray(traj.t) <= traj.t_start + args.duration + 1e-9
                if keep.sum() < 2:
                    raise InputError(
                        f"--duration {args.duration} s keeps fewer than 2 trajectory samples."
                    )
                traj = type(traj)(
                    t=traj.t[keep],
                    p=traj.p[keep],
                    v=traj.v[keep],
                    a=traj.a[keep],
                    q=None if traj.q is None else traj.q[keep],
                    omega=None if traj.omega is None else traj.omega[keep],
                    alpha=None if traj.alpha is None else traj.alpha[keep],
                    name=traj.name,
                )
    else:
        traj = preset(args.preset or "paper-orbits", robot, duration=args.duration)
    _check_samples(traj.t_end - traj.t_start, args.rate_pose, args.rate_tension)
    noise = SensorNoise(
        position_m=args.noise_pos, orientation_rad=args.noise_rot, tension_N=args.noise_tension,
        length_m=args.noise_length,
    )
    print(
        f"simulating '{traj.name}' ({traj.t_end - traj.t_start:g} s) on {robot.name} "
        f"({robot.n_cables} cables)...",
        flush=True,
    )
    res = simulate(
        robot,
        traj,
        effects=effects,
        noise=noise,
        rate_pose=args.rate_pose,
        rate_tension=args.rate_tension,
        seed=args.seed,
        lengths=args.lengths,
    )
    path = write_simulation(res, out, overwrite=args.force)
    names = ", ".join(e.name for e in res.effects) or "none"
    rot = "with quaternions" if res.quaternion is not None else "translation only"
    print(
        f"wrote {path}: {res.pose_t.size} pose samples ({rot}), {res.tension_t.size} tension "
        f"samples, tensions {res.tension.min():.1f} to {res.tension.max():.1f} N"
        + (f" ({res.n_qp} samples by QP)" if res.n_qp else "")
        + (", winch encoder lengths" if res.lengths is not None else "")
        + f", effects: {names} [{time.perf_counter() - start:.1f} s]"
    )
    return 0


def _check_samples(span_s: float, rate_pose: float, rate_tension: float) -> None:
    """Refuse, before any work, a recording with more samples per stream than memory holds
    (the bound is on samples: 4 h at 100 kHz passed a duration bound and ran out of memory)."""
    from cdprid.base import InputError
    from cdprid.cli._types import SIMULATE_MAX_SAMPLES

    for flag, rate in (("--rate-pose", rate_pose), ("--rate-tension", rate_tension)):
        n = span_s * rate
        if n > SIMULATE_MAX_SAMPLES:
            raise InputError(f"{flag} {rate:g} Hz over {span_s:g} s is {n:.3g} samples, more "
                             f"than the {SIMULATE_MAX_SAMPLES:,} a simulated stream may have "
                             "(every sample and its tension distribution are held in memory): "
                             "lower the rate or --duration.")


def configure(p: argparse.ArgumentParser) -> None:
    """Give the ``simulate`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it). The description lists the effect vocabulary and
    ``--preset`` the presets: building it imports :mod:`cdprid.effects` and
    :mod:`cdprid.model` (and so JAX)."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)
    from cdprid.effects import VOCABULARY
    from cdprid.model import PRESETS

    p.description = (
        "Simulate a cable robot following a trajectory and write pose, tensions "
        "and the truth as a spec-v1 dataset. Effects: "
        + "; ".join(f"{k} {{{', '.join(v)}}}" if v else k for k, v in VOCABULARY.items())
        + "."
    )
    p.add_argument("--out", required=True, help="dataset folder to write")
    p.add_argument("--trajectory", type=V.existing_file,
                   help="trajectory CSV (t,x,y,z,vx,...,az[,qw,...,alz])")
    p.add_argument(
        "--preset",
        choices=list(PRESETS),
        default=None,
        help="named trajectory (default paper-orbits)",
    )
    p.add_argument("--robot", type=V.existing_file,
                   help="robot.toml (default: the built-in CRAFT-like robot)")
    p.add_argument(
        "--effect",
        dest="effect_items",
        action=_Ordered,
        const="effect",
        metavar="NAME",
        help="inject an effect (repeatable)",
    )
    p.add_argument(
        "--param",
        dest="effect_items",
        action=_Ordered,
        const="param",
        metavar="KEY=VALUE",
        help="parameter of the preceding --effect",
    )
    p.add_argument("--seed", type=V.nonneg_int, default=0, help="noise seed (default 0)")
    p.add_argument(
        "--noise-pos", type=V.nonneg_float, default=2e-4,
        help="position noise std, m (default 2e-4)"
    )
    p.add_argument(
        "--noise-tension", type=V.nonneg_float, default=0.5,
        help="tension noise std, N (default 0.5)"
    )
    p.add_argument(
        "--noise-rot", type=V.nonneg_float, default=0.0,
        help="orientation noise std, rad (default 0)"
    )
    p.add_argument(
        "--lengths", action="store_true",
        help="also write lengths.csv (t,l_1..l_m: winch encoder lengths, m); always written "
        "with --effect cable_elasticity"
    )
    p.add_argument(
        "--noise-length", type=V.nonneg_float, default=5e-5,
        help="winch encoder (lengths.csv) noise std, m (default 5e-5)"
    )
    p.add_argument("--rate-pose", type=V.float_in(1.0, 1e5), default=100.0,
                   help="pose rate, Hz (default 100)")
    p.add_argument(
        "--rate-tension", type=V.float_in(1.0, 1e5), default=100.0,
        help="tension rate, Hz (default 100)"
    )
    p.add_argument(
        "--duration", type=V.duration_up_to(
            V.SIMULATE_MAX_S, "every stream and its tension distribution are held in memory"),
        default=None,
        help="duration, s (default: the trajectory's)"
    )
    p.add_argument("--force", action="store_true", help="overwrite an existing dataset")
    p.set_defaults(func=run, effect_items=[])
