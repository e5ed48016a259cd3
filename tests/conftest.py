"""Strict numerics for the whole suite: float64 JAX, sample robots as fixtures."""

from __future__ import annotations

import os
from pathlib import Path

# XLA's compiler is most of the suite's time (a JAX monitoring listener, 2026-11-28: 85-95 % of
# the 10-60 s identify tests is trace + lower + compile, the compiled programs then run for
# under a second), so the suite asks JAX to compile with little optimization
# (jax_disable_most_optimizations: LLVM at -O0 without its expensive passes; XLA's HLO passes,
# hence the computation and its float64 arithmetic, are unchanged): tests/identify/test_eiv.py
# took 68 s of CPU compiled as users run it and 52 s so. Set before jax is imported, so the
# commands and notebook kernels the tests start inherit it. scripts/test.sh with CI=true sets
# it to 0: CI runs every test compiled exactly as users run them.
os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")

import jax  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_disable_most_optimizations",
                  os.environ["JAX_DISABLE_MOST_OPTIMIZATIONS"] not in ("", "0", "false", "False"))

# The persistent JAX compilation cache is off for the suite unless the caller sets
# CDPRID_CACHE_DIR: a whole-suite run (slow tests included) died in JAX's deserialisation of a
# cached executable (segfault in compilation_cache.get_executable_and_time, 2026-11-27, during
# tests/identify/test_online.py, after an in-process `cdprid` command had switched the cache on).
# Each test process then compiles what it uses; commands run in subprocesses inherit this.
os.environ.setdefault("CDPRID_CACHE_DIR", "off")


#: Compiled programs a test process keeps alive across test modules: after a module, JAX's
#: caches are dropped once more programs than this were compiled since they were last dropped
#: (``CDPRID_TEST_KEEP_PROGRAMS``; 0, the default: after every module that compiled any). The
#: default stays 0 until a CI run with the slow tests shows a larger bound safe: a crash in
#: XLA's compiler turns CI red, and 10 % of the suite's time does not pay for that risk.
KEEP_PROGRAMS = int(os.environ.get("CDPRID_TEST_KEEP_PROGRAMS", "0"))
_compiled = [0]


def _count_compiles(event: str, duration: float, **kw) -> None:
    if event == "/jax/core/compile/backend_compile_duration":
        _compiled[0] += 1


jax.monitoring.register_event_duration_secs_listener(_count_compiles)


@pytest.fixture(autouse=True, scope="module")
def _fresh_jax_executables_per_module():
    """Drop JAX's compiled executables after a test module once the process has compiled more
    than :data:`KEEP_PROGRAMS` programs since they were last dropped.

    One pytest process that had compiled the executables of ~400 tests segfaulted inside
    XLA:CPU's compiler (``backend_compile_and_load``, tests/identify/test_online.py, in CI and
    reproduced here twice at the same test); the same run with ``jax.clear_caches()`` after each
    module passed all 445 tests (2026-11-27). scripts/test.sh also runs one process per folder.
    Below the bound, the modules of a folder share what they compiled (the same simulator,
    identification and diagnosis programs are compiled by many modules; dropping them after
    every module recompiled them each time).
    """
    yield
    if os.environ.get("CDPRID_TEST_COUNT_COMPILES"):
        print(f"\n[compiled programs since the last drop: {_compiled[0]}]")
    if _compiled[0] > KEEP_PROGRAMS:
        jax.clear_caches()
        _compiled[0] = 0

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
DATASETS = SHARED / "datasets"


def shared_dataset(name: str) -> Path:
    """Path of a shared dataset, skipping the test with a clear reason when ../shared is absent."""
    p = DATASETS / name
    if not p.is_dir():
        pytest.skip(f"shared dataset {p} is not present (../shared is provided beside the repo)")
    return p


ROBOT_CRAFT = {
    "name": "test-craft",
    "gravity": [0.0, 0.0, -9.81],
    "limits": {"tension_min": 1.0, "tension_max": 150.0},
    "cable": [
        {"exit": [-1.9, -1.7, 2.6], "anchor": [0.14, -0.14, -0.10]},
        {"exit": [-1.95, -1.62, 2.6], "anchor": [-0.14, 0.10, 0.10]},
        {"exit": [-1.95, 1.62, 2.6], "anchor": [-0.14, -0.08, -0.10]},
        {"exit": [-1.9, 1.7, 2.6], "anchor": [0.14, 0.10, 0.10]},
        {"exit": [1.9, 1.7, 2.6], "anchor": [-0.14, 0.14, -0.10]},
        {"exit": [1.95, 1.62, 2.6], "anchor": [0.14, -0.10, 0.10]},
        {"exit": [1.95, -1.62, 2.6], "anchor": [0.14, 0.08, -0.10]},
        {"exit": [1.9, -1.7, 2.6], "anchor": [-0.14, -0.10, 0.10]},
    ],
}


def _with_pulleys(d: dict, r: float = 0.04) -> dict:
    out = {k: v for k, v in d.items() if k != "cable"}
    out["name"] = d["name"] + "-pulleys"
    out["cable"] = [dict(c, pulley_radius=r, pulley_axis=[0.0, 0.0, -1.0]) for c in d["cable"]]
    return out


