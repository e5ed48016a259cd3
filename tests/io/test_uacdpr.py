"""UACDPR importer, rigid-body marker fit, and geometric calibration.

Real-data tests read ../shared/datasets/uacdpr-freemotion02 and skip when it is absent; the
files are never copied into the repository.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io
from scipy.spatial.transform import Rotation

from cdprid.io._dataset import read_dataset
from cdprid.io._vicon import estimate_layout, fit_rigid_body, kabsch, read_vicon_trajectories
from conftest import ROBOT_FOUR, shared_dataset

NAME = "uacdpr-freemotion02"


def _run_cli(argv, capsys, monkeypatch):
    """Run ``cdprid`` with the import command registered; return (code, stdout, stderr)."""
    from cdprid.cli import main

    code = main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


# --------------------------------------------------------------------------- Kabsch / layout


def test_kabsch_matches_scipy_align_vectors(rng):
    """Oracle: scipy's Rotation.align_vectors on centred points."""
    M = rng.normal(size=(9, 3)) * 0.2
    R_true = Rotation.from_rotvec([0.4, -1.1, 2.0]).as_matrix()
    p_true = np.array([0.3, -0.2, 0.9])
    V = M @ R_true.T + p_true + rng.normal(0, 1e-4, (9, 3))
    R, p = kabsch(M, V)
    R_sp, _ = Rotation.align_vectors(V - V.mean(0), M - M.mean(0))
    np.testing.assert_allclose(R, R_sp.as_matrix(), atol=1e-10)
    np.testing.assert_allclose(R, R_true, atol=2e-3)
    np.testing.assert_allclose(p, p_true, atol=2e-3)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_kabsch_batched_and_missing_markers(rng):
    M = rng.normal(size=(6, 3)) * 0.2
    Rs = Rotation.random(20, random_state=1).as_matrix()
    ps = rng.normal(size=(20, 3))
    V = np.einsum("nab,kb->nka", Rs, M) + ps[:, None, :]
    V[3, 2] = np.nan  # a missing marker
    R, p = kabsch(M, V)
    np.testing.assert_allclose(R, Rs, atol=1e-10)
    np.testing.assert_allclose(p, ps, atol=1e-10)


def test_estimate_layout_recovers_rigid_body(rng):
    M = rng.normal(size=(9, 3)) * 0.15
    n = 200
    Rs = Rotation.from_rotvec(rng.normal(0, 0.3, (n, 3))).as_matrix()
    ps = rng.normal(0, 0.1, (n, 3))
    V = np.einsum("nab,kb->nka", Rs, M) + ps[:, None, :]
    V[10:20, 4] = np.nan
    fit = estimate_layout(V, origin_marker=8)
    assert fit.rms < 1e-10
    np.testing.assert_allclose(fit.M_m[8], 0.0, atol=1e-12)
    # the layout is the true one up to the gauge: pairwise distances agree
    d = lambda X: np.linalg.norm(X[:, None] - X[None], axis=2)  # noqa: E731
    np.testing.assert_allclose(d(fit.M_m), d(M), atol=1e-10)
    np.testing.assert_allclose(fit.V_R_M[fit.reference_frame], np.eye(3), atol=1e-10)
    R, p, res = fit_rigid_body(V, fit.M_m)
    assert np.nanmax(res) < 1e-10


# --------------------------------------------------------------------------- synthetic calibration


