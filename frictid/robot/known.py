"""The rigid body known: a robot description's own inertial parameters subtracted, only friction identified.

``frictid fit LOG... --robot ROBOT --rigid-body known``: where a URDF (``<inertial>``) or a DH YAML (each
joint's ``mass``, ``com``, ``inertia``; :mod:`.description`) gives every link's inertial parameters, the
rigid-body torque of every joint is computed from them (Pinocchio's RNEA) along the same filtered q, qd,
qdd the identification uses (:func:`.identify.prepare`) and taken from the measured torque; each joint's
Coulomb, viscous and offset friction is then fitted to what is left by the identification's own weighted
least squares on the parallel-filtered torque (:func:`.identify.solve`), its standing hold as there
(:mod:`.hold`), and frictid's single-joint models run on the friction torque as in stage 2.

A description is somebody's numbers, not this robot's: a catalogue's links differ from the arm at hand, a
tool or cable changes them. What they get wrong lands in the friction, and the friction-only fit shows
it only in part (its standard errors grow with the residual and its correlation in time, but a gravity
error goes into the offsets, biased far beyond them: scorecard part 5). So the fit asks the
log whether the given rigid body explains it (:func:`rigid_body_check`): the robot's own base-parameter
regressor is fitted to what the known rigid body leaves; if it explains more than noise would (an F test
at the 0.1 % level, on the effective number of samples), the notes say by how much and give each joint's
friction with the rigid body identified instead, where the log excites the rigid body well enough to do so.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import f as f_dist

from ..errors import ConfigError
from .description import Robot
from .identify import (COND_LIMIT, RobotData, RobotFit, _hold, _lag1, check, friction_columns, friction_estimates,
                       parallel_filter, prepare, solve, validity)
from .regressor import base_parameters, full_regressor, rigid_torque

#: The F test's level: a known rigid body is questioned when noise alone would leave so much less often.
LEVEL = 0.001


def require_inertias(robot: Robot) -> None:
    """ConfigError naming what the description lacks when some link has no inertial parameters."""
    if robot.inertia_gaps:
        where = robot.file or robot.name
        raise ConfigError(
            f"{where}: --rigid-body known needs every link's inertial parameters, and the description lacks "
            f"them ({'; '.join(robot.inertia_gaps)}): give each DH joint mass, com and inertia (and rotor with "
            "armature: true; docs/robots.md), or a URDF with <inertial> on every moving link (e.g. "
            "recipes/robots/panda.urdf); or identify the rigid body from the log with --rigid-body identify")


def rigid_source(robot: Robot) -> dict:
    """What the parameter file says of a known rigid body: its name, file and the file's sha256."""
    return {"mode": "known", "source": "the robot description's inertial parameters", "name": robot.name,
            "file": robot.file, "sha256": robot.sha256}


