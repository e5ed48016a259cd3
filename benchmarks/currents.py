"""Monte Carlo of ``identify --source currents`` on an independent simulator (issue 41).

6- and 8-cable robots (the six-cable suspended one and the CRAFT-like eight), currents and
encoder lengths at 500 Hz (0.03 A, 0.05 mm), motion capture
at 100 Hz (0.2 mm, 0.3 mrad), no load cells; drive 1's torque constant exact
(``--reference drive:1``), the others' datasheet values up to 10 % off; reflected friction
2-10 N (viscous N s/m and Coulomb N), inertia 0.5-5 kg. The simulator is
``tests/identify/winch_sim.py`` (numpy, its own Newton-Euler, geometry and winch torque
balance). Writes ``results/currents.md``.

Run: ``nice -n 10 .venv/bin/python -m benchmarks.currents [--seeds 20] [--duration 30]``;
``--robot-toml DIR`` then ``cdprid excite DIR/ROBOT.toml --source currents --json x.json`` and
``--trajectory x.json --robot ROBOT``: the same Monte Carlo on the designed trajectory
(results/currents-designed.md).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

ROOT = Path(__file__).resolve().parents[1]

from tests.conftest import ROBOT_CRAFT  # noqa: E402  (the 8-cable CRAFT-like geometry, no pulleys)
from tests.identify import winch_sim  # noqa: E402

from cdprid.identify import identify_currents  # noqa: E402
from cdprid.io import read_dataset  # noqa: E402
from cdprid.model import SIX_SUSPENDED  # noqa: E402

# EIGHT_REDUNDANT is singular at its centre (smallest singular value of W 1e-3): the
# CRAFT-like suspended geometry instead (tensions 8-40 N on every seed)
ROBOTS = {"six-suspended": (dict(SIX_SUSPENDED, home=[0.0, 0.0, 1.4]), 40.0),
          "eight-craft": (dict(ROBOT_CRAFT, home=[0.0, 0.0, 1.3]), 30.0)}
PLATFORM = (6.0, np.array([0.01, -0.005, -0.05]), np.diag([0.06, 0.07, 0.09]))
KINDS = ("k", "J", "fv", "fc", "c")
ESTIMATOR = "cls"
"""The estimator of the plain run: results/currents.md is the corrected
least squares' table; ``--compare`` runs both."""


SIX_TWIN_DZ = 0.02
"""m: how much higher the six-suspended robot's design twin attaches cables 2, 4 and 6
(:func:`robot_toml`)."""
NOMINAL_DRIVE = {"drum_radius": 0.045, "gear_ratio": 12.5, "torque_constant": 0.099}
"""The middle of the simulator's draws (r 3-6 cm, N 5-20, k = N K_t / r 15-40 N/A: 27.5 N/A):
the nominal drive data of the robot.toml ``cdprid excite --source currents`` designs on."""


def robot_toml(name: str, path) -> Path:
    """Write the benchmark robot ``name`` as a robot.toml for ``cdprid excite``: the nominal
    drive data (:data:`NOMINAL_DRIVE`, drive 1 the scale reference, as ``--reference
    drive:1``) and the true platform (mass, centre of mass, inertia about G) with the default
    uncertainties; for six-suspended its design twin (the comment below)."""
    import tomli_w

    robot, _ = ROBOTS[name]
    d = {k: v for k, v in robot.items() if k != "home"}
    d["cable"] = [dict(c, **NOMINAL_DRIVE, drive_reference=j == 0)
                  for j, c in enumerate(robot["cable"])]
    if name == "six-suspended":
        # its crossed cable pairs (1-2, 3-4, 5-6) are the diagonals of a trapezoid whenever the
        # platform does not rotate: they meet at home and on every sum of sines (clearance
        # 0 m, which excite refuses; the simulator has no cable contact). The design's twin:
        # cables 2, 4 and 6 attached 2 cm higher (13.6 mm apart at home), clearance 1 mm
        for j in (1, 3, 5):
            d["cable"][j] = dict(d["cable"][j], anchor=[*d["cable"][j]["anchor"][:2],
                                                        d["cable"][j]["anchor"][2] + SIX_TWIN_DZ])
        d["limits"] = dict(d["limits"], cable_clearance=0.001)
        d["name"] = "six-suspended-design-twin"
    m, s, IG = PLATFORM
    d["platform"] = {"mass": m, "com": s.tolist(), "inertia": IG.tolist()}
    path = Path(path)
    with open(path, "wb") as fh:
        tomli_w.dump(d, fh)
    return path


