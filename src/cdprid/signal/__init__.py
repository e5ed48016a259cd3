"""Signal processing: numerical differentiators (SIHD, Euler + filter, Kalman-RTS, ...) and
filters.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.signal._baselines import zero_phase_filter as zero_phase_filter
from cdprid.signal._differentiators import METHODS as METHODS
from cdprid.signal._differentiators import MethodInfo as MethodInfo
from cdprid.signal._differentiators import acceleration_filter as acceleration_filter
from cdprid.signal._differentiators import differentiate as differentiate
from cdprid.signal._filters import ZeroPhaseFilter as ZeroPhaseFilter
from cdprid.signal._filters import butter_lowpass as butter_lowpass
from cdprid.signal._filters import butter_sos as butter_sos
from cdprid.signal._filters import lfilter as lfilter
from cdprid.signal._filters import lfilter_zi as lfilter_zi
from cdprid.signal._filters import make_zero_phase_filter as make_zero_phase_filter
from cdprid.signal._filters import sosfilt as sosfilt
from cdprid.signal._filters import sosfilt_zi as sosfilt_zi
from cdprid.signal._filters import sosfiltfilt as sosfiltfilt
from cdprid.signal._scan import _CHANNEL_FNS as _CHANNEL_FNS
from cdprid.signal._scan import TRACE_COUNTS as TRACE_COUNTS
from cdprid.signal._scan import _block_size as _block_size
from cdprid.signal._scan import _jax_kernel as _jax_kernel
from cdprid.signal._scan import _sharded_kernel as _sharded_kernel
from cdprid.signal._scan import scan_blocked as scan_blocked
from cdprid.signal._sihd_high import METHOD_INFO as METHOD_INFO
from cdprid.signal._sihd_high import alpha_min as alpha_min
from cdprid.signal._sihd_high import channel as channel
from cdprid.signal._sihd_high import differentiate_high as differentiate_high
from cdprid.signal._sihd_high import poly_gains as poly_gains
from cdprid.signal._sihd_high import sihdn_channel as sihdn_channel
from cdprid.signal._sihd_high import sihdn_step as sihdn_step
from cdprid.signal._sihd_steps import levant_step as levant_step
from cdprid.signal._sihd_steps import projector as projector
from cdprid.signal._sihd_steps import sihd2_step as sihd2_step
from cdprid.signal._sihd_steps import sihd3_step as sihd3_step
