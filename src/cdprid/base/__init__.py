"""Base layer: error types, atomic outputs, named defaults, progress lines."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.base._defaults import CUTOFF_HZ as CUTOFF_HZ
from cdprid.base._defaults import FILTER_ORDER as FILTER_ORDER
from cdprid.base._defaults import REST_SPEED_M_S as REST_SPEED_M_S
from cdprid.base._defaults import TAUT_THRESHOLD_N as TAUT_THRESHOLD_N
from cdprid.base._defaults import TRIM_S as TRIM_S
from cdprid.base._errors import ConvergenceError as ConvergenceError
from cdprid.base._errors import InputError as InputError
from cdprid.base._errors import OutputError as OutputError
from cdprid.base._errors import OutputExistsError as OutputExistsError
from cdprid.base._errors import UserError as UserError
from cdprid.base._interrupts import Terminated as Terminated
from cdprid.base._interrupts import check_pending as check_pending
from cdprid.base._interrupts import clear_pending as clear_pending
from cdprid.base._interrupts import deliver as deliver
from cdprid.base._interrupts import pending as pending
from cdprid.base._outputs import atomic_dir as atomic_dir
from cdprid.base._outputs import atomic_file as atomic_file
from cdprid.base._outputs import check_distinct as check_distinct
from cdprid.base._outputs import check_output as check_output
from cdprid.base._outputs import input_clash as input_clash
from cdprid.base._outputs import save_figure as save_figure
from cdprid.base._outputs import write_json as write_json
from cdprid.base._outputs import write_text as write_text
from cdprid.base._progress import Progress as Progress
from cdprid.base._status import Status as Status
from cdprid.base._sweep import load_log as load_log
from cdprid.base._sweep import run_sweep as run_sweep
from cdprid.base._tails import chi2_isf as chi2_isf
from cdprid.base._tails import chi2_logsf as chi2_logsf
from cdprid.base._tails import chi2_sf as chi2_sf
from cdprid.base._tails import f_isf as f_isf
from cdprid.base._tails import f_sf as f_sf
from cdprid.base._tails import normal_isf as normal_isf
from cdprid.base._tails import normal_sf as normal_sf
