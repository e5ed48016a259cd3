"""Benchmarks: rates, accuracy and speed of cdprid, each writing its table to ``results/``.

Not part of the ``cdprid`` library. Run from the repository root as modules, e.g.
``python -m benchmarks.coverage``; the test suite imports them through pytest's
``pythonpath = ["."]``.
"""
