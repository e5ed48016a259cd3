"""Synthetic measured data: plant, sensors and injectable effects (spec-v1 datasets)."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.simulation._currents import DriveSimulation as DriveSimulation
from cdprid.simulation._currents import length_derivatives as length_derivatives
from cdprid.simulation._currents import simulate_drives as simulate_drives
from cdprid.simulation._currents import write_drive_simulation as write_drive_simulation
from cdprid.simulation._simulate import SensorNoise as SensorNoise
from cdprid.simulation._simulate import SimResult as SimResult
from cdprid.simulation._simulate import plant_wrenches as plant_wrenches
from cdprid.simulation._simulate import simulate as simulate
from cdprid.simulation._simulate import write_simulation as write_simulation
