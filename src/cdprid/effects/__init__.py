"""The effect vocabulary: unmodelled phenomena injected by the simulator and named by the
diagnosis, one object per effect (:class:`EffectSpec`, one module each), listed once in a
registry from which the vocabulary, the sensor chain, the diagnosis table, the validation and
``docs/effects.md`` are derived.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.effects._context import CableContext as CableContext
from cdprid.effects._docs import vocabulary_markdown as vocabulary_markdown
from cdprid.effects._effects import Effect as Effect
from cdprid.effects._effects import effect_parameters_table as effect_parameters_table
from cdprid.effects._effects import encoder_lengths as encoder_lengths
from cdprid.effects._effects import external_wrench as external_wrench
from cdprid.effects._effects import load_cell_friction as load_cell_friction
from cdprid.effects._effects import parse_effect as parse_effect
from cdprid.effects._effects import true_gravity as true_gravity
from cdprid.effects._effects import true_robot as true_robot
from cdprid.effects._effects import validate_effects as validate_effects
from cdprid.effects._external_wrench import EXTERNAL_WRENCH as EXTERNAL_WRENCH
from cdprid.effects._form import DiagnosisForm as DiagnosisForm
from cdprid.effects._form import SpecError as SpecError
from cdprid.effects._frame_tilt import tilt_gravity as tilt_gravity
from cdprid.effects._frame_tilt import tilt_matrix as tilt_matrix
from cdprid.effects._load_cell_hysteresis import hysteresis_regressor as hysteresis_regressor
from cdprid.effects._load_cell_hysteresis import play_operator as play_operator
from cdprid.effects._load_cell_hysteresis import play_regressor as play_regressor
from cdprid.effects._load_cell_hysteresis import reversal_regressor as reversal_regressor
from cdprid.effects._plant import PlantTerms as PlantTerms
from cdprid.effects._plant import plant_terms as plant_terms
from cdprid.effects._registry import DIAGNOSIS as DIAGNOSIS
from cdprid.effects._registry import ENCODER_EFFECT as ENCODER_EFFECT
from cdprid.effects._registry import EPISODE_EFFECTS as EPISODE_EFFECTS
from cdprid.effects._registry import REGISTRY as REGISTRY
from cdprid.effects._registry import SENSOR_CHAIN as SENSOR_CHAIN
from cdprid.effects._registry import VOCABULARY as VOCABULARY
from cdprid.effects._sensor import load_cell_reading as load_cell_reading
from cdprid.effects._spec import EffectSpec as EffectSpec
from cdprid.effects._spec import Parameter as Parameter
from cdprid.effects._spec import Place as Place
