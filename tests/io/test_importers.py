"""Importers (table, rosbag, c3d) and the package sample data: round trips and bad input.

Each round trip writes the package sample dataset (a simulated 8-cable robot of its own, with
rotation, noise, and tensions on their own clock) into another format with the library that
format belongs to (rosbags writers, ezc3d, plain text in other units), imports it with the CLI
options of the contract, identifies the 10-parameter model and compares with the native
dataset: the streams within the format's precision, the mass within 0.1 %.
"""

from __future__ import annotations

import numpy as np
import pytest

from cdprid import identify_dataset, read_dataset
from cdprid.cli import main

MODEL = "full"


@pytest.fixture(scope="module")
def native(sample_dataset):
    ds = read_dataset(sample_dataset)
    return ds, identify_dataset(ds, model=MODEL)


def _check_round_trip(native, out, pos_tol, tau_tol, t_tol=1e-9):
    ds, rep = native
    imp = read_dataset(out)
    assert imp.meta["source"] == "imported" and imp.meta["units"]["tension"] == "N"
    # pose samples present in both (C3D may drop gap frames)
    idx = np.searchsorted(ds.pose_t, imp.pose_t - 1e-6)
    np.testing.assert_allclose(imp.pose_t, ds.pose_t[idx], atol=t_tol)
    np.testing.assert_allclose(imp.position, ds.position[idx], atol=pos_tol)
    dq = np.abs(np.abs(np.einsum("ij,ij->i", imp.quaternion, ds.quaternion[idx])) - 1)
    assert dq.max() < max(pos_tol, 1e-9) * 10
    np.testing.assert_allclose(imp.tension_t, ds.tension_t, atol=t_tol)
    np.testing.assert_allclose(imp.tension, ds.tension, atol=tau_tol)
    got = identify_dataset(imp, model=MODEL)
    m0 = rep.result.x[0]
    assert abs(got.result.x[0] / m0 - 1) < 1e-3
    assert abs(m0 / ds.truth["mass"] - 1) < 0.01  # and the native estimate is near the truth
    return imp


def test_sample_dataset_is_simulated_non_craft_with_rotation(native):
    ds, rep = native
    assert ds.robot.n_cables == 8 and ds.quaternion is not None
    assert ds.meta["source"] == "simulated" and ds.truth["mass"] == 6.3
    assert not np.array_equal(ds.pose_t, ds.tension_t)  # separate clocks
    assert abs(rep.result.x[0] / 6.3 - 1) < 0.005


def test_cli_example_writes_sample_and_refuses_existing(tmp_path, capsys):
    out = tmp_path / "ex"
    assert main(["example", "--out", str(out)]) == 0
    assert read_dataset(out).robot.n_cables == 8
    assert main(["example", "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert main(["example", "--out", str(out), "--force"]) == 0


# ----------------------------------------------------------------------------- table


def _write_tables(ds, d, offset):
    from scipy.spatial.transform import Rotation

    q = ds.quaternion
    e = Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])).as_euler("ZYX", degrees=True)
    pose = d / "pose.tsv"
    with open(pose, "w", encoding="utf-8-sig") as fh:  # BOM, tabs, quoted headers, other order
        fh.write('"Time [ms]"\t"yaw"\t"pitch"\t"roll"\t"X mm"\t"Y mm"\t"Z mm"\n')
        for k in range(len(ds.pose_t)):
            vals = [1e3 * ds.pose_t[k], *e[k], *(1e3 * ds.position[k])]
            fh.write("\t".join(f"{v:.17g}" for v in vals) + "\n")
    tens = d / "loadcells.csv"
    with open(tens, "w", encoding="utf-8") as fh:  # semicolons, kN, clock shifted by -offset
        fh.write("clock;" + ";".join(f"LC{i}" for i in range(8, 0, -1)) + "\n")
        for k in range(len(ds.tension_t)):
            vals = [ds.tension_t[k] - offset, *(ds.tension[k, ::-1] / 1e3)]
            fh.write(";".join(f"{v:.17g}" for v in vals) + "\n")
    return pose, tens


