"""The core data path: motion from poses, regression (W_ID, Y_ID), least squares, covariance,
sensor nuisances, physical consistency.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.core._covariance import andrews_bandwidth as andrews_bandwidth
from cdprid.core._covariance import hac_covariance as hac_covariance
from cdprid.core._covariance import hac_covariance_blocks as hac_covariance_blocks
from cdprid.core._covariance import iid_covariance as iid_covariance
from cdprid.core._covariance import sample_scores as sample_scores
from cdprid.core._covariance import std_from_cov as std_from_cov
from cdprid.core._identification import LSResult as LSResult
from cdprid.core._identification import condition_number as condition_number
from cdprid.core._identification import group_weights as group_weights
from cdprid.core._identification import least_squares as least_squares
from cdprid.core._identification import least_squares_blocks as least_squares_blocks
from cdprid.core._motion import BLOCK as BLOCK
from cdprid.core._motion import ROTATION_WARN_DEG as ROTATION_WARN_DEG
from cdprid.core._motion import Motion as Motion
from cdprid.core._motion import angular_rates as angular_rates
from cdprid.core._motion import blockwise as blockwise
from cdprid.core._motion import estimate_motion as estimate_motion
from cdprid.core._motion import rotation_angle_deg as rotation_angle_deg
from cdprid.core._motion import rotation_matrices as rotation_matrices
from cdprid.core._motion import segment_mask as segment_mask
from cdprid.core._noise import estimate_noise as estimate_noise
from cdprid.core._nuisance import INTERPOLATION as INTERPOLATION
from cdprid.core._nuisance import REST_MIN_DURATION_S as REST_MIN_DURATION_S
from cdprid.core._nuisance import TAUT_WINDOW_S as TAUT_WINDOW_S
from cdprid.core._nuisance import InsufficientDataError as InsufficientDataError
from cdprid.core._nuisance import NuisanceFit as NuisanceFit
from cdprid.core._nuisance import NuisanceSpec as NuisanceSpec
from cdprid.core._nuisance import TensionStream as TensionStream
from cdprid.core._nuisance import fit_nuisance as fit_nuisance
from cdprid.core._nuisance import mask_windows as mask_windows
from cdprid.core._nuisance import rest_mask as rest_mask
from cdprid.core._nuisance import taut_mask as taut_mask
from cdprid.core._nuisance import tension_at as tension_at
from cdprid.core._physical import SIGNIFICANCE_Z as SIGNIFICANCE_Z
from cdprid.core._physical import inertia_about_com as inertia_about_com
from cdprid.core._physical import inertia_com_matrix as inertia_com_matrix
from cdprid.core._physical import margin_z as margin_z
from cdprid.core._physical import physical_fit as physical_fit
from cdprid.core._physical import physical_warnings as physical_warnings
from cdprid.core._physical import pseudo_inertia_to_vector as pseudo_inertia_to_vector
from cdprid.core._physical import realisability_margin as realisability_margin
from cdprid.core._physical import violations as violations
from cdprid.core._regression import CHUNK as CHUNK
from cdprid.core._regression import Regression as Regression
from cdprid.core._regression import StreamedRegression as StreamedRegression
from cdprid.core._regression import build_regression as build_regression
from cdprid.core._regression import cable_wrench as cable_wrench
from cdprid.core._regression import measured_wrench as measured_wrench
from cdprid.core._regression import regressor_blocks as regressor_blocks
from cdprid.core._regression import regressors as regressors
from cdprid.core._regression import wrench_matrices as wrench_matrices
