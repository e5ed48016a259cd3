"""An independent test simulator of cable robots (numpy only; no cdprid model or simulator).

It shares nothing with ``cdprid.model`` or ``cdprid.simulation``: its own swivel-pulley
geometry (leave points, wrap angles, cable lengths), its own Newton-Euler, its own rotation
integration (RK4 on quaternions), its own sensors (tension clock, white + AR(1) noise, per-cell
offset and gain, pulley friction with the sign of where the cell sits, a hysteretic cell as a
play operator written as a plain loop), hand pushes (an outside wrench in its Newton-Euler)
and marker glitches (:mod:`._episodes`), and its own robots. cdprid is used only to write the
files (``cdprid.io.write_dataset``) and to build the ``CableRobot`` that robot.toml is written
from (``cdprid.model.robot_from_dict``).

Where it lives: ``tests/_testbench/`` so that the tests can use it (the tests may not import
``benchmarks/``, ``tests/test_architecture.py``), and ``benchmarks/`` import it as
``tests._testbench`` when run from the repository root as modules
(``python -m benchmarks.many_effects``); pytest finds it through ``pythonpath = ["."]`` in
pyproject.toml. It is not part of the installed package.
"""

# ruff: noqa: F401  (explicit re-exports)

from tests._testbench._cases import floor8_case as floor8_case
from tests._testbench._cases import floor8_combined as floor8_combined
from tests._testbench._cases import floor8_with as floor8_with
from tests._testbench._episodes import Glitch as Glitch
from tests._testbench._episodes import Push as Push
from tests._testbench._episodes import push_wrench as push_wrench
from tests._testbench._geometry import pulley_geometry as pulley_geometry
from tests._testbench._motion import Motion as Motion
from tests._testbench._motion import motion as motion
from tests._testbench._motion import newton_euler as newton_euler
from tests._testbench._record import Recording as Recording
from tests._testbench._record import record as record
from tests._testbench._record import write as write
from tests._testbench._robots import ROBOTS as ROBOTS
from tests._testbench._robots import Robot as Robot
from tests._testbench._robots import robot as robot
from tests._testbench._sensors import Sensors as Sensors
from tests._testbench._sensors import ar1_noise as ar1_noise
from tests._testbench._sensors import play as play
