"""The effect vocabulary: unmodelled phenomena injected by the simulator and named by the
diagnosis.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.effects._effects import DIAGNOSIS as DIAGNOSIS
from cdprid.effects._effects import EPISODE_EFFECTS as EPISODE_EFFECTS
from cdprid.effects._effects import VOCABULARY as VOCABULARY
from cdprid.effects._effects import DiagnosisForm as DiagnosisForm
from cdprid.effects._effects import Effect as Effect
from cdprid.effects._effects import effect_parameters_table as effect_parameters_table
from cdprid.effects._effects import encoder_lengths as encoder_lengths
from cdprid.effects._effects import load_cell_friction as load_cell_friction
from cdprid.effects._effects import parse_effect as parse_effect
from cdprid.effects._effects import tilt_gravity as tilt_gravity
from cdprid.effects._effects import tilt_matrix as tilt_matrix
from cdprid.effects._effects import true_gravity as true_gravity
from cdprid.effects._effects import true_robot as true_robot
from cdprid.effects._effects import validate_effects as validate_effects
from cdprid.effects._effects import vocabulary_markdown as vocabulary_markdown
from cdprid.effects._external_wrench import EXTERNAL_WRENCH as EXTERNAL_WRENCH
from cdprid.effects._external_wrench import external_wrench as external_wrench
from cdprid.effects._plant import ENCODER_EFFECT as ENCODER_EFFECT
from cdprid.effects._plant import PlantTerms as PlantTerms
from cdprid.effects._plant import plant_terms as plant_terms
from cdprid.effects._sensor import load_cell_reading as load_cell_reading