def _table_argv(ds_path, pose, tens, out, offset):
    return ["import", "table", "--pose", str(pose), "--tensions", str(tens),
            "--robot", str(ds_path / "robot.toml"), "--out", str(out),
            "--pose-columns", "t=Time [ms],x=X mm,y=Y mm,z=Z mm,e1=yaw,e2=pitch,e3=roll",
            "--euler", "ZYX", "--pose-units", "time=ms,length=mm,angle=deg",
            "--tension-columns", "t=clock," + ",".join(f"tau_{i}=LC{i}" for i in range(1, 9)),
            "--tension-units", "time=s,force=kN", "--tension-time-offset", str(offset)]


def test_table_round_trip_mm_deg_ms_offset(native, sample_dataset, tmp_path):
    pose, tens = _write_tables(native[0], tmp_path, offset=0.37)
    out = tmp_path / "out"
    assert main(_table_argv(sample_dataset, pose, tens, out, 0.37)) == 0
    imp = _check_round_trip(native, out, 1e-12, 1e-9, t_tol=1e-12)
    assert imp.meta["import"]["pose_units"] == {"time": "ms", "length": "mm", "angle": "deg"}
    assert imp.meta["import"]["pose_delimiter"] == "tab"
    assert imp.meta["import"]["tension_delimiter"] == "semicolon"
    assert imp.meta["import"]["tension_time_offset_s"] == 0.37
    assert imp.meta["import"]["euler"] == "ZYX"


def test_table_semicolon_decimal_comma(tmp_path):
    from cdprid.io._table import read_table

    f = tmp_path / "t.csv"
    f.write_text('"t";"tau 1"\n0,5;12,25\n1;13\n')
    tab = read_table(f)
    assert tab.delimiter == ";" and tab.columns == ("t", "tau 1")
    np.testing.assert_array_equal(tab.values, [[0.5, 12.25], [1.0, 13.0]])


def test_table_whitespace_and_dropped_rows(sample_dataset, tmp_path):
    ds = read_dataset(sample_dataset)
    pose = tmp_path / "p.txt"
    rows = [f"{t:.9f} {x:.9f} {y:.9f} {z:.9f}"
            for t, (x, y, z) in zip(ds.pose_t, ds.position, strict=True)]
    rows[5] = f"{ds.pose_t[5]:.9f} nan {ds.position[5, 1]:.9f} {ds.position[5, 2]:.9f}"
    pose.write_text("t x y z\n" + "\n".join(rows) + "\n")
    out = tmp_path / "o"
    assert main(["import", "table", "--pose", str(pose), "--tensions",
                 str(sample_dataset / "tensions.csv"), "--robot",
                 str(sample_dataset / "robot.toml"), "--out", str(out)]) == 0
    imp = read_dataset(out)
    assert imp.quaternion is None and len(imp.pose_t) == len(ds.pose_t) - 1
    assert imp.meta["import"]["pose_rows_dropped"] == 1
    assert imp.meta["import"]["pose_delimiter"] == "whitespace"


@pytest.mark.parametrize("change,expect", [
    (("--pose-columns", "t=Time [ms],x=NOPE,y=Y mm,z=Z mm"), "has no column 'NOPE'"),
    (("--tension-columns", "t=clock,tau_1=LC1"), "lacks 'tau_2'"),
    (("--pose-units", "time=fortnight"), "unknown time unit"),
    (("--euler", "ZZQ"), "--euler"),
    (("--pose", "/nonexistent/p.csv"), "file is missing"),
])
def test_table_bad_input_one_sentence_exit_2(sample_dataset, tmp_path, capsys, change, expect):
    ds = read_dataset(sample_dataset)
    pose, tens = _write_tables(ds, tmp_path, 0.0)
    argv = _table_argv(sample_dataset, pose, tens, tmp_path / "o", 0.0)
    i = argv.index(change[0])
    argv[i + 1] = change[1]
    if change[0] == "--pose-columns":
        argv[argv.index("--euler"):argv.index("--euler") + 2] = []
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert expect in err and len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- rosbag


