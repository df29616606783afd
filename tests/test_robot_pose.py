"""One joint of a robot moved, the others standing (issues 19 and 24): the gravity form the robot's
kinematics give the moving joint (frictid/robot/pose.py) and the one-joint fit that ``fit --robot`` runs on
such a log.

- A simulated 3-joint DH arm with physical link inertias, one joint oscillating at a time, logged through
  20-bit encoders with torque noise: the base joint's axis (vertical) and the elbow's axis where the
  shoulder turns it vertical have no gravity; the shoulder's (horizontal) and the elbow's in a pose where
  its axis is horizontal have ``Px cos q + Py sin q``. The fit holds Px, Py at zero only in the first case,
  says so in the parameter file, and recovers the inertia; in the second it fits the true gravity.
- The UR10e jointwise files (../shared/realdata): joints 1 and 5 (vertical axes in that pose) are read
  without gravity, joints 2-4 and 6 keep theirs.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictid.data import JointLog
from frictid.robot.description import DHJoint, DHRobot, robot_from_dh

from conftest import REALDATA, ROOT

pin = pytest.importorskip("pinocchio")

STEP = 2 * math.pi / 2 ** 20  # a 20-bit encoder


def arm():
    """A 3-joint arm: base joint about the vertical, shoulder horizontal, elbow perpendicular to the
    shoulder (so the shoulder's angle turns the elbow's axis between vertical and horizontal); physical
    link inertias with centres of mass off every axis."""
    joints = [DHJoint(name="1", a=0.0, d=0.3, alpha=math.pi / 2), DHJoint(name="2", a=0.4, alpha=math.pi / 2),
              DHJoint(name="3", a=0.3, d=0.05)]
    robot = robot_from_dh(DHRobot(name="arm", joints=joints))
    for i, (m, c) in enumerate([(6.0, (0.02, 0.03, -0.1)), (4.0, (-0.2, 0.02, 0.05)), (2.0, (-0.1, 0.04, 0.03))]):
        robot.model.inertias[i + 1] = pin.Inertia(m, np.array(c), np.diag([0.05, 0.06, 0.04]) * m)
    return robot


def elbow_axis_tilt(robot, q2: float) -> float:
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, np.array([0.0, q2, 0.0]))
    return float(np.linalg.norm(np.cross(data.oMi[3].rotation[:, 2], [0, 0, 1])))


def one_joint_logs(robot, moving: int, pose, seed: int, fs: float = 200.0, duration: float = 24.0):
    """Joint ``moving`` (index) oscillates (two tones, 0.6 rad) about the standing ``pose``; torque from the
    rigid body (pinocchio) plus Coulomb 1.5 and viscous 2 N m s/rad on the moving joint, noise 0.02 N m;
    angles quantized to :data:`STEP`."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, duration, 1 / fs)
    w1, w2 = 2 * np.pi * 0.25, 2 * np.pi * 0.65
    q = np.tile(np.asarray(pose, float), (t.size, 1))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    q[:, moving] += 0.45 * np.sin(w1 * t) + 0.15 * np.sin(w2 * t)
    qd[:, moving] = 0.45 * w1 * np.cos(w1 * t) + 0.15 * w2 * np.cos(w2 * t)
    qdd[:, moving] = -0.45 * w1 ** 2 * np.sin(w1 * t) - 0.15 * w2 ** 2 * np.sin(w2 * t)
    data = robot.model.createData()
    tau = np.stack([pin.rnea(robot.model, data, q[k], qd[k], qdd[k]) for k in range(t.size)])
    tau[:, moving] += 1.5 * np.sign(qd[:, moving]) + 2.0 * qd[:, moving]
    tau += rng.normal(0, 0.02, tau.shape)
    qlog = np.round(q / STEP) * STEP
    return [JointLog(joint=j, t=t, tau=tau[:, i], q=qlog[:, i], qd=qd[:, i]) for i, j in enumerate(robot.joints)]


def gravity_truth(robot, moving: int, pose) -> tuple[float, float]:
    """Px, Py of the moving joint's gravity torque ``Px cos q + Py sin q`` at the standing pose."""
    data = robot.model.createData()
    g = []
    for qj in (0.0, math.pi / 2):
        q = np.asarray(pose, float).copy()
        q[moving] = qj
        g.append(float(pin.computeGeneralizedGravity(robot.model, data, q)[moving]))
    return g[0], g[1]


def inertia_truth(robot, moving: int, pose) -> float:
    data = robot.model.createData()
    return float(pin.crba(robot.model, data, np.asarray(pose, float))[moving, moving])


