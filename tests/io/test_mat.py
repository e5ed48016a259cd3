"""``identify --mat`` / ``diagnose --mat``: MATLAB files read back with scipy.io.loadmat.

Round trip: every number of ``identify --json`` is in the .mat (struct ``json``, names made
valid for MATLAB), and the flat arrays equal the JSON's estimates and std.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import scipy.io

from cdprid.cli import main
from cdprid.io import write_mat
from cdprid.io._mat import matlab_name

MATLAB_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    """``cdprid identify`` of the package's sample dataset with --json and --mat."""
    from cdprid.data import write_sample

    d = tmp_path_factory.mktemp("mat")
    ds = write_sample(d / "sample")
    rc = main(["identify", str(ds), "--json", str(d / "id.json"), "--mat", str(d / "id.mat")])
    assert rc == 0
    return json.loads((d / "id.json").read_text()), d / "id.mat"


def _numbers(obj, path=()):
    """(path, number) of every number in a JSON value (bools are not numbers here)."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _numbers(v, path + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _numbers(v, path + (i,))
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield path, float(obj)


def _lookup(mat_json, json_obj, path):
    """The .mat value at a JSON path: dict keys -> struct fields (MATLAB names), a list of
    numbers -> a column, a list of lists of numbers -> a matrix, other lists -> a cell."""
    node, src = mat_json, json_obj
    i = 0
    while i < len(path):
        key = path[i]
        if isinstance(src, dict):
            taken: set = set()
            names = {k: matlab_name(k, taken) for k in src}
            node = node[names[key]]
            src = src[key]
            if isinstance(src, dict):  # a struct is a 1 x 1 array
                node = node[0, 0]
            i += 1
        elif isinstance(src, list) and all(isinstance(x, (int, float)) for x in src):
            return np.asarray(node, float).ravel()[key]
        elif isinstance(src, list) and src and all(isinstance(x, list) for x in src) \
                and i + 1 < len(path):
            return np.asarray(node, float)[key, path[i + 1]]
        else:  # a cell array (n, 1)
            node = node[key, 0]
            src = src[key]
            if isinstance(src, dict):
                node = node[0, 0]
            i += 1
    return np.asarray(node, float).ravel()[0]


def test_every_number_of_identify_json_is_in_the_mat(identified):
    data, mat = identified
    m = scipy.io.loadmat(mat)
    nums = list(_numbers(data))
    assert len(nums) > 60  # parameters (6 numbers each), noise levels, cond, ...
    missing = []
    for path, v in nums:
        got = _lookup(m["json"][0, 0], data, path)
        if not (got == v or (np.isnan(v) and np.isnan(got))):
            missing.append((path, v, got))
    assert not missing, missing[:5]


def test_flat_arrays_match_the_json(identified):
    data, mat = identified
    m = scipy.io.loadmat(mat)
    names = [str(c[0][0]) for c in m["parameter_names"]]
    assert names == list(data["parameters"])
    p = data["parameters"]
    np.testing.assert_array_equal(m["estimates"].ravel(), [p[k]["value"] for k in names])
    np.testing.assert_array_equal(m["std"].ravel(), [p[k]["std"] for k in names])
    np.testing.assert_allclose(m["crb_std"].ravel(), [p[k]["crb_std"] for k in names],
                               rtol=1e-12)
    cov = m["covariance"]
    assert cov.shape == (len(names), len(names))
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), m["std"].ravel(), rtol=1e-12)
    t, r = m["t"].ravel(), m["residual"]
    assert r.shape == (len(t), 6) and np.all(np.diff(t) > 0)
    assert m["episodes"]["start_s"][0, 0].size == 0  # no episodes in this result
    made = m["made_by"][0, 0]
    assert str(made["command"][0]).startswith("cdprid identify ")


def test_names_are_valid_matlab_and_unique(tmp_path):
    """Keys that are not MATLAB names are made valid, clashes made unique; None is []."""
    out = write_mat(tmp_path / "x.mat", {"a": {"fx [N]": 1.0, "fx-N": 2.0, "2nd": [1, 2],
                                               "_x": None, "s": "text", "ok": True,
                                               "l": [{"k": 1}, "b"]}})
    m = scipy.io.loadmat(out)
    a = m["a"][0, 0]
    names = a.dtype.names
    assert all(MATLAB_NAME.match(n) for n in names), names
    assert set(names) == {"fx_N", "fx_N_2", "x2nd", "x", "s", "ok", "l"}
    assert a["fx_N"][0, 0] == 1.0 and a["fx_N_2"][0, 0] == 2.0
    assert a["x"].size == 0 and str(a["s"][0]) == "text" and bool(a["ok"][0, 0])
    assert a["l"][0, 0]["k"][0, 0][0, 0] == 1.0 and str(a["l"][1, 0][0]) == "b"
    assert matlab_name("x" * 80) == "x" * 63


def test_mat_refused_before_work(tmp_path, capsys):
    """--mat that exists without --force, or not named .mat: exit 2 before any work."""
    from cdprid.data import write_sample

    ds = write_sample(tmp_path / "sample")
    (tmp_path / "a.mat").write_text("keep")
    capsys.readouterr()
    rc = main(["identify", str(ds), "--mat", str(tmp_path / "a.mat")])
    err = capsys.readouterr().err
    assert rc == 2 and "--mat" in err and "exists" in err, err
    rc = main(["identify", str(ds), "--mat", str(tmp_path / "b.txt")])
    err = capsys.readouterr().err
    assert rc == 2 and "must end in .mat" in err
    assert (tmp_path / "a.mat").read_text() == "keep"
