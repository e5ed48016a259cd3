"""MATLAB ``.mat`` output (format 5, readable by ``scipy.io.loadmat`` and MATLAB).

:func:`write_mat` writes a mapping of variables atomically. Values are converted for MATLAB:

- a dict becomes a struct; its keys become valid MATLAB names (:func:`matlab_name`: letters,
  digits and ``_``, starting with a letter, at most 63 characters; ``fx [N]`` -> ``fx_N``,
  ``2nd`` -> ``x2nd``; a clash gets ``_2``, ``_3``, ...);
- a list of numbers (or of equal-length lists of numbers) becomes a double matrix, a list of
  anything else a cell array (a list of dicts: a cell array of structs);
- ``None`` becomes the empty matrix ``[]``, a bool a logical, a string a char array.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

__all__ = ["matlab_name", "matlab_value", "write_mat"]

_MAX = 63


def matlab_name(key: str, taken: set | None = None) -> str:
    """A valid MATLAB variable/field name for ``key`` (unique within ``taken``, which is updated).

    Parameters
    ----------
    key : str
    taken : set of str, optional
        Names already used in the same struct.

    Returns
    -------
    str
    """
    name = re.sub(r"[^0-9A-Za-z_]+", "_", str(key)).strip("_") or "x"
    if not name[0].isalpha():
        name = "x" + name
    name = name[:_MAX]
    if taken is not None:
        base, k = name, 2
        while name in taken:
            suffix = f"_{k}"
            name = base[:_MAX - len(suffix)] + suffix
            k += 1
        taken.add(name)
    return name


def _numeric(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def matlab_value(v):
    """``v`` converted to what :func:`scipy.io.savemat` writes as the MATLAB value described in
    the module docstring."""
    if v is None:
        return np.zeros((0, 0))
    if isinstance(v, dict):
        taken: set = set()
        return {matlab_name(k, taken): matlab_value(x) for k, x in v.items()}
    if isinstance(v, (bool, np.bool_)):
        return np.bool_(v)
    if _numeric(v):
        return float(v)
    if isinstance(v, str):
        return v
    if isinstance(v, np.ndarray):
        if v.dtype == object:
            return _cell([matlab_value(x) for x in v.ravel()])
        return v.astype(float) if v.dtype.kind in "iuf" else v
    if isinstance(v, (list, tuple)):
        if all(_numeric(x) for x in v):
            return np.asarray(v, float).reshape(-1, 1) if v else np.zeros((0, 0))
        if v and all(isinstance(x, (list, tuple)) and x and all(_numeric(y) for y in x)
                     for x in v) and len({len(x) for x in v}) == 1:
            return np.asarray(v, float)
        return _cell([matlab_value(x) for x in v])
    return str(v)


def _cell(items: list) -> np.ndarray:
    out = np.empty((len(items), 1), dtype=object)
    for i, x in enumerate(items):
        out[i, 0] = x
    return out


def write_mat(path: str | Path, variables: dict, force: bool = True) -> Path:
    """Write ``variables`` (name -> value) as a MATLAB format-5 ``.mat`` file, atomically.

    Parameters
    ----------
    path : path
        The ``.mat`` file (its folder must exist); check it with
        :func:`cdprid.base.check_output` before the work starts.
    variables : dict
        Top-level variables; names and values converted as the module docstring says.
    force : bool
        Replace an existing file.

    Returns
    -------
    Path
    """
    from scipy.io import savemat

    from cdprid.base import atomic_file

    mdict = matlab_value(dict(variables))
    with atomic_file(path, mode="wb", force=force) as fh:
        savemat(fh, mdict, format="5", long_field_names=True, do_compression=True,
                oned_as="column")
    return Path(path)