def identify_known(robot: Robot, logs) -> RobotFit:
    """Each joint's Coulomb, viscous and offset friction (and standing hold) with the rigid-body torque of
    the description's inertial parameters subtracted (module docstring); the notes say whether the log
    bears the rigid body out."""
    require_inertias(robot)
    d = prepare(robot, logs)
    n, nv = d.q.shape
    rb = rigid_torque(robot, d.q, d.qd, d.qdd)
    F = friction_columns(d)
    A, y, jid = parallel_filter(d, np.hstack([F, rb.reshape(-1, 1)]), d.tau.reshape(-1))
    yf, A = y - A[:, -1], A[:, :-1]
    idle = _idle_joints(A, jid, nv)
    use = np.array([c for c in range(3 * nv) if c // 3 not in idle], dtype=int)
    x, se = np.zeros(3 * nv), np.zeros(3 * nv)
    xu, cov, r, cond = solve(A[:, use], yf, jid, nv)
    x[use], se[use] = xu, np.sqrt(np.maximum(np.diag(cov), 0.0))
    friction = friction_estimates(robot, x, se, 0)
    for i, why in idle.items():
        for p in friction[robot.joints[i]].values():
            p.stderr, p.identifiable, p.reason = None, False, why
    _hold(friction, d, d.tau - rb - (F @ x).reshape(n, nv))
    rms = {j: float(np.sqrt(np.mean(r[jid == i] ** 2))) if np.any(jid == i) else float("nan")
           for i, j in enumerate(robot.joints)}
    out = RobotFit([], [], friction, cond, float(np.linalg.norm(r) / max(np.linalg.norm(y), 1e-300)), rms,
                   d.cutoff, int(y.size), x=x, rigid=rigid_source(robot))
    out.notes = check(out, None, robot) + [f"joint {robot.joints[i]}: {why}" for i, why in idle.items()]
    out.notes += rigid_body_check(robot, d, A[:, use], yf, jid, out, use)
    out.validity = validity(robot, d)
    return out


def _idle_joints(A: np.ndarray, jid: np.ndarray, nv: int) -> dict[int, str]:
    """The joints whose friction the log cannot give, with the reason: no moving sample, or friction
    columns that do not separate (a joint moved one way only: its Coulomb level and offset are one
    column), condition number of the joint's own columns over :data:`COND_LIMIT`. Each joint's friction
    has its own rows, so the others are fitted without them."""
    out = {}
    for i in range(nv):
        B = A[jid == i][:, 3 * i:3 * i + 3]
        if B.shape[0] <= 3:
            out[i] = "the joint does not move in the log: its friction has no velocity to follow"
            continue
        c = float(np.linalg.cond(B / np.maximum(np.linalg.norm(B, axis=0), 1e-300)))
        if not c <= COND_LIMIT:
            out[i] = (f"the joint's motion does not separate its viscous, Coulomb and offset terms (condition "
                      f"number {c:.3g} > {COND_LIMIT:g}; e.g. it moves one way only)")
    return out


def _weighted_rss(A: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(estimate, weighted residual, rank) of the least squares of ``A x = y`` with row weights ``w``."""
    Aw = A * w[:, None]
    scale = np.maximum(np.linalg.norm(Aw, axis=0), 1e-300)
    xs, _, rank, _ = np.linalg.lstsq(Aw / scale, y * w, rcond=None)
    x = xs / scale
    return x, (y - A @ x) * w, int(rank)


def rigid_body_check(robot: Robot, d: RobotData, A: np.ndarray, y: np.ndarray, jid: np.ndarray,
                     fit: RobotFit, use: np.ndarray) -> list[str]:
    """Does the known rigid body explain the log? (module docstring). ``A``, ``y``, ``jid``: the friction
    fit's parallel-filtered columns (those of ``use`` among each joint's fv, fc, fo), torque less the known
    rigid body, and rows' joints. Returns notes: one
    for the robot, and one per joint ("joint J: ...") whose friction moves beyond its standard errors when
    the rigid body is identified from the log instead."""
    nv = robot.nv
    bp = base_parameters(robot, robot.armature)
    Y = full_regressor(robot, d.q, d.qd, d.qdd, robot.armature)[:, bp.columns]
    Yf = parallel_filter(d, Y, np.zeros(Y.shape[0]))[0]
    r0 = y - A @ fit.x[use]
    sd = np.array([max(r0[jid == j].std(), 1e-12) if np.any(jid == j) else 1.0 for j in range(nv)])
    w = 1.0 / sd[jid]
    xj, rj, rank = _weighted_rss(np.hstack([Yf, A]), y, w)
    infl = np.mean([(1 + rho) / (1 - rho) for rho in (_lag1(rj[jid == j]) for j in range(nv) if np.sum(jid == j) > 2)])
    n_eff = y.size / infl
    extra = rank - A.shape[1]
    rss0, rss1 = float(np.sum((r0 * w) ** 2)), float(np.sum(rj ** 2))
    if extra <= 0 or n_eff <= rank + 1:
        return ["known rigid body: the log cannot test it (the robot's regressor adds no independent column)"]
    stat = ((rss0 - rss1) / extra) / (rss1 / (n_eff - rank))
    crit = float(f_dist.ppf(1.0 - LEVEL, extra, n_eff - rank))
    rms0, rms1 = (float(np.sqrt(np.mean((rr / w) ** 2))) for rr in (r0 * w, rj))
    if stat <= crit:
        return [f"known rigid body: the log bears it out (the robot's base parameters fitted on top lower the "
                f"residual from {rms0:.3g} to {rms1:.3g} N m RMS, F = {stat:.3g} <= {crit:.3g}, level {LEVEL:g})"]
    notes = [f"known rigid body: the log does not bear it out: the robot's base parameters fitted on top lower "
             f"the residual from {rms0:.3g} to {rms1:.3g} N m RMS (F = {stat:.3g} > {crit:.3g}, level {LEVEL:g}); "
             "the description's inertias are not this robot's, and each joint's friction takes up part of the "
             "difference, which its standard errors do not include"]
    Z = np.hstack([Yf, A]) * w[:, None]
    cond = float(np.linalg.cond(Z / np.maximum(np.linalg.norm(Z, axis=0), 1e-300)))
    if cond > COND_LIMIT:
        return notes + [f"known rigid body: the log excites the rigid body too little to identify it instead "
                        f"(condition number {cond:.3g} > {COND_LIMIT:g}): the friction's bias is not measured"]
    nb, where = Yf.shape[1], {int(c): k for k, c in enumerate(use)}
    for i, j in enumerate(robot.joints):
        f = fit.friction[j]
        if 3 * i not in where:
            continue
        alt = {k: float(xj[nb + where[3 * i + m]]) for m, k in enumerate(("fv", "fc", "fo"))}
        moved = [k for k in ("fc", "fv", "fo") if abs(alt[k] - f[k].value) > 2.0 * f[k].stderr]
        if moved:
            notes.append(f"joint {j}: with the rigid body identified from the log instead, "
                         + ", ".join(f"{k} {alt[k]:.4g} (known: {f[k].value:.4g} +- {f[k].stderr:.2g})" for k in moved)
                         + ": the known rigid body's error moves this joint's friction beyond its standard errors")
    return notes