def test_the_pose_decides_which_joints_carry_gravity():
    from frictid.robot.pose import one_joint_motion, pose_gravity

    robot = arm()
    vertical = min((0.0, math.pi / 2), key=lambda a: elbow_axis_tilt(robot, a))
    assert elbow_axis_tilt(robot, vertical) < 1e-12 and elbow_axis_tilt(robot, vertical + math.pi / 2) > 0.99
    cases = [(0, (0.0, 0.4, 0.3), "none"), (1, (0.3, 0.0, 0.2), "angle"),
             (2, (0.2, vertical, 0.0), "none"), (2, (0.2, vertical + math.pi / 2, 0.0), "angle")]
    for moving, pose, form in cases:
        logs = one_joint_logs(robot, moving, pose, seed=11, duration=6.0)
        assert one_joint_motion(robot, logs)[0] == [str(moving + 1)]
        pg = pose_gravity(robot, logs, str(moving + 1))
        assert pg.form == form, (moving, pose, pg)
    # the shoulder standing 2 encoder steps off the vertical elbow pose is within what the angles resolve;
    # 0.01 rad off is not (the elbow then carries 1 % of its gravity moment)
    for off, form in ((2 * STEP, "none"), (0.01, "angle")):
        logs = one_joint_logs(robot, 2, (0.2, vertical + off, 0.0), seed=12, duration=6.0)
        assert pose_gravity(robot, logs, "3").form == form
    # a multi-joint motion is not read one joint at a time
    both = one_joint_logs(robot, 1, (0.3, 0.0, 0.2), seed=13, duration=6.0)
    other = one_joint_logs(robot, 2, (0.3, 0.0, 0.2), seed=13, duration=6.0)
    both[2] = other[2]
    assert one_joint_motion(robot, both)[0] == []


def test_fit_with_the_robot_holds_gravity_only_where_the_kinematics_say_so():
    from frictid.robotfit import fit_robot

    robot = arm()
    vertical = min((0.0, math.pi / 2), key=lambda a: elbow_axis_tilt(robot, a))
    for pose, zero in (((0.2, vertical, 0.0), True), ((0.2, vertical + math.pi / 2, 0.0), False)):
        logs = one_joint_logs(robot, 2, pose, seed=21)
        res = fit_robot(logs, robot, diagnose=False)
        jf = res["3"]
        said = res.settings["robot_pose"]["joints"]["3"]
        J = inertia_truth(robot, 2, pose)
        assert abs(jf.inertia.value - J) < 0.05 * J, (pose, jf.inertia.value, J)
        if zero:
            assert said["form"] == "none"
            assert jf.gravity["Px"].value == 0 and jf.gravity["Py"].value == 0
            assert jf.gravity["Px"].source.startswith("robot kinematics")
        else:
            assert said["form"] == "angle"
            px, py = gravity_truth(robot, 2, pose)
            amp = math.hypot(px, py)
            assert amp > 1.0  # the pose does carry gravity
            assert math.hypot(jf.gravity["Px"].value - px, jf.gravity["Py"].value - py) < 0.03 * amp
            assert not jf.gravity["Px"].source.startswith("robot kinematics") and jf.gravity["Px"].identifiable


@pytest.mark.skipif(not (REALDATA / "ur10e_mamedov2020").is_dir(), reason="../shared/realdata is absent")
def test_ur10e_jointwise_runs_gravity_from_the_pose():
    from frictid.io.logs import read_many
    from frictid.robot import load_robot
    from frictid.robot.pose import one_joint_motion, pose_gravity

    robot = load_robot(ROOT / "recipes" / "robots" / "ur10e.yaml")
    base = REALDATA / "ur10e_mamedov2020" / "jointwise_motion"
    forms = {}
    for k in range(1, 7):
        logs = read_many([str(base / f"ur-20_01_22-joint_{k}.csv")],
                         str(ROOT / "recipes" / "realdata" / "ur10e_harmonic.yaml"), None)
        solo, _ = one_joint_motion(robot, logs)
        assert str(k) in solo
        forms[k] = pose_gravity(robot, logs, str(k)).form
    # joints 1 and 5 turn about vertical axes in this pose; joint 6's axis is horizontal (its flange's
    # centre of mass, which a DH table does not give, decides its gravity); joints 2-4 carry the arm
    assert forms[1] == forms[5] == "none"
    assert all(forms[k] in ("angle", "varies") for k in (2, 3, 4, 6)), forms


def test_fit_command_with_a_robot_reads_a_one_joint_log_joint_by_joint(tmp_path, cli):
    import json

    import yaml

    from frictid.io.logs import write_logs

    robot = arm()
    dh = {"name": "arm", "gravity": [0, 0, -9.81],
          "joints": [{"name": "1", "d": 0.3, "alpha": math.pi / 2}, {"name": "2", "a": 0.4, "alpha": math.pi / 2},
                     {"name": "3", "a": 0.3, "d": 0.05}]}
    (tmp_path / "arm.yaml").write_text(yaml.safe_dump(dh))
    logs = one_joint_logs(robot, 0, (0.0, 0.4, 0.3), seed=31, duration=12.0)
    write_logs(logs, str(tmp_path / "base.parquet"))
    write_logs(logs[:1], str(tmp_path / "joint1.parquet"))
    r = cli("fit", tmp_path / "base.parquet", "--robot", tmp_path / "arm.yaml", "-o", tmp_path / "p.yaml",
            "--no-diagnose", "--json")
    assert r.code == 0, r
    out = json.loads(r.out)
    assert list(out["joints"]) == ["1"] and out["robot_pose"]["joints"]["1"]["form"] == "none"
    p = yaml.safe_load((tmp_path / "p.yaml").read_text())
    assert p["joints"]["1"]["gravity"]["Px"]["source"].startswith("robot kinematics")
    assert "one joint moves at a time" in p["settings"]["robot_pose"]["motion"]
    # the parameter file replays the joint's log without the robot, as any one-joint fit
    r = cli("simulate", "--params", tmp_path / "p.yaml", "--replay", tmp_path / "joint1.parquet",
            "-o", tmp_path / "replay.parquet")
    assert r.code == 0, r
