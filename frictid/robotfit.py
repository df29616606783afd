"""Whole-robot identification end to end: the rigid-body base parameters with each joint's Coulomb, viscous
and offset friction (:mod:`frictid.robot`), then frictid's own single-joint identification on each joint's
*friction torque* (the measured torque less the rigid-body torque of the base parameters, held): segments,
static maps, Stribeck and polynomial models, selection, diagnosis, all as for one joint (docs/robots.md).

``friction="linear"`` stops after the first stage (each joint's Coulomb-viscous model, as the joint
estimate gives it); ``"models"`` (the default) runs the second.

A log that moves one joint at a time (:func:`frictid.robot.pose.one_joint_motion`), or a joint named with
``joint``, is fitted one joint at a time instead (the rigid body cannot be identified from it): the robot
gives each moving joint the form of its pose's gravity (:func:`frictid.robot.pose.pose_gravity`), none
where its axis is parallel to gravity; ``settings.robot_pose`` of the result says what it did.
"""
from __future__ import annotations

import copy

import numpy as np

from .api import fit as fit_joints
from .data import JointLog
from .errors import FrictidInputError
from .io.logs import file_sha256, read_many
from .result import FitResult
from .robot import identify_robot, load_robot
from .robot.identify import Prediction, cut_log, friction_log, predict
from .robot.known import identify_known, require_inertias
from .robot.pose import one_joint_motion, pose_gravity
from .robot.result import fit_result

FRICTION_STAGES = ("models", "linear")
RIGID_BODY = ("identify", "known")


def friction_logs(logs: list[JointLog], p: Prediction) -> list[JointLog]:
    """Each joint's log with its torque replaced by the friction torque of the robot model's prediction
    ``p`` (:func:`frictid.robot.identify.friction_log`)."""
    return [friction_log(lg, p.tau[str(lg.joint)], p.F[str(lg.joint)]) for lg in logs]


def fit_robot(paths_or_logs, robot, mapping=None, units=None, *, friction: str = "models",
              diagnose: bool = True, jobs: int = 1, robot_file: str | None = None,
              joint: str | None = None, rigid_body: str = "identify") -> FitResult:
    """Identify a robot from multi-joint logs (paths or :class:`JointLog` objects, one log per robot joint,
    on a common time base). robot : a :class:`~frictid.robot.description.Robot` or the path of a DH YAML or
    URDF. friction : ``"models"`` or ``"linear"`` (see the module). Returns the parameter file's
    :class:`FitResult`: the joints' models, and the robot's base parameters under ``settings.robot``; for
    one-joint motion (or ``joint`` given) the moving joints' one-joint fits with the pose's gravity, and what
    the kinematics said under ``settings.robot_pose`` (:func:`fit_pose`). rigid_body : ``"identify"`` (the
    base parameters identified with the friction) or ``"known"`` (the robot description's inertial parameters
    subtracted, only friction identified: :mod:`frictid.robot.known`; any motion of every joint, one joint at
    a time included)."""
    if friction not in FRICTION_STAGES:
        raise FrictidInputError(f"fit: --robot-friction must be one of {', '.join(FRICTION_STAGES)}, not {friction!r}")
    if rigid_body not in RIGID_BODY:
        raise FrictidInputError(f"fit: --rigid-body must be one of {', '.join(RIGID_BODY)}, not {rigid_body!r}")
    rb = load_robot(robot) if isinstance(robot, (str, bytes)) or hasattr(robot, "__fspath__") else robot
    if rigid_body == "known":
        require_inertias(rb)  # before anything is read
        if joint is not None:
            raise FrictidInputError("fit: --joint does not combine with --rigid-body known, which fits every joint "
                                    "of the robot (the rigid body of each joint depends on all the others' motion)")
    items = [paths_or_logs] if isinstance(paths_or_logs, (str, JointLog)) else list(paths_or_logs)
    paths = [str(x) for x in items if not isinstance(x, JointLog)]
    logs = [x for x in items if isinstance(x, JointLog)] + (read_many(paths, mapping, units) if paths else [])
    rows: dict[str, int] = {}
    for lg in logs:
        rows[lg.source] = max(rows.get(lg.source, 0), lg.n)
    sources = [{"path": p, "sha256": file_sha256(p), "rows": rows.get(p, 0)} for p in paths]
    if rigid_body == "known":
        rf = identify_known(rb, logs)
    else:
        solo, why = ([str(joint)], f"joint {joint} named") if joint is not None else one_joint_motion(rb, logs)
        if solo:
            return fit_pose(rb, logs, solo, why, sources, robot_file, diagnose=diagnose, jobs=jobs)
        rf = identify_robot(rb, logs)
    first = fit_result(rb, rf, sources, robot_file or str(robot if not hasattr(robot, "model") else rb.name))
    if friction == "linear":
        return first
    res = fit_joints(friction_logs(logs, predict(rb, rf, logs)), diagnose=diagnose, jobs=jobs)
    hashes = {s["path"]: s["sha256"] for s in sources}
    for s in res.sources:
        s["sha256"] = hashes.get(s["path"])
    res.settings["robot"] = dict(first.settings["robot"], friction_stage="models")
    return res


