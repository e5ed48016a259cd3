"""Free motion on a UACDPR-like simulated recording: is the estimator unbiased where the truth
is known, and what do hand pushes and hand braking do to z_G (issue 41, item 3)?

The plant is ``tests/identify/free_sim.py`` (numpy, its own rigid body and elastic locked
cables) with the UACDPR's geometry (exits, attachments of IRMA4U_Mar25), mass 12.966 kg,
s_G = (0, 0, 0.173) m, I_G = diag(0.184, 0.115, 0.186) kg m^2, locked lengths that rest the
platform off centre as on the recording; its swing has the recording's frequencies
(1.8-2.2 Hz, 4 Hz in z). 37 s at 100 Hz, pushes of 0.8 s at the recording's push starts
(4.9, 12.0, 19.1, 27.7 s), pose noise as measured on the recording (0.07 mm, 0.4 mrad),
load cells exact plus 0.5 N noise. Scenarios: ``free`` (no push), ``pushed`` (pushes only),
``braked`` (pushes, and a hand braking the swing for 1 s in every decay:
``-c v_G``, ``-c_w omega`` at G). Each is fitted (a) by ``identify_free_motion`` (pushes
located by the episodes stage from the load cells) and (b) on the decays with the pushes and
brakings left out exactly (the rows of the same command), at several cutoffs.

Run: ``nice -n 10 .venv/bin/python -m benchmarks.free_motion_sim [--seeds 2]``.

``--mc N`` instead runs the load-cell Monte Carlo of ``tests/identify/test_free_motion.py``
(4-cable sim4 robot, 20 s, two pushes, pose noise 0.2 mm and 0.5 mrad times ``--noise``,
random cell gains and offsets; seeds 100, 101, ...) with and without the errors-in-variables
correction (``eiv``; a tree without it runs once) and prints every parameter's error in std
units (mean, RMS, largest) and the 95 % intervals' coverage of the platform parameters and of
the cells' gains and offsets.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

from tests.identify.free_sim import FreePlatform, noisy  # noqa: E402

from cdprid.identify import identify_free_motion  # noqa: E402
from cdprid.io import read_dataset, write_dataset  # noqa: E402
from cdprid.model import robot_from_dict  # noqa: E402

A = np.array([[1.065, -1.155, 1.839], [1.066, 1.155, 1.839], [-1.066, 1.155, 1.839],
              [-1.065, -1.155, 1.839]])
B = np.array([[0.075, -0.075, 0.266], [0.075, 0.075, 0.266], [-0.075, 0.075, 0.266],
              [-0.075, -0.075, 0.266]])
MASS, SG, IG = 12.966, np.array([0.0, 0.0, 0.173]), np.diag([0.1840, 0.1154, 0.1864])
P0 = [-0.158, -0.029, 0.583]
PUSH_STARTS = (4.9, 12.0, 19.1, 27.7)
BRAKES = (9.5, 16.5, 24.0, 33.0)
CUTOFFS = (2.0, 4.0, 8.0, 16.0, None)  # None: chosen from the data


def simulate(seed: int, scenario: str, folder: Path, duration: float = 37.0,
             brake=(15.0, 1.5)) -> tuple[Path, list]:
    """Write one simulated recording; return its folder and the spans (s) that are not free."""
    rng = np.random.default_rng(seed)
    pushes = [{"start_s": a, "end_s": a + 0.8,
               "force_N": (rng.normal(0, 15, 3) * [1, 1, 0.3]).tolist(),
               "moment_Nm": rng.normal(0, 2.0, 3).tolist()} for a in PUSH_STARTS]
    if scenario == "free":
        pushes = []
    brakes = [(a, a + 1.0, *brake) for a in BRAKES] if scenario == "braked" else []
    plant = FreePlatform(A, B, MASS, SG, IG, P0)
    t, P, Q, T = plant.run(duration, pushes, p_start=P0,
                           om_start=rng.normal(0, 0.8, 3) + [0.0, 1.0, 0.0], brakes=brakes)
    Pn, Qn = noisy(P, Q, rng, noise_pos=7e-5, noise_rot=4e-4)
    rd = {"name": "uacdpr-like", "cable": [{"exit": a.tolist(), "anchor": b.tolist()}
                                           for a, b in zip(A, B, strict=True)],
          "platform": {"mass": MASS, "mass_uncertainty": 0.0}}
    out = write_dataset(folder / f"{scenario}{seed}", robot_from_dict(rd), t, Pn, t,
                        T + 0.5 * rng.standard_normal(T.shape), quaternion=Qn)
    spans = [(p["start_s"], p["end_s"]) for p in pushes] + [(a, b) for a, b, _, _ in brakes]
    return out, spans


def exact_fit(ds, spans, cutoff: float) -> tuple[float, float]:
    """z_G and its HAC std with the given spans cut out of every stream (gaps: the command
    filters each remaining segment apart and trims its edges), nothing located."""
    def cut(t, *xs):
        keep = np.ones(len(t), bool)
        for a, b in spans:
            keep &= ~((t > a - 0.5) & (t < b + 0.5))
        return (t[keep],) + tuple(x[keep] for x in xs)

    pt, pos, q = cut(np.asarray(ds.pose_t), ds.position, ds.quaternion)
    tt, tau = cut(np.asarray(ds.tension_t), ds.tension)
    gapped = dataclasses.replace(ds, pose_t=pt, position=pos, quaternion=q, tension_t=tt,
                                 tension=tau)
    rep = identify_free_motion(gapped, reference="mass", params={"cutoff_hz": cutoff},
                               check_cutoff=False, keep_episodes=None)
    return float(rep.theta[3] / rep.theta[0]), float(rep.std[3] / rep.theta[0])


def cells_recording(seed: int, folder: Path, noise: float = 1.0):
    """The load-cell Monte Carlo's recording ``seed`` (as the test): its folder, the cells'
    gains and offsets, and the platform's true parameters (m, m s_G, I_P)."""
    from tests.identify.test_free_motion import IG as IG4
    from tests.identify.test_free_motion import MASS as M4
    from tests.identify.test_free_motion import SG as SG4
    from tests.identify.test_free_motion import A as A4
    from tests.identify.test_free_motion import B as B4

    rd = {"name": "sim4", "cable": [{"exit": a.tolist(), "anchor": b.tolist()}
                                    for a, b in zip(A4, B4, strict=True)],
          "platform": {"mass": M4, "mass_uncertainty": 0.0}}
    rng = np.random.default_rng(100 + seed)
    pushes = [{"start_s": t0, "end_s": t0 + rng.uniform(1.5, 2.5),
               "force_N": (rng.normal(0, 10, 3) * [1, 1, 0.3]).tolist(),
               "moment_Nm": rng.normal(0, 1.0, 3).tolist()} for t0 in (3.0, 11.0)]
    plant = FreePlatform(A4, B4, M4, SG4, IG4, [0.0, 0.0, 0.6])
    t, P, Q, T = plant.run(20.0, pushes, p_start=[0.0, 0.0, 0.6],
                           om_start=rng.normal(0, 0.5, 3))
    Pn, Qn = noisy(P, Q, rng, 2e-4 * noise, 5e-4 * noise)
    g, o = rng.uniform(0.85, 1.15, 4), rng.uniform(-5, 5, 4)
    out = write_dataset(folder / f"cells{seed}_{noise:g}", robot_from_dict(rd), t, Pn, t,
                        g * T + o + 0.5 * rng.standard_normal(T.shape), quaternion=Qn)
    IP = IG4 + M4 * (SG4 @ SG4 * np.eye(3) - np.outer(SG4, SG4))
    truth = np.array([M4, *(M4 * SG4), IP[0, 0], IP[0, 1], IP[0, 2], IP[1, 1], IP[1, 2],
                      IP[2, 2]])
    return out, g, o, truth


