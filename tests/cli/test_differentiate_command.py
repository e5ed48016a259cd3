"""`cdprid differentiate`: columns, exactness on polynomials, errors."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.cli._main import main


def _write(path, t, cols):
    np.savetxt(path, np.column_stack([t] + list(cols.values())), delimiter=",",
               header=",".join(["t"] + list(cols)), comments="")


@pytest.mark.parametrize("method", ["savgol", "rts", "euler-filtfilt", "sihd2-cascade"])
def test_differentiate_polynomial_columns(tmp_path, method):
    t = np.arange(0, 30, 0.01)
    _write(tmp_path / "in.csv", t, {"p": 0.3 + 0.2 * t + 0.05 * t**2, "q": -0.1 * t})
    assert main(["differentiate", str(tmp_path / "in.csv"), "--method", method,
                 "--out", str(tmp_path / "out.csv")]) == 0
    header = (tmp_path / "out.csv").read_text().splitlines()[0]
    assert header == "t,p_d1,q_d1,p_d2,q_d2"
    d = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    late = (t > 5) & (t < 25)  # away from both ends (filter and observer transients)
    tol = {"savgol": 1e-5, "rts": 1e-3, "euler-filtfilt": 1e-6, "sihd2-cascade": 2e-2}[method]
    assert np.max(np.abs(d[late, 1] - (0.2 + 0.1 * t[late]))) < tol
    assert np.max(np.abs(d[late, 3] - 0.1)) < tol * 10
    assert np.max(np.abs(d[late, 2] + 0.1)) < tol


def test_differentiate_errors(tmp_path, capsys):
    t = np.arange(0, 1, 0.01)
    _write(tmp_path / "in.csv", t, {"p": t})
    assert main(["differentiate", str(tmp_path / "in.csv"), "--method", "nope",
                 "--out", str(tmp_path / "o.csv")]) == 2
    assert "unknown method" in capsys.readouterr().err
    (tmp_path / "o.csv").write_text("keep")
    assert main(["differentiate", str(tmp_path / "in.csv"), "--out", str(tmp_path / "o.csv")]) == 2
    assert (tmp_path / "o.csv").read_text() == "keep"
    assert main(["differentiate", str(tmp_path / "missing.csv"), "--out",
                 str(tmp_path / "x.csv")]) == 2
    assert main(["differentiate", str(tmp_path / "in.csv"), "--params", "[1]",
                 "--out", str(tmp_path / "y.csv")]) == 2
