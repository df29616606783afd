"""Replay a whole-robot identification along a measured log: every joint's predicted torque (the rigid-body
torque of the identified base parameters plus the joint's friction), as ``frictid simulate --params P
--replay LOG --robot ROBOT`` writes it.

The parameter file holds what the prediction needs (``settings.robot``: the base parameters, which columns
of the full regressor they start from, the rotor-inertia flag; per joint the Coulomb, viscous and offset
friction). The robot file gives the kinematics; a robot whose base parameters differ from the file's (a
different robot, or a changed description) is refused rather than predicted wrongly.
"""
from __future__ import annotations

import numpy as np

from ..errors import FrictidInputError
from ..replay import ReplayResult
from ..result import ParamEstimate
from .description import Robot
from .identify import RobotFit, predict
from .regressor import base_parameters


def _number(entry, where: str) -> float:
    """The ``value`` of a parameter file's entry, or a clear error naming it."""
    try:
        return float(entry["value"])
    except (KeyError, TypeError, ValueError):
        raise FrictidInputError(f"the parameter file's {where} has no numeric value; write it again with "
                                "frictid fit LOG --robot ROBOT") from None


def fit_from_params(robot: Robot, res) -> RobotFit:
    """The :class:`RobotFit` a parameter file of ``frictid fit --robot`` describes, for ``robot``."""
    rs = (res.settings or {}).get("robot")
    if not rs or "base_parameters" not in rs:
        raise FrictidInputError("the parameter file holds no whole-robot identification (settings.robot); "
                                "make one with frictid fit LOG --robot ROBOT")
    if list(rs.get("joints", [])) != list(robot.joints):
        raise FrictidInputError(f"the parameter file was identified on joints {', '.join(map(str, rs.get('joints', [])))}"
                                f" but robot {robot.name} has {', '.join(robot.joints)}; give the robot it was "
                                "identified with")
    if bool(rs.get("armature")) != bool(robot.armature):
        raise FrictidInputError(f"robot {robot.name}: armature is {robot.armature} but the parameter file was "
                                f"identified with armature {rs.get('armature')}")
    known = (rs.get("rigid_body") or {}).get("mode") == "known"
    if known:
        _same_rigid_body(robot, rs["rigid_body"])
    bp = None if known else base_parameters(robot, robot.armature)
    names = [p["name"] for p in rs["base_parameters"]]
    cols = rs.get("base_columns")
    if not known and (names != bp.names(robot) or (cols is not None and list(cols) != bp.columns.tolist())):
        raise FrictidInputError(f"robot {robot.name}: its base parameters ({bp.n}) are not those of the parameter "
                                f"file ({len(names)}); give the robot description it was identified with")
    x = [_number(p, f"settings.robot.base_parameters.{p.get('name', '?')}") for p in rs["base_parameters"]]
    fr = rs.get("friction") or {}
    held = {}
    for j in robot.joints:
        if str(j) in fr:  # the joint estimate's own friction
            f = fr[str(j)]
            x += [_number(f.get(k), f"settings.robot.friction.{j}.{k}") for k in ("fv", "fc", "fo")]
            if "fh" in f:  # the friction held at standstill (frictid.robot.hold)
                h = f["fh"]
                held[j] = {"fh": ParamEstimate("fh", _number(h, f"settings.robot.friction.{j}.fh"), h.get("stderr"),
                                               "N m", h.get("identifiable", True), h.get("reason", ""))}
            continue
        cv = res[j].models.get("coulomb_viscous")
        if cv is None:
            raise FrictidInputError(f"joint {j}: the parameter file has no coulomb_viscous model")
        off = res[j].offset.value if res[j].offset is not None else 0.0
        x += [cv.params["sigma2"].value, cv.params["Fc"].value, off]
    out = RobotFit(names, [], held, float(rs.get("condition_number", np.nan)),
                   float(rs.get("relative_torque_error", np.nan)), {}, float(rs.get("cutoff_hz", np.nan)),
                   0, x=np.array(x), bp=bp)
    if known:
        out.rigid = dict(rs["rigid_body"])
    return out


def _same_rigid_body(robot: Robot, rb: dict) -> None:
    """Refuse a robot description other than the one whose inertias a known-rigid-body fit subtracted."""
    if robot.inertia_gaps:
        raise FrictidInputError(f"robot {robot.name}: the parameter file's friction was fitted with the rigid body "
                                f"of {rb.get('file')} known, and this description lacks inertias "
                                f"({'; '.join(robot.inertia_gaps)}); give that file")
    if rb.get("sha256") and robot.sha256 and rb["sha256"] != robot.sha256:
        raise FrictidInputError(f"robot {robot.name}: the parameter file's friction was fitted with the rigid body "
                                f"of {rb.get('file')} (sha256 {rb['sha256'][:12]}...), not of {robot.file} "
                                f"(sha256 {robot.sha256[:12]}...); give the description it was fitted with")


def replay_robot(robot: Robot, res, logs) -> tuple[list[ReplayResult], dict]:
    """Every joint's predicted torque along ``logs`` (one log per robot joint), at each log's own samples:
    (results in the order of ``logs``, per joint the residual RMS)."""
    fit = fit_from_params(robot, res)
    p = predict(robot, fit, logs)
    out, info = [], {}
    for lg in logs:
        j = str(lg.joint)
        r = ReplayResult(F_model=p.F[j], tau_model=p.tau[j], tau=np.asarray(lg.tau, float), z=np.zeros(lg.n),
                         T=np.full(lg.n, np.nan), w=p.qd[j], a=p.qdd[j])
        rigid = f"{fit.bp.n} base parameters" if fit.bp is not None else "its description's rigid body"
        r.notes.append(f"whole-robot model of {robot.name} ({rigid}, coulomb_viscous friction)")
        out.append(r)
        info[j] = {"model": f"robot:{robot.name}", "rms_residual": float(np.sqrt(np.mean(r.residual ** 2))),
                   "closed_loop": False}
    return out, info
