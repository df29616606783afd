"""A whole-robot identification as frictid's parameter file: per joint, the Coulomb-viscous model with its
offset (the friction the robot stage identifies), and the robot's base parameters under ``settings.robot``."""
from __future__ import annotations

from ..result import FitResult, JointFit, ModelFit, ParamEstimate
from ..version import __version__
from .description import Robot
from .identify import RobotFit

RULE = ("whole-robot identification: each joint's Coulomb, viscous and offset friction identified jointly "
        "with the robot's rigid-body base parameters (docs/robots.md); the rigid-body torque is the robot "
        "model's, not a per-joint inertia and gravity")
RULE_KNOWN = ("whole-robot fit with the rigid body known: each joint's Coulomb, viscous and offset friction "
              "identified on the measured torque less the rigid-body torque of the robot description's own "
              "inertial parameters (settings.robot.rigid_body; docs/robots.md)")


def joint_fit(name: str, fit: RobotFit) -> JointFit:
    f = fit.friction[name]
    fc, fv, fo = f["fc"], f["fv"], f["fo"]
    mf = ModelFit("coulomb_viscous", "coulomb_viscous",
                  {"Fc": ParamEstimate("Fc", fc.value, fc.stderr, "N m", fc.identifiable, fc.reason),
                   "sigma2": ParamEstimate("sigma2", fv.value, fv.stderr, "N m s/rad", fv.identifiable, fv.reason)},
                  metrics={"rms": fit.rms_per_joint.get(name), "n": fit.n_samples}, method="robot WLS")
    ok = mf.identifiable
    jf = JointFit(joint=name, units={"q": "rad", "qd": "rad/s", "tau": "N m"},
                  offset=ParamEstimate("offset", fo.value, fo.stderr, "N m", fo.identifiable, fo.reason),
                  models={mf.name: mf}, selected=mf.name if ok else None,
                  selection={"rule": RULE_KNOWN if fit.bp is None else RULE}, validity=fit.validity.get(name, {}))
    if not ok:
        bad = [p for p in mf.params.values() if not p.identifiable]
        jf.not_identified = [{"name": f"coulomb_viscous.{p.name}", "reason": p.reason} for p in bad]
    jf.warnings = [n for n in fit.notes if n.startswith(f"joint {name}:")]
    return jf


def _estimate(p) -> dict:
    out = {"value": p.value, "stderr": p.stderr}
    if not p.identifiable:
        out.update(identifiable=False, reason=p.reason)
    return out


def fit_result(robot: Robot, fit: RobotFit, sources: list[dict], robot_file: str) -> FitResult:
    """The parameter file of a whole-robot identification."""
    base = [{"name": p.name, "value": p.value, "stderr": p.stderr, "identifiable": p.identifiable,
             **({"reason": p.reason} if p.reason else {})} for p in fit.base]
    settings = {"robot": {"name": robot.name, "file": robot_file, "joints": list(robot.joints),
                          "armature": robot.armature, "rigid_body": dict(fit.rigid), "condition_number": fit.condition,
                          "relative_torque_error": fit.rel_error, "cutoff_hz": fit.cutoff_hz,
                          "samples": fit.n_samples, "base_parameters": base,
                          "base_columns": fit.bp.columns.tolist() if fit.bp is not None else None,
                          # the joint estimate's friction (what the robot model's prediction uses)
                          "friction": {j: {k: _estimate(p) for k, p in f.items()} for j, f in fit.friction.items()},
                          "notes": list(fit.notes)}}
    return FitResult(joints={j: joint_fit(j, fit) for j in robot.joints}, sources=sources, version=__version__,
                     settings=settings)
