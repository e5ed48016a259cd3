"""ROS 1 and ROS 2 bags -> spec-v1 dataset (``cdprid import rosbag``), pure Python (``rosbags``).

ROS 1 ``.bag`` files and ROS 2 bag folders (SQLite ``.db3`` or MCAP storage) are opened with
``rosbags.highlevel.AnyReader``; messages are deserialised with the type definitions the bag
carries.

Pose topic (one), by message type:

- ``geometry_msgs/PoseStamped``, ``geometry_msgs/PoseWithCovarianceStamped``,
  ``nav_msgs/Odometry``: the pose, at the header stamp;
- ``geometry_msgs/TransformStamped`` and ``tf2_msgs/TFMessage``: the transform of the frame
  pair given by ``frames=(parent, child)`` (required for TFMessage, which mixes frames).

Tension topics: one ``sensor_msgs/JointState`` (``effort``, at the header stamp) or
``std_msgs/Float64MultiArray`` (``data``) topic with one element per cable in robot.toml's
order (or reordered by ``joints``), or one topic per cable in robot.toml's order, each
``std_msgs/Float64`` or ``geometry_msgs/WrenchStamped`` (the force's norm, or one component).
Per-cable topics are linearly interpolated onto the first cable's times (within their common
range; this is stated in meta.toml).

Times are header stamps, never receipt times, except for messages that carry no header
(``Float64``, ``Float64MultiArray``): their bag receipt time is used, and meta.toml says so.
Times are written relative to the first pose stamp; that stamp (ns since the epoch) is in
meta.toml ``[import] t0_ns``. Units: ROS uses SI (REP 103): m, s and N.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from cdprid.base import InputError, UserError
from cdprid.io._rosbag_messages import (
    ARRAY_TENSION_TYPES,
    CABLE_TENSION_TYPES,
    HEADERLESS,
    POSE_TYPES,
    TENSION_TYPES,
    write_rosbag,
)

__all__ = ["POSE_TYPES", "TENSION_TYPES", "import_rosbag", "list_topics", "read_pose_topic",
           "read_tension_topics", "write_rosbag", "open_bag", "pose_values", "fast_decode",
           "decode_topic"]


def open_bag(bag: str | Path):
    """Open a ROS 1 .bag or ROS 2 bag folder with rosbags' AnyReader (UserError if unreadable)."""
    from rosbags.highlevel import AnyReader
    from rosbags.highlevel.anyreader import AnyReaderError

    path = Path(bag)
    if not path.exists():
        raise UserError(f"{path}: bag is missing.")
    try:
        reader = AnyReader([path])
        reader.open()
    except (AnyReaderError, Exception) as exc:  # noqa: BLE001 - any failure to parse the bag
        raise UserError(f"{path}: cannot be read as a ROS 1 .bag or a ROS 2 bag folder "
                        f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}).") \
            from None
    return reader


def list_topics(bag: str | Path) -> list[tuple[str, str, int]]:
    """Topics of a bag, sorted by topic.

    Parameters
    ----------
    bag : path-like
        A ROS 1 ``.bag`` file or a ROS 2 bag folder.

    Returns
    -------
    list of (str, str, int)
        ``(topic, message type, message count)``; type ``"?"`` when the bag does not say.

    Raises
    ------
    UserError
        The bag cannot be read (one sentence naming it).
    """
    reader = open_bag(bag)
    try:
        return [(name, info.msgtype or "?", int(info.msgcount))
                for name, info in sorted(reader.topics.items())]
    finally:
        reader.close()


def _topic(reader, bag, topic: str, allowed: tuple[str, ...], option: str):
    topics = reader.topics
    if topic not in topics:
        raise UserError(f"{option} {topic}: the bag {bag} has no such topic; its topics are "
                        f"{', '.join(sorted(topics)) or 'none'} (see --list).")
    typ = topics[topic].msgtype
    if typ not in allowed:
        raise UserError(f"{option} {topic}: has type {typ}, not one of "
                        f"{', '.join(t.replace('/msg/', '/') for t in allowed)}.")
    return typ, [c for c in reader.connections if c.topic == topic]


