"""``cdprid excite``: optimise a safe excitation trajectory for a robot.

Writes into the folder ``--out`` (built whole, then renamed into place):
``trajectory.csv`` (100 Hz, columns of :mod:`cdprid.model._trajectories`; ``wx..alz`` are the
angular
velocity and acceleration in the BASE frame, rad/s and rad/s^2), ``trajectory.png`` (3-D view),
``safety.png`` (time series of tensions, cable speeds, acceleration, jerk, tilt, angular
velocity and clearances with their limits), ``dataset/`` (a simulated spec-v1 dataset along
the trajectory, unless ``--no-dataset``), and with ``--json`` the report. Existing outputs are
never replaced without ``--force``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

__all__ = ["configure", "run"]


def _initial_params(text, prob, flag="--initial"):
    """``--initial`` JSON over the default initial design (the gentle first run)."""
    if not text:
        return None
    import numpy as np

    from cdprid.base import UserError
    from cdprid.cli._json_args import load_json_object
    from cdprid.excitation import initial_design

    family = prob.family
    init = load_json_object(text, flag, "a JSON object of the family's parameters")
    base = dict(family.initial_params(prob.robot))
    unknown = sorted(set(init) - set(base))
    if unknown:
        raise UserError(f"{flag}: unknown parameter {unknown[0]!r} for the {family.name!r} "
                        f"family (known: {', '.join(base)}).")
    base = dict(initial_design(prob)[0])
    base.update({k: np.asarray(v, float) for k, v in init.items()})
    return base


def _print_limits(prob):
    import numpy as np

    lim = prob.limits
    used = set(lim.defaults_used)
    rows = [("tension_min", lim.tension_min, "N"), ("tension_max", lim.tension_max, "N"),
            ("cable_speed_max", lim.cable_speed_max, "m/s"),
            ("acceleration_max", lim.acceleration_max, "m/s^2"),
            ("jerk_max", lim.jerk_max, "m/s^3"),
            ("tilt_max", lim.tilt_max, "rad"),
            ("angular_velocity_max", lim.angular_velocity_max, "rad/s"),
            ("angular_acceleration_max", lim.angular_acceleration_max, "rad/s^2"),
            ("cable_clearance", lim.cable_clearance, "m")]
    print("limits (* = default, not in robot.toml):")
    for name, v, unit in rows:
        print(f"  {name:26s}{v:10.4g} {unit}{'  *' if name in used else ''}")
    star = "  *" if "workspace" in used else ""
    print(f"  {'workspace':26s}{list(lim.workspace_min)} .. {list(lim.workspace_max)} m{star}")
    box = prob.box
    print(f"platform uncertainty from {box.source}: {box.description['n_corners']} corners"
          + "".join(f"; {d} (default)" for d in box.description.get("defaults_used", [])))
    print(f"home {np.round(prob.home, 4).tolist()} m")


def _print_sigma(prob, res):
    i, o = res.initial, res.optimised
    print(f"predicted sigma (sigma_rho = {prob.sigma_rho} N per row; relative only where the "
          "nominal value is not 0):")
    for n in prob.names:
        ri, ro = i.rel_sigma[n], o.rel_sigma[n]
        rel = "" if ri is None or ro is None else f"   ({100 * ri:.3g} % -> {100 * ro:.3g} %)"
        print(f"  {n:6s}{i.sigma[n]:12.4g} -> {o.sigma[n]:12.4g}{rel}")


def _write_outputs(tmp, prob, res, args):
    import jax
    import numpy as np

    from cdprid.excitation import safety_series
    from cdprid.io import save_trajectory_csv
    from cdprid.report import plot_safety_series, plot_trajectory

    save_trajectory_csv(res.trajectory, tmp / "trajectory.csv", rate_hz=100.0)
    initial_traj = prob.homed(jax.numpy.asarray(res.initial.z))
    plot_trajectory(prob.robot, res.trajectory, tmp / "trajectory.png", initial=initial_traj,
                    box=(prob.limits.workspace_min, prob.limits.workspace_max),
                    title=f"{prob.family.name}: cond {res.initial.cond:.2f} -> "
                    f"{res.optimised.cond:.2f}")
    tr = res.trajectory
    t = np.arange(int(np.floor(tr.t_end * 100.0 + 1e-9)) + 1) / 100.0
    ser = safety_series(prob.robot, tr.evaluate(t), prob.limits, prob.box)
    plot_safety_series(ser, prob.limits, tmp / "safety.png",
                       title=f"{prob.family.name} excitation: checked quantities (dashed: limits)")
    if not args.no_dataset:
        from cdprid.simulation import simulate, write_simulation

        sim = simulate(prob.robot, res.trajectory, seed=args.seed)
        write_simulation(sim, tmp / "dataset", overwrite=True)


def run(args) -> int:
    """Handler of ``cdprid excite``; returns the exit code."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import cdprid.excitation as ex
    from cdprid.base import UserError, atomic_dir, check_output, write_json
    from cdprid.model import load_robot

    t_wall = time.perf_counter()
    robot = load_robot(args.robot)
    from cdprid.base import check_distinct

    check_distinct({"--out": args.out, "--json": args.json})
    out = check_output(args.out, args.force, "--out", kind="dir", inputs=[args.robot])
    if args.json:
        check_output(args.json, args.force, "--json", inputs=[args.robot])
    if args.starts < 1:
        raise UserError(f"--starts must be at least 1, got {args.starts}.")
    drives = None
    if args.source == "currents":
        from cdprid.io import read_drives

        drives = read_drives(args.robot)
    prob = ex.make_problem(robot, args.family, args.objective, model=args.model,
                           duration=args.duration, prior=args.prior, home=args.home,
                           source=args.source, drives=drives)
    init = _initial_params(args.initial, prob)
    _print_limits(prob)
    if args.gentle:
        if init is not None:
            raise UserError("--gentle writes the default gentle first run; it does not take "
                            "--initial (drop one of them).")
        res = ex.gentle_run(prob, move_home=args.home is None, progress=True)
    else:
        res = ex.optimise_excitation(prob, n_starts=args.starts, seed=args.seed,
                                     initial_params=init, progress=True)
    with atomic_dir(out, force=args.force) as tmp:
        _write_outputs(Path(tmp), prob, res, args)
    data = res.as_json()
    data["wall_time_s"] = time.perf_counter() - t_wall
    data["outputs"] = {"trajectory_csv": str(out / "trajectory.csv"),
                       "figure": str(out / "trajectory.png"),
                       "safety_figure": str(out / "safety.png"),
                       "dataset": None if args.no_dataset else str(out / "dataset")}
    data["csv_frames"] = ("x..az: position, velocity, acceleration of P, base frame; qw..qz: "
                          "platform -> base quaternion, scalar first; wx..wz, alx..alz: angular "
                          "velocity and acceleration in the base frame")
    i, o = res.initial, res.optimised
    print(f"family {prob.family.name}, model {prob.model}, objective {prob.objective}"
          + (f", source currents (joint platform and drive regressor, column-scaled; drive "
             f"{prob.reference + 1}'s constant the scale reference)"
             if prob.source == "currents" else ""))
    print(f"{'':12s}{'cond':>10s}{'cond_scaled':>13s}{'margin N':>10s}  certified")
    for name, r in (("initial", i), ("optimised", o)):
        print(f"{name:12s}{r.cond:10.3f}{r.cond_scaled:13.3f}{r.min_tension_margin_N:10.2f}  "
              f"{r.certified}")
    print(f"initial design: {res.initial_rule}")
    if not i.certified:
        print("initial design not certified: " + "; ".join(i.certificate.failed))
    pk = o.certificate.peaks
    print("optimised peaks: " + ", ".join(f"{k} {v:.4g}" for k, v in pk.items() if v is not None))
    _print_sigma(prob, res)
    print(f"duration {o.duration:.1f} s (moves from and back to home {o.t_move:.1f} s each)")
    if res.note:
        print(f"note: {res.note}")
    print(f"wrote {out}/ (trajectory.csv, trajectory.png, safety.png"
          + ("" if args.no_dataset else ", dataset/") + ")")
    if args.json:
        print(f"wrote {write_json(args.json, data)}")
    return 0


