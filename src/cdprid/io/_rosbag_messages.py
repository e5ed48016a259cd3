"""The ROS message types the bag importer reads, and bags written from a dataset's pose and
tension streams (for tests, benchmarks and demos).

The reader, :mod:`cdprid.io._rosbag`, documents the topics and message types.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["ARRAY_TENSION_TYPES", "CABLE_TENSION_TYPES", "HEADERLESS", "POSE_TYPES",
           "TENSION_TYPES", "write_rosbag"]

POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
              "nav_msgs/msg/Odometry", "geometry_msgs/msg/TransformStamped",
              "tf2_msgs/msg/TFMessage")
ARRAY_TENSION_TYPES = ("sensor_msgs/msg/JointState", "std_msgs/msg/Float64MultiArray")
CABLE_TENSION_TYPES = ("std_msgs/msg/Float64", "geometry_msgs/msg/WrenchStamped")
TENSION_TYPES = ARRAY_TENSION_TYPES + CABLE_TENSION_TYPES
HEADERLESS = ("std_msgs/msg/Float64", "std_msgs/msg/Float64MultiArray")


def _stamp(types, t_ns: int):
    return types["builtin_interfaces/msg/Time"](sec=int(t_ns // 1_000_000_000),
                                                nanosec=int(t_ns % 1_000_000_000))


def _header(types, ros1: bool, t_ns: int, frame: str):
    kw = {"seq": 0} if ros1 else {}
    return types["std_msgs/msg/Header"](**kw, stamp=_stamp(types, t_ns), frame_id=frame)


def _pose_msg(types, ros1, typ, t_ns, p, q, frames):
    H = _header(types, ros1, t_ns, frames[0])
    P = types["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2])
    Q = types["geometry_msgs/msg/Quaternion"](x=q[1], y=q[2], z=q[3], w=q[0])
    if typ == "geometry_msgs/msg/PoseStamped":
        return types[typ](header=H, pose=types["geometry_msgs/msg/Pose"](position=P, orientation=Q))
    if typ == "nav_msgs/msg/Odometry":
        cov = np.zeros(36)
        pose = types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](position=P, orientation=Q), covariance=cov)
        V3 = types["geometry_msgs/msg/Vector3"]
        tw = types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](linear=V3(x=0.0, y=0.0, z=0.0),
                                                  angular=V3(x=0.0, y=0.0, z=0.0)),
            covariance=cov)
        return types[typ](header=H, child_frame_id=frames[1], pose=pose, twist=tw)
    tr = types["geometry_msgs/msg/TransformStamped"](
        header=H, child_frame_id=frames[1],
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]), rotation=Q))
    if typ == "tf2_msgs/msg/TFMessage":
        return types[typ](transforms=[tr])
    return tr


def write_rosbag(ds, path: str | Path, kind: str = "ros2-mcap",
                 pose_type: str = "geometry_msgs/msg/PoseStamped",
                 tension_type: str = "sensor_msgs/msg/JointState",
                 t0_ns: int = 1_700_000_000_000_000_000,
                 frames: tuple[str, str] = ("base", "platform")) -> Path:
    """Write a dataset's pose and tension streams as a bag (for tests, benchmarks and demos).

    Parameters
    ----------
    ds : Dataset
    path : path
        ``.bag`` file (``kind="ros1"``) or ROS 2 bag folder (``ros2-mcap``, ``ros2-sqlite``);
        must not exist.
    kind : {"ros2-mcap", "ros2-sqlite", "ros1"}
        Bag format.
    pose_type : str
        One of :data:`POSE_TYPES` (topic ``/platform/pose``, or ``/tf`` for TFMessage).
    tension_type : str
        JointState / Float64MultiArray on ``/cable/tensions``, or Float64 / WrenchStamped:
        one topic ``/cable{i}/tension`` per cable.
    t0_ns : int
        Epoch stamp of t = 0. Headerless messages get their stamp as receipt time.
    frames : (parent, child)

    Returns
    -------
    Path
    """
    from rosbags.typesys import Stores, get_typestore

    ros1 = kind == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:  # the ROS 1 store lacks it
        from rosbags.typesys import get_types_from_msg

        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                       "tf2_msgs/msg/TFMessage"))
    T = ts.types
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    writer = _bag_writer(path, kind)
    q = ds.quaternion if ds.quaternion is not None else \
        np.tile([1.0, 0.0, 0.0, 0.0], (len(ds.pose_t), 1))
    pose_ns = t0_ns + np.round(ds.pose_t * 1e9).astype(np.int64)
    tens_ns = t0_ns + np.round(ds.tension_t * 1e9).astype(np.int64)
    with writer as w:
        pc = w.add_connection("/tf" if pose_type == "tf2_msgs/msg/TFMessage" else
                              "/platform/pose", pose_type, typestore=ts)
        for k in range(len(pose_ns)):
            msg = _pose_msg(T, ros1, pose_type, int(pose_ns[k]), ds.position[k], q[k], frames)
            w.write(pc, int(pose_ns[k]), ser(msg, pose_type))
        _write_tensions(w, ts, ros1, ser, ds.tension, tension_type, tens_ns)
    return Path(path)


def _bag_writer(path, kind: str):
    """The rosbags writer of ``kind``: a ROS 1 ``.bag`` file, or a ROS 2 bag folder (MCAP or
    SQLite storage)."""
    if kind == "ros1":
        from rosbags.rosbag1 import Writer

        return Writer(Path(path))
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if kind == "ros2-mcap" else StoragePlugin.SQLITE3
    return Writer(Path(path), version=9, storage_plugin=plugin)


def _write_tensions(w, ts, ros1: bool, ser, tension, tension_type: str, tens_ns) -> None:
    """Write the tensions (n, m) into the open bag ``w``: one ``/cable/tensions`` topic of an
    array type, or one ``/cable{i}/tension`` topic per cable (Float64, WrenchStamped)."""
    T = ts.types
    m = tension.shape[1]
    if tension_type in ARRAY_TENSION_TYPES:
        tc = w.add_connection("/cable/tensions", tension_type, typestore=ts)
        names = [f"cable{i + 1}" for i in range(m)]
        for k in range(len(tens_ns)):
            if tension_type == "sensor_msgs/msg/JointState":
                msg = T[tension_type](header=_header(T, ros1, int(tens_ns[k]), ""),
                                      name=names, position=np.zeros(m),
                                      velocity=np.zeros(m), effort=tension[k].copy())
            else:
                lay = T["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
                msg = T[tension_type](layout=lay, data=tension[k].copy())
            w.write(tc, int(tens_ns[k]), ser(msg, tension_type))
        return
    V3 = T["geometry_msgs/msg/Vector3"]
    for i in range(m):
        tc = w.add_connection(f"/cable{i + 1}/tension", tension_type, typestore=ts)
        for k in range(len(tens_ns)):
            v = float(tension[k, i])
            if tension_type == "std_msgs/msg/Float64":
                msg = T[tension_type](data=v)
            else:
                msg = T[tension_type](
                    header=_header(T, ros1, int(tens_ns[k]), f"cable{i + 1}"),
                    wrench=T["geometry_msgs/msg/Wrench"](force=V3(x=0.0, y=0.0, z=v),
                                                         torque=V3(x=0.0, y=0.0, z=0.0)))
            w.write(tc, int(tens_ns[k]), ser(msg, tension_type))
