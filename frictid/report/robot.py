"""The report's robot page, for a parameter file of ``frictid fit --robot`` (docs/robots.md).

The page shows the whole-robot identification: the excitation (condition number of the regressor, the
cut-off of the parallel filter, the samples), the torque fit (each joint's measured torque against the
robot model's, rigid body plus friction, along the logs given), the base parameters with their standard
errors and what the checks found. The joints' own sections then draw each joint's *friction torque*: the
measured torque less the rigid-body torque of the identified base parameters, which is what each joint's
friction model describes (a joint's section drawn from its whole torque would compare a friction law with
the arm's inertia and gravity).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data import JointLog
from ..errors import FrictidInputError
from ..result import FitResult
from . import figures as fg


def _robot_file(settings: dict, given: str | None) -> Path | None:
    path = Path(given) if given else Path(str(settings.get("file") or ""))
    return path if str(path) and path.is_file() else None


def _base_rows(settings: dict, fmt_pm) -> list[dict]:
    rows = []
    for p in settings.get("base_parameters") or []:
        ok = p.get("identifiable", True)
        rows.append({"name": p["name"], "value": fmt_pm(p.get("value"), p.get("stderr")), "unit": "",
                     "status": "identified" if ok else "not identifiable", "reason": p.get("reason", "")})
    return rows


def _rigid_body(rs: dict) -> str:
    """Where the page's rigid body comes from (``settings.robot.rigid_body``)."""
    rb = rs.get("rigid_body") or {"mode": "identify"}
    if rb.get("mode") == "known":
        return f"known: the inertias of {rb.get('file')} (sha256 {str(rb.get('sha256'))[:12]}...), only friction fitted"
    return "identified from the logs (the base parameters below)"


def robot_page(params: dict, logs: list[JointLog], robot_file: str | None, fmt_pm, fmt_num
               ) -> tuple[dict | None, list[JointLog]]:
    """(the page's context, or None for a single-joint parameter file; the logs the joints' sections
    draw: each joint's friction torque, or none when the robot model cannot be evaluated, with the reason
    on the page)."""
    rs = (params.get("settings") or {}).get("robot")
    if not isinstance(rs, dict):
        return None, logs
    page = {"name": rs.get("name", "robot"), "joints": rs.get("joints", []),
            "facts": [("condition number of the regressor (columns scaled to unit norm)", fmt_num(rs.get("condition_number"))),
                      ("relative torque error of the fit", f"{100 * float(rs.get('relative_torque_error', np.nan)):.2f} %"),
                      ("parallel-filter cut-off", f"{fmt_num(rs.get('cutoff_hz'), 3)} Hz"),
                      ("samples in the fit (joint rows)", str(rs.get("samples", "-"))),
                      ("base parameters", str(len(rs.get("base_parameters") or []))),
                      ("rigid body", _rigid_body(rs))],
            "base": _base_rows(rs, fmt_pm), "notes": list(rs.get("notes") or []), "figures": [], "rows": [],
            "why": ""}
    if not logs:
        page["why"] = "No log given: the torque fit is not drawn."
        return page, logs
    path = _robot_file(rs, robot_file)
    if path is None:
        page["why"] = (f"The robot file {rs.get('file')!r} is not found from here, so the robot model cannot be "
                       "evaluated: the torque fit and the joints' friction torques are not drawn (give it with "
                       "--robot).")
        return page, []
    from ..robot import load_robot
    from ..robot.identify import friction_log
    from ..robot.replay import replay_robot

    robot = load_robot(path)
    try:
        results, _ = replay_robot(robot, FitResult.from_dict(params), logs)
    except (FrictidInputError, ValueError) as exc:
        page["why"] = f"The robot model cannot be evaluated along these logs: {exc}"
        return page, []
    friction_logs = []
    for k, (lg, r) in enumerate(zip(logs, results)):
        units = {"tau": "N m", "q": "rad"}
        page["figures"].append(fg.replay(lg.t, lg.tau, r.tau_model, units, f"Joint {lg.joint}: measured and robot "
                                         "model torque", f"robot-torque-{k}", source=lg.source))
        rms_tau = float(np.sqrt(np.mean(np.asarray(lg.tau, float) ** 2)))
        rms_r = float(np.sqrt(np.mean(r.residual ** 2)))
        page["rows"].append({"joint": lg.joint, "rms_tau": fmt_num(rms_tau), "rms_res": fmt_num(rms_r),
                             "share": f"{100 * rms_r / rms_tau:.1f} %" if rms_tau > 0 else "-",
                             "rms_F": fmt_num(float(np.sqrt(np.mean(r.F_model ** 2))))})
        friction_logs.append(friction_log(lg, r.tau_model, r.F_model))
    return page, friction_logs