def truth_vector(p):
    m, s, IG = PLATFORM
    IP = IG + m * (s @ s * np.eye(3) - np.outer(s, s))
    return np.array([m, *(m * s), IP[0, 0], IP[0, 1], IP[0, 2], IP[1, 1], IP[1, 2],
                     IP[2, 2]])[:p]


def one(robot, tau_ref, seed, duration, tmp, path=None, params=None):
    """(platform z, mass rel. error, m s_G rel. error, drive z (5, m), notes) of one seed
    (``path``: the platform's motion instead of the seed's sum of sines; ``params``: the
    differentiator's, e.g. ``{"cutoff_hz": 3.0}``, chosen from the data when None)."""
    sim = winch_sim.simulate(robot, PLATFORM, seed=seed, duration=duration, tau_ref=tau_ref,
                             path=path)
    ds = read_dataset(winch_sim.write(tmp / f"s{seed}", robot, sim), require_tensions=False)
    rep = identify_currents(ds, reference="drive:1", bound=False, estimator=ESTIMATOR,
                            params=params)
    m = len(robot["cable"])
    p = len(rep.names) - 5 * m
    x = truth_vector(p)
    est, std = rep.theta, rep.std
    z = (est[:p] - x) / std[:p]
    dz = ((est[p:] - sim["truth"].reshape(-1)) / np.where(std[p:] > 0, std[p:], np.inf))
    ms = np.linalg.norm(est[1:4] - x[1:4]) / np.linalg.norm(x[1:4])
    return z, est[0] / x[0] - 1, ms, dz.reshape(5, m), rep


_wrench_x = winch_sim.wrench_of_parameters


