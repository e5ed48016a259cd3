"""Identification features: batch pipeline, online identification, real recordings, geometric
calibration.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.identify._batch import COND_WARN as COND_WARN
from cdprid.identify._batch import DEFAULT_TRIM_S as DEFAULT_TRIM_S
from cdprid.identify._batch import MODELS as MODELS
from cdprid.identify._batch import ROTATION_WARN_DEG as ROTATION_WARN_DEG
from cdprid.identify._batch import WRENCH_FILTERS as WRENCH_FILTERS
from cdprid.identify._batch import ZERO_COLUMN_REL as ZERO_COLUMN_REL
from cdprid.identify._batch import IdentificationReport as IdentificationReport
from cdprid.identify._batch import excitation_warnings as excitation_warnings
from cdprid.identify._batch import format_table as format_table
from cdprid.identify._batch import identify_dataset as identify_dataset
from cdprid.identify._batch import physical_report as physical_report
from cdprid.identify._batch import rotation_angle_deg as rotation_angle_deg
from cdprid.identify._calibration import CalibrationData as CalibrationData
from cdprid.identify._calibration import CalibrationResult as CalibrationResult
from cdprid.identify._calibration import calibrate_geometry as calibrate_geometry
from cdprid.identify._calibration import calibration_data as calibration_data
from cdprid.identify._calibration import import_calibrated_uacdpr as import_calibrated_uacdpr
from cdprid.identify._calibration import platform_pose as platform_pose
from cdprid.identify._calibration import write_calibrated_dataset as write_calibrated_dataset
from cdprid.identify._online import online_identify as online_identify
from cdprid.identify._online_step import OnlineStepper as OnlineStepper
from cdprid.identify._online_step import online_init as online_init
from cdprid.identify._online_step import online_step as online_step
from cdprid.identify._online_types import SIHD_METHOD as SIHD_METHOD
from cdprid.identify._online_types import CascadeState as CascadeState
from cdprid.identify._online_types import DelayState as DelayState
from cdprid.identify._online_types import MatchedFilterState as MatchedFilterState
from cdprid.identify._online_types import OnlineConfig as OnlineConfig
from cdprid.identify._online_types import OnlineOutput as OnlineOutput
from cdprid.identify._online_types import OnlineResult as OnlineResult
from cdprid.identify._online_types import OnlineSample as OnlineSample
from cdprid.identify._online_types import OnlineState as OnlineState
from cdprid.identify._online_types import RLSResult as RLSResult
from cdprid.identify._real import RealData as RealData
from cdprid.identify._real import RealResult as RealResult
from cdprid.identify._real import compare_extensions as compare_extensions
from cdprid.identify._real import identify_real as identify_real
from cdprid.identify._real import jax_zero_phase_filter as jax_zero_phase_filter
from cdprid.identify._real import nuisance_summary as nuisance_summary
from cdprid.identify._real import prepare_real as prepare_real
from cdprid.identify._real import rest_windows as rest_windows
from cdprid.identify._real import taut_mask as taut_mask
from cdprid.identify._real import weight_at_rest as weight_at_rest
from cdprid.identify._rls import recursive_least_squares as recursive_least_squares
