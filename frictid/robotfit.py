"""Whole-robot identification end to end: the rigid-body base parameters with each joint's Coulomb, viscous
and offset friction (:mod:`frictid.robot`), then frictid's own single-joint identification on each joint's
*friction torque* (the measured torque less the rigid-body torque of the base parameters, held): segments,
static maps, Stribeck and polynomial models, selection, diagnosis, all as for one joint (docs/robots.md).

``friction="linear"`` stops after the first stage (each joint's Coulomb-viscous model, as the joint
estimate gives it); ``"models"`` (the default) runs the second. Stage 2 keeps a joint's model only where it
predicts the friction torque of the fitted logs' own held-out time blocks better than stage 1's linear
friction (:func:`guard_models`); elsewhere the joint's entry is stage 1's, with the reason.

A log that moves one joint at a time (:func:`frictid.robot.pose.one_joint_motion`), or a joint named with
``joint``, is fitted one joint at a time instead (the rigid body cannot be identified from it): the robot
gives each moving joint the form of its pose's gravity (:func:`frictid.robot.pose.pose_gravity`), none
where its axis is parallel to gravity; ``settings.robot_pose`` of the result says what it did.
"""
from __future__ import annotations

import copy
import warnings

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

#: contiguous time blocks of the fitted logs on which stage 2's models face stage 1's linear friction
#: (each block held out in turn, the model refitted on the others)
GUARD_BLOCKS = 4

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
    res = stage_two(rb, rf, logs, first, diagnose=diagnose, jobs=jobs)
    hashes = {s["path"]: s["sha256"] for s in sources}
    for s in res.sources:
        s["sha256"] = hashes.get(s["path"])
    res.settings["robot"] = dict(first.settings["robot"], friction_stage="models", stage2=res.settings.pop("stage2"))
    return res


def stage_two(rb, rf, logs: list[JointLog], first: FitResult, diagnose: bool = True, jobs: int = 1) -> FitResult:
    """frictid's single-joint fit on each joint's friction torque (the rigid body of ``rf`` held), each
    joint's entry then judged against stage 1's linear friction (:func:`guard_models`, :func:`keep_linear`).
    ``settings['stage2']`` holds the comparison per joint."""
    p = predict(rb, rf, logs)
    flogs = friction_logs(logs, p)
    res = fit_joints(flogs, diagnose=diagnose, jobs=jobs)
    return keep_linear(res, first, guard_models(flogs, p, res, jobs=jobs))


def keep_linear(res: FitResult, first: FitResult, verdict: dict) -> FitResult:
    """``res`` with the entry of every joint whose verdict keeps the linear friction replaced by ``first``'s
    (stage 1's), the reason among its warnings; each entry's ``selection['stage2']`` and the result's
    ``settings['stage2']`` hold the verdicts."""
    for j, v in verdict.items():
        if v["kept"] == "linear":
            jf = copy.deepcopy(first[j])
            jf.warnings.append(f"stage 2's model is not kept: {v['reason']}")
            jf.selection = dict(jf.selection, stage2=v)
            res.joints[j] = jf
        else:
            res[j].selection["stage2"] = v
    res.settings["stage2"] = verdict
    return res


def _base_name(jf) -> str | None:
    """The velocity-only model stage 2's choice starts from (the diagnosis' base when it ran)."""
    return (jf.selection.get("diagnosis") or {}).get("base") or jf.selected


def _wanted(names) -> list[str]:
    """The models a block's refit needs for ``names`` (a ``lugre`` with the maps it may build on)."""
    out = set(n for n in names if n)
    if "lugre" in out:
        out |= {"coulomb_viscous", "stribeck", "stribeck_asym", "stribeck_2exp", "stribeck_2exp_asym",
                "polynomial", "polynomial_ls"}
    return sorted(out)