def bound(name, seed, sigma=0.03, tol=0.1, duration=30.0, amp=0.25, rot_amp=0.08, prior=True,
          path=None):
    """Cramer-Rao bound (%) of the mass and of m s_G (norm of the three std over |m s_G|) from
    the currents alone, on the simulator's recording of ``seed``: poses and lengths exact,
    white current noise ``sigma`` A at 500 Hz (250 Hz here, two samples averaged), drive 1's
    k known, the others' datasheet tolerance ``tol`` as priors (std tol k / sqrt(3)), the
    internal forces of a redundant robot a free nuisance per sample. A lower bound of any
    unbiased estimator's std on the noisy recording (which also has pose and encoder
    noise). ``path``: the platform's motion instead of the seed's sum of sines (the same
    drive draws)."""
    robot, tau_ref = ROBOTS[name]
    rng = np.random.default_rng(seed)
    A = np.array([c["exit"] for c in robot["cable"]], float)
    b = np.array([c["anchor"] for c in robot["cable"]], float)
    mc = len(A)
    own = winch_sim.Path(rng, robot.get("home"), [amp, amp, 0.6 * amp], rot_amp)
    path = own if path is None else path
    td = np.arange(0.0, duration, 1 / 500.0)[::2]  # every other sample: 250 Hz, sigma scaled
    p, v, a, R, om, al = winch_sim.rates(path, td)
    W = winch_sim.wrench_matrix(A, b, p, R)
    x0 = truth_vector(10)
    w0 = _wrench_x(x0, p, a, R, om, al)
    tau = winch_sim.tensions(W, w0, tau_ref)
    L0, L1, L2 = winch_sim.lengths(A, b, path, td)
    d = winch_sim.drive_truth(rng, mc)
    k, J, fv, fc, c = winch_sim.reflected(d)
    aa = 1 / k
    Z = np.stack([(_wrench_x(x0 + h, p, a, R, om, al) - _wrench_x(x0 - h, p, a, R, om, al))
                  / 2e-4 for h in 1e-4 * np.eye(10)], axis=2)  # (n, 6, 10), linear in x
    Wp = np.linalg.pinv(W)  # (n, m, 6)
    G = Wp @ Z  # tension's sensitivity to x (the least-norm part)
    q = 10 + 5 * mc
    Nn = None
    if mc > 6:
        Nn = np.linalg.svd(W)[2][:, 6:, :].transpose(0, 2, 1)  # (n, m, m-6) null space
    s = np.sign(L1)
    ipure = (tau - J * L2 - fv * L1 - fc * s + c)  # = k i (noise-free), per cable
    n = len(td)
    Jac = np.zeros((n, mc, q))
    Jac[:, :, :10] = aa[None, :, None] * G
    for j in range(mc):
        Jac[:, j, 10 + j] = ipure[:, j]          # d i / d a_j
        Jac[:, j, 10 + mc + j] = -aa[j] * L2[:, j]
        Jac[:, j, 10 + 2 * mc + j] = -aa[j] * L1[:, j]
        Jac[:, j, 10 + 3 * mc + j] = -aa[j] * s[:, j]
        Jac[:, j, 10 + 4 * mc + j] = aa[j]
    s2 = sigma ** 2 / 2  # two 500 Hz samples averaged per kept sample
    if Nn is None:
        F = np.einsum("nja,njb->ab", Jac, Jac) / s2
    else:  # internal forces: a free nuisance per sample (tau + N lam), projected out
        B = aa[None, :, None] * Nn  # (n, m, r)
        P = np.eye(mc)[None] - B @ np.linalg.solve(np.swapaxes(B, 1, 2) @ B, np.swapaxes(B, 1, 2))
        F = np.einsum("nja,njk,nkb->ab", Jac, P, Jac) / s2
    keep = np.r_[0:10, 11:q]  # a_1 known
    F = F[np.ix_(keep, keep)]
    if prior:
        for j in range(1, mc):
            F[10 + j - 1, 10 + j - 1] += 1 / (aa[j] * tol / np.sqrt(3)) ** 2
    C = np.linalg.inv(F)
    sd = np.sqrt(np.diag(C))
    return 100 * sd[0] / x0[0], 100 * np.linalg.norm(sd[1:4]) / np.linalg.norm(x0[1:4])


def row(name, Z, M, S, D, names, seconds, failed, untold=0) -> str:
    """One table row from the seeds so far."""
    Z, M, S, D = map(np.array, (Z, M, S, D))
    rmsz = np.sqrt(np.mean(Z ** 2, axis=0))
    cover = np.mean(np.abs(D) <= 1.96, axis=0)  # (5, m); the reference k_1 (std 0) counts
    cover[0, 0] = 1.0
    w = int(np.argmin(cover))
    return (f"| {name} | {len(M)} (+{untold} 'cannot tell', +{failed} infeasible) | "
            f"{100 * np.max(np.abs(M)):.2f} | "
            f"{100 * np.median(np.abs(M)):.2f} | {100 * np.max(S):.1f} | "
            f"{100 * np.median(S):.1f} | {np.max(rmsz):.2f} ({names[int(np.argmax(rmsz))]}) | "
            f"{' '.join(f'{n} {r:.2f}' for n, r in zip(names, rmsz, strict=True))} | "
            f"{100 * cover.min():.0f} % ({KINDS[w // cover.shape[1]]}_{w % cover.shape[1] + 1});"
            f" mean {100 * cover.mean():.0f} % | {seconds:.0f} s |")


def run(name: str, seeds: int, duration: float, write, path=None, params=None) -> str:
    """The table row of one robot; ``write(row)`` after every seed (partial results kept)."""
    robot, tau_ref = ROBOTS[name]
    t0 = time.perf_counter()
    Z, M, S, D, failed, untold = [], [], [], [], 0, 0
    line = ""
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            try:
                z, mr, ms, dz, rep = one(robot, tau_ref, seed, duration, Path(tmp), path,
                                         params)
            except ValueError as e:  # the independent simulator's slack-cable check
                failed += 1
                print(f"{name} seed {seed}: {e}", flush=True)
                continue
            if not np.isfinite(rep.std[0]):  # the command said "cannot tell"
                untold += 1
                print(f"{name} seed {seed}: cannot tell (mass {100 * mr:+.1f} %)", flush=True)
                line = row(name, Z or [z * 0], M or [0.0], S or [0.0], D or [dz * 0],
                           rep.names[:len(z)], time.perf_counter() - t0, failed, untold)
                write(line)
                continue
            Z.append(z), M.append(mr), S.append(ms), D.append(dz)
            print(f"{name} seed {seed}: mass {100 * mr:+.2f} %, m s_G {100 * ms:.1f} %, "
                  f"RMS z {np.sqrt(np.mean(z ** 2)):.2f}", flush=True)
            line = row(name, Z, M, S, D, rep.names[:len(z)], time.perf_counter() - t0, failed,
                       untold)
            write(line)
    return line


