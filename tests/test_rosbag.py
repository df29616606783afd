"""ROS 2 bags (issue 24): sensor_msgs/JointState in sqlite3 and MCAP bags, written with the rosbags library's
own writer, read as joint logs (joint names -> joint ids, several topics aligned in time), and refused
with one message when they hold no usable joint states."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from frictid.errors import LogFormatError
from frictid.io.logs import read_logs

rosbags = pytest.importorskip("rosbags")


def write_bag(path, topics: dict[str, list[str]], n: int = 500, rate: float = 200.0, effort: bool = True,
              velocity: bool = True, storage: str = "sqlite3"):
    """A bag with one JointState topic per entry (topic -> joint names), sine motions, effort = 2 qd + 0.5 sgn."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    JointState = store.types["sensor_msgs/msg/JointState"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    truth = {}
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {tp: w.add_connection(tp, JointState.__msgtype__, typestore=store) for tp in topics}
        for k in range(n):
            for i, (tp, names) in enumerate(topics.items()):
                t_ns = 1_700_000_000_000_000_000 + int((k / rate + i * 1e-3) * 1e9)
                t = (t_ns - 1_700_000_000_000_000_000) * 1e-9
                q = np.array([0.5 * np.sin(2 * np.pi * 0.5 * t + j) for j in range(len(names))])
                qd = np.array([0.5 * np.pi * np.cos(2 * np.pi * 0.5 * t + j) for j in range(len(names))])
                tau = 2 * qd + 0.5 * np.sign(qd)
                for name, a, b, c in zip(names, q, qd, tau):
                    truth.setdefault(name, []).append((t, a, b, c))
                msg = JointState(header=Header(stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=""),
                                 name=list(names), position=q, velocity=qd if velocity else np.zeros(0),
                                 effort=tau if effort else np.zeros(0))
                w.write(conns[tp], t_ns, store.serialize_cdr(msg, JointState.__msgtype__))
    return {k: np.array(v) for k, v in truth.items()}


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_joint_states_of_two_topics_become_aligned_joint_logs(tmp_path, storage):
    truth = write_bag(tmp_path / "bag", {"/arm/joint_states": ["shoulder", "elbow"], "/wrist/joint_states": ["wrist"]},
                      storage=storage)
    logs = {lg.joint: lg for lg in read_logs(str(tmp_path / "bag"))}
    assert set(logs) == {"shoulder", "elbow", "wrist"}
    t_first = min(v[0, 0] for v in truth.values())
    for name, lg in logs.items():
        v = truth[name]
        np.testing.assert_allclose(lg.t, v[:, 0] - t_first, atol=1e-9)
        np.testing.assert_allclose(lg.q, v[:, 1])
        np.testing.assert_allclose(lg.qd, v[:, 2])
        np.testing.assert_allclose(lg.tau, v[:, 3])
    assert logs["wrist"].t[0] == pytest.approx(1e-3, abs=1e-9)  # its topic's stamps, not re-zeroed


def test_a_storage_file_path_reads_its_bag_and_velocity_may_be_absent(tmp_path):
    write_bag(tmp_path / "bag", {"/joint_states": ["j1"]}, velocity=False)
    db3 = next((tmp_path / "bag").glob("*.db3"))
    (lg,) = read_logs(str(db3))
    assert lg.joint == "j1" and lg.qd is None and lg.n == 500


def test_bags_without_usable_joint_states_are_refused(tmp_path):
    write_bag(tmp_path / "noeffort", {"/joint_states": ["j1"]}, effort=False)
    with pytest.raises(LogFormatError, match="no effort"):
        read_logs(str(tmp_path / "noeffort"))
    r = subprocess.run([sys.executable, "-m", "frictid", "fit", str(tmp_path / "noeffort"), "-o",
                        str(tmp_path / "p.yaml")], capture_output=True, text=True)
    assert r.returncode == 2 and "no effort" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "p.yaml").exists()


def test_fit_reads_a_bag(tmp_path):
    write_bag(tmp_path / "bag", {"/joint_states": ["j1"]}, n=4000, rate=200.0)
    r = subprocess.run([sys.executable, "-m", "frictid", "fit", str(tmp_path / "bag"), "-o", str(tmp_path / "p.yaml")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    import frictid
    assert "j1" in frictid.read_params(tmp_path / "p.yaml").joints