def _blocks(n: int, k: int = GUARD_BLOCKS) -> list[slice]:
    edges = np.linspace(0, n, k + 1).round().astype(int)
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def _linear(y: np.ndarray, v: np.ndarray, mov: np.ndarray) -> np.ndarray:
    """Stage 1's law refitted on the moving samples given: ``[fc, fv, fo]`` of ``fc sgn v + fv v + fo``."""
    A = np.column_stack([np.sign(v[mov]), v[mov], np.ones(int(mov.sum()))])
    return np.linalg.lstsq(A, y[mov], rcond=None)[0]


def guard_models(flogs: list[JointLog], p: Prediction, res: FitResult, jobs: int = 1,
                 k: int = GUARD_BLOCKS) -> dict:
    """Whether each joint's stage-2 model predicts its friction torque better than stage 1's linear
    friction, judged on the fitted logs' own time: ``k`` contiguous blocks, each held out in turn, stage 2's
    velocity model (its base, :func:`_base_name`) and the linear law (``fc sgn v + fv v + fo``) refitted on
    the rest, both predicting the block as the robot model does (the model as the parameter file evaluates
    it, at the prediction's filtered velocity where the joint moves; the offset and the held friction where
    it stands). Per joint {'kept': 'models' or 'linear', 'model', 'heldout_rms': {'models', 'linear'},
    'blocks', 'reason'}; 'models' only when it beats the linear law by more than two paired errors: the
    mean over the blocks of (linear - model) mean squared error above twice its standard error."""
    names = {str(lg.joint): _base_name(res[str(lg.joint)]) for lg in flogs}
    sse: dict[str, list] = {j: [] for j in names}
    failed: dict[str, str] = {}
    for i in range(k):
        train = []
        for lg in flogs:
            b = _blocks(lg.n, k)[i]
            train += [cut_log(lg, s) for s in (slice(0, b.start), slice(b.stop, lg.n)) if s.stop - s.start > 1]
        try:
            refit = fit_joints(train, models=_wanted(names.values()), diagnose=False, jobs=jobs)
        except (FrictidInputError, ValueError, np.linalg.LinAlgError) as exc:
            failed.update({j: f"stage 2's refit without a block failed ({exc})" for j in names})
            continue
        for lg in flogs:
            j = str(lg.joint)
            sse[j].append(_block_errors(lg, p, refit, names[j], _blocks(lg.n, k)[i], failed))
    return {j: _verdict(names[j], np.array(sse[j]).reshape(-1, 3), failed.get(j), k) for j in names}


