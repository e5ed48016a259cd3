"""``cdprid excite``: optimise an excitation trajectory for a robot.

Writes ``DIR/trajectory.csv`` (100 Hz, columns of :mod:`cdprid.trajectories`),
``DIR/trajectory.png`` (3-D view: exit points, cables at a few instants, workspace box),
``DIR/dataset/`` (a simulated spec-v1 dataset along the optimised trajectory) and, with
``--json``, the before/after report. Existing outputs are never replaced without ``--force``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

__all__ = ["add_parser", "run", "plot_trajectory"]


def plot_trajectory(robot, traj, path, initial=None, title: str = "", n_cables_at: int = 4):
    """3-D figure of a trajectory inside the robot: exit points, cables, workspace box.

    Parameters
    ----------
    robot : CableRobot
    traj : Trajectory-like (``evaluate``, ``t_start``, ``t_end``)
    path : str or Path
        PNG file written.
    initial : Trajectory-like, optional
        Drawn dashed for comparison.
    n_cables_at : int
        Number of instants at which the cables are drawn.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .geometry import leave_points
    from .rotations import quat_to_matrix

    t = np.linspace(traj.t_start, traj.t_end, 1500)
    s = traj.evaluate(t)
    p = np.asarray(s.p)
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    A = np.asarray(robot.B_A)
    ax.scatter(A[:, 0], A[:, 1], A[:, 2], c="k", marker="^", label="exit points")
    lim = robot.limits
    if lim.workspace_min is not None and lim.workspace_max is not None:
        lo, hi = np.asarray(lim.workspace_min), np.asarray(lim.workspace_max)
        for i in range(8):
            for j in range(i + 1, 8):
                a = np.array([(hi if (i >> k) & 1 else lo)[k] for k in range(3)])
                b = np.array([(hi if (j >> k) & 1 else lo)[k] for k in range(3)])
                if np.sum(a != b) == 1:
                    ax.plot(*zip(a, b, strict=True), color="0.7", lw=0.8)
    if initial is not None:
        pi = np.asarray(initial.evaluate(t).p)
        ax.plot(pi[:, 0], pi[:, 1], pi[:, 2], "--", color="tab:gray", lw=1, label="initial")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], color="tab:blue", lw=1.2, label="optimised")
    P_b = np.asarray(robot.P_b)
    for k, idx in enumerate(np.linspace(0, len(t) - 1, n_cables_at + 2).astype(int)[1:-1]):
        R = np.asarray(quat_to_matrix(s.q[idx]))
        T = np.asarray(leave_points(robot, s.p[idx], R))
        Bw = p[idx] + P_b @ R.T
        for i in range(robot.n_cables):
            ax.plot(*zip(Bw[i], T[i], strict=True), color=f"C{1 + k}", lw=0.6)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(title or "excitation trajectory")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _initial_params(text, family):
    if not text:
        return None
    from .cli import load_json_object

    return load_json_object(text, "--initial", "a JSON object of the family's parameters")