def configure(p: argparse.ArgumentParser) -> None:
    """Give the ``excite`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.cli import _types as V

    p.description = (
        "Optimise an exciting trajectory for the identification of the platform's "
        "inertial parameters: minimise cond(W_ID) (or D-optimality) over a trajectory family, "
        "subject to every limit of robot.toml (spec 1.1: workspace, cable speed, acceleration, "
        "jerk, tilt, angular velocity and acceleration, cable clearance; absent limits get "
        "stated defaults) and tension feasibility for every platform in the uncertainty box "
        "([platform] of robot.toml or --prior). The trajectory starts and ends at rest at "
        "--home; every check is recomputed exactly on the written 100 Hz grid.")
    p.add_argument("robot", help="robot.toml (spec v1.1)")
    p.add_argument("--family", choices=["orbit", "orbits", "fourier"], default="orbit",
                   help="trajectory family (default orbit; fourier rotates, for --model full)")
    p.add_argument("--duration", type=V.duration_up_to(
                       V.EXCITE_MAX_S, "the optimiser differentiates through every 100 Hz "
                       "sample"), default=None,
                   help="duration of the exciting part, s (default 20 orbit, 52 orbits, 30 "
                   "fourier); the moves from and back to home are added")
    p.add_argument("--objective", choices=["cond", "cond_scaled", "dopt", "sigma"], default="cond",
                   help="cond: raw condition number of W_ID; dopt: -log det of the information "
                   "matrix; sigma: worst predicted relative sigma")
    p.add_argument("--source", choices=["tensions", "currents"], default="tensions",
                   help="what the identification will measure: tensions (load cells, default) "
                        "or currents (motor currents and encoders: the design conditions the "
                        "joint regressor of the platform and every drive; robot.toml's "
                        "[[cable]] drive fields are needed)")
    p.add_argument("--model", choices=["translation", "full"], default=None,
                   help="parameter model (default translation; full for --family fourier)")
    p.add_argument("--prior", default=None,
                   help="JSON of an earlier `cdprid identify --json`: tensions are certified for "
                   "every parameter within its estimate +- 3 std (instead of robot.toml "
                   "[platform] and its uncertainty)")
    p.add_argument("--home", default=None,
                   help="home position x,y,z of P (m, base frame) where the trajectory starts and "
                   "ends at rest (default: the workspace centre)")
    p.add_argument("--initial", help="initial design parameters as JSON (or a JSON file)")
    p.add_argument("--starts", type=int, default=4, help="number of optimiser starts (default 4)")
    p.add_argument("--gentle", action="store_true",
                   help="do not optimise: write the gentle first run (the default initial "
                   "design: the paper's orbit scaled so that every peak is at most 50 %% of its "
                   "limit), certified like an optimised design; the first step of the workflow "
                   "gentle run -> identify -> excite --prior")
    p.add_argument("--out", default="excitation", help="output folder (default ./excitation)")
    p.add_argument("--json", help="write the before/after report as JSON to this file")
    p.add_argument("--seed", type=int, default=0, help="seed of the multi-start and simulation")
    p.add_argument("--no-dataset", action="store_true", help="do not simulate a dataset")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.set_defaults(func=run)