def compare_one(name, seed, duration, tmp, path=None, params=None):
    """Per estimator ``(z (p,), mass err, m s_G err, drive z (5m,), mass std / bound, mass
    bound %)`` (``path``: the platform's motion instead of the seed's sum of sines)."""
    robot, tau_ref = ROBOTS[name]
    sim = winch_sim.simulate(robot, PLATFORM, seed=seed, duration=duration, tau_ref=tau_ref,
                             path=path)
    ds = read_dataset(winch_sim.write(tmp / f"s{seed}", robot, sim), require_tensions=False)
    rep = identify_currents(ds, reference="drive:1", bound=False, estimator="oe",
                            params=params)
    c = rep.compared
    b_pct = bound(name, seed, duration=duration, path=path)[0]
    b_mass = b_pct / 100 * PLATFORM[0]
    p = len(rep.names) - 5 * len(robot["cable"])
    x, d = truth_vector(p), sim["truth"].reshape(-1)
    out = {}
    # the output error before the pose noise's correction (_currents_pose), from the same fit:
    # the shift added back, its Monte-Carlo covariance taken out (None: no correction made)
    sh = c.get("pose_shift")
    th_u, cov_u = ((rep.theta, rep.cov) if sh is None
                   else (rep.theta + sh, c.get("cov_uncorrected",
                                               rep.cov - c["pose_shift_cov"])))
    # the corrected estimate with session 13's covariance (the pose noise's first-order
    # variance not in the floor), for the intervals side by side
    cov_p = rep.cov if sh is None else cov_u + c["pose_shift_cov"]
    for key, th, cov in (("cls", c["cls_theta"], c["cls_cov"]), ("oe", rep.theta, rep.cov),
                         ("oe-uncorrected", th_u, cov_u), ("oe-nofirst", rep.theta, cov_p),
                         ("oe-sandwich", rep.theta, c["cov_sandwich"]),
                         ("oe-andrews", rep.theta, c["cov_andrews"]),
                         ("oe-model", rep.theta, c["cov_model"])):
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            dz = (th[p:] - d) / np.where(sd[p:] > 0, sd[p:], np.inf)
        ms = np.linalg.norm(th[1:4] - x[1:4]) / np.linalg.norm(x[1:4])
        out[key] = ((th[:p] - x) / sd[:p], th[0] / x[0] - 1, ms, dz, sd[0] / b_mass, b_pct)
    return out, rep.names[:p]


def compare(name, seeds, duration, write, path=None, row=None, params=None, dump=None,
            first=0):
    """Rows of the side-by-side comparison for one robot, rewritten after every seed
    (``path``: the designed motion; ``row(name, key, res, names)``: the row's format,
    :func:`compare_row` by default; ``dump``: a file each seed's results are appended to, one
    JSON line per seed; seeds ``first .. first + seeds - 1``)."""
    row = row or compare_row
    res = {"cls": [], "oe": [], "oe-uncorrected": [], "oe-nofirst": [], "oe-sandwich": [],
           "oe-andrews": [], "oe-model": []}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(first, first + seeds):
            try:
                out, names = compare_one(name, seed, duration, Path(tmp), path, params)
            except ValueError as e:
                print(f"{name} seed {seed}: {e}", flush=True)
                continue
            for k, v in out.items():
                res[k].append(v)
            if dump:
                _dump(dump, name, seed, names, out)
            print(f"{name} seed {seed}: " + "; ".join(
                f"{k} mass {100 * v[1]:+.2f} % (eff {v[4]:.2f}) m s_G {100 * v[2]:.1f} %"
                for k, v in out.items() if k in ("cls", "oe", "oe-uncorrected")), flush=True)
            dz, m = out["oe"][3], len(out["oe"][3]) // 5
            print(f"{name} seed {seed}: oe drive intervals missing: " + (", ".join(
                f"{KINDS[j // m]}_{j % m + 1} (z {dz[j]:+.2f})" for j in np.flatnonzero(
                    np.abs(dz) > 1.96)) or "none"), flush=True)
            write([row(name, k, v, names) for k, v in res.items()])