def _solve_pose(lengths_fn, L, x, y, guess):
    """Pose with P at (x, y) whose cable lengths equal L (z and rotation solved)."""
    from scipy.optimize import least_squares

    def f(u):
        R = Rotation.from_rotvec(u[1:]).as_matrix()
        return np.asarray(lengths_fn(np.array([x, y, u[0]]), R)) - L

    sol = least_squares(f, guess, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert np.max(np.abs(sol.fun)) < 1e-11
    return sol.x


def test_calibration_recovers_known_transform_synthetic():
    import jax
    import jax.numpy as jnp

    from cdprid.identify import CalibrationData, calibrate_geometry, platform_pose
    from cdprid.model import cable_lengths, robot_from_dict, swivel_angles

    robot = robot_from_dict(ROBOT_FOUR)
    L = np.asarray(cable_lengths(robot, jnp.array([0.02, -0.01, 0.6]), jnp.eye(3)))
    # a grid of P positions, the rest of the pose solved on the locked-cable manifold
    lengths_fn = jax.jit(lambda p, R: cable_lengths(robot, p, R))
    poses, guess = [], np.array([0.6, 0.0, 0.0, 0.0])
    for x in np.linspace(-0.04, 0.04, 5):
        for y in np.linspace(-0.04, 0.04, 5):
            guess = _solve_pose(lengths_fn, L, x, y, guess)
            poses.append((np.array([x, y, guess[0]]), Rotation.from_rotvec(guess[1:]).as_matrix()))
    B_p_P = np.array([p for p, _ in poses])
    B_R_P = np.array([R for _, R in poses])
    # truth: Vicon -> base and platform-in-marker transforms
    B_R_V = Rotation.from_rotvec([0.01, -0.02, 0.05]).as_matrix()
    B_p_V = np.array([0.03, -0.05, 1.1])
    M_R_P = Rotation.from_rotvec([0.02, 0.01, -0.03]).as_matrix()
    M_p_P = np.array([0.01, -0.02, -0.2])
    # marker pose: B_T_M = B_T_P (M_T_P)^-1, then V_T_M = (B_T_V)^-1 B_T_M
    B_R_M = B_R_P @ M_R_P.T
    B_p_M = B_p_P - np.einsum("nab,b->na", B_R_M, M_p_P)
    V_R_M = np.einsum("ba,nbc->nac", B_R_V, B_R_M)
    V_p_M = (B_p_M - B_p_V) @ B_R_V
    delta = np.array([0.3, -0.2, 0.1, 0.5])
    psi = np.asarray(jax.vmap(lambda p, R: swivel_angles(robot, p, R))(B_p_P, B_R_P)) - delta
    data = CalibrationData(np.arange(len(poses)) * 0.01, V_R_M, V_p_M, psi)
    res = calibrate_geometry(robot, data, anchors="config", yaw_starts=1, start_subsample=1)
    assert res.rms_after["length_m"] < 1e-9
    assert res.rms_after["swivel_rad"] < 1e-9
    np.testing.assert_allclose(res.B_R_V, B_R_V, atol=1e-8)
    np.testing.assert_allclose(res.B_p_V, B_p_V, atol=1e-8)
    np.testing.assert_allclose(res.M_R_P, M_R_P, atol=1e-8)
    np.testing.assert_allclose(res.M_p_P, M_p_P, atol=1e-8)
    np.testing.assert_allclose(res.lengths, L, atol=1e-8)
    np.testing.assert_allclose(res.swivel_offset, delta, atol=1e-8)
    assert res.rms_before["length_m"] > 1e-3
    R_hat, p_hat = platform_pose(res, V_R_M, V_p_M)
    np.testing.assert_allclose(p_hat, B_p_P, atol=1e-8)
    np.testing.assert_allclose(R_hat, B_R_P, atol=1e-8)


# --------------------------------------------------------------------------- real data


@pytest.fixture(scope="module")
def uacdpr_files():
    root = shared_dataset(NAME)
    return {"vicon": root / "FreeMotion02.txt", "log": root / "FreeMotion02_exp.mat",
            "config": root / "IRMA4U_Mar25.mat"}


@pytest.fixture(scope="module")
def imported(uacdpr_files, tmp_path_factory):
    from cdprid.io._uacdpr import import_uacdpr

    out = tmp_path_factory.mktemp("uacdpr") / "ds"
    return import_uacdpr(uacdpr_files["vicon"], uacdpr_files["log"], uacdpr_files["config"], out)


def test_import_passes_reader_with_expected_streams(imported):
    ds = read_dataset(imported)
    assert ds.robot.n_cables == 4
    assert ds.position.shape == (3700, 3) and ds.quaternion.shape == (3700, 4)
    np.testing.assert_allclose(np.diff(ds.pose_t), 0.01, atol=1e-9)
    assert ds.pose_t[0] == 0.0
    assert ds.tension.shape == (32580, 4)
    np.testing.assert_allclose(np.diff(ds.tension_t), 0.001, atol=1e-9)
    assert ds.tension_t[0] == pytest.approx(4.42)
    cols, sw = ds.extra["swivel"]
    assert cols == ["t", "swivel_1", "swivel_2", "swivel_3", "swivel_4"] and sw.shape == (32580, 5)
    cols, inc = ds.extra["inclinometer"]
    assert cols == ["t", "eps_1", "eps_2", "eps_3"]
    np.testing.assert_allclose(ds.robot.pulley_radius, 0.03)
    np.testing.assert_allclose(np.abs(np.asarray(ds.robot.B_A)[:, :2]), [[1.065, 1.155]] * 4,
                               atol=2e-3)
    assert ds.robot.platform.mass == pytest.approx(12.992)
    assert "marker frame" in ds.meta["frames"]["pose"]


def test_marker_fit_residual_is_small(uacdpr_files, capsys):
    v = read_vicon_trajectories(uacdpr_files["vicon"])
    fit = estimate_layout(v.V_m, origin_marker=8)
    per = 1e3 * fit.rms_per_marker
    with capsys.disabled():
        print(f"\nmarker fit RMS per marker, mm: {np.round(per, 3).tolist()}; "
              f"overall {1e3 * fit.rms:.3f} mm, max {1e3 * np.nanmax(fit.residual):.2f} mm")
    assert np.all(per < 1.0)
    # the position of marker 9 agrees with the authors' filtered pose_v to ~1 mm
    st = scipy.io.loadmat(uacdpr_files["log"], squeeze_me=True, struct_as_record=False)["st_out"]
    f = np.round(st.t[st.vicon_idx - 1] / 0.01).astype(int)
    err = np.sqrt(np.mean((1e3 * fit.V_p_M[f] - st.pose_v[:3].T) ** 2))
    assert err < 3.0


def test_import_refuses_to_overwrite(imported, uacdpr_files, capsys, monkeypatch):
    argv = ["import", "uacdpr", "--vicon", str(uacdpr_files["vicon"]), "--robot-log",
            str(uacdpr_files["log"]), "--config", str(uacdpr_files["config"]), "--out",
            str(imported)]
    code, _, err = _run_cli(argv, capsys, monkeypatch)
    assert code == 2 and "--force" in err and len(err.strip().splitlines()) == 1


# --------------------------------------------------------------------------- malformed inputs


def _cfg_dict(drop: str | None = None) -> dict:
    pulleys = np.empty(4, dtype=object)
    pts = np.empty(4, dtype=object)
    for i, (sx, sy) in enumerate([(1, -1), (1, 1), (-1, 1), (-1, -1)]):
        ff = np.empty(3, dtype=object)
        ff[0], ff[1], ff[2] = [0.0, 0.0, -1.0], [0.0, sx * 1.0, 0.0], [sx * 1.0, 0.0, 0.0]
        pulleys[i] = {"Id": i + 1, "r": 0.03, "CableEnterPosition": [1.066 * sx, 1.155 * sy, 1.839],
                      "FixedFrame": ff}
        pts[i] = [0.075 * sx, 0.075 * sy, 0.266]
    plat = {"m": 13.0, "PtoG": [0.0, 0.0, 0.173], "InertialMatrix": np.eye(3) * 0.1,
            "points": pts}
    s = {"Trasmission": {"Pulley": pulleys}, "EndEffector": {"Platform": plat}}
    if drop:
        del s["EndEffector"]["Platform"][drop]
    return {"s": s}


@pytest.fixture
def small_inputs(tmp_path):
    """Tiny synthetic inputs of the three formats (no shared data needed)."""
    scipy.io.savemat(tmp_path / "cfg.mat", _cfg_dict())
    n = 500
    t = 0.2 + 0.001 * np.arange(n)
    st = {"t": t, "tensions": np.full((4, n), 30.0), "swivel": np.zeros((4, n)),
          "cable_length": np.zeros((4, n)), "epsilon": np.zeros((3, n))}
    scipy.io.savemat(tmp_path / "log.mat", {"st_out": st})
    rng = np.random.default_rng(3)
    M = rng.normal(0, 100, (9, 3))
    rows = []
    for f in range(1, 61):
        R = Rotation.from_rotvec([0.01 * f, 0.0, 0.02 * f]).as_matrix()
        V = M @ R.T + [0.0, 0.0, 700.0]
        rows.append("\t".join([str(f), "0"] + [f"{v:.4f}" for v in V.ravel()]))
    head = ["Trajectories", "100",
            "\t\t" + "\t\t\t".join(f"platform:points{k}" for k in range(1, 10)) + "\t\t",
            "Frame\tSub Frame\t" + "\t".join(["X\tY\tZ"] * 9),
            "\t\t" + "\t".join(["mm"] * 27)]
    (tmp_path / "vicon.txt").write_text("\n".join(head + rows) + "\n")
    return tmp_path


def _argv(d, out, **over):
    files = {"vicon": d / "vicon.txt", "log": d / "log.mat", "config": d / "cfg.mat", **over}
    return ["import", "uacdpr", "--vicon", str(files["vicon"]), "--robot-log", str(files["log"]),
            "--config", str(files["config"]), "--out", str(out), "--no-calibrate"]


def test_small_synthetic_import_succeeds(small_inputs, capsys, monkeypatch):
    code, out, err = _run_cli(_argv(small_inputs, small_inputs / "ds"), capsys, monkeypatch)
    assert code == 0, err
    ds = read_dataset(small_inputs / "ds")
    assert ds.position.shape == (60, 3)
    assert "marker fit RMS" in out


@pytest.mark.parametrize("case", ["missing-file", "wrong-header", "not-mat", "missing-field",
                                  "truncated-row", "no-struct", "log-shape"])
def test_malformed_inputs_exit_2_with_one_sentence(case, small_inputs, capsys, monkeypatch):
    d = small_inputs
    over, expect = {}, ""
    if case == "missing-file":
        over, expect = {"vicon": d / "nope.txt"}, "missing"
    elif case == "wrong-header":
        lines = (d / "vicon.txt").read_text().splitlines()
        (d / "bad.txt").write_text("\n".join(["Model outputs"] + lines[1:]) + "\n")
        over, expect = {"vicon": d / "bad.txt"}, "Trajectories"
    elif case == "not-mat":
        (d / "bad.mat").write_text("this is not a MAT file\n")
        over, expect = {"config": d / "bad.mat"}, "not a readable MATLAB"
    elif case == "missing-field":
        scipy.io.savemat(d / "bad.mat", _cfg_dict(drop="points"))
        over, expect = {"config": d / "bad.mat"}, "'points'"
    elif case == "truncated-row":
        lines = (d / "vicon.txt").read_text().splitlines()
        lines[20] = "\t".join(lines[20].split("\t")[:10])
        (d / "bad.txt").write_text("\n".join(lines) + "\n")
        over, expect = {"vicon": d / "bad.txt"}, "line 21 is truncated"
    elif case == "no-struct":
        scipy.io.savemat(d / "bad.mat", {"other": np.zeros(3)})
        over, expect = {"log": d / "bad.mat"}, "st_out"
    elif case == "log-shape":
        st = {"t": np.arange(10.0), "tensions": np.zeros((4, 9)), "swivel": np.zeros((4, 10)),
              "cable_length": np.zeros((4, 10)), "epsilon": np.zeros((3, 10))}
        scipy.io.savemat(d / "bad.mat", {"st_out": st})
        over, expect = {"log": d / "bad.mat"}, "st_out.tensions"
    code, _, err = _run_cli(_argv(d, d / "ds", **over), capsys, monkeypatch)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0], err
    assert "Traceback" not in err