# ------------------------------------------------------------- fast decoders of common types
# PoseStamped and JointState dominate long recordings; decoding their bytes directly (CDR for
# ROS 2, ROS 1 serialisation) is ~5x faster than the generic deserialiser. Each topic checks
# the fast decoder against rosbags' deserialiser on its first messages and falls back to the
# generic path on any difference.


def _align(off: int, a: int, ros1: bool) -> int:
    return off if ros1 else 4 + (off - 4 + a - 1) // a * a


def _layout(raw, ros1: bool, kind: str):
    """Byte layout of one message: (fixed regions [(start, end)], values offset, count).

    The fixed regions (frame id, joint names, array counts) must be byte-identical in every
    message decoded with this layout; the stamp is at bytes 4-12 (ROS 1) or 4-12 after the
    CDR encapsulation (ROS 2).
    """
    if not ros1 and raw[1] != 1:
        raise InputError("big-endian CDR")
    (n,) = struct.unpack_from("<I", raw, 12)
    off = 16 + n
    fixed = [(12, off)]
    if kind == "pose":
        return fixed, _align(off, 8, ros1), 7
    off = _align(off, 4, ros1)
    start = off
    (k,) = struct.unpack_from("<I", raw, off)
    off += 4
    for _ in range(k):
        off = _align(off, 4, ros1)
        (n,) = struct.unpack_from("<I", raw, off)
        off += 4 + n
    fixed.append((start, off))
    for _ in range(3):  # position, velocity, effort
        off = _align(off, 4, ros1)
        fixed.append((off, off + 4))
        (n,) = struct.unpack_from("<I", raw, off)
        off += 4
        if n:
            off = _align(off, 8, ros1)
        if _ < 2:
            off += 8 * n
    return fixed, off, n


def fast_decode(raws: list, ros1: bool, kind: str):
    """Vectorised decoding of PoseStamped (``kind="pose"``) or JointState effort
    (``kind="effort"``) messages: ``stamps_ns (n,), values (n, c)`` in bag order.

    Messages are grouped by byte length; within a group the layout of its first message is
    used after checking that the frame id, joint names and array counts are byte-identical
    in every message. Raises ValueError when they are not (the caller then uses rosbags'
    generic deserialiser).
    """
    lens = np.fromiter((len(r) for r in raws), np.int64, len(raws))
    stamps = np.empty(len(raws), np.int64)
    vals = None
    for L in np.unique(lens):
        idx = np.nonzero(lens == L)[0]
        buf = np.frombuffer(b"".join(raws[i] for i in idx), np.uint8).reshape(len(idx), L)
        fixed, off, n = _layout(raws[idx[0]], ros1, kind)
        for a, b in fixed:
            if not np.all(buf[:, a:b] == buf[0, a:b]):
                raise InputError("message layouts differ")
        sec = buf[:, 4:8].copy().view("<u4" if ros1 else "<i4")[:, 0].astype(np.int64)
        nsec = buf[:, 8:12].copy().view("<u4")[:, 0].astype(np.int64)
        stamps[idx] = sec * 1_000_000_000 + nsec
        v = buf[:, off:off + 8 * n].copy().view("<f8")
        if vals is None:
            vals = np.empty((len(raws), n))
        if v.shape[1] != vals.shape[1]:
            raise InputError("value counts differ")
        vals[idx] = v
    if kind == "pose":  # x, y, z, qx, qy, qz, qw -> x, y, z, qw, qx, qy, qz
        vals = vals[:, [0, 1, 2, 6, 3, 4, 5]]
    return stamps, vals


