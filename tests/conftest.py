"""Strict numerics for the whole suite: float64 JAX, sample robots as fixtures."""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pytest

jax.config.update("jax_enable_x64", True)

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
    from cdprid.geometry import robot_from_dict

    return robot_from_dict(SAMPLE_ROBOTS[request.param], source=request.param)


@pytest.fixture(scope="session")
def sample_dataset(tmp_path_factory):
    """Folder of the package sample dataset (simulated 8-cable robot with rotation, truth in
    meta.toml); written once per session from ``cdprid.data`` (no ../shared needed)."""
    from cdprid.data import write_sample

    return write_sample(tmp_path_factory.mktemp("sample") / "sample-8cable")


@pytest.fixture
def rng():
    """A seeded numpy generator (no global random state)."""
    return np.random.default_rng(12345)
