"""Synthetic measured data: plant, sensors and injectable effects (spec-v1 datasets)."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.simulation._simulate import SensorNoise as SensorNoise
from cdprid.simulation._simulate import SimResult as SimResult
from cdprid.simulation._simulate import plant_wrenches as plant_wrenches
from cdprid.simulation._simulate import simulate as simulate
from cdprid.simulation._simulate import write_simulation as write_simulation
