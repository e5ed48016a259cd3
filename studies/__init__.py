"""Investigations: scripts that find out why a number is what it is (the real UACDPR
recording, the sources of identify's bias), not benchmarks of rates or speed.

Not part of the ``cdprid`` library. Run from the repository root as modules, e.g.
``python -m studies.real_uacdpr_energy --help``; the test suite imports them through pytest's
``pythonpath = ["."]``.
"""