def pose_logs(rb, logs: list[JointLog], joints: list[str]) -> tuple[list[JointLog], dict]:
    """The logs of ``joints`` for one-joint fits, each with its pose's gravity from the robot's kinematics
    where they fix it (none: ``meta.gravity`` held at 0; a gravity the log's metadata declares is kept), and
    per joint what the kinematics said (:class:`frictid.robot.pose.PoseGravity` as a dict)."""
    by = {str(lg.joint): lg for lg in logs}
    missing = [j for j in joints if j not in by]
    if missing:
        raise FrictidInputError(f"fit: joint {', '.join(missing)} is not in the logs (their joints: {', '.join(by)})")
    out, said = [], {}
    for j in joints:
        pg = pose_gravity(rb, logs, j)
        lg = copy.copy(by[j])
        said[j] = pg.to_dict()
        if pg.form == "none":
            if lg.meta.get("gravity") is not None:
                said[j]["note"] += "; the log's metadata declares a gravity, which is kept"
            else:
                why = (f"robot kinematics: joint {j}'s axis is parallel to gravity in the logged pose "
                       "(settings.robot_pose)")
                lg.meta = {**lg.meta, "gravity": [0.0, 0.0], "gravity_source": why}
        out.append(lg)
    return out, said


def fit_pose(rb, logs: list[JointLog], joints: list[str], why: str, sources: list[dict], robot_file,
             diagnose: bool = True, jobs: int = 1) -> FitResult:
    """One-joint fits of ``joints`` (each log with its pose's gravity, :func:`pose_logs`); ``settings.robot_pose``
    records the robot, why the log was read one joint at a time, and each joint's gravity form."""
    jl, said = pose_logs(rb, logs, joints)
    res = fit_joints(jl, diagnose=diagnose, jobs=jobs)
    hashes = {s["path"]: s["sha256"] for s in sources}
    for s in res.sources:
        s["sha256"] = hashes.get(s["path"], s.get("sha256"))
    res.settings["robot_pose"] = {"robot": rb.name, "file": robot_file or rb.name, "motion": why, "joints": said}
    return res


def model_torque(res: FitResult, p: Prediction, logs: list[JointLog]) -> dict:
    """Each joint's torque as the rigid body of the robot model's prediction ``p`` plus the joint's selected
    friction model of ``res`` at the filtered velocity (where the joint stands, its offset and the friction
    the robot estimate holds there, :mod:`frictid.robot.hold`), at each log's own samples."""
    out = {}
    for lg in logs:
        j = str(lg.joint)
        jf = res[j]
        off = jf.offset.value if jf.offset is not None and jf.offset.value is not None else 0.0
        mov = p.moving[j]
        F = off + p.held.get(j, np.zeros(lg.n))
        F[mov] += jf.model.friction(p.qd[j][mov], q=None if lg.q is None else lg.q[mov])
        out[j] = p.tau[j] - p.F[j] + F
    return out


def heldout_models(robot, logs: list[JointLog], fraction: float = 0.3, smooth_hz: float | None = None,
                   rigid_body: str = "identify") -> dict:
    """:func:`frictid.robot.identify.heldout_errors` for both stages: identify on the first ``1 - fraction``
    of the logs, predict the rest with stage 1 (``linear``) and with the rigid body of stage 1 plus each
    joint's selected velocity model of stage 2 (``models``, fitted without the diagnosis). Returns per
    stage {'whole', 'moving'} RMS per joint [N m], at the logs' own samples; ``rigid_body="known"``: the
    robot description's rigid body (:mod:`frictid.robot.known`) instead of stage 1's identified one."""
    from scipy.signal import butter, sosfiltfilt

    k = int(round((1.0 - fraction) * min(lg.n for lg in logs)))
    head, tail = [cut_log(lg, slice(0, k)) for lg in logs], [cut_log(lg, slice(k, None)) for lg in logs]
    rf = (identify_known if rigid_body == "known" else identify_robot)(robot, head)
    res = fit_joints(friction_logs(head, predict(robot, rf, head)), diagnose=False)
    p = predict(robot, rf, tail)
    preds = {"linear": p.tau, "models": model_torque(res, p, tail)}
    out = {stage: {"whole": {}, "moving": {}} for stage in preds}
    for lg in tail:
        j = str(lg.joint)
        tau = np.asarray(lg.tau, float)
        fs = 1.0 / float(np.median(np.diff(lg.t)))
        if smooth_hz is not None and smooth_hz < 0.5 * fs:
            tau = sosfiltfilt(butter(4, smooth_hz, fs=fs, output="sos"), tau)
        for stage, pr in preds.items():
            r = tau - pr[j]
            out[stage]["whole"][j] = float(np.sqrt(np.mean(r ** 2)))
            out[stage]["moving"][j] = float(np.sqrt(np.mean(r[p.moving[j]] ** 2)))
    return out