@pytest.mark.parametrize("kind,pose_type,tension_type,ext", [
    ("ros2-mcap", "geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/JointState", ""),
    ("ros2-sqlite", "nav_msgs/msg/Odometry", "geometry_msgs/msg/WrenchStamped", ""),
    ("ros1", "tf2_msgs/msg/TFMessage", "std_msgs/msg/Float64MultiArray", ".bag"),
    ("ros1", "geometry_msgs/msg/TransformStamped", "std_msgs/msg/Float64", ".bag"),
])
def test_rosbag_round_trip(native, sample_dataset, tmp_path, capsys, kind, pose_type,
                           tension_type, ext):
    from cdprid.io._rosbag import write_rosbag

    bag = write_rosbag(native[0], tmp_path / f"bag{ext}", kind=kind, pose_type=pose_type,
                       tension_type=tension_type)
    assert main(["import", "rosbag", str(bag), "--list"]) == 0
    listing = capsys.readouterr().out
    assert pose_type in listing and tension_type in listing
    pose_topic = "/tf" if pose_type.startswith("tf2") else "/platform/pose"
    argv = ["import", "rosbag", str(bag), "--robot", str(sample_dataset / "robot.toml"),
            "--pose-topic", pose_topic, "--out", str(tmp_path / "out"), "--frames",
            "base,platform"]
    if tension_type in ("std_msgs/msg/Float64", "geometry_msgs/msg/WrenchStamped"):
        for i in range(1, 9):
            argv += ["--tension-topic", f"/cable{i}/tension"]
    else:
        argv += ["--tension-topic", "/cable/tensions"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    imp = _check_round_trip(native, tmp_path / "out", 1e-15, 1e-12, t_tol=1e-9)
    headerless = "Float64" in tension_type
    assert ("no header" in out) == headerless
    assert any("receipt time" in n for n in imp.meta["import"]["notes"]) == headerless


def test_rosbag_bad_input(native, sample_dataset, tmp_path, capsys):
    from cdprid.io._rosbag import write_rosbag

    bag = write_rosbag(native[0], tmp_path / "b", kind="ros2-mcap",
                       pose_type="tf2_msgs/msg/TFMessage")
    base = ["import", "rosbag", str(bag), "--robot", str(sample_dataset / "robot.toml"),
            "--out", str(tmp_path / "o")]
    cases = [
        (["--pose-topic", "/nope", "--tension-topic", "/cable/tensions"], "no such topic"),
        (["--pose-topic", "/tf", "--tension-topic", "/cable/tensions"], "--frames"),
        (["--pose-topic", "/tf", "--frames", "world,x", "--tension-topic", "/cable/tensions"],
         "base,platform"),
        (["--pose-topic", "/cable/tensions", "--tension-topic", "/tf"], "has type"),
        (["--pose-topic", "/tf", "--frames", "base,platform", "--tension-topic", "/a",
          "--tension-topic", "/b"], "given 2 times"),
    ]
    for extra, expect in cases:
        assert main(base + extra) == 2, extra
        err = capsys.readouterr().err.strip()
        assert expect in err and len(err.splitlines()) == 1, err
    assert main(["import", "rosbag", str(tmp_path / "missing.bag"), "--list"]) == 2
    assert "missing" in capsys.readouterr().err


# ----------------------------------------------------------------------------- c3d

LAYOUT = np.array([[0.1, 0.08, 0.06], [-0.1, 0.08, 0.06], [-0.1, -0.08, 0.06],
                   [0.1, -0.08, -0.06], [0.0, 0.0, 0.09]])


def _write_c3d(ds, path, drop):
    import ezc3d
    from scipy.spatial.transform import Rotation

    q = ds.quaternion
    R = Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])).as_matrix()
    V = np.einsum("nab,kb->nka", R, LAYOUT) + ds.position[:, None, :]  # (n, k, 3), m
    for frame, markers in drop.items():
        V[frame, markers] = np.nan
    c = ezc3d.c3d()
    rate = 1.0 / np.median(np.diff(ds.pose_t))
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(f"plat{i + 1}" for i in range(5))
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, 5, len(ds.pose_t)))
    pts[:3] = np.transpose(V * 1e3, (2, 1, 0))
    c["data"]["points"] = pts
    c["parameters"]["ANALOG"]["RATE"]["value"] = [1.0 / np.median(np.diff(ds.tension_t))]
    c["parameters"]["ANALOG"]["LABELS"]["value"] = tuple(f"load{i + 1}" for i in range(8))
    c["parameters"]["ANALOG"]["UNITS"]["value"] = ["N"] * 8
    n_an = 2 * len(ds.pose_t)  # analog frames: ratio x point frames
    an = np.zeros((1, 8, n_an))
    an[0, :, :len(ds.tension_t)] = ds.tension[:n_an].T
    c["data"]["analogs"] = an
    c.write(str(path))
    return path