def decode_topic(reader, conns, generic, kind: str | None = None, n_check: int = 3):
    """Decode every message of ``conns`` in bag order: ``(stamps_ns (n,), values (n, c))``.

    ``generic(msg, t_rx) -> (stamp_ns, values)`` runs on rosbags' deserialised messages;
    with ``kind`` ("pose", "effort") :func:`fast_decode` is used instead when it reproduces
    ``generic`` on the first ``n_check`` messages and finds one layout per message length.
    """
    raws, gen = [], []
    for i, (conn, t_rx, raw) in enumerate(reader.messages(connections=conns)):
        raws.append(raw)
        if kind is None or i < n_check:
            gen.append(generic(reader.deserialize(raw, conn.msgtype), t_rx))
    if kind is not None and raws:
        try:
            st, v = fast_decode(raws, not reader.is2, kind)
            same = all(st[i] == g[0] and np.array_equal(v[i], np.asarray(g[1], float))
                       for i, g in enumerate(gen))
            if same:
                return st, v
        except (ValueError, struct.error, IndexError):
            pass
        gen = [generic(reader.deserialize(raw, conn.msgtype), t_rx)
               for conn, t_rx, raw in reader.messages(connections=conns)]
    if not gen:
        return np.zeros(0, np.int64), np.zeros((0, 0))
    sizes = {np.size(g[1]) for g in gen}
    if len(sizes) != 1:
        raise UserError("a topic's messages hold different numbers of values "
                        f"({', '.join(str(x) for x in sorted(sizes))}).")
    return (np.fromiter((g[0] for g in gen), np.int64, len(gen)),
            np.array([np.asarray(g[1], float) for g in gen]))

