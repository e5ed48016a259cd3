"""cdprid: dynamic identification of cable-driven parallel robots, in JAX.

The data path reads in one direction::

    io (dataset, aligned signals) -> motion (derivatives) -> regression (W_ID, Y_ID)
    -> identification (least squares) -> diagnose / report

Float64: call ``jax.config.update("jax_enable_x64", True)`` in your script (the CLI does it);
importing cdprid does not change JAX's configuration.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# Public names, imported on first use (PEP 562) so that ``import cdprid`` and ``cdprid --help``
# stay fast: JAX, SciPy and the models load only when a name below is touched.
_LAZY = {
    "METHODS": (".signal", "METHODS"),
    "differentiate": (".signal", "differentiate"),
    "PARAMETER_NAMES": (".model", "PARAMETER_NAMES"),
    "InertialParameters": (".model", "InertialParameters"),
    "platform_wrench": (".model", "platform_wrench"),
    "regressor_full": (".model", "regressor_full"),
    "regressor_translation": (".model", "regressor_translation"),
    "CableRobot": (".model", "CableRobot"),
    "cable_lengths": (".model", "cable_lengths"),
    "cable_vectors": (".model", "cable_vectors"),
    "leave_points": (".model", "leave_points"),
    "load_robot": (".model", "load_robot"),
    "unit_vectors": (".model", "unit_vectors"),
    "wrench_matrix": (".model", "wrench_matrix"),
    "LSResult": (".core", "LSResult"),
    "least_squares": (".core", "least_squares"),
    "Dataset": (".io", "Dataset"),
    "DatasetError": (".io", "DatasetError"),
    "align": (".io", "align"),
    "read_dataset": (".io", "read_dataset"),
    "write_dataset": (".io", "write_dataset"),
    "IdentificationReport": (".identify", "IdentificationReport"),
    "identify_dataset": (".identify", "identify_dataset"),
    "DiagnosisResult": (".diagnosis", "DiagnosisResult"),
    "diagnose": (".diagnosis", "diagnose"),
    "run_sweep": (".base", "run_sweep"),
    "VOCABULARY": (".effects", "VOCABULARY"),
    "Effect": (".effects", "Effect"),
    "OnlineStepper": (".identify", "OnlineStepper"),
    "online_identify": (".identify", "online_identify"),
    "online_init": (".identify", "online_init"),
    "craft_like_robot": (".model", "craft_like_robot"),
    "craft_like_truth": (".model", "craft_like_truth"),
    "SensorNoise": (".simulation", "SensorNoise"),
    "simulate": (".simulation", "simulate"),
    "write_simulation": (".simulation", "write_simulation"),
    "distribute_tensions": (".model", "distribute_tensions"),
    "feasibility_margin": (".model", "feasibility_margin"),
    "load_trajectory_csv": (".io", "load_trajectory_csv"),
    "preset": (".model", "preset"),
}

__all__ = [*_LAZY, "__version__"]


def _load(name: str):
    mod, attr = _LAZY[name]
    return getattr(importlib.import_module(mod, __name__), attr)


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'cdprid' has no attribute {name!r}")
    value = _load(name)
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *_LAZY})
