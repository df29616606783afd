"""ROS 2 bags (sqlite3 and MCAP) with ``sensor_msgs/msg/JointState`` messages, through the ``rosbags`` library
(which reads both storage formats and the CDR serialisation without a ROS installation).

A bag is the folder ``ros2 bag record`` writes (``metadata.yaml`` and the ``.db3`` or ``.mcap`` files); the
path of one of its storage files is taken as its folder. Every JointState topic is read (or only the
``topics`` a mapping file names); each joint name becomes a joint id, with ``position`` -> q,
``velocity`` -> qd (absent when the messages carry none) and ``effort`` -> tau. Time is the message
header's stamp (the bag's receive time where the stamp is zero), from the bag's first message, so that the
joints of several topics stay aligned. A joint without effort, or a bag without JointState messages, is
refused with the reason.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa

from ..errors import LogFormatError

JOINT_STATE = "sensor_msgs/msg/JointState"


def bag_folder(path: str) -> Path | None:
    """The bag folder of ``path`` (a folder with metadata.yaml, or a .db3/.mcap file inside one), or None."""
    p = Path(path)
    if p.is_dir() and (p / "metadata.yaml").is_file():
        return p
    if p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        return p.parent
    return None


def _collect(reader, topics) -> dict[str, dict[str, list]]:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    conns = [c for c in reader.connections if c.msgtype == JOINT_STATE and (not topics or c.topic in topics)]
    out: dict[str, dict[str, list]] = {}
    for conn, stamp_ns, raw in reader.messages(connections=conns):
        msg = store.deserialize_cdr(raw, conn.msgtype)
        st = msg.header.stamp
        t_ns = st.sec * 1_000_000_000 + st.nanosec or stamp_ns
        for i, name in enumerate(msg.name):
            d = out.setdefault(str(name), {"t": [], "q": [], "qd": [], "tau": []})
            d["t"].append(t_ns)
            d["q"].append(msg.position[i] if i < len(msg.position) else np.nan)
            d["qd"].append(msg.velocity[i] if i < len(msg.velocity) else np.nan)
            d["tau"].append(msg.effort[i] if i < len(msg.effort) else np.nan)
    return out


def read_rosbag(path: str, topics: list[str] | None = None) -> pa.Table:
    """The bag's joint states as a long table (``joint, t, q, [qd], tau``), validated by the caller."""
    from rosbags.rosbag2 import Reader

    folder = bag_folder(path)
    if folder is None:
        raise LogFormatError(path, ["is not a ROS 2 bag: give the folder that holds metadata.yaml"])
    try:
        with Reader(folder) as reader:
            data = _collect(reader, topics)
    except Exception as exc:  # noqa: BLE001 - the library's many error types: one message
        raise LogFormatError(str(folder), [f"cannot read the bag ({exc.__class__.__name__}: {exc})"]) from None
    if not data:
        raise LogFormatError(str(folder), [f"no {JOINT_STATE} messages" + (f" on {', '.join(topics)}" if topics else "")])
    no_effort = [j for j, d in data.items() if np.all(np.isnan(d["tau"]))]
    if no_effort:
        raise LogFormatError(str(folder), [f"joint {', '.join(no_effort)}: no effort in its JointState messages; "
                                           "frictid needs the joint torque (effort)"])
    t0 = min(min(d["t"]) for d in data.values())
    cols: dict[str, list] = {"joint": [], "t": [], "q": [], "qd": [], "tau": []}
    for joint, d in data.items():
        order = np.argsort(np.asarray(d["t"]), kind="stable")
        cols["joint"] += [joint] * order.size
        cols["t"].append((np.asarray(d["t"], dtype=np.int64)[order] - t0) * 1e-9)
        for k in ("q", "qd", "tau"):
            cols[k].append(np.asarray(d[k], dtype=float)[order])
    arrays = {"joint": pa.array(cols["joint"], pa.string())}
    for k in ("t", "q", "qd", "tau"):
        v = np.concatenate(cols[k])
        if k == "qd" and np.all(np.isnan(v)):
            continue
        arrays[k] = pa.array(v)
    return pa.table(arrays)
