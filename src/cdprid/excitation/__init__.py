"""Optimal, certified-safe excitation trajectories."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.excitation._check import SafetyCertificate as SafetyCertificate
from cdprid.excitation._check import SafetySeries as SafetySeries
from cdprid.excitation._check import certify_trajectory as certify_trajectory
from cdprid.excitation._check import kinematic_peaks as kinematic_peaks
from cdprid.excitation._check import limit_ratios as limit_ratios
from cdprid.excitation._check import robust_tension_margins as robust_tension_margins
from cdprid.excitation._check import safety_series as safety_series
from cdprid.excitation._constraints import certify_tensions as certify_tensions
from cdprid.excitation._constraints import (
    robust_tension_margin_smooth as robust_tension_margin_smooth,
)
from cdprid.excitation._constraints import tension_margin_smooth as tension_margin_smooth
from cdprid.excitation._evaluation import DesignReport as DesignReport
from cdprid.excitation._evaluation import ExcitationResult as ExcitationResult
from cdprid.excitation._evaluation import evaluate_design as evaluate_design
from cdprid.excitation._families import FAMILIES as FAMILIES
from cdprid.excitation._families import REST_S as REST_S
from cdprid.excitation._families import FourierFamily as FourierFamily
from cdprid.excitation._families import FourierTrajectory as FourierTrajectory
from cdprid.excitation._families import HomedTrajectory as HomedTrajectory
from cdprid.excitation._families import OrbitFamily as OrbitFamily
from cdprid.excitation._families import make_family as make_family
from cdprid.excitation._families import move_duration as move_duration
from cdprid.excitation._objective import OBJECTIVES as OBJECTIVES
from cdprid.excitation._objective import d_optimality as d_optimality
from cdprid.excitation._objective import information_cond as information_cond
from cdprid.excitation._objective import predicted_sigma as predicted_sigma
from cdprid.excitation._objective import soft_log_cond as soft_log_cond
from cdprid.excitation._objective import stacked_regressor as stacked_regressor
from cdprid.excitation._optimise import COMPILER_OPTIONS as COMPILER_OPTIONS
from cdprid.excitation._optimise import fit_to_limits as fit_to_limits
from cdprid.excitation._optimise import gentle_run as gentle_run
from cdprid.excitation._optimise import initial_design as initial_design
from cdprid.excitation._optimise import optimise_excitation as optimise_excitation
from cdprid.excitation._optimise import robust_homes as robust_homes
from cdprid.excitation._optimise import start_points as start_points
from cdprid.excitation._problem import CERTIFICATE_SCOPE as CERTIFICATE_SCOPE
from cdprid.excitation._problem import GENTLE_FRACTION as GENTLE_FRACTION
from cdprid.excitation._problem import ExcitationProblem as ExcitationProblem
from cdprid.excitation._problem import Fractions as Fractions
from cdprid.excitation._problem import make_problem as make_problem
from cdprid.excitation._problem import parse_home as parse_home
from cdprid.excitation._safety import DEFAULT_LIMITS as DEFAULT_LIMITS
from cdprid.excitation._safety import DEFAULT_UNCERTAINTY as DEFAULT_UNCERTAINTY
from cdprid.excitation._safety import SafetyLimits as SafetyLimits
from cdprid.excitation._safety import UncertaintyBox as UncertaintyBox
from cdprid.excitation._safety import corner_parameters as corner_parameters
from cdprid.excitation._safety import safety_limits as safety_limits
from cdprid.excitation._safety import uncertainty_from_prior as uncertainty_from_prior
from cdprid.excitation._safety import uncertainty_from_robot as uncertainty_from_robot
from cdprid.excitation._slsqp import slsqp_baseline as slsqp_baseline
