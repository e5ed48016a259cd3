"""cdprid: dynamic identification of cable-driven parallel robots, in JAX.

The data path reads in one direction::

    io (dataset, aligned signals) -> motion (derivatives) -> regression (W_ID, Y_ID)
    -> identification (least squares) -> diagnose / report

Float64: call ``jax.config.update("jax_enable_x64", True)`` in your script (the CLI does it);
importing cdprid does not change JAX's configuration.
"""

from .differentiators import METHODS as METHODS, differentiate as differentiate
from .dynamics import (
    PARAMETER_NAMES as PARAMETER_NAMES,
    InertialParameters as InertialParameters,
    platform_wrench as platform_wrench,
    regressor_full as regressor_full,
    regressor_translation as regressor_translation,
)
from .geometry import (
    CableRobot as CableRobot,
    cable_lengths as cable_lengths,
    cable_vectors as cable_vectors,
    leave_points as leave_points,
    load_robot as load_robot,
    unit_vectors as unit_vectors,
    wrench_matrix as wrench_matrix,
)
from .identification import LSResult as LSResult, least_squares as least_squares
from .io import Dataset as Dataset, DatasetError as DatasetError, align as align
from .io import read_dataset as read_dataset, write_dataset as write_dataset
from .pipeline import IdentificationReport as IdentificationReport
from .pipeline import identify_dataset as identify_dataset

__version__ = "0.1.0"