def _dump(file, name, seed, names, out):
    """Append one seed's :func:`compare_one` results to ``file`` as a JSON line."""
    import json

    rec = {"robot": name, "seed": seed, "names": list(names), "kinds": list(KINDS),
           "estimators": {k: {"z": np.asarray(v[0]).tolist(), "mass_err": float(v[1]),
                              "msg_err": float(v[2]), "drive_z": np.asarray(v[3]).tolist(),
                              "mass_std_over_bound": float(v[4]), "mass_bound_pct": float(v[5])}
                          for k, v in out.items()}}
    with open(file, "a") as fh:
        fh.write(json.dumps(rec, allow_nan=True) + "\n")


def compare_row(name, key, res, names) -> str:
    """One row: the estimator's errors, RMS z, coverage and efficiency over the seeds."""
    fin = [r for r in res if np.all(np.isfinite(r[0])) and np.isfinite(r[4])]
    untold = len(res) - len(fin)
    if not fin:
        return f"| {name} | {key} | 0 (+{untold} 'cannot tell') |" + " |" * 9
    Z, M, S, D, E = (np.array([r[i] for r in fin]) for i in range(5))
    rmsz = np.sqrt(np.mean(Z ** 2, axis=0))
    cover = np.mean(np.abs(D) <= 1.96, axis=0)
    cover[0] = 1.0  # k_1: the reference (std 0)
    w = int(np.argmin(cover))
    m = D.shape[1] // 5
    return (f"| {name} | {key} | {len(fin)} (+{untold} 'cannot tell') | "
            f"{100 * np.median(np.abs(M)):.2f} / {100 * np.max(np.abs(M)):.2f} | "
            f"{100 * np.median(S):.1f} / {100 * np.max(S):.1f} | {rmsz[0]:.2f} | "
            f"{np.max(rmsz):.2f} ({names[int(np.argmax(rmsz))]}) | "
            f"{100 * cover.min():.0f} % ({KINDS[w // m]}_{w % m + 1}); mean "
            f"{100 * cover.mean():.0f} % | {np.median(E):.2f} ({E.min():.2f}-{E.max():.2f}) |")


