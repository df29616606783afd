"""Whole robots (issue 24): the kinematic tree from DH tables, base parameters, and the joint identification
of rigid-body base parameters with each joint's Coulomb, viscous and offset friction.

- DH (standard and modified) give the forward kinematics of the textbook products of transforms.
- A random 4-joint arm with random inertias and known friction, driven by a Fourier trajectory and logged
  at 500 Hz with torque noise: friction recovered (Coulomb 3 %, viscous 10 %, offsets within a few noise
  levels), the torque fitted to the noise, and the truth within the standard errors.
- The Franka Panda excitation run (Gaz et al. 2019): relative torque error below the published 1.41 %, a
  well-conditioned regressor, Coulomb levels near Table III.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictid.data import JointLog
from frictid.robot import identify_robot, load_robot
from frictid.robot.description import DHJoint, DHRobot, robot_from_dh
from frictid.robot.feasibility import feasibility_note, nearest_consistent

from conftest import REALDATA, ROOT

pin = pytest.importorskip("pinocchio")


def dh_matrix(a, d, alpha, theta, modified: bool) -> np.ndarray:
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    if modified:  # RotX(alpha) TransX(a) RotZ(theta) TransZ(d)
        return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_forward_kinematics(convention):
    rng = np.random.default_rng(240)
    joints = [DHJoint(name=str(i), a=rng.uniform(-0.5, 0.5), d=rng.uniform(-0.3, 0.3), alpha=rng.uniform(-3, 3),
                      offset=rng.uniform(-1, 1)) for i in range(5)]
    robot = robot_from_dh(DHRobot(name="r", convention=convention, joints=joints))
    data = robot.model.createData()
    for _ in range(5):
        q = rng.uniform(-3, 3, 5)
        pin.forwardKinematics(robot.model, data, q)
        T = np.eye(4)
        for j, qi in zip(joints, q):
            T = T @ dh_matrix(j.a, j.d, j.alpha, qi + j.offset, convention == "modified")
        M = data.oMi[5].homogeneous
        if convention == "modified":
            np.testing.assert_allclose(M, T, atol=1e-12)
        else:  # the last joint's frame: its rotation, before its own fixed transform
            last = dh_matrix(joints[-1].a, joints[-1].d, joints[-1].alpha, q[-1] + joints[-1].offset, False)
            rot = dh_matrix(0, 0, 0, q[-1] + joints[-1].offset, False)
            np.testing.assert_allclose(M, T @ np.linalg.inv(last) @ rot, atol=1e-12)


def physical_inertia(rng, m: float, size=(0.05, 0.45)) -> "pin.Inertia":
    """A link of mass m [kg]: a solid box of random sides (``size`` [m]), randomly turned, its centre of mass
    within 0.1 m of the frame's origin: a physically consistent inertia (principal moments that satisfy the
    triangle inequality)."""
    a, b, c = rng.uniform(*size, 3)
    moments = m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    R = pin.Quaternion(*rng.normal(size=4)).normalized().matrix()
    return pin.Inertia(m, rng.uniform(-0.1, 0.1, 3), R @ np.diag(moments) @ R.T)


def random_arm(rng, n: int = 4):
    """A DH arm with random, physically consistent link inertias and its friction per joint."""
    joints = [DHJoint(name=str(i + 1), a=rng.uniform(0.1, 0.4) * (i > 0), d=rng.uniform(0.0, 0.3),
                      alpha=float(rng.choice([0.0, math.pi / 2, -math.pi / 2]))) for i in range(n)]
    robot = robot_from_dh(DHRobot(name="arm", joints=joints))
    robot.dh_joints = joints  # the kinematics, for a robot file a command reads
    for i in range(1, n + 1):
        robot.model.inertias[i] = physical_inertia(rng, rng.uniform(1, 8))
    friction = {j.name: (rng.uniform(0.5, 5), rng.uniform(0.5, 8), rng.uniform(-1, 1)) for j in joints}
    return robot, friction


def _pausing_clock(t, move, rest):
    """A clock s(t) that runs for ``move`` seconds and stands for ``rest`` seconds in turn, with its first
    and second derivatives; it starts and stops over 0.4 s raised-cosine ramps (smooth acceleration)."""
    ramp, period = 0.4, move + rest
    ph = np.mod(t, period)
    up = np.clip(ph / ramp, 0, 1)
    down = np.clip((move - ph) / ramp, 0, 1)
    rate = np.minimum(0.5 - 0.5 * np.cos(np.pi * up), 0.5 - 0.5 * np.cos(np.pi * down))
    rate = np.where(ph < move, rate, 0.0)
    s = np.cumsum(rate) * (t[1] - t[0])
    return s, rate, np.gradient(rate, t)


def simulate_excitation(robot, friction, rng, fs=500.0, duration=40.0, noise=0.05, pauses=None, hold=None):
    """Joint logs of a 5-harmonic Fourier trajectory (0.1 Hz base) with the rigid-body and friction torque.
    pauses : (move, rest) seconds: the trajectory runs and stands in turn; hold : per joint, the friction
    held while standing, as a fraction of its Coulomb level in the direction of its last motion."""
    t = np.arange(0, duration, 1 / fs)
    s, rate, rate_d = (t, np.ones_like(t), np.zeros_like(t)) if pauses is None else _pausing_clock(t, *pauses)
    nv = robot.nv
    wf = 2 * np.pi * 0.1
    a = rng.normal(0, 0.4, (nv, 5))
    b = rng.normal(0, 0.4, (nv, 5))
    ks = np.arange(1, 6)
    q = np.stack([sum(a[j, k - 1] / (k * wf) * np.sin(k * wf * s) - b[j, k - 1] / (k * wf) * np.cos(k * wf * s)
                      for k in ks) for j in range(nv)], axis=1)
    v = np.stack([sum(a[j, k - 1] * np.cos(k * wf * s) + b[j, k - 1] * np.sin(k * wf * s) for k in ks)
                  for j in range(nv)], axis=1)
    acc = np.stack([sum(-a[j, k - 1] * k * wf * np.sin(k * wf * s) + b[j, k - 1] * k * wf * np.cos(k * wf * s)
                        for k in ks) for j in range(nv)], axis=1)
    qd, qdd = v * rate[:, None], acc * (rate ** 2)[:, None] + v * rate_d[:, None]
    data = robot.model.createData()
    tau = np.stack([pin.rnea(robot.model, data, q[k], qd[k], qdd[k]) for k in range(t.size)])
    for i, j in enumerate(robot.joints):
        fv, fc, fo = friction[j]
        tau[:, i] += fv * qd[:, i] + fc * np.sign(qd[:, i]) + fo
        if hold:
            standing = rate == 0
            tau[standing, i] += hold[j] * fc * np.sign(v[standing, i])
    tau += rng.normal(0, noise, tau.shape)
    return [JointLog(joint=j, t=t, tau=tau[:, i], q=q[:, i], qd=qd[:, i]) for i, j in enumerate(robot.joints)]


def test_friction_recovered_jointly_with_the_rigid_body_on_a_random_arm():
    rng = np.random.default_rng(241)
    robot, friction = random_arm(rng)
    logs = simulate_excitation(robot, friction, rng)
    fit = identify_robot(robot, logs)
    assert fit.condition < 1e4 and fit.rel_error < 0.02
    for j, (fv, fc, fo) in friction.items():
        got = fit.friction[j]
        assert got["fc"].value == pytest.approx(fc, rel=0.03), (j, got["fc"], fc)
        assert got["fv"].value == pytest.approx(fv, rel=0.10), (j, got["fv"], fv)
        assert abs(got["fo"].value - fo) < 0.1, (j, got["fo"], fo)
        for k, true in zip(("fv", "fc", "fo"), (fv, fc, fo)):
            assert abs(got[k].value - true) < 4 * got[k].stderr + 0.01 * abs(true), (j, k, got[k], true)
    # a physical arm's estimate is physically consistent; the same numbers negated (negative masses) are not
    assert any(n.startswith("physical feasibility: ") for n in fit.notes), fit.notes
    flipped = nearest_consistent(fit.bp, -fit.x[:fit.bp.n], fit.base_cov, robot.nv)
    assert not flipped.consistent and flipped.distance > 10 * flipped.limit
    assert not feasibility_note(flipped, fit.base_names).startswith("physical feasibility: ")


def test_the_friction_held_at_standstill_is_identified_and_predicted():
    """An arm that stops now and then, two of its joints holding part of their Coulomb level in the direction
    of their last motion while they stand: their level in the standing band is identified (the hold, plus
    the sliding of the samples below the band as the joint stops and starts: up to 12 % more here), and
    predicting it lowers the held-out error at rest on every joint where it is identified (by half where a
    hold is simulated); an arm in
    continuous motion never stands and identifies none."""
    from frictid.robot.identify import cut_log, heldout_errors, predict

    rng = np.random.default_rng(247)
    robot, friction = random_arm(rng)
    hold = {"1": 0.6, "2": 0.0, "3": 0.35, "4": 0.0}
    logs = simulate_excitation(robot, friction, rng, duration=40.0, pauses=(3.0, 1.0), hold=hold)
    for lg in logs:
        lg.qd = lg.qd + rng.normal(0, 0.002, lg.n)   # a measured velocity's noise
    fit = heldout_errors(robot, logs, 0.3)["fit"]
    tail = [cut_log(lg, slice(int(0.7 * lg.n), None)) for lg in logs]
    p = predict(robot, fit, tail)
    for lg in tail:
        j = str(lg.joint)
        fh, true = fit.friction[j]["fh"], hold[j] * friction[j][1]
        if true:
            assert fh.identifiable and true - 3 * fh.stderr < fh.value < 1.12 * true + 3 * fh.stderr, (j, fh, true)
        if fh.identifiable:
            rest = ~p.moving[j]
            r = np.asarray(lg.tau)[rest] - p.tau[j][rest]
            gain = np.sqrt(np.mean(r ** 2)) / np.sqrt(np.mean((r + p.held[j][rest]) ** 2))
            assert gain < (0.5 if true else 1.0), (j, gain)
    steady = identify_robot(robot, simulate_excitation(robot, friction, rng, duration=20.0))
    assert not any(f["fh"].identifiable for f in steady.friction.values())


def test_hold_level_needs_stops_that_agree():
    from frictid.result import ParamEstimate
    from frictid.robot.hold import hold_level, last_sign

    qd = np.array([0.0, 0.2, 0.0, 0.0, -0.3, 0.0, 0.1, 0.0])
    mov = qd != 0
    np.testing.assert_array_equal(last_sign(qd[:, None], mov[:, None])[:, 0], [0, 1, 1, 1, -1, -1, 1, 1])
    rng = np.random.default_rng(5)
    n, fc = 600, ParamEstimate("fc", 2.0, 0.05, "N m")
    s = np.where(np.arange(n) // 100 % 2, 1.0, -1.0)      # six stops, alternating directions
    standing = np.arange(n) % 100 >= 40
    noise = rng.normal(0, 0.1, n)
    p = hold_level(1.2 * s + noise, s, standing, fc)
    assert p.identifiable and abs(p.value - 1.2) < 3 * p.stderr, p
    assert not hold_level(-1.2 * s + noise, s, standing, fc).identifiable            # against the motion
    assert "exceeds the Coulomb level" in hold_level(3.0 * s + noise, s, standing, fc).reason
    assert "fewer than" in hold_level(1.2 * s + noise, s, standing & (np.arange(n) < 200), fc).reason
    assert not hold_level(noise, s, standing, fc).identifiable                          # no hold at all


def test_the_consistency_search_covers_every_physical_link():
    """The Cholesky factor reaches any positive definite pseudo-inertia and map back to Pinocchio's
    link parameters exactly; a link breaking the triangle inequality has a pseudo-inertia with a negative
    eigenvalue, and its own parameters (a robot whose base parameters are its link parameters) lie outside."""
    from frictid.robot.feasibility import factor_of, link_parameters, pseudo_inertia
    from frictid.robot.regressor import BaseParameters

    rng = np.random.default_rng(245)
    links = np.stack([physical_inertia(rng, m).toDynamicParameters() for m in rng.uniform(0.5, 10, 5)])
    J = pseudo_inertia(links)
    for p, Jk in zip(links, J):
        np.testing.assert_allclose(Jk, pin.Inertia.FromDynamicParameters(p).toPseudoInertia().toMatrix(), atol=1e-12)
    np.testing.assert_allclose(link_parameters(factor_of(J, 0.0)), links, rtol=1e-9, atol=1e-12)
    bad = pin.Inertia(2.0, np.zeros(3), np.diag([0.01, 0.01, 0.1])).toDynamicParameters()   # Izz > Ixx + Iyy
    assert np.linalg.eigvalsh(pseudo_inertia(bad[None]))[0, 0] < 0
    whole = BaseParameters(np.arange(10), np.arange(10, 10), np.zeros((10, 0)), 10)
    cov = np.diag((1e-3 * np.maximum(np.abs(bad), 1e-3)) ** 2)
    assert not nearest_consistent(whole, bad, cov, 1).consistent
    assert nearest_consistent(whole, links[0], cov, 1).distance < 1e-3


def test_a_stretch_is_predicted_with_the_fits_filter():
    """The model predicts a short stretch of a log as it predicts the whole log: the stretch's signals pass
    the fit's filter. A cut-off found anew on the stretch (its velocity noise weighs more in a short log: 24 Hz
    here against the fit's 5 Hz) differentiates that noise into the acceleration (0.3-0.4 N m RMS apart)."""
    from frictid.robot.identify import cut_log, predict

    rng = np.random.default_rng(243)
    robot, friction = random_arm(rng)
    logs = simulate_excitation(robot, friction, rng, duration=20.0)
    for lg in logs:
        lg.qd = lg.qd + rng.normal(0, 0.02, lg.n)   # a measured velocity's noise
    fit = identify_robot(robot, logs)
    n = logs[0].n
    k0, k1 = n // 2, n // 2 + n // 8
    whole, part = predict(robot, fit, logs), predict(robot, fit, [cut_log(lg, slice(k0, k1)) for lg in logs])
    edge = int(3 * 500.0 / fit.cutoff_hz)   # the filter's settling at the stretch's ends
    for j in robot.joints:
        same = (part.moving[j] == whole.moving[j][k0:k1])[edge:-edge]   # the standing band is the stretch's own
        assert same.mean() > 0.95, j
        d = (part.tau[j] - whole.tau[j][k0:k1])[edge:-edge][same]
        assert np.sqrt(np.mean(d ** 2)) < 0.01, (j, np.sqrt(np.mean(d ** 2)))


