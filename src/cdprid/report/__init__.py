"""Report layer: every figure and table of every feature lives here (one module per feature).

Features compute; this layer draws. Nothing in the core or feature layers imports matplotlib.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.report._calibration import calibration_figures as calibration_figures
from cdprid.report._diagnosis import episode_lines as episode_lines
from cdprid.report._diagnosis import format_values as format_values
from cdprid.report._diagnosis import not_named_lines as not_named_lines
from cdprid.report._diagnosis import save_report as save_report
from cdprid.report._excitation import plot_safety_series as plot_safety_series
from cdprid.report._excitation import plot_trajectory as plot_trajectory
from cdprid.report._html_diagnosis import write_diagnosis_html as write_diagnosis_html
from cdprid.report._html_identify import save_identify_report as save_identify_report
from cdprid.report._mat import diagnosis_variables as diagnosis_variables
from cdprid.report._mat import episodes_of as episodes_of
from cdprid.report._mat import identify_variables as identify_variables
from cdprid.report._online import plot_online as plot_online
from cdprid.report._real import fig_nuisance as fig_nuisance
from cdprid.report._real import fig_residuals as fig_residuals
from cdprid.report._real import fig_tensions as fig_tensions
from cdprid.report._real import fig_wrench as fig_wrench
from cdprid.report._tuning import plot_response as plot_response
