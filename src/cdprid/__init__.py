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


def _shadow(name: str) -> property:
    # ``cdprid.simulate`` / ``cdprid.diagnose`` are the functions (as with eager imports), even
    # after the submodules of the same name are imported (the import system binds those here).
    return property(lambda self: _load(name), lambda self, value: None)


class _Package(types.ModuleType):
    simulate = _shadow("simulate")
    diagnose = _shadow("diagnose")


sys.modules[__name__].__class__ = _Package


# Modules of the flat layout (wave 1-2) and where they live now (issue 22's layout). Importing an
# old path still works for users' scripts, through a proxy module that warns once and forwards.
_MOVED = {
    "errors": "base._errors",
    "outputs": "base._outputs",
    "defaults": "base._defaults",
    "progress": "base._progress",
    "geometry": "model._geometry",
    "rotations": "model._rotations",
    "dynamics": "model._dynamics",
    "robots": "model._robots",
    "clearance": "model._clearance",
    "tensions": "model._tensions",
    "trajectories": "model._trajectories",
    "filters": "signal._filters",
    "differentiators": "signal._differentiators",
    "sihd_high": "signal._sihd_high",
    "motion": "core._motion",
    "regression": "core._regression",
    "identification": "core._identification",
    "covariance": "core._covariance",
    "nuisance": "core._nuisance",
    "physical": "core._physical",
    "effects": "effects._effects",
    "simulate": "simulation._simulate",
    "pipeline": "identify._batch",
    "online": "identify._online",
    "real": "identify._real",
    "calibration": "identify._calibration",
    "excitation": "excitation._optimise",
    "excitation_check": "excitation._check",
    "excitation_families": "excitation._families",
    "excitation_safety": "excitation._safety",
    "tuning": "tuning._tuning",
    "cli": "cli._main",
    "cli_diagnose": "cli._diagnose",
    "cli_differentiate": "cli._differentiate",
    "cli_example": "cli._example",
    "cli_excite": "cli._excite",
    "cli_import": "cli._import",
    "cli_online": "cli._online",
    "cli_simulate": "cli._simulate",
    "cli_tune": "cli._tune",
    "cli_types": "cli._types",
    "plots": "report.figures",
}


class _MovedModule(types.ModuleType):
    """Proxy for a module's former path: attribute reads forward to the module's new home."""

    def __init__(self, name: str, target: str):
        super().__init__(name)
        self.__dict__["_target"] = target

    def __getattr__(self, attr):
        return getattr(importlib.import_module(self.__dict__["_target"]), attr)

    def __dir__(self):
        return dir(importlib.import_module(self.__dict__["_target"]))


class _MovedFinder:
    """``sys.meta_path`` finder for ``cdprid.<old module>``: warns, naming the new home."""

    @staticmethod
    def find_spec(fullname, path=None, target=None):
        head, _, tail = fullname.partition(".")
        if head != __name__ or tail not in _MOVED:
            return None
        import importlib.machinery
        import warnings

        new = f"{__name__}.{_MOVED[tail].partition('.')[0]}"
        warnings.warn(f"{fullname} moved into {new} (cdprid's layered layout); import from there",
                      DeprecationWarning, stacklevel=3)
        return importlib.machinery.ModuleSpec(fullname, _MovedFinder, origin=new)

    @staticmethod
    def create_module(spec):
        return _MovedModule(spec.name, f"{__name__}.{_MOVED[spec.name.partition('.')[2]]}")

    @staticmethod
    def exec_module(module):
        return None


if not any(isinstance(f, type) and f.__name__ == "_MovedFinder" for f in sys.meta_path):
    sys.meta_path.append(_MovedFinder)


def __dir__():
    return sorted({*globals(), *_LAZY})