COMPARE_HEAD = ["| robot | estimator | seeds | mass error % median / worst | m s_G error % "
                "median / worst | mass RMS z | worst HAC RMS z | worst drive coverage | mass "
                "std / bound, median (range) |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--robot", choices=sorted(ROBOTS), action="append",
                    help="robots to run (default: all)")
    ap.add_argument("--out", default=None,
                    help="default results/currents.md, results/currents-ROBOT.md with one --robot")
    ap.add_argument("--bound", action="store_true",
                    help="print the mass and m s_G Cramer-Rao bounds per seed (no fit)")
    ap.add_argument("--merge", action="store_true",
                    help="write results/currents.md from the results/currents-ROBOT.md tables")
    ap.add_argument("--compare", action="store_true",
                    help="corrected least squares and output error side by side (one run per "
                         "seed), with each seed's mass bound")
    ap.add_argument("--trajectory", default=None,
                    help="the designed trajectory to record instead of each seed's sum of sines: "
                         "the JSON of `cdprid excite --json` (its trajectory.csv) or a "
                         "trajectory.csv; with one --robot, for its whole duration (--duration "
                         "ignored); writes results/currents-designed.md (default)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="with --trajectory: play it this many times back to back (it starts "
                         "and ends at rest at home)")
    ap.add_argument("--cutoff", type=float, default=None, metavar="HZ",
                    help="the differentiator's cutoff for every fit (default: chosen from the "
                         "data, as `identify`); with --trajectory the rows say it")
    ap.add_argument("--dump", default=None, metavar="FILE",
                    help="with --compare: append each seed's results (platform z, errors, drive "
                         "z per estimator) to FILE, one JSON line per seed")
    ap.add_argument("--first-seed", type=int, default=0, metavar="N",
                    help="with --compare: seeds N .. N + --seeds - 1 (to add seeds to a dump)")
    ap.add_argument("--robot-toml", default=None, metavar="DIR",
                    help="write DIR/ROBOT.toml for each robot (nominal drive data, drive 1 the "
                         "reference, the true platform) for `cdprid excite --source currents`")
    args = ap.parse_args(argv)
    if args.cutoff is not None and not (np.isfinite(args.cutoff) and args.cutoff > 0):
        print(f"--cutoff: {args.cutoff:g} Hz is not a positive number.", file=sys.stderr)
        return 2
    if args.first_seed < 0:
        print(f"--first-seed: {args.first_seed} is not a seed (0 or more).", file=sys.stderr)
        return 2
    params = None if args.cutoff is None else {"cutoff_hz": args.cutoff}
    if args.robot_toml:
        for name in args.robot or list(ROBOTS):
            print(f"wrote {robot_toml(name, Path(args.robot_toml) / f'{name}.toml')}")
        return 0
    if args.trajectory:
        return designed(args)
    if args.compare:
        out = Path(args.out or ROOT / "results" / "currents-oe.md")
        rows = {}

        def put(name, lines):
            rows[name] = lines
            out.write_text("\n".join(COMPARE_HEAD + [x for v in rows.values() for x in v])
                           + "\n")

        for name in args.robot or list(ROBOTS):
            compare(name, args.seeds, args.duration, lambda lines, name=name: put(name, lines),
                    params=params, dump=args.dump, first=args.first_seed)
        print(out.read_text())
        return 0
    if args.bound:
        for name in args.robot or list(ROBOTS):
            b = np.array([bound(name, seed, duration=args.duration) for seed in range(args.seeds)])
            print(f"| {name} | {args.seeds} | {np.median(b[:, 0]):.2f} | {b[:, 0].min():.2f}-"
                  f"{b[:, 0].max():.2f} | {np.median(b[:, 1]):.1f} | {b[:, 1].min():.1f}-"
                  f"{b[:, 1].max():.1f} |", flush=True)
        return 0
    if args.merge:
        found = [line for name in ROBOTS
                 for f in [ROOT / "results" / f"currents-{name}.md"] if f.exists()
                 for line in f.read_text().splitlines() if line.startswith(f"| {name} ")]
        (ROOT / "results" / "currents.md").write_text(_text(args, found))
        print(_text(args, found))
        return 0
    if args.out is None:
        one_robot = args.robot is not None and len(args.robot) == 1
        args.out = str(ROOT / "results" / (f"currents-{args.robot[0]}.md" if one_robot
                                           else "currents.md"))
    rows = {}

    def write(name, line):
        rows[name] = line
        Path(args.out).write_text(_text(args, list(rows.values())))

    for name in args.robot or list(ROBOTS):
        run(name, args.seeds, args.duration, lambda line, name=name: write(name, line),
            params=params)
    print(_text(args, list(rows.values())))
    return 0


def trajectory_csv(file) -> Path:
    """The trajectory.csv of ``cdprid excite``'s JSON (``outputs.trajectory_csv``, relative to
    the current folder or to the JSON's), or ``file`` itself when it is not JSON."""
    import json

    file = Path(file)
    if file.suffix.lower() != ".json":
        return file
    csv = Path(json.loads(file.read_text())["outputs"]["trajectory_csv"])
    return csv if csv.is_absolute() or csv.exists() else file.parent / csv


DESIGNED_HEAD = [
    "| robot | trajectory | seeds | worst mass error % | median mass error % | worst m s_G "
    "error % | median m s_G error % | worst HAC RMS z | RMS z per parameter | worst drive "
    "coverage | time |", "|---|---|---:|---:|---:|---:|---:|---:|---|---:|---:|"]


def designed(args) -> int:
    """``--trajectory``: the Monte Carlo on the designed trajectory; upserts the robot's row
    of results/currents-designed.md next to its sum-of-sines row of results/currents.md, and
    keeps the file's text from ``## Reading`` on."""
    if not args.robot or len(args.robot) != 1:
        print("--trajectory: give the one --robot it was designed for.", file=sys.stderr)
        return 2
    name = args.robot[0]
    if not Path(args.trajectory).is_file():
        print(f"--trajectory: {args.trajectory} is not a file.", file=sys.stderr)
        return 2
    try:
        csv = trajectory_csv(args.trajectory)
    except (ValueError, KeyError) as exc:  # not excite's JSON
        print(f"--trajectory: {args.trajectory} is not the JSON of `cdprid excite --json` "
              f"({exc}).", file=sys.stderr)
        return 2
    if not csv.is_file():
        print(f"--trajectory: {args.trajectory} names {csv}, which is not a file.",
              file=sys.stderr)
        return 2
    try:
        path = winch_sim.path_from_csv(csv, repeat=args.repeat)
    except (ValueError, IndexError, KeyError) as exc:
        print(f"--trajectory: {csv} is not a trajectory.csv of `cdprid excite` ({exc}).",
              file=sys.stderr)
        return 2
    if args.bound:
        b = np.array([bound(name, seed, duration=path.duration, path=path)
                      for seed in range(args.seeds)])
        print(f"| {name} | designed: {Path(args.trajectory).name} ({path.duration:.1f} s) | "
              f"{args.seeds} | {np.median(b[:, 0]):.2f} | {b[:, 0].min():.2f}-"
              f"{b[:, 0].max():.2f} | {np.median(b[:, 1]):.1f} | {b[:, 1].min():.1f}-"
              f"{b[:, 1].max():.1f} |", flush=True)
        return 0
    out = Path(args.out or ROOT / "results" / "currents-designed.md")
    rows, crows, tail = _designed_tables(out)
    label = (f" designed: {Path(args.trajectory).name}"
             + (f" x {args.repeat}" if args.repeat > 1 else "") + f" ({path.duration:.1f} s)"
             + (f", cutoff {args.cutoff:g} Hz " if args.cutoff is not None else " "))
    params = None if args.cutoff is None else {"cutoff_hz": args.cutoff}

    def write(line):
        cells = line.split("|")
        rows[f"{name}|{label.strip()}"] = "|".join(cells[:2] + [label] + cells[2:])
        _designed_write(out, args.seeds, rows, crows, tail)

    def write_compared(lines):
        for line in lines:
            cells = line.split("|")
            if cells[2].strip() in DESIGNED_COMPARED:
                crows[f"{name}|{label.strip()}|{cells[2].strip()}"] = "|".join(
                    cells[:2] + [label] + cells[2:])
        _designed_write(out, args.seeds, rows, crows, tail)

    if args.compare:
        compare(name, args.seeds, path.duration, write_compared, path=path,
                row=designed_compare_row, params=params, dump=args.dump, first=args.first_seed)
    else:
        run(name, args.seeds, path.duration, write, path=path, params=params)
    print(out.read_text())
    return 0


DESIGNED_COMPARED = ("cls", "oe", "oe-uncorrected")
"""The estimators of results/currents-designed.md's ``--compare`` table (the output error's
other covariances are printed per seed only through results/currents-oe.md's runs)."""
DESIGNED_COMPARE_HEAD = [
    "| robot | trajectory | estimator | seeds | mass error % median / worst | m s_G error % "
    "median / worst | mass RMS z | worst HAC RMS z | worst drive coverage | mass std / bound, "
    "median (range) | mass error % mean +- its std error; std over seeds | mass bound % "
    "median | RMS z per parameter |",
    "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]


def designed_compare_row(name, key, res, names) -> str:
    """:func:`compare_row` and three cells: the mass error's mean (with its standard error) and
    spread over the seeds (bias against spread), the median mass bound (%) and the RMS z of
    every platform parameter."""
    line = compare_row(name, key, res, names)
    fin = [r for r in res if np.all(np.isfinite(r[0])) and np.isfinite(r[4])]
    if len(fin) < 2:
        return line + " | | |"
    M = 100 * np.array([r[1] for r in fin])
    sd = M.std(ddof=1)
    return (line + f" {M.mean():+.2f} +- {sd / np.sqrt(len(M)):.2f}; {sd:.2f} | "
            f"{np.median([r[5] for r in fin]):.2f} | " + " ".join(
                f"{n} {z:.2f}" for n, z in zip(names, np.sqrt(np.mean(
                    np.array([r[0] for r in fin]) ** 2, axis=0)), strict=True)) + " |")


def _designed_tables(out):
    """results/currents-designed.md's rows: the plain Monte Carlo's (keyed robot|trajectory,
    with the sums of sines' rows of results/currents.md), the ``--compare`` table's (keyed
    robot|trajectory|estimator), and the text from ``## Reading`` on."""
    old = out.read_text() if out.exists() else ""
    cut = old.index("## Reading") if "## Reading" in old else len(old)
    old, tail = old[:cut], old[cut:]
    rows, crows, table = {}, {}, None
    for line in old.splitlines():
        if line.startswith("| robot "):
            table = crows if "| estimator |" in line else rows
        elif line.startswith("| ") and "---" not in line and table is not None:
            cells = [c.strip() for c in line.split("|")]
            table["|".join(cells[1:4] if table is crows else cells[1:3])] = line
    base = ROOT / "results" / "currents.md"
    label = " 30 s sums of sines (results/currents.md) "
    for line in base.read_text().splitlines() if base.exists() else []:
        cells = line.split("|")  # the Monte Carlo table's rows (not the bound's)
        if len(cells) > 2 and cells[1].strip() in ROBOTS and "'cannot tell'" in cells[2]:
            rows[f"{cells[1].strip()}|{label.strip()}"] = "|".join(cells[:2] + [label]
                                                                  + cells[2:])
    return rows, crows, tail


def _designed_write(out, seeds, rows, crows, tail):
    """Write results/currents-designed.md: the plain table, the ``--compare`` table (when it
    has rows) and the kept text."""
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    compared = ["", "Both estimators on the same recordings (`--compare`, one "
                "`identify_currents(..., estimator=\"oe\")` run per seed; `cls` its starting "
                "point); mass std / bound: that seed's Cramer-Rao bound of the same designed "
                "recording (`--bound`).", "", *DESIGNED_COMPARE_HEAD,
                *[crows[k] for k in sorted(crows)]] if crows else []
    out.write_text("\n".join([
        "# Identification from motor currents on a designed trajectory (issue 41)", "",
        "Generated by `benchmarks/currents.py --trajectory ... [--repeat N] [--compare] "
        f"--robot ... --seeds {seeds}` at {commit}, one robot per run (each run updates its "
        "rows). The recordings are those of results/currents.md (same simulator, noises, "
        "per-seed drive constants, drive 1 the reference), the platform's motion the designed "
        "trajectory (`cdprid excite --source currents`) instead of each seed's sum of sines. "
        f"The first table's fit is the benchmark's plain estimator (`{ESTIMATOR}`, the "
        "corrected least squares, as in results/currents.md).", "", *DESIGNED_HEAD,
        *[rows[k] for k in sorted(rows)], *compared, "", tail]))


def _text(args, rows) -> str:
    """results/currents.md."""
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    text = "\n".join([
        "# Identification from motor currents: Monte Carlo (issue 41)", "",
        f"Generated by `benchmarks/currents.py --seeds {args.seeds} --duration "
        f"{args.duration:g}` at {commit}. " + __doc__.split("\n\n")[1].replace("\n", " "), "",
        "Acceptance: mass within 1 %, m s_G within 5 %, HAC RMS z <= 1.3 per platform "
        "parameter over the seeds, every drive parameter inside its 95 % interval in >= 90 % "
        "of the seeds.", "",
        "| robot | seeds | worst mass error % | median mass error % | worst m s_G error % | "
        "median m s_G error % | worst HAC RMS z | RMS z per parameter | worst drive "
        "coverage | time |",
        "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|", *rows, ""])
    return text


if __name__ == "__main__":
    raise SystemExit(main())
