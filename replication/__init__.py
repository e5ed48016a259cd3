"""Replication of the seed paper (Table 1, Figs. 3-4, the mzG gap) on the shared dataset.

Not part of the ``cdprid`` library: it reads ``../shared``, holds the paper's constants and
draws its own figures. Used by ``benchmarks/paper_replication.py``,
``notebooks/02_paper_replication.ipynb`` and ``tests/test_replication.py``: a package
reached from the repository root (``python -m benchmarks.paper_replication``; pytest's
``pythonpath = ["."]``).
"""

from .paper import *  # noqa: F403
from .paper import __all__ as __all__
