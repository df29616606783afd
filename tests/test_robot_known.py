"""The rigid body known (issue 24, ``fit --robot ROBOT --rigid-body known``): a robot description's own link
inertias subtracted, only friction identified.

- Frames: a DH YAML's ``com`` is in the link's DH frame (standard: frame i at the link's far end; modified:
  Craig's frame i): the robot's centre of mass agrees with the textbook product of DH transforms.
- recipes/robots/panda.urdf and panda_arm.urdf (example-robot-data's Panda, with and without the hand) have
  the kinematics of recipes/robots/panda.yaml.
- A random 4-joint arm whose DH YAML carries its true inertias, friction known per joint, 500 Hz with torque
  noise: Coulomb within 3 %, viscous within 10 %, offsets within 0.1 N m, and the log bears the rigid body
  out. The competing explanation: the same arm described with inertias 10 % off: the friction's errors grow,
  and the fit says so (the log does not bear the rigid body out; every estimate off by more than three
  standard errors is named in its joint's warning).
- A description without inertias: exit 2 with what, where and how to fix, nothing written.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from frictid.robot.description import DHRobot, load_robot, robot_from_dh

from conftest import ROOT
from test_robot import dh_matrix, simulate_excitation

pin = pytest.importorskip("pinocchio")


def link(rng, m: float) -> dict:
    """A solid box of mass m [kg], random sides and orientation, its centre of mass within 0.1 m of the
    frame: mass, com, inertia (Ixx Iyy Izz Ixy Ixz Iyz about the centre of mass) as a DH YAML holds them."""
    a, b, c = rng.uniform(0.05, 0.45, 3)
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    inertia = R @ np.diag(m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])) @ R.T
    return {"mass": float(m), "com": [float(v) for v in rng.uniform(-0.1, 0.1, 3)],
            "inertia": [float(inertia[i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))]}


def arm_yaml(rng, n: int = 4, convention: str = "standard") -> tuple[dict, dict]:
    """A random DH arm with its links' inertias, as the YAML a user writes, and its friction per joint
    (fv, fc, fo)."""
    joints = []
    for i in range(n):
        joints.append({"name": str(i + 1), "a": float(rng.uniform(0.1, 0.4) * (i > 0)), "d": float(rng.uniform(0, 0.3)),
                       "alpha": float(rng.choice([0.0, math.pi / 2, -math.pi / 2])), **link(rng, rng.uniform(1, 8))})
    friction = {j["name"]: (rng.uniform(0.5, 5), rng.uniform(0.5, 8), rng.uniform(-1, 1)) for j in joints}
    return {"name": "arm", "convention": convention, "joints": joints}, friction


def scaled(desc: dict, factor: float) -> dict:
    """The same arm described with every mass and inertia times ``factor``."""
    out = {**desc, "joints": [dict(j) for j in desc["joints"]]}
    for j in out["joints"]:
        j["mass"] *= factor
        j["inertia"] = [v * factor for v in j["inertia"]]
    return out


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_a_dh_links_centre_of_mass_is_in_its_dh_frame(convention):
    rng = np.random.default_rng(2401)
    desc, _ = arm_yaml(rng, 4, convention)
    robot = robot_from_dh(DHRobot.model_validate(desc))
    assert robot.inertia_gaps == []
    data = robot.model.createData()
    for _ in range(3):
        q = rng.uniform(-3, 3, 4)
        T, num, mass = np.eye(4), np.zeros(3), 0.0
        for j, qi in zip(desc["joints"], q):
            T = T @ dh_matrix(j["a"], j["d"], j["alpha"], qi, convention == "modified")
            num += j["mass"] * (T @ np.r_[j["com"], 1.0])[:3]
            mass += j["mass"]
        np.testing.assert_allclose(pin.centerOfMass(robot.model, data, q), num / mass, atol=1e-12)


@pytest.mark.parametrize("name, mass", [("panda.urdf", 16.82), ("panda_arm.urdf", 16.06)])  # with/without the hand
def test_the_shipped_panda_urdfs_have_the_kinematics_of_the_dh_table(name, mass):
    urdf, dh = load_robot(ROOT / "recipes/robots" / name), load_robot(ROOT / "recipes/robots/panda.yaml")
    assert urdf.joints == dh.joints and urdf.inertia_gaps == [] and dh.inertia_gaps
    rng = np.random.default_rng(2402)
    du, dd = urdf.model.createData(), dh.model.createData()
    for _ in range(5):
        q = rng.uniform(-2.5, 2.5, 7)
        pin.forwardKinematics(urdf.model, du, q)
        pin.forwardKinematics(dh.model, dd, q)
        for i in range(1, 8):
            np.testing.assert_allclose(du.oMi[i].homogeneous, dd.oMi[i].homogeneous, atol=1e-9)
    assert sum(urdf.model.inertias[i].mass for i in range(1, 8)) == pytest.approx(mass, abs=0.01)


def _fit(tmp_path, desc, logs):
    from frictid.robotfit import fit_robot

    path = tmp_path / "arm.yaml"
    path.write_text(yaml.safe_dump(desc))
    return fit_robot(logs, str(path), friction="linear", rigid_body="known", robot_file=str(path)), path


def test_known_inertias_recover_the_friction_and_wrong_ones_say_so(tmp_path):
    rng = np.random.default_rng(2403)
    desc, friction = arm_yaml(rng)
    logs = simulate_excitation(robot_from_dh(DHRobot.model_validate(desc)), friction, rng)
    res, path = _fit(tmp_path, desc, logs)
    rs = res.settings["robot"]
    assert rs["rigid_body"]["mode"] == "known" and rs["rigid_body"]["file"] == str(path)
    assert len(rs["rigid_body"]["sha256"]) == 64 and rs["base_parameters"] == []
    assert any(n.startswith("known rigid body: the log bears it out") for n in rs["notes"]), rs["notes"]
    err_exact = []
    for j, (fv, fc, fo) in friction.items():
        got = rs["friction"][j]
        assert got["fc"]["value"] == pytest.approx(fc, rel=0.03), (j, got, fc)
        assert got["fv"]["value"] == pytest.approx(fv, rel=0.10), (j, got, fv)
        assert abs(got["fo"]["value"] - fo) < 0.1, (j, got, fo)
        err_exact.append(abs(got["fc"]["value"] / fc - 1))
    # the competing explanation: a description 10 % off
    off, _ = _fit(tmp_path, scaled(desc, 1.1), logs)
    rs = off.settings["robot"]
    assert any(n.startswith("known rigid body: the log does not bear it out") for n in rs["notes"]), rs["notes"]
    err_off = []
    for j, truth in friction.items():
        got, warned = rs["friction"][j], " ".join(off[j].warnings)
        err_off.append(abs(got["fc"]["value"] / truth[1] - 1))
        for k, true in zip(("fv", "fc", "fo"), truth):
            if abs(got[k]["value"] - true) > 3 * got[k]["stderr"]:
                assert f"{k} " in warned, (j, k, got[k], true, warned)
    assert np.mean(err_off) > 5 * np.mean(err_exact), (err_off, err_exact)


def test_a_known_fit_replays_with_its_own_description_only(tmp_path):
    from frictid.result import FitResult
    from frictid.robot.replay import replay_robot
    from frictid.errors import FrictidInputError

    rng = np.random.default_rng(2404)
    desc, friction = arm_yaml(rng, 3)
    logs = simulate_excitation(robot_from_dh(DHRobot.model_validate(desc)), friction, rng, duration=20.0)
    res, path = _fit(tmp_path, desc, logs)
    back = FitResult.from_dict(res.to_dict())
    results, info = replay_robot(load_robot(path), back, logs)
    assert all(v["rms_residual"] < 0.1 for v in info.values()), info   # the noise: 0.05 N m
    other = tmp_path / "other.yaml"
    other.write_text(yaml.safe_dump(scaled(desc, 1.1)))
    with pytest.raises(FrictidInputError, match="sha256"):
        replay_robot(load_robot(other), back, logs)


def test_a_description_without_inertias_exits_2(cli, tmp_path):
    franka = ROOT.parent / "shared/realdata/franka_panda_gaz2019"
    out = tmp_path / "p.yaml"
    r = cli("fit", franka, "--map", ROOT / "recipes/realdata/franka_panda.yaml", "--robot",
            ROOT / "recipes/robots/panda.yaml", "--rigid-body", "known", "-o", out)
    assert r.code == 2 and "Traceback" not in r.err and not out.exists(), r
    assert "panda.yaml" in r.err and "mass, com and inertia" in r.err and "--rigid-body identify" in r.err, r.err
    urdf = tmp_path / "bare.urdf"   # a URDF whose second link has no <inertial>
    urdf.write_text('<robot name="bare"><link name="l0"/><link name="l1"><inertial><mass value="1"/>'
                    '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link><link name="l2"/>'
                    '<joint name="a" type="revolute"><parent link="l0"/><child link="l1"/><axis xyz="0 0 1"/>'
                    '<limit effort="1" lower="-3" upper="3" velocity="1"/></joint>'
                    '<joint name="b" type="revolute"><parent link="l1"/><child link="l2"/><axis xyz="0 1 0"/>'
                    '<limit effort="1" lower="-3" upper="3" velocity="1"/></joint></robot>')
    r = cli("fit", franka, "--map", ROOT / "recipes/realdata/franka_panda.yaml", "--robot", urdf,
            "--rigid-body", "known", "-o", out)
    assert r.code == 2 and "joint b" in r.err and "<inertial>" in r.err and not out.exists(), r
    r = cli("fit", franka, "--map", ROOT / "recipes/realdata/franka_panda.yaml", "--rigid-body", "known", "-o", out)
    assert r.code == 2 and "--robot" in r.err and not out.exists(), r


def test_a_motor_current_robot_needs_its_rotor_inertias(tmp_path):
    """armature: true (torque from motor current): each joint's rotor inertia [kg m^2] is part of the known
    rigid body; a description without it is refused, one with it recovers the friction of torques that
    carry ``rotor * qdd``."""
    from frictid.errors import ConfigError
    from frictid.robot.known import require_inertias

    rng = np.random.default_rng(2405)
    desc, friction = arm_yaml(rng, 3)
    desc["armature"] = True
    with pytest.raises(ConfigError, match="no rotor"):
        require_inertias(robot_from_dh(DHRobot.model_validate(desc)))
    rotor = rng.uniform(0.5, 2.0, 3)
    for j, r in zip(desc["joints"], rotor):
        j["rotor"] = float(r)
    robot = robot_from_dh(DHRobot.model_validate(desc))
    logs = simulate_excitation(robot, friction, rng, duration=20.0)
    for lg, r in zip(logs, rotor):   # the drive's rotor, accelerated with its joint
        acc = np.gradient(lg.qd, lg.t)
        lg.tau = lg.tau + r * acc
    res, _ = _fit(tmp_path, desc, logs)
    rs = res.settings["robot"]
    # the rotor's torque is orthogonal to the friction's columns on a periodic excitation (the friction alone
    # would not show it missing); the torque fit and the check do
    assert rs["relative_torque_error"] < 0.01 and any(n.startswith("known rigid body: the log bears it out")
                                                      for n in rs["notes"]), rs["notes"]
    for j, (fv, fc, fo) in friction.items():
        got = rs["friction"][j]
        assert got["fc"]["value"] == pytest.approx(fc, rel=0.03) and got["fv"]["value"] == pytest.approx(fv, rel=0.10)
        assert abs(got["fo"]["value"] - fo) < 0.1, (j, got, fo)


def test_one_joint_moved_the_others_standing():
    """The rigid body known needs no excitation of it: a log that moves one joint (test_robot_pose's arm
    and log, 20-bit angles) gives that joint's friction; the standing joints' friction is marked not
    identifiable with the reason, and does not spoil the moving joint's."""
    from frictid.robot.known import identify_known
    from test_robot_pose import arm, one_joint_logs

    robot = arm()
    robot.inertia_gaps = []   # its link inertias are set in the model (the description is a DH table)
    fit = identify_known(robot, one_joint_logs(robot, 1, (0.3, 0.0, 0.2), seed=2406))
    got = fit.friction["2"]
    assert got["fc"].identifiable and got["fc"].value == pytest.approx(1.5, rel=0.03), got
    assert got["fv"].value == pytest.approx(2.0, rel=0.10) and abs(got["fo"].value) < 0.1, got
    for j in ("1", "3"):
        assert not fit.friction[j]["fc"].identifiable and "does not move" in fit.friction[j]["fc"].reason
    assert any(n.startswith("known rigid body: the log bears it out") for n in fit.notes), fit.notes
