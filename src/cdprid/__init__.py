"""cdprid: dynamic identification of cable-driven parallel robots, in JAX.

The data path reads in one direction::

    io (dataset, aligned signals) -> motion (derivatives) -> regression (W_ID, Y_ID)
    -> identification (least squares) -> diagnose / report

Float64: call ``jax.config.update("jax_enable_x64", True)`` in your script (the CLI does it);
importing cdprid does not change JAX's configuration.
"""

from __future__ import annotations

import importlib
import sys
import types

__version__ = "0.1.0"

# Public names, imported on first use (PEP 562) so that ``import cdprid`` and ``cdprid --help``
# stay fast: JAX, SciPy and the models load only when a name below is touched.
_LAZY = {
    "METHODS": (".differentiators", "METHODS"),
    "differentiate": (".differentiators", "differentiate"),
    "PARAMETER_NAMES": (".dynamics", "PARAMETER_NAMES"),
    "InertialParameters": (".dynamics", "InertialParameters"),
    "platform_wrench": (".dynamics", "platform_wrench"),
    "regressor_full": (".dynamics", "regressor_full"),
    "regressor_translation": (".dynamics", "regressor_translation"),
    "CableRobot": (".geometry", "CableRobot"),
    "cable_lengths": (".geometry", "cable_lengths"),
    "cable_vectors": (".geometry", "cable_vectors"),
    "leave_points": (".geometry", "leave_points"),
    "load_robot": (".geometry", "load_robot"),
    "unit_vectors": (".geometry", "unit_vectors"),
    "wrench_matrix": (".geometry", "wrench_matrix"),
    "LSResult": (".identification", "LSResult"),
    "least_squares": (".identification", "least_squares"),
    "Dataset": (".io", "Dataset"),
    "DatasetError": (".io", "DatasetError"),
    "align": (".io", "align"),
    "read_dataset": (".io", "read_dataset"),
    "write_dataset": (".io", "write_dataset"),
    "IdentificationReport": (".pipeline", "IdentificationReport"),
    "identify_dataset": (".pipeline", "identify_dataset"),
    "DiagnosisResult": (".diagnosis", "DiagnosisResult"),
    "diagnose": (".diagnosis", "diagnose"),
    "VOCABULARY": (".effects", "VOCABULARY"),
    "Effect": (".effects", "Effect"),
    "OnlineStepper": (".online", "OnlineStepper"),
    "online_identify": (".online", "online_identify"),
    "online_init": (".online", "online_init"),
    "craft_like_robot": (".robots", "craft_like_robot"),
    "craft_like_truth": (".robots", "craft_like_truth"),
    "SensorNoise": (".simulate", "SensorNoise"),
    "simulate": (".simulate", "simulate"),
    "write_simulation": (".simulate", "write_simulation"),
    "distribute_tensions": (".tensions", "distribute_tensions"),
    "feasibility_margin": (".tensions", "feasibility_margin"),
    "load_trajectory_csv": (".trajectories", "load_trajectory_csv"),
    "preset": (".trajectories", "preset"),
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


def _shadow(name: str) -> property:
    # ``cdprid.simulate`` / ``cdprid.diagnose`` are the functions (as with eager imports), even
    # after the submodules of the same name are imported (the import system binds those here).
    return property(lambda self: _load(name), lambda self, value: None)


class _Package(types.ModuleType):
    simulate = _shadow("simulate")
    diagnose = _shadow("diagnose")


sys.modules[__name__].__class__ = _Package


def __dir__():
    return sorted({*globals(), *_LAZY})
