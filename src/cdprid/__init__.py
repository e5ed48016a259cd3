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


from .diagnose import DiagnosisResult as DiagnosisResult, diagnose as diagnose
from .effects import VOCABULARY as VOCABULARY, Effect as Effect
from .online import OnlineStepper as OnlineStepper, online_identify as online_identify
from .online import online_init as online_init
from .robots import craft_like_robot as craft_like_robot, craft_like_truth as craft_like_truth
from .simulate import SensorNoise as SensorNoise, simulate as simulate
from .simulate import write_simulation as write_simulation
from .tensions import distribute_tensions as distribute_tensions
from .tensions import feasibility_margin as feasibility_margin
from .trajectories import load_trajectory_csv as load_trajectory_csv, preset as preset

__version__ = "0.1.0"