def run(args) -> int:
    """Handler of ``cdprid excite``; returns the exit code."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from . import excitation as ex
    from .geometry import load_robot
    from .trajectories import save_trajectory_csv

    t_wall = time.perf_counter()
    robot = load_robot(args.robot)
    out = Path(args.out)
    targets = [out / "trajectory.csv", out / "trajectory.png", out / "dataset"]
    if args.json:
        targets.append(Path(args.json))
    existing = [str(p) for p in targets if p.exists()]
    if existing and not args.force:
        raise FileExistsError(f"{existing[0]}: already exists; refusing to overwrite (use --force).")
    if args.starts < 1:
        raise ValueError(f"--starts must be at least 1, got {args.starts}.")
    prob = ex.make_problem(robot, args.family, args.objective, model=args.model,
                           duration=args.duration)
    init = _initial_params(args.initial, prob.family)
    if init is not None:
        base = prob.family.initial_params(robot)
        unknown = sorted(set(init) - set(base))
        if unknown:
            raise ValueError(f"--initial: unknown parameter {unknown[0]!r} for the {args.family!r} "
                             f"family (known: {', '.join(base)}).")
        base.update({k: np.asarray(v, float) for k, v in init.items()})
        init = base
    res = ex.optimise_excitation(prob, n_starts=args.starts, seed=args.seed, initial_params=init,
                                 progress=True)
    out.mkdir(parents=True, exist_ok=True)
    save_trajectory_csv(res.trajectory, out / "trajectory.csv", rate_hz=100.0, overwrite=args.force)
    initial_traj = prob.family.trajectory(jax.numpy.asarray(res.initial.z))
    plot_trajectory(robot, res.trajectory, out / "trajectory.png", initial=initial_traj,
                    title=f"{prob.family.name}: cond {res.initial.cond:.2f} -> {res.optimised.cond:.2f}")
    dataset_note = None
    if not args.no_dataset:
        try:
            from .simulate import simulate, write_simulation
        except ImportError:
            dataset_note = "cdprid.simulate is not available; no dataset written."
        else:
            sim = simulate(robot, res.trajectory, seed=args.seed)
            write_simulation(sim, out / "dataset", overwrite=args.force)
    data = res.as_json()
    data["wall_time_s"] = time.perf_counter() - t_wall
    data["outputs"] = {"trajectory_csv": str(out / "trajectory.csv"),
                       "figure": str(out / "trajectory.png"),
                       "dataset": None if (dataset_note or args.no_dataset) else str(out / "dataset")}
    if dataset_note:
        data["note"] = (data["note"] + " " + dataset_note).strip()
    i, o = res.initial, res.optimised
    print(f"family {prob.family.name}, model {prob.model}, objective {prob.objective}")
    print(f"{'':12s}{'cond':>10s}{'cond_scaled':>13s}{'margin N':>10s}  certified")
    for name, r in (("initial", i), ("optimised", o)):
        print(f"{name:12s}{r.cond:10.3f}{r.cond_scaled:13.3f}{r.min_tension_margin_N:10.2f}  {r.certified}")
    worst = max(o.rel_sigma, key=lambda k: i.rel_sigma[k])
    print(f"predicted relative sigma of {worst}: {100 * i.rel_sigma[worst]:.3g} % -> "
          f"{100 * o.rel_sigma[worst]:.3g} % (sigma_rho = {prob.sigma_rho} N)")
    if res.note:
        print(f"note: {res.note}")
    print(f"wrote {out / 'trajectory.csv'}, {out / 'trajectory.png'}"
          + ("" if data["outputs"]["dataset"] is None else f", {out / 'dataset'}"))
    if args.json:
        from .cli import write_json

        print(f"wrote {write_json(args.json, data)}")
    return 0


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``cdprid excite`` on an argparse subparsers object."""
    p = subparsers.add_parser(
        "excite", help="optimise an excitation trajectory (condition number of W_ID)",
        description="Optimise an exciting trajectory for the identification of the platform's "
        "inertial parameters: minimise cond(W_ID) (or D-optimality) over a trajectory family, "
        "subject to the workspace box, the cable speed limit and tension feasibility (CasADi "
        "certificate). The initial design is the paper-like orbit (0.4 m, 0.25 Hz, horizontal, "
        "workspace centre).")
    p.add_argument("robot", help="robot.toml (spec v1)")
    p.add_argument("--family", choices=["orbit", "orbits", "fourier"], default="orbit",
                   help="trajectory family (default orbit; fourier rotates, for --model full)")
    p.add_argument("--duration", type=float, default=None,
                   help="trajectory duration, s (default 20 orbit, 52 orbits, 30 fourier)")
    p.add_argument("--objective", choices=["cond", "cond_scaled", "dopt", "sigma"], default="cond",
                   help="cond: raw condition number of W_ID; dopt: -log det of the information "
                   "matrix; sigma: worst predicted relative sigma")
    p.add_argument("--model", choices=["translation", "full"], default=None,
                   help="parameter model (default translation; full for --family fourier)")
    p.add_argument("--initial", help="initial design parameters as JSON (or a JSON file)")
    p.add_argument("--starts", type=int, default=4, help="number of optimiser starts (default 4)")
    p.add_argument("--out", default="excitation", help="output folder (default ./excitation)")
    p.add_argument("--json", help="write the before/after report as JSON to this file")
    p.add_argument("--seed", type=int, default=0, help="seed of the multi-start and simulation")
    p.add_argument("--no-dataset", action="store_true", help="do not simulate a dataset")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(func=run)
    return p
