"""The core data path: motion from poses, regression (W_ID, Y_ID), least squares, covariance,
sensor nuisances, physical consistency, the matched-filter regressions (zero-phase and linear
match) and the errors-in-variables weighting.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.core._bandwidth import BUDGET as BUDGET
from cdprid.core._bandwidth import BandwidthChoice as BandwidthChoice
from cdprid.core._bandwidth import choose_cutoff as choose_cutoff
from cdprid.core._covariance import andrews_bandwidth as andrews_bandwidth
from cdprid.core._covariance import hac_covariance as hac_covariance
from cdprid.core._covariance import hac_covariance_blocks as hac_covariance_blocks
from cdprid.core._covariance import iid_covariance as iid_covariance
from cdprid.core._covariance import sample_scores as sample_scores
from cdprid.core._covariance import std_from_cov as std_from_cov
from cdprid.core._crb import CRBResult as CRBResult
from cdprid.core._crb import crb as crb
from cdprid.core._crb import regressor_jacobians as regressor_jacobians
from cdprid.core._crb import sample_jacobians as sample_jacobians
from cdprid.core._eiv import EIV_NOTE as EIV_NOTE
from cdprid.core._eiv import bias_correction as bias_correction
from cdprid.core._eiv import eiv_fit as eiv_fit
from cdprid.core._eiv import input_covariance as input_covariance
from cdprid.core._eiv import noise_gains as noise_gains
from cdprid.core._eiv import noise_levels as noise_levels
from cdprid.core._eiv import whitening as whitening
from cdprid.core._identification import LSResult as LSResult
from cdprid.core._identification import condition_number as condition_number
from cdprid.core._identification import group_weights as group_weights
from cdprid.core._identification import least_squares as least_squares
from cdprid.core._identification import least_squares_blocks as least_squares_blocks
from cdprid.core._linear_match import FIR_SECONDS as FIR_SECONDS
from cdprid.core._linear_match import FIT_WARN as FIT_WARN
from cdprid.core._linear_match import LinearMatch as LinearMatch
from cdprid.core._linear_match import fir_length as fir_length
from cdprid.core._linear_match import fit_linear_match as fit_linear_match
from cdprid.core._linear_match import linear_match_regression as linear_match_regression
from cdprid.core._linear_match import matched_regression as matched_regression
from cdprid.core._linear_match import reference_fir as reference_fir
from cdprid.core._linear_match import reference_rates as reference_rates
from cdprid.core._linear_match import rotation_remainder as rotation_remainder
from cdprid.core._linear_match import settled as settled
from cdprid.core._linear_match import uses_linear_match as uses_linear_match
from cdprid.core._motion import BLOCK as BLOCK
from cdprid.core._motion import ROTATION_WARN_DEG as ROTATION_WARN_DEG
from cdprid.core._motion import Motion as Motion
from cdprid.core._motion import angular_rates as angular_rates
from cdprid.core._motion import blockwise as blockwise
from cdprid.core._motion import differentiate_pose as differentiate_pose
from cdprid.core._motion import estimate_motion as estimate_motion
from cdprid.core._motion import rotation_angle_deg as rotation_angle_deg
from cdprid.core._motion import rotation_matrices as rotation_matrices
from cdprid.core._motion import segment_mask as segment_mask
from cdprid.core._noise import estimate_noise as estimate_noise
from cdprid.core._nuisance import REST_MIN_DURATION_S as REST_MIN_DURATION_S
from cdprid.core._nuisance import SMOOTH_HZ as SMOOTH_HZ
from cdprid.core._nuisance import TAUT_WINDOW_S as TAUT_WINDOW_S
from cdprid.core._nuisance import InsufficientDataError as InsufficientDataError
from cdprid.core._nuisance import NuisanceFit as NuisanceFit
from cdprid.core._nuisance import NuisanceSpec as NuisanceSpec
from cdprid.core._nuisance import fit_nuisance as fit_nuisance
from cdprid.core._nuisance import mask_windows as mask_windows
from cdprid.core._nuisance import rest_mask as rest_mask
from cdprid.core._nuisance import taut_mask as taut_mask
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
from cdprid.core._sliding import SLIDE_NOISE_M_S as SLIDE_NOISE_M_S
from cdprid.core._sliding import gauss_derivative as gauss_derivative
from cdprid.core._sliding import sliding_sign as sliding_sign
from cdprid.core._tension import CATMULL_ROM as CATMULL_ROM
from cdprid.core._tension import INTERPOLATION as INTERPOLATION
from cdprid.core._tension import TensionStream as TensionStream
from cdprid.core._tension import tension_at as tension_at
from cdprid.core._tension import tension_rate_at as tension_rate_at
from cdprid.core._zero_phase_match import platform_radius as platform_radius
from cdprid.core._zero_phase_match import regressor_scale as regressor_scale
from cdprid.core._zero_phase_match import seen_mass as seen_mass
from cdprid.core._zero_phase_match import uses_zero_phase_match as uses_zero_phase_match
from cdprid.core._zero_phase_match import (
    zero_phase_matched_regression as zero_phase_matched_regression,
)