def test_a_log_missing_a_joint_is_refused():
    rng = np.random.default_rng(242)
    robot, friction = random_arm(rng, 3)
    logs = simulate_excitation(robot, friction, rng, duration=5.0)
    from frictid.errors import ConfigError
    with pytest.raises(ConfigError, match="no log for joint 3"):
        identify_robot(robot, logs[:2])


def test_franka_panda_against_gaz_2019():
    from frictid.io.logs import read_logs

    logs = read_logs(str(REALDATA / "franka_panda_gaz2019"), str(ROOT / "recipes/realdata/franka_panda.yaml"))
    fit = identify_robot(load_robot(ROOT / "recipes/robots/panda.yaml"), logs)
    table3_fc = {"1": 0.2450, "2": 0.1523, "3": 0.1827, "4": 0.3591, "5": 0.2669, "6": 0.1658, "7": 0.2109}
    assert fit.rel_error < 0.0141 and fit.condition < 122  # Gaz: 1.41 %, condition 121.88
    for j, fc in table3_fc.items():
        assert fit.friction[j]["fc"].value == pytest.approx(fc, rel=0.40), j  # docs/robots.md: -2 to +36 % today


#: AURT's held-out torque error on the UR10e harmonic run (issue 24), per joint [N m RMS], against the drive
#: gain x current as logged and low-passed at 20 Hz (last 30 % of the run held out).
AURT_RAW = {"1": 3.44, "2": 6.25, "3": 2.27, "4": 0.65, "5": 1.19, "6": 0.80}
AURT_20HZ = {"1": 3.33, "2": 6.18, "3": 2.23, "4": 0.65, "5": 1.19, "6": 0.80}