def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def pose_values(msg, typ: str, frames):
    """Pose of a message: ``(stamp_ns, x, y, z, qw, qx, qy, qz)``; None when the message
    holds no transform of the frame pair."""
    if typ == "tf2_msgs/msg/TFMessage":
        for tr in msg.transforms:
            if (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/")) == frames:
                return pose_values(tr, "geometry_msgs/msg/TransformStamped", None)
        return None
    if typ == "geometry_msgs/msg/TransformStamped":
        if frames is not None and \
                (msg.header.frame_id.lstrip("/"), msg.child_frame_id.lstrip("/")) != frames:
            return None
        p, q = msg.transform.translation, msg.transform.rotation
    elif typ == "geometry_msgs/msg/PoseStamped":
        p, q = msg.pose.position, msg.pose.orientation
    else:  # Odometry, PoseWithCovarianceStamped
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
    return (_ns(msg.header.stamp), p.x, p.y, p.z, q.w, q.x, q.y, q.z)


def read_pose_topic(reader, bag, topic: str, frames=None):
    """Pose stream of a topic: ``stamps_ns (n,) int64, values (n, 7)`` (x, y, z, qw..qz).

    Messages are sorted by stamp; duplicated stamps are reported as an error.
    """
    typ, conns = _topic(reader, bag, topic, POSE_TYPES, "--pose-topic")
    if typ == "tf2_msgs/msg/TFMessage" and frames is None:
        raise UserError(f"--frames: is required for the tf2_msgs/TFMessage topic {topic} "
                        "(give the pair as --frames parent,child).")
    if typ not in ("tf2_msgs/msg/TFMessage", "geometry_msgs/msg/TransformStamped"):
        def generic(msg, t_rx):
            r = pose_values(msg, typ, frames)
            return r[0], r[1:]

        kind = "pose" if typ == "geometry_msgs/msg/PoseStamped" else None
        stamps, vals = decode_topic(reader, conns, generic, kind)
        if not len(stamps):
            raise UserError(f"--pose-topic {topic}: holds no message.")
        return typ, stamps, vals
    rows = []
    seen = set()
    for conn, _, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        trs = msg.transforms if typ == "tf2_msgs/msg/TFMessage" else [msg]
        seen.update((tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
                    for tr in trs)
        r = pose_values(msg, typ, frames)
        if r is not None:
            rows.append(r)
    if not rows:
        pairs = ", ".join(f"{a},{b}" for a, b in sorted(seen)) or "none"
        raise UserError(f"--frames {','.join(frames or ())}: no transform of this frame pair on "
                        f"{topic}; the pairs seen are {pairs}.")
    stamps = np.fromiter((r[0] for r in rows), np.int64, len(rows))
    vals = np.array([r[1:] for r in rows], dtype=float)
    return typ, stamps, vals


def _array_of(msg, typ: str, joints, topic: str):
    if typ == "sensor_msgs/msg/JointState":
        eff = np.asarray(msg.effort, float)
        if joints is not None:
            names = list(msg.name)
            missing = [j for j in joints if j not in names]
            if missing:
                raise UserError(f"--joints: {missing[0]!r} is not a joint name on {topic} "
                                f"(names: {', '.join(names)}).")
            eff = eff[[names.index(j) for j in joints]] if eff.size else eff
        return _ns(msg.header.stamp), eff
    return None, np.asarray(msg.data, float)


def _read_array_topic(reader, bag, topic, m, joints):
    typ, conns = _topic(reader, bag, topic, ARRAY_TENSION_TYPES, "--tension-topic")

    def generic(msg, t_rx):
        stamp, vals = _array_of(msg, typ, joints, topic)
        return (t_rx if stamp is None else stamp), vals

    kind = "effort" if typ == "sensor_msgs/msg/JointState" and joints is None else None
    stamps, vals = decode_topic(reader, conns, generic, kind)
    if not len(stamps):
        raise UserError(f"--tension-topic {topic}: holds no message.")
    if vals.shape[1] != m:
        raise UserError(f"--tension-topic {topic}: its messages hold {vals.shape[1]} values but "
                        f"robot.toml has {m} cables (one value per cable is expected).")
    return typ, stamps, vals


def _read_cable_topic(reader, bag, topic, component):
    typ, conns = _topic(reader, bag, topic, CABLE_TENSION_TYPES, "--tension-topic")
    stamps, vals = [], []
    for conn, t_rx, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        if typ == "std_msgs/msg/Float64":
            stamps.append(t_rx)
            vals.append(float(msg.data))
        else:
            f = msg.wrench.force
            v = np.array([f.x, f.y, f.z])
            stamps.append(_ns(msg.header.stamp))
            vals.append(float(np.linalg.norm(v)) if component == "norm"
                        else float(v["xyz".index(component)]))
    if not vals:
        raise UserError(f"--tension-topic {topic}: holds no message.")
    return typ, np.asarray(stamps, np.int64), np.asarray(vals, float)


def _sorted_unique(stamps, vals, topic, option):
    order = np.argsort(stamps, kind="stable")
    stamps, vals = stamps[order], vals[order]
    dup = np.nonzero(np.diff(stamps) <= 0)[0]
    if dup.size:
        raise UserError(f"{option} {topic}: two messages carry the same stamp "
                        f"({stamps[dup[0]]} ns); the stream has no strictly increasing time.")
    return stamps, vals


def read_tension_topics(reader, bag, topics: list[str], m: int, joints=None,
                        component: str = "norm"):
    """Tension stream: ``stamps_ns (k,), tension (k, m), types, notes``."""
    notes = []
    if len(topics) == 1:
        typ, st, tau = _read_array_topic(reader, bag, topics[0], m, joints)
        st, tau = _sorted_unique(st, tau, topics[0], "--tension-topic")
        if typ in HEADERLESS:
            notes.append(f"{topics[0]} ({typ}) has no header: the bag receipt time is used as "
                         "the tension time")
        return st, tau, [typ], notes
    if len(topics) != m:
        raise UserError(f"--tension-topic: given {len(topics)} times but robot.toml has {m} "
                        "cables (give one array topic, or one topic per cable in order).")
    streams, types = [], []
    for i, topic in enumerate(topics):
        typ, st, v = _read_cable_topic(reader, bag, topic, component)
        st, v = _sorted_unique(st, v, topic, "--tension-topic")
        if typ in HEADERLESS:
            notes.append(f"{topic} (cable {i + 1}, {typ}) has no header: the bag receipt time is "
                         "used as its tension time")
        streams.append((st, v))
        types.append(typ)
    base = streams[0][0]
    lo = max(s[0] for s, _ in streams)
    hi = min(s[-1] for s, _ in streams)
    base = base[(base >= lo) & (base <= hi)]
    if base.size < 2:
        raise UserError("--tension-topic: the per-cable topics do not overlap in time.")
    t0 = base[0]
    tau = np.column_stack([np.interp((base - t0).astype(float), (s - t0).astype(float), v)
                           for s, v in streams])
    if any(not np.array_equal(s, streams[0][0]) for s, _ in streams[1:]):
        notes.append(f"per-cable tensions linearly interpolated onto the times of {topics[0]}")
    return base, tau, types, notes


def import_rosbag(bag: str | Path, robot: str | Path, out: str | Path, pose_topic: str,
                  tension_topics: list[str], frames: tuple[str, str] | None = None,
                  joints: list[str] | None = None, wrench_component: str = "norm",
                  force: bool = False) -> Path:
    """Convert a ROS 1 or ROS 2 bag into a spec-v1 dataset folder.

    Parameters
    ----------
    bag : path
        ROS 1 ``.bag`` file or ROS 2 bag folder (SQLite or MCAP).
    robot : path
        robot.toml (copied into the dataset).
    out : path
        Dataset folder to create.
    pose_topic : str
        Topic of the platform pose in the base frame (see the module docstring for types).
    tension_topics : list of str
        One array topic, or one topic per cable in robot.toml's order.
    frames : (parent, child), optional
        Frame pair of a TransformStamped / TFMessage topic (parent = base, child = platform).
    joints : list of str, optional
        JointState names in robot.toml's cable order (default: the message's order).
    wrench_component : {"norm", "x", "y", "z"}
        What a WrenchStamped topic contributes as the tension.
    force : bool
        Replace an existing ``out``.

    Returns
    -------
    Path
    """
    from cdprid.base import check_output
    from cdprid.io._table import write_imported
    from cdprid.model import load_robot

    check_output(out, force, "--out", kind="dir", inputs=[bag, robot])
    rob = load_robot(robot)
    if wrench_component not in ("norm", "x", "y", "z"):
        raise UserError(f"--wrench-component: {wrench_component!r} is not norm, x, y or z.")
    if frames is not None:
        frames = tuple(f.strip().lstrip("/") for f in frames)
    reader = open_bag(bag)
    try:
        ptyp, pst, pv = read_pose_topic(reader, bag, pose_topic, frames)
        pst, pv = _sorted_unique(pst, pv, pose_topic, "--pose-topic")
        tst, tau, ttypes, notes = read_tension_topics(reader, bag, list(tension_topics),
                                                      rob.n_cables, joints, wrench_component)
    finally:
        reader.close()
    if len(pst) < 2:
        raise UserError(f"--pose-topic {pose_topic}: fewer than 2 pose messages.")
    q = pv[:, 3:]
    norm = _quaternion_norms(q, pose_topic)
    t0 = int(pst[0])
    meta = _rosbag_meta(bag, pose_topic, ptyp, tension_topics, ttypes, t0, notes, frames, joints,
                        wrench_component)
    return write_imported(out, rob, (pst - t0) * 1e-9, pv[:, :3], (tst - t0) * 1e-9, tau,
                          quaternion=q / norm[:, None], meta=meta, force=force)


def _quaternion_norms(q: np.ndarray, pose_topic: str) -> np.ndarray:
    """Norms of the pose messages' quaternions; :class:`UserError` naming the first message
    whose norm is not 1 within 1e-3."""
    norm = np.linalg.norm(q, axis=1)
    if np.any(np.abs(norm - 1.0) > 1e-3):
        k = int(np.argmax(np.abs(norm - 1.0)))
        raise UserError(f"--pose-topic {pose_topic}: message {k + 1} has an orientation "
                        f"quaternion of norm {norm[k]:.6g}, not 1 within 1e-3.")
    return norm


def _rosbag_meta(bag, pose_topic, ptyp, tension_topics, ttypes, t0, notes, frames, joints,
                 wrench_component) -> dict:
    """meta.toml of a bag import: its ``[import]`` record (topics, message types, time origin,
    notes, and the frames, joints and wrench component when they apply)."""
    meta = {
        "description": f"imported from the bag {Path(bag).name} by `cdprid import rosbag`",
        "source": "imported",
        "import": {
            "format": "rosbag",
            "bag": str(bag),
            "pose_topic": pose_topic,
            "pose_type": ptyp,
            "tension_topics": list(tension_topics),
            "tension_types": ttypes,
            "t0_ns": t0,
            "time": "header stamps relative to t0_ns (the first pose stamp)",
            "units": "ROS (REP 103): positions m, forces N, times s; no conversion",
            "notes": notes,
        },
        "units": {"t": "s", "position": "m", "quaternion": "scalar first, platform -> base",
                  "tension": "N"},
    }
    if frames is not None:
        meta["import"]["frames"] = list(frames)
    if joints is not None:
        meta["import"]["joints"] = list(joints)
    if any(t == "geometry_msgs/msg/WrenchStamped" for t in ttypes):
        meta["import"]["wrench_component"] = wrench_component
    return meta