def test_c3d_round_trip_layout_given_and_gaps(native, sample_dataset, tmp_path, capsys):
    ds = native[0]
    assert len(ds.tension_t) <= 2 * len(ds.pose_t)
    drop = {100: [0, 1, 2], 101: [0, 1, 2, 3], 300: [4]}  # 2 frames lose the pose, 1 keeps it
    f = _write_c3d(ds, tmp_path / "rec.c3d", drop)
    layout = tmp_path / "layout.csv"
    layout.write_text("name,x,y,z\n" + "\n".join(
        f"plat{i + 1},{1e3 * x},{1e3 * y},{1e3 * z}" for i, (x, y, z) in enumerate(LAYOUT)))
    tensions = ",".join(f"load{i}" for i in range(1, 9))
    argv = ["import", "c3d", str(f), "--robot", str(sample_dataset / "robot.toml"), "--out",
            str(tmp_path / "out"), "--layout", str(layout), "--layout-units", "mm",
            "--analog-tensions", tensions]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "2 of 1001 frames without a pose" in out
    n_t = len(ds.tension_t)
    imp = read_dataset(tmp_path / "out")
    assert imp.meta["import"]["gaps"] == [[ds.pose_t[100], ds.pose_t[101]]]
    assert len(imp.pose_t) == len(ds.pose_t) - 2
    # analog frames beyond the tension stream are zeros: compare the recorded part only
    assert imp.tension.shape[0] >= n_t
    np.testing.assert_allclose(imp.tension[:n_t], ds.tension, atol=1e-4)  # float32 in C3D
    trimmed = tmp_path / "trim"
    from cdprid.io import write_dataset

    write_dataset(trimmed, imp.robot, imp.pose_t, imp.position, imp.tension_t[:n_t],
                  imp.tension[:n_t], quaternion=imp.quaternion, meta=imp.meta)
    _check_round_trip(native, trimmed, 1e-6, 1e-4, t_tol=1e-9)


def test_c3d_estimated_layout_and_bad_input(native, sample_dataset, tmp_path, capsys):
    f = _write_c3d(native[0], tmp_path / "rec.c3d", {})
    robot = str(sample_dataset / "robot.toml")
    tensions = ",".join(f"load{i}" for i in range(1, 9))
    assert main(["import", "c3d", str(f), "--robot", robot, "--out", str(tmp_path / "o"),
                 "--analog-tensions", tensions, "--origin-marker", "plat5"]) == 0
    assert "marker frame" in capsys.readouterr().out
    imp = read_dataset(tmp_path / "o")
    assert imp.meta["import"]["fit_rms_mm"] < 0.01
    from scipy.spatial.transform import Rotation

    ds = native[0]
    q = ds.quaternion
    R = Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])).as_matrix()
    marker5 = R @ LAYOUT[4] + ds.position  # the marker-frame origin is marker plat5
    np.testing.assert_allclose(imp.position, marker5, atol=1e-6)  # float32 in the C3D
    cases = [
        (["--markers", "plat1,plat9"], "no marker 'plat9'"),
        (["--analog-tensions", "load1,load2"], "names 2 channel(s)"),
        (["--analog-tensions", tensions.replace("load8", "loadX")], "no analog channel"),
        (["--markers", "plat1,plat2"], "at least 3"),
    ]
    for extra, expect in cases:
        argv = ["import", "c3d", str(f), "--robot", robot, "--out", str(tmp_path / "x")]
        if "--analog-tensions" not in extra:
            argv += ["--analog-tensions", tensions]
        assert main(argv + extra) == 2, extra
        err = capsys.readouterr().err.strip()
        assert expect in err and len(err.splitlines()) == 1, err
    assert main(["import", "c3d", str(tmp_path / "none.c3d"), "--robot", robot, "--out",
                 str(tmp_path / "x"), "--analog-tensions", tensions]) == 2
    assert "missing" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite"])