def _block_errors(lg: JointLog, p: Prediction, refit: FitResult, name: str | None, b: slice,
                  failed: dict) -> np.ndarray:
    """[model, linear] squared held-out errors of one joint's block ``b`` and its sample count (``refit``:
    stage 2 fitted without the block); a model that cannot be judged is recorded in ``failed``."""
    j = str(lg.joint)
    y, v, held = (np.asarray(x, float) for x in (lg.tau, p.qd[j], p.held[j]))
    mov = np.asarray(p.moving[j], bool)
    train = np.ones(lg.n, bool)
    train[b] = False
    if (mov & train).sum() < 3:
        failed.setdefault(j, "too few moving samples outside a block")
        return np.zeros(3)
    fc, fv, fo = _linear(y - held, v, mov & train)
    lin = fo + held[b] + np.where(mov[b], fc * np.sign(v[b]) + fv * v[b], 0.0)
    jf = refit.joints.get(j)
    if jf is None or name is None or name not in jf.models or not jf.models[name].success:
        failed.setdefault(j, f"stage 2's model {name} could not be refitted without a block")
        return np.zeros(3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mod = joint_friction(jf, jf.friction_model(name), v[b], None if lg.q is None else np.asarray(lg.q, float)[b],
                             held[b], mov[b])
    return np.array([np.sum((y[b] - mod) ** 2), np.sum((y[b] - lin) ** 2), b.stop - b.start])


def _verdict(name: str | None, sse: np.ndarray, failed: str | None, k: int) -> dict:
    """One joint's entry of :func:`guard_models` from its blocks' squared errors (rows [model, linear,
    count])."""
    out = {"model": name, "blocks": k}
    if failed is not None or len(sse) < 2:
        return dict(out, kept="linear", reason=failed or "fewer than two blocks judged")
    n = max(float(sse[:, 2].sum()), 1.0)
    rms_m, rms_l = float(np.sqrt(sse[:, 0].sum() / n)), float(np.sqrt(sse[:, 1].sum() / n))
    d = (sse[:, 1] - sse[:, 0]) / np.maximum(sse[:, 2], 1.0)   # per block: linear's MSE less the model's
    se = float(np.std(d, ddof=1) / np.sqrt(len(d)))
    out["heldout_rms"] = {"models": rms_m, "linear": rms_l}
    if d.mean() > 2.0 * se:
        return dict(out, kept="models", reason="")
    return dict(out, kept="linear", reason=(
        f"on the fitted logs' own {k} time blocks, each held out in turn, {name} predicts the friction torque "
        f"with an RMS error of {rms_m:.3g} N m against {rms_l:.3g} for stage 1's linear friction (not better "
        "by two paired errors)"))


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
    the robot estimate holds there, :mod:`frictid.robot.hold`), at each log's own samples; a joint whose
    entry is stage 1's (:func:`guard_models`) has stage 1's torque."""
    out = {}
    for lg in logs:
        j = str(lg.joint)
        jf = res[j]
        if (jf.selection.get("stage2") or {}).get("kept") == "linear":
            out[j] = p.tau[j]
            continue
        F = joint_friction(jf, jf.model, p.qd[j], lg.q, p.held.get(j, np.zeros(lg.n)), p.moving[j])
        out[j] = p.tau[j] - p.F[j] + F
    return out


def joint_friction(jf, model, v: np.ndarray, q, held: np.ndarray, mov: np.ndarray) -> np.ndarray:
    """A joint's friction torque [F] as the robot model composes it: ``model`` (a
    :class:`frictid.model.FrictionModel`) at the velocity v where the joint moves (``mov``), plus the joint's
    offset and the friction the robot estimate holds (``held``, :mod:`frictid.robot.hold`) everywhere."""
    off = jf.offset.value if jf.offset is not None and jf.offset.value is not None else 0.0
    F = off + np.asarray(held, dtype=float)
    F[mov] += model.friction(v[mov], q=None if q is None else q[mov])
    return F


def heldout_models(robot, logs: list[JointLog], fraction: float = 0.3, smooth_hz: float | None = None,
                   rigid_body: str = "identify", guard: bool = True) -> dict:
    """:func:`frictid.robot.identify.heldout_errors` for both stages: identify on the first ``1 - fraction``
    of the logs, predict the rest with stage 1 (``linear``) and with the rigid body of stage 1 plus each
    joint's selected velocity model of stage 2, fitted without the diagnosis: every joint's (``models_all``)
    and, with ``guard``, stage 1's friction where :func:`guard_models` does not keep it (``models``, as
    :func:`fit_robot` keeps them; ``stage2``: the verdicts). Returns per
    stage {'whole', 'moving'} RMS per joint [N m], at the logs' own samples; ``rigid_body="known"``: the
    robot description's rigid body (:mod:`frictid.robot.known`) instead of stage 1's identified one."""
    from scipy.signal import butter, sosfiltfilt

    k = int(round((1.0 - fraction) * min(lg.n for lg in logs)))
    head, tail = [cut_log(lg, slice(0, k)) for lg in logs], [cut_log(lg, slice(k, None)) for lg in logs]
    rf = (identify_known if rigid_body == "known" else identify_robot)(robot, head)
    ph = predict(robot, rf, head)
    flogs = friction_logs(head, ph)
    res = fit_joints(flogs, diagnose=False)
    p = predict(robot, rf, tail)
    preds = {"linear": p.tau, "models_all": model_torque(res, p, tail)}
    if guard:
        res = keep_linear(res, fit_result(robot, rf, [], robot.name), guard_models(flogs, ph, res))
        preds["models"] = model_torque(res, p, tail)
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
    out["stage2"] = res.settings.get("stage2", {})
    return out

