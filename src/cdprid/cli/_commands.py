"""The registry of the ``cdprid`` commands, from which the parser and its help are built.

Each command lives in its own module, which defines ``configure(parser)``: it gives the
(sub)parser its description and options and sets ``func``, the function that runs the command.
The registry below names the command, that module and the one-line help ``cdprid --help``
lists. :func:`cdprid.cli.build_parser` imports a command's module only when that command is
asked for, so ``cdprid --help`` imports no command module (and no JAX, SciPy or Matplotlib).

Adding a command: write ``cli/_<name>.py`` with ``configure`` and add one line here.
"""

from __future__ import annotations

from collections import namedtuple

__all__ = ["COMMANDS", "Command"]


class Command(namedtuple("Command", "name module help")):
    """One ``cdprid`` command.

    Parameters
    ----------
    name : str
        The command as typed (``cdprid NAME ...``).
    module : str
        The module defining ``configure(parser)`` for it.
    help : str
        The one-line help listed by ``cdprid --help``.
    """

    __slots__ = ()


COMMANDS: tuple[Command, ...] = (
    Command("identify", "cdprid.cli._identify",
            "identify the platform's dynamic parameters (least squares)"),
    Command("differentiate", "cdprid.cli._differentiate",
            "estimate first and second derivatives of CSV columns"),
    Command("simulate", "cdprid.cli._simulate",
            "write a synthetic dataset (spec v1) with optional injected effects"),
    Command("diagnose", "cdprid.cli._diagnose",
            "find what the paper's model misses, name the cause, measure the gain"),
    Command("excite", "cdprid.cli._excite",
            "optimise a safe excitation trajectory (condition number of W_ID)"),
    Command("import", "cdprid.cli._import", "convert another format into a spec-v1 dataset"),
    Command("calibrate", "cdprid.cli._calibrate",
            "geometric calibration of a locked-winch recording"),
    Command("example", "cdprid.cli._example",
            "write a sample dataset (simulated, with its truth)"),
    Command("tune", "cdprid.cli._tune",
            "tune a differentiator's parameters for the data's noise level"),
)