def test_ur10e_harmonic_run_predicted_better_than_aurt():
    from frictid.io.logs import read_logs
    from frictid.robot.identify import heldout_errors

    run = REALDATA / "ur10e_mamedov2020/identification_data/ur-20_02_19_15harm50sec.csv"
    logs = read_logs(str(run), str(ROOT / "recipes/realdata/ur10e_harmonic.yaml"))
    robot = load_robot(ROOT / "recipes/robots/ur10e.yaml")
    for smooth, aurt in ((None, AURT_RAW), (20.0, AURT_20HZ)):
        e = heldout_errors(robot, logs, 0.3, smooth_hz=smooth)
        for j, a in aurt.items():   # docs/robots.md: joint 6 as logged 0.35 (0.80 before the standing level)
            assert e["whole"][j] < a, (smooth, j, e["whole"][j], a)


def test_robots_page_example_runs():
    import os
    import re
    import subprocess
    import sys

    text = (ROOT / "docs" / "robots.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks
    for code in blocks:
        r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                           env=dict(os.environ))
        assert r.returncode == 0, r.stderr[-2000:]
        assert "base parameters" in r.stdout


def test_designed_excitation_respects_limits_and_identifies_the_arm(tmp_path):
    """A designed trajectory: inside every limit, from rest, better conditioned than random starts; the
    arm driven along it (3 periods, 500 Hz, torque noise) gives back its friction."""
    from frictid.robot.design import Limits, design_excitation

    rng = np.random.default_rng(243)
    robot, friction = random_arm(rng, 3)
    lim = Limits(lo=np.full(3, -1.5), hi=np.full(3, 1.0), velocity=np.full(3, 1.5), acceleration=np.full(3, 4.0))
    tr = design_excitation(robot, lim, period=8.0, harmonics=4, starts=4, iterations=60, rate=500.0)
    assert np.all(tr.q >= lim.lo - 1e-12) and np.all(tr.q <= lim.hi + 1e-12)
    assert np.all(np.abs(tr.qd) <= lim.velocity) and np.all(np.abs(tr.qdd) <= lim.acceleration)
    assert np.max(np.abs(tr.qd[0])) < 1e-12 and np.max(np.abs(tr.qdd[0])) < 1e-12
    assert tr.condition < tr.condition_start
    t = np.concatenate([tr.t + k * tr.period for k in range(3)])
    q, qd, qdd = (np.tile(x, (3, 1)) for x in (tr.q, tr.qd, tr.qdd))
    data = robot.model.createData()
    tau = np.stack([pin.rnea(robot.model, data, q[k], qd[k], qdd[k]) for k in range(t.size)])
    for i, j in enumerate(robot.joints):
        fv, fc, fo = friction[j]
        tau[:, i] += fv * qd[:, i] + fc * np.sign(qd[:, i]) + fo
    tau += rng.normal(0, 0.05, tau.shape)
    logs = [JointLog(joint=j, t=t, tau=tau[:, i], q=q[:, i], qd=qd[:, i]) for i, j in enumerate(robot.joints)]
    fit = identify_robot(robot, logs)
    for j, (fv, fc, fo) in friction.items():
        assert fit.friction[j]["fc"].value == pytest.approx(fc, rel=0.05), j
        assert fit.friction[j]["fv"].value == pytest.approx(fv, rel=0.15), j


