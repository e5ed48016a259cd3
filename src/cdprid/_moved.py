"""Old import paths kept for one release: each is a stub module that warns and forwards.

``cdprid.geometry`` (the flat layout of waves 1-2) and ``cdprid.io.dataset`` (io, diagnosis and
report modules before they became private) still import, with a ``DeprecationWarning`` naming the
package face to import from instead; attribute reads forward to the module's new home. The stubs
go in the next release. Importing the old module ``cdprid.simulate`` binds that name to the
stub (the function is ``cdprid.simulation.simulate``).
"""

from __future__ import annotations

import importlib
import warnings


def moved(old: str, target: str, face: str):
    """Warn that ``old`` moved and return a module ``__getattr__`` and ``__dir__`` forwarding to
    ``target``.

    Parameters
    ----------
    old : str
        The deprecated module path (the stub's ``__name__``).
    target : str
        The module that now holds the code (private, inside ``face``).
    face : str
        The package to import the public names from.

    Returns
    -------
    tuple of callable
        ``(__getattr__, __dir__)`` for the stub module.
    """
    warnings.warn(f"{old} is deprecated and goes in the next release: import from {face} "
                  "(cdprid's layered layout)", DeprecationWarning, stacklevel=3)

    def __getattr__(name: str):
        return getattr(importlib.import_module(target), name)

    def __dir__():
        return dir(importlib.import_module(target))

    return __getattr__, __dir__