ROBOT_FOUR = {
    "name": "test-four-tilted-pulleys",
    "gravity": [0.0, 0.0, -9.81],
    "cable": [
        {"exit": [1.066, 1.155, 1.839], "anchor": [0.075, 0.075, 0.266], "pulley_radius": 0.03,
         "pulley_axis": [0.1, 0.0, -1.0]},
        {"exit": [-1.066, 1.155, 1.839], "anchor": [-0.075, 0.075, 0.266], "pulley_radius": 0.03},
        {"exit": [-1.066, -1.155, 1.839], "anchor": [-0.075, -0.075, 0.266], "pulley_radius": 0.03},
        {"exit": [1.066, -1.155, 1.839], "anchor": [0.075, -0.075, 0.266], "pulley_radius": 0.03,
         "pulley_axis": [0.0, 0.2, -1.0], "pulley_reference": [0.0, 1.0, 0.0]},
    ],
}

SAMPLE_ROBOTS = {
    "craft": ROBOT_CRAFT,
    "craft-pulleys": _with_pulleys(ROBOT_CRAFT),
    "four-pulleys": ROBOT_FOUR,
}


@pytest.fixture(params=sorted(SAMPLE_ROBOTS), scope="session")
def robot(request):
    """Each sample robot in turn."""
    from cdprid.model import robot_from_dict

    return robot_from_dict(SAMPLE_ROBOTS[request.param], source=request.param)


@pytest.fixture(scope="session")
def sample_dataset(tmp_path_factory):
    """Folder of the package sample dataset (simulated 8-cable robot with rotation, truth in
    meta.toml); written once per session from ``cdprid.data`` (no ../shared needed)."""
    from cdprid.data import write_sample

    return write_sample(tmp_path_factory.mktemp("sample") / "sample-8cable")


@pytest.fixture(scope="session")
def craft_robot_toml(tmp_path_factory):
    """robot.toml of the built-in CRAFT-like robot (the same numbers as
    ``../shared/datasets/craft-sim-orbits/robot.toml``), written to a temporary folder."""
    import tomli_w

    from cdprid.model import CRAFT_LIKE

    path = tmp_path_factory.mktemp("craft-robot") / "robot.toml"
    with open(path, "wb") as fh:
        tomli_w.dump(CRAFT_LIKE, fh)
    return path


@pytest.fixture(scope="session")
def craft_orbits(tmp_path_factory):
    """The CRAFT-like paper-orbits dataset (52 s at 100 Hz, 0.2 mm / 0.5 N noise, seed 0)
    regenerated by the simulator: what ``../shared/datasets/craft-sim-orbits`` holds (the same
    robot, truth, trajectory and noise levels; another noise draw), so no ../shared is needed."""
    from cdprid.model import craft_like_robot, preset
    from cdprid.simulation import simulate, write_simulation

    robot = craft_like_robot()
    res = simulate(robot, preset("paper-orbits", robot), seed=0)
    return write_simulation(res, tmp_path_factory.mktemp("craft") / "craft-sim-orbits")


@pytest.fixture(scope="session")
def two_orbits():
    """Two tilted orbits of the CRAFT-like robot's workspace (an ``orbit_sequence`` with rest at
    both ends; about 12 s): the trajectory of tests/model/test_trajectories.py and
    tests/simulation/test_simulate.py, built once per session."""
    from cdprid.model import Orbit, orbit_sequence

    orbits = [
        Orbit(0.3, 0.4, 5.0, azimuth=0.3, tilt=1.0, phase=0.2, ramp=1.5),
        Orbit(0.2, 0.6, 4.0, azimuth=1.2, tilt=0.4, ramp=1.0, centre=(0.1, -0.1, 1.3)),
    ]
    return orbit_sequence(orbits, [0.0, 0.0, 1.2], 0.3, 0.4, 0.3, name="test")


@pytest.fixture
def rng():
    """A seeded numpy generator (no global random state)."""
    return np.random.default_rng(12345)


@pytest.fixture
def small_ds(tmp_path):
    """A small valid dataset written by the project's writer (5 s, 8 cables, static-ish)."""
    from cdprid.io import write_dataset
    from cdprid.model import robot_from_dict

    robot = robot_from_dict(ROBOT_CRAFT)
    t = np.arange(0, 5, 0.01)
    pos = np.column_stack([0.1 * np.sin(t), 0.1 * np.cos(t), 1.2 + 0 * t])
    q = np.tile([1.0, 0, 0, 0], (len(t), 1))
    tau = 20 + np.random.default_rng(0).normal(0, 0.5, (len(t), 8))
    return write_dataset(tmp_path / "ds", robot, t, pos, t, tau, quaternion=q)


def moving_position(t):
    """A smooth platform path (m) at times ``t`` for small dataset tests."""
    return np.column_stack([0.2 * np.sin(0.7 * t), 0.15 * np.cos(0.5 * t), 1.2 + 0.05 * np.sin(t)])


def smooth_tensions(t, m=8, seed=0):
    """Positive, smooth tensions (N) with 0.1 N of seeded noise at times ``t``."""
    rng = np.random.default_rng(seed)
    return 30 + 5 * np.sin(np.outer(t, np.ones(m)) + np.arange(m)) + rng.normal(0, 0.1, (len(t), m))


def write_moving_dataset(root, t, pos=None, tau=None, tt=None, **kw):
    """A spec-v1 dataset of the CRAFT-like test robot moving along :func:`moving_position`."""
    from cdprid.io import write_dataset
    from cdprid.model import robot_from_dict

    robot = robot_from_dict(ROBOT_CRAFT)
    pos = moving_position(t) if pos is None else pos
    tt = t if tt is None else tt
    tau = smooth_tensions(tt) if tau is None else tau
    return write_dataset(root, robot, t, pos, tt, tau, **kw)