def test_write_calibrated_dataset_moves_pose_to_base_frame(small_inputs, capsys, monkeypatch):
    from cdprid.identify import (
        CalibrationResult,
        platform_pose,
        write_calibrated_dataset,
    )
    from cdprid.model import quat_to_matrix

    code, _, err = _run_cli(_argv(small_inputs, small_inputs / "ds"), capsys, monkeypatch)
    assert code == 0, err
    src = read_dataset(small_inputs / "ds")
    B_R_V = Rotation.from_rotvec([0.0, 0.0, np.pi]).as_matrix()
    M_R_P = Rotation.from_rotvec([0.1, 0.0, 0.0]).as_matrix()
    res = CalibrationResult(
        anchors="config", B_R_V=B_R_V, B_p_V=np.array([0.1, 0.2, 0.3]), M_R_P=M_R_P,
        M_p_P=np.array([0.0, 0.01, 0.02]), M_b=np.zeros((4, 3)), lengths=np.ones(4),
        swivel_offset=np.zeros(4), params={}, sigma={}, rms_before={}, rms_after={},
        rms_per_cable={}, n_samples=1, condition=1.0, swivel_sign=1.0)
    write_calibrated_dataset(small_inputs / "ds", res, small_inputs / "dsB")
    out = read_dataset(small_inputs / "dsB")
    V_R_M = np.stack([np.asarray(quat_to_matrix(q)) for q in src.quaternion])
    R, p = platform_pose(res, V_R_M, src.position)
    np.testing.assert_allclose(out.position, p, atol=1e-12)
    R_out = np.stack([np.asarray(quat_to_matrix(q)) for q in out.quaternion])
    np.testing.assert_allclose(R_out, R, atol=1e-9)
    np.testing.assert_allclose(out.tension, src.tension)
    assert "swivel" in out.extra and "calibration" in out.meta
    np.testing.assert_allclose(np.asarray(out.robot.P_b), np.asarray(src.robot.P_b))


def test_import_is_atomic_when_writing_fails(small_inputs, monkeypatch):
    """A failure while the dataset is written leaves neither the folder nor a temporary one."""
    import cdprid.io._uacdpr as uac

    real_write = uac.write_uacdpr

    def failing(rec, out, meta, *a, **kw):
        real_write(rec, out, meta, *a, **kw)  # the files exist in the temporary folder ...
        raise RuntimeError("disk full")  # ... and then the write fails

    monkeypatch.setattr(uac, "write_uacdpr", failing)
    out = small_inputs / "ds"
    with pytest.raises(RuntimeError, match="disk full"):
        uac.import_uacdpr(small_inputs / "vicon.txt", small_inputs / "log.mat",
                          small_inputs / "cfg.mat", out)
    assert not out.exists()
    assert not [p for p in small_inputs.iterdir() if p.name.startswith(".ds")]
    monkeypatch.setattr(uac, "write_uacdpr", real_write)
    uac.import_uacdpr(small_inputs / "vicon.txt", small_inputs / "log.mat",
                      small_inputs / "cfg.mat", out)
    assert read_dataset(out).position.shape == (60, 3)