def test_rosbag_fast_decoder_matches_rosbags_deserialiser(native, tmp_path, kind):
    from cdprid.io._rosbag import fast_decode, open_bag, pose_values, write_rosbag

    ds = native[0]
    bag = write_rosbag(ds, tmp_path / ("b.bag" if kind == "ros1" else "b"), kind=kind)
    reader = open_bag(bag)
    try:
        for topic, what in (("/platform/pose", "pose"), ("/cable/tensions", "effort")):
            conns = [c for c in reader.connections if c.topic == topic]
            msgs = list(reader.messages(connections=conns))
            st, v = fast_decode([raw for _, _, raw in msgs], not reader.is2, what)
            for k in (0, len(msgs) // 2, len(msgs) - 1):
                conn, _, raw = msgs[k]
                msg = reader.deserialize(raw, conn.msgtype)
                if what == "pose":
                    ref = pose_values(msg, conn.msgtype, None)
                    assert st[k] == ref[0] and np.array_equal(v[k], ref[1:])
                else:
                    assert np.array_equal(v[k], msg.effort)
    finally:
        reader.close()


def test_rosbag_joints_reorder_and_extrinsic_euler_table(native, sample_dataset, tmp_path):
    from scipy.spatial.transform import Rotation

    from cdprid.io._rosbag import write_rosbag

    ds = native[0]
    bag = write_rosbag(ds, tmp_path / "b", kind="ros2-mcap")
    joints = ",".join(f"cable{i}" for i in range(8, 0, -1))
    assert main(["import", "rosbag", str(bag), "--robot", str(sample_dataset / "robot.toml"),
                 "--pose-topic", "/platform/pose", "--tension-topic", "/cable/tensions",
                 "--joints", joints, "--out", str(tmp_path / "o")]) == 0
    np.testing.assert_array_equal(read_dataset(tmp_path / "o").tension, ds.tension[:, ::-1])
    # extrinsic lower-case sequence, radians, comma-separated, default tension columns
    q = ds.quaternion
    e = Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])).as_euler("xyz")
    pose = tmp_path / "p.csv"
    rows = np.column_stack([ds.pose_t, ds.position, e])
    np.savetxt(pose, rows, delimiter=",", fmt="%.17g", header="t,x,y,z,a,b,c", comments="")
    assert main(["import", "table", "--pose", str(pose), "--tensions",
                 str(sample_dataset / "tensions.csv"), "--robot",
                 str(sample_dataset / "robot.toml"), "--out", str(tmp_path / "t"),
                 "--pose-columns", "t=t,x=x,y=y,z=z,e1=a,e2=b,e3=c", "--euler", "xyz"]) == 0
    imp = read_dataset(tmp_path / "t")
    dots = np.abs(np.einsum("ij,ij->i", imp.quaternion, ds.quaternion))
    assert np.all(1 - dots < 1e-12)
    assert "extrinsic" in imp.meta["import"]["orientation"]


def test_c3d_cut_in_half_is_refused(native, sample_dataset, tmp_path, capsys):
    """A C3D truncated in a copy imported 496 of 1001 frames with no note (issue 25)."""
    f = _write_c3d(native[0], tmp_path / "rec.c3d", {})
    data = f.read_bytes()
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[: len(data) // 2])
    rc = main(["import", "c3d", str(cut), "--robot", str(sample_dataset / "robot.toml"),
               "--out", str(tmp_path / "o"), "--analog-tensions",
               ",".join(f"load{i}" for i in range(1, 9))])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "truncated" in err or "cannot be read" in err or "not a C3D" in err, err
    assert not (tmp_path / "o").exists()