def test_design_command_refuses_a_robot_without_limits(tmp_path):
    import subprocess
    import sys

    bare = tmp_path / "arm.yaml"
    bare.write_text('name: arm\njoints:\n  - {name: "1", d: 0.3}\n  - {name: "2", a: 0.4}\n')
    r = subprocess.run([sys.executable, "-m", "frictid", "design", str(bare), "-o", str(tmp_path / "x.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "no limit 1.position" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "x.csv").exists()


def test_poor_excitation_and_negative_friction_are_marked():
    """One joint barely moving: the condition number exceeds the limit and nothing is trusted; a negative
    Coulomb level in the truth comes back marked, not as a friction."""
    rng = np.random.default_rng(244)
    robot, friction = random_arm(rng, 2)
    friction["2"] = (1.0, -2.0, 0.0)
    logs = simulate_excitation(robot, friction, rng, duration=20.0)
    fit = identify_robot(robot, logs)
    assert not fit.friction["2"]["fc"].identifiable and "not a dissipative" in fit.friction["2"]["fc"].reason
    assert fit.friction["1"]["fc"].identifiable
    logs[1].q = np.full_like(logs[1].q, 0.3) + 1e-4 * np.sin(logs[1].t)
    logs[1].qd = 1e-4 * np.cos(logs[1].t)
    poor = identify_robot(robot, logs)
    assert poor.condition > 1000 and not any(p.identifiable for p in poor.base)
    assert any("poorly conditioned" in n for n in poor.notes)


def test_fit_robot_command_writes_a_parameter_file_and_refuses_a_mismatch(tmp_path):
    import subprocess
    import sys

    import frictid

    data, mapping = str(REALDATA / "franka_panda_gaz2019"), str(ROOT / "recipes/realdata/franka_panda.yaml")
    out = tmp_path / "panda.yaml"
    r = subprocess.run([sys.executable, "-m", "frictid", "fit", data, "--map", mapping, "--robot",
                        str(ROOT / "recipes/robots/panda.yaml"), "--robot-friction", "linear", "-o", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    res = frictid.read_params(out)
    assert sorted(res.joints) == [str(i) for i in range(1, 8)]
    assert all(res[j].selected == "coulomb_viscous" for j in res.joints)
    assert res.settings["robot"]["condition_number"] < 122 and len(res.settings["robot"]["base_parameters"]) == 43
    m = res["5"].model
    assert m.friction(0.5) == pytest.approx(m.params["Fc"].value + 0.5 * m.params["sigma2"].value)
    bad = subprocess.run([sys.executable, "-m", "frictid", "fit", data, "--map", mapping, "--robot",
                          str(ROOT / "recipes/robots/ur10e.yaml"), "-o", str(tmp_path / "x.yaml")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "joint 7" in bad.stderr and not (tmp_path / "x.yaml").exists()


@pytest.fixture(scope="module")
def arm_files(tmp_path_factory):
    """A random 3-joint arm as a user has it: its DH file, an excitation log, a held-out log (noise 0.05
    N m) and the parameter file of frictid fit --robot on the first."""
    import yaml

    from frictid.cli import main
    from frictid.io.logs import write_logs

    tmp = tmp_path_factory.mktemp("arm")
    rng = np.random.default_rng(243)
    robot, friction = random_arm(rng, 3)
    robot.friction_truth = friction
    dh = {"name": "arm", "convention": "standard", "gravity": [0, 0, -9.81],
          "joints": [{"name": j.name, "a": float(j.a), "d": float(j.d), "alpha": float(j.alpha)}
                     for j in robot.dh_joints]}
    (tmp / "arm.yaml").write_text(yaml.safe_dump(dh))
    write_logs(simulate_excitation(robot, friction, rng, duration=20.0), str(tmp / "a.parquet"))
    write_logs(simulate_excitation(robot, friction, rng, duration=10.0), str(tmp / "b.parquet"))
    with pytest.raises(SystemExit) as ex:
        main(["fit", str(tmp / "a.parquet"), "--robot", str(tmp / "arm.yaml"), "-o", str(tmp / "p.yaml"), "-q"])
    assert ex.value.code in (0, None)
    return tmp, robot, dh


def test_the_friction_models_are_fitted_on_each_joints_friction_torque(arm_files):
    """The second stage: every model of frictid on each joint's friction torque (the rigid body held), with
    inertia and gravity given as zero; the truth is a Coulomb-viscous law plus an offset."""
    import frictid

    tmp, robot, _ = arm_files
    res = frictid.read_params(tmp / "p.yaml")
    rs = res.settings["robot"]
    assert rs["friction_stage"] == "models" and set(rs["friction"]) == set(robot.joints)
    heads = res.to_dict()["joints"]
    for j in robot.joints:
        jf = res[j]
        linear = rs["stage2"][j]["kept"] == "linear"  # stage 1's entry (robotfit.guard_models): no inertia
        assert jf.selected and (jf.inertia is None if linear else jf.inertia.value == 0.0)
        assert heads[j]["model"]["torque"].startswith("tau = the rigid-body torque of arm")
        m = jf.model
        fv, fc, fo = robot.friction_truth[j]
        for w in (0.3, 0.8):  # inside the speeds the excitation covers; the model carries the joint's offset
            # (a diagnosis model's offset is its tau_offset term, m.offset 0; stage 1's entry carries it as m.offset)
            assert abs(m.friction(w) + m.offset - (fc + fv * w + fo)) < 0.05 * (fc + fv * w) + 0.1, (j, w)


def test_simulate_replays_a_robot_identification_on_a_held_out_log(arm_files, cli):
    """frictid simulate --params --replay --robot on a log the fit did not see: every joint's torque
    predicted to the sensor noise, at the log's own samples; mismatches refused with exit 2."""
    import pandas as pd
    import yaml

    tmp, robot, dh = arm_files
    r = cli("simulate", "--params", tmp / "p.yaml", "--replay", tmp / "b.parquet", "--robot", tmp / "arm.yaml",
            "-o", tmp / "r.parquet", "-q")
    assert r.code == 0, r.err
    out = pd.read_parquet(tmp / "r.parquet")
    for j in robot.joints:
        part = out[out["joint"] == j]
        assert len(part) == 5000 and np.sqrt(np.mean(part["residual"] ** 2)) < 0.1, j  # noise 0.05 N m
    single = tmp / "single.yaml"
    assert cli("fit", ROOT / "sample_logs/hydraulic_sweep.csv", "-o", single, "-q").code == 0
    r = cli("simulate", "--params", single, "--replay", tmp / "b.parquet", "--robot", tmp / "arm.yaml",
            "-o", tmp / "x.parquet")
    assert r.code == 2 and "settings.robot" in r.err and not (tmp / "x.parquet").exists()
    (tmp / "arm2.yaml").write_text(yaml.safe_dump(dict(dh, joints=dh["joints"][:2])))
    r = cli("simulate", "--params", tmp / "p.yaml", "--replay", tmp / "b.parquet", "--robot", tmp / "arm2.yaml",
            "-o", tmp / "x.parquet")
    assert r.code == 2 and "joints" in r.err and "Traceback" not in r.err and not (tmp / "x.parquet").exists()
    broken = yaml.safe_load((tmp / "p.yaml").read_text())
    del broken["settings"]["robot"]["friction"][robot.joints[0]]["fh"]["value"]   # an entry edited by hand
    (tmp / "broken.yaml").write_text(yaml.safe_dump(broken))
    r = cli("simulate", "--params", tmp / "broken.yaml", "--replay", tmp / "b.parquet", "--robot", tmp / "arm.yaml",
            "-o", tmp / "x.parquet")
    assert r.code == 2 and f"friction.{robot.joints[0]}.fh" in r.err and "Traceback" not in r.err
    assert not (tmp / "x.parquet").exists()


def test_the_report_of_a_robot_has_its_page_and_draws_friction_torques(arm_files, cli):
    """The robot page: the identification's facts, the torque fit per joint (residual at the noise), the base
    parameters; the joints' sections draw the friction torque (the measured torque less the rigid body)."""
    import re

    tmp, robot, _ = arm_files
    r = cli("report", tmp / "p.yaml", tmp / "b.parquet", "-o", tmp / "r.html", "-q", "--jobs", "1")
    assert r.code == 0, r.err
    html = (tmp / "r.html").read_text()
    assert "<h2>Robot: arm</h2>" in html and "Torque fit along the logs" in html
    rows = re.findall(r"<tr><td>(\d)</td><td class=\"num\">([-\d.e]+)</td><td class=\"num\">([-\d.e]+)</td>", html)
    assert [j for j, _, _ in rows] == robot.joints
    assert all(float(res) < 0.1 for _, _, res in rows), rows  # the torque fit at the noise (0.05 N m)
    assert html.count("measured and robot model torque") >= 3 and "Base parameters" in html
    moved = tmp / "elsewhere.yaml"
    text = (tmp / "p.yaml").read_text().replace(str(tmp / "arm.yaml"), str(tmp / "gone.yaml"))
    moved.write_text(text)
    r = cli("report", moved, tmp / "b.parquet", "-o", tmp / "r2.html", "-q", "--jobs", "1")
    assert r.code == 0, r.err
    assert "is not found from here" in (tmp / "r2.html").read_text()


def test_designed_sweep_gives_each_joint_plateaus_the_single_joint_fit_reads():
    """frictid design --experiment sweep: inside the limits; played on a random arm (perfect tracking, the
    rigid body and a Coulomb-viscous friction per joint, torque noise), one joint's part is a log whose
    plateaus the segmentation finds and whose friction the single-joint fit recovers."""
    import frictid
    from frictid.robot.design import Limits
    from frictid.robot.experiments import sweep_experiment

    rng = np.random.default_rng(244)
    robot, friction = random_arm(rng, 3)
    lim = Limits(lo=np.full(3, -2.0), hi=np.full(3, 2.0), velocity=np.full(3, 1.5), acceleration=np.full(3, 4.0))
    ex = sweep_experiment(robot, lim, speeds=8, plateau_s=1.5, rate=200.0)
    assert np.all(ex.q >= -2.0) and np.all(ex.q <= 2.0)
    assert np.max(np.abs(ex.qd)) <= 1.5 + 1e-9 and np.max(np.abs(ex.qdd)) <= 4.0 + 1e-9
    np.testing.assert_allclose(np.gradient(ex.q, ex.t, axis=0), ex.qd, atol=0.03)
    data = robot.model.createData()
    i, j = 1, robot.joints[1]
    sel = ex.active == i
    q, qd, qdd = ex.q[sel], ex.qd[sel], ex.qdd[sel]
    tau = np.array([pin.rnea(robot.model, data, q[k], qd[k], qdd[k])[i] for k in range(q.shape[0])])
    fv, fc, fo = friction[j]
    tau += fv * qd[:, i] + fc * np.sign(qd[:, i]) + fo + rng.normal(0, 0.02, tau.size)
    log = JointLog(joint=j, t=ex.t[sel] - ex.t[sel][0], tau=tau, q=q[:, i], qd=qd[:, i])
    res = frictid.fit(log, models="coulomb_viscous", diagnose=False)
    kinds = list(res[j].segment_list[0]["kind"])
    assert kinds.count("constant_velocity") >= 12, kinds  # 8 speeds x 2 signs
    p = res[j].models["coulomb_viscous"].params
    assert p["Fc"].value == pytest.approx(fc, rel=0.03) and p["sigma2"].value == pytest.approx(fv, rel=0.05)


def test_designed_ramps_hold_the_arm_and_stay_below_each_joints_coulomb_level(arm_files, cli):
    """frictid design --experiment ramps --params P: each joint's ramps on the torque that holds the arm at
    the centre pose (the identified rigid body at rest plus the offset: the true gravity torque within a few
    per cent of the friction), peaks at 85 % of the identified Coulomb level; refused without --params."""
    import pandas as pd
    import yaml

    tmp, robot, dh = arm_files
    lim = {"position": [-2.0, 2.0], "velocity": 1.5, "acceleration": 4.0}
    (tmp / "arm_lim.yaml").write_text(yaml.safe_dump(dict(dh, joints=[dict(j, **lim) for j in dh["joints"]])))
    r = cli("design", tmp / "arm_lim.yaml", "--experiment", "ramps", "--params", tmp / "p.yaml", "-o", tmp / "ramps.csv")
    assert r.code == 0, r.err
    out = pd.read_csv(tmp / "ramps.csv")
    data = robot.model.createData()
    q0 = np.zeros(robot.nv)
    g = pin.rnea(robot.model, data, q0, q0, q0)
    for i, j in enumerate(robot.joints):
        fv, fc, fo = robot.friction_truth[j]
        idle = out[out["active_joint"] != i + 1][f"tau_{j}"]
        assert np.allclose(idle, idle.iloc[0]) and abs(idle.iloc[0] - (g[i] + fo)) < 0.05 * fc + 0.05, j
        mine = out[out["active_joint"] == i + 1][f"tau_{j}"] - idle.iloc[0]
        assert 0.8 * fc < mine.max() < 0.9 * fc and 0.8 * fc < -mine.min() < 0.9 * fc, (j, mine.max(), fc)
    r = cli("design", tmp / "arm_lim.yaml", "--experiment", "ramps", "-o", tmp / "x.csv")
    assert r.code == 2 and "--params" in r.err and not (tmp / "x.csv").exists()
