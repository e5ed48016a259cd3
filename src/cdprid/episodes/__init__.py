"""Episodes: what happens only sometimes (pushes, contacts, load-cell steps, marker glitches),
located in time so that the fits can leave it out.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.episodes._energy import energy_runs as energy_runs
from cdprid.episodes._energy import mechanical_energy as mechanical_energy
from cdprid.episodes._glitches import add_glitches as add_glitches
from cdprid.episodes._glitches import find_glitches as find_glitches
from cdprid.episodes._lengths import winch_lengths as winch_lengths
from cdprid.episodes._scan import filter_autocorrelation as filter_autocorrelation
from cdprid.episodes._scan import locate as locate
from cdprid.episodes._scan import noise_model as noise_model
from cdprid.episodes._scan import window_level as window_level
from cdprid.episodes._stage import FAR_PER_HOUR as FAR_PER_HOUR
from cdprid.episodes._stage import Episode as Episode
from cdprid.episodes._stage import Episodes as Episodes
from cdprid.episodes._stage import find_episodes as find_episodes