def monte_carlo(n: int, noise: float) -> None:
    """The load-cell Monte Carlo (module docstring): one table row per setting."""
    import inspect

    has_eiv = "eiv" in inspect.signature(identify_free_motion).parameters
    settings = (True, False) if has_eiv else (None,)
    z = {k: [] for k in settings}
    cells = {k: [0, 0] for k in settings}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(n):
            out, g, o, truth = cells_recording(seed, Path(tmp), noise)
            ds = read_dataset(out)
            for k in settings:
                kw = {} if k is None else {"eiv": k}
                rep = identify_free_motion(ds, reference="mass", params={"cutoff_hz": 4.0},
                                           check_cutoff=False, **kw)
                z[k].append((rep.theta - truth)[1:] / rep.std[1:])
                c = rep.cells
                cells[k][0] += int(np.sum(np.abs(c.gain - g) < 1.96 * c.gain_std)
                                   + np.sum(np.abs(c.offset - o) < 1.96 * c.offset_std))
                cells[k][1] += 8
                print(f"seed {seed} eiv {k}: z " + " ".join(
                    f"{v:+.2f}" for v in z[k][-1]), flush=True)
            names = rep.names[1:]
    print(f"\n| eiv | statistic | {' | '.join(names)} |")
    print("|---|---|" + "---:|" * len(names))
    for k in settings:
        Z = np.array(z[k])
        for lab, v in (("mean z", Z.mean(0)), ("RMS z", np.sqrt(np.mean(Z ** 2, 0))),
                       ("max abs z", np.max(np.abs(Z), 0)),
                       ("covered (95 %)", np.sum(np.abs(Z) < 1.96, 0))):
            fmt = "{:d}" if lab.startswith("covered") else "{:+.2f}"
            print(f"| {k} | {lab} | " + " | ".join(fmt.format(int(x) if fmt == "{:d}" else x)
                                                    for x in v) + " |")
        print(f"| {k} | load cells covered | {cells[k][0]} of {cells[k][1]} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--scenarios", default="free,pushed,braked")
    ap.add_argument("--mc", type=int, default=0, help="load-cell Monte Carlo seeds (0: off)")
    ap.add_argument("--noise", type=float, default=1.0, help="--mc pose noise factor")
    a = ap.parse_args()
    if a.mc:
        monte_carlo(a.mc, a.noise)
        return
    print("| scenario | seed | cutoff Hz | command: z_G (m) | episodes "
          "| exact spans out: z_G (m) |")
    print("|---|---:|---:|---|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(a.seeds):
            for sc in a.scenarios.split(","):
                out, spans = simulate(seed, sc, Path(tmp))
                ds = read_dataset(out)
                for c in CUTOFFS:
                    rep = identify_free_motion(ds, reference="mass", check_cutoff=False,
                                               params=None if c is None else {"cutoff_hz": c})
                    z, s = rep.theta[3] / rep.theta[0], rep.std[3] / rep.theta[0]
                    lab = f"{c:g}" if c else f"{rep.params['cutoff_hz']:g} (data)"
                    ze, se = exact_fit(ds, spans, float(rep.params["cutoff_hz"]))
                    print(f"| {sc} | {seed} | {lab} | {z:.4f} +- {s:.4f} | {len(rep.episodes)} "
                          f"| {ze:.4f} +- {se:.4f} |", flush=True)


if __name__ == "__main__":
    main()
