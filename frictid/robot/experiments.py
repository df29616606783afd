"""The single-joint identification experiments for every joint of a robot, as files a controller can play:
a constant-velocity sweep (position mode) and presliding torque ramps (torque mode), one joint at a time
while the others hold the centre of their range (docs/robots.md, "Designing experiments").

Sweep: per joint, ``speeds`` log-spaced speeds from ``v_min`` to the joint's speed limit (times the design
fraction), each as a plateau up the range and one back down (both signs), reached and left at the joint's
acceleration limit, each plateau held ``plateau_s`` seconds where the range allows it (shorter, but at least
:data:`MIN_PLATEAU` s, where it does not; a speed the range cannot hold that long is left out and named).
The plateaus of one speed return the joint to where they started, so the sweep never drifts.

Ramps: per joint, torque ramps to +-``peak`` of the joint's Coulomb level and back (``ramp_s`` up, ``hold_s``
held, ``ramp_s`` down), on top of the torque that holds the arm still at the pose: that holding torque is
the rigid-body model of a whole-robot identification (its base parameters at zero speed) plus the joint's
offset, so the ramps need a parameter file of ``frictid fit --robot``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .description import Robot
from .design import Limits

#: Shortest plateau a sweep keeps [s]: below it a plateau is too short to average.
MIN_PLATEAU = 0.5
#: The share of the range kept clear at each end.
RANGE_MARGIN = 0.05


@dataclass
class Experiment:
    """Samples for the controller: t [s], and per joint (n, nv) q, qd, qdd (sweep) or tau (ramps); the joint
    each sample exercises (``active``, an index, -1 between joints), and what was left out, one sentence each."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray | None = None
    active: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)


def _trapezoid(d: float, v: float, a: float, rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Displacement, speed and acceleration of a move of length d > 0 at cruise speed v, acceleration a."""
    v = min(v, float(np.sqrt(d * a)))  # a short move never reaches the cruise speed
    ta = v / a
    tc = max(d / v - ta, 0.0)
    T = 2 * ta + tc
    t = np.arange(0.0, T, 1.0 / rate)
    acc = np.where(t < ta, a, np.where(t < ta + tc, 0.0, -a))
    vel = np.where(t < ta, a * t, np.where(t < ta + tc, v, np.maximum(v - a * (t - ta - tc), 0.0)))
    pos = np.where(t < ta, 0.5 * a * t**2, np.where(t < ta + tc, 0.5 * a * ta**2 + v * (t - ta),
                                                     d - 0.5 * a * np.maximum(T - t, 0.0) ** 2))
    return pos, vel, acc


def _joint_sweep(lo, hi, vmax, amax, speeds, v_min, plateau_s, dwell_s, rate):
    """Position, speed and acceleration of one joint's sweep starting and ending at lo; kept speeds; notes."""
    span = hi - lo
    parts_q, parts_v, parts_a, kept, notes = [], [], [], [], []
    pos = lo
    for v in np.geomspace(v_min, vmax, speeds):
        hold = min(plateau_s, (span - v * v / amax) / v)
        if hold < MIN_PLATEAU:
            notes.append(f"{v:.3g} rad/s left out: the range ({span:.3g} rad) holds it for {max(hold, 0):.2g} s")
            continue
        d = v * hold + v * v / amax
        for sign in (1.0, -1.0):
            p, w, acc = _trapezoid(d, v, amax, rate)
            parts_q.append(pos + sign * p)
            parts_v.append(sign * w)
            parts_a.append(sign * acc)
            pos = pos + sign * d
            n = int(round(dwell_s * rate))
            parts_q.append(np.full(n, pos))
            parts_v.append(np.zeros(n))
            parts_a.append(np.zeros(n))
        kept.append(float(v))
    return np.concatenate(parts_q), np.concatenate(parts_v), np.concatenate(parts_a), kept, notes


def sweep_experiment(robot: Robot, lim: Limits, *, speeds: int = 12, v_min: float = 0.01, plateau_s: float = 2.0,
                     dwell_s: float = 0.5, rate: float = 100.0) -> Experiment:
    """Every joint's constant-velocity sweep, one joint after another (the others at the centre of their
    range); each joint starts and ends at the low end of its range (margin :data:`RANGE_MARGIN`), reached
    from the centre by a slow move."""
    centre = 0.5 * (lim.lo + lim.hi)
    blocks, active, notes = [], [], []
    for i, j in enumerate(robot.joints):
        margin = RANGE_MARGIN * (lim.hi[i] - lim.lo[i])
        lo, hi = lim.lo[i] + margin, lim.hi[i] - margin
        vmin = min(v_min, 0.5 * lim.velocity[i])
        q, w, a, kept, why = _joint_sweep(lo, hi, lim.velocity[i], lim.acceleration[i], speeds, vmin,
                                          plateau_s, dwell_s, rate)
        notes += [f"joint {j}: {x}" for x in why]
        slow = min(0.5 * lim.velocity[i], 0.2)
        to, wt, at = _trapezoid(centre[i] - lo, slow, lim.acceleration[i], rate)  # centre -> lo and back
        qi = np.concatenate([centre[i] - to, q, lo + to])
        wi = np.concatenate([-wt, w, wt])
        ai = np.concatenate([-at, a, at])
        Q = np.tile(centre, (qi.size, 1))
        Q[:, i] = qi
        W, A = np.zeros_like(Q), np.zeros_like(Q)
        W[:, i], A[:, i] = wi, ai
        blocks.append((Q, W, A))
        active.append(np.full(qi.size, i))
        notes.append(f"joint {j}: {len(kept)} speeds from {kept[0]:.3g} to {kept[-1]:.3g} rad/s" if kept
                     else f"joint {j}: no speed fits its range")
    Q, W, A = (np.concatenate([b[k] for b in blocks]) for k in range(3))
    return Experiment(np.arange(Q.shape[0]) / rate, Q, W, A, active=np.concatenate(active), notes=notes)


def ramp_experiment(robot: Robot, lim: Limits, holding: np.ndarray, levels: dict[str, float], *,
                    peak: float = 0.85, ramp_s: float = 4.0, hold_s: float = 1.0, rate: float = 100.0) -> Experiment:
    """Every joint's presliding torque ramps (to +-``peak`` times its Coulomb level ``levels[joint]`` and
    back, one joint after another) on top of ``holding``, the torque that holds the arm still at the centre
    pose (nv,)."""
    centre = 0.5 * (lim.lo + lim.hi)
    up = np.linspace(0.0, 1.0, int(round(ramp_s * rate)), endpoint=False)
    shape = np.concatenate([up, np.ones(int(round(hold_s * rate))), 1.0 - up,
                            np.zeros(int(round(hold_s * rate)))])
    blocks, active = [], []
    for i, j in enumerate(robot.joints):
        prof = peak * levels[j] * np.concatenate([shape, -shape])
        T = np.tile(holding, (prof.size, 1))
        T[:, i] += prof
        blocks.append(T)
        active.append(np.full(prof.size, i))
    tau = np.concatenate(blocks)
    Q = np.tile(centre, (tau.shape[0], 1))
    notes = [f"joint {j}: ramps to +-{peak * levels[j]:.3g} N m ({100 * peak:.0f} % of its Coulomb level "
             f"{levels[j]:.3g}) on a holding torque of {holding[i]:.3g} N m" for i, j in enumerate(robot.joints)]
    return Experiment(np.arange(tau.shape[0]) / rate, Q, np.zeros_like(Q), np.zeros_like(Q), tau=tau,
                      active=np.concatenate(active), notes=notes)


def holding_torque(robot: Robot, fit, q0: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The torque that holds the arm still at ``q0``: the rigid-body model of ``fit`` (a
    :class:`~.identify.RobotFit` with base parameters) at zero speed and acceleration, plus each joint's
    offset."""
    from .regressor import full_regressor

    z = np.zeros((1, robot.nv))
    Y = full_regressor(robot, q0[None, :], z, z, robot.armature)[:, fit.bp.columns]
    return Y @ fit.x[:fit.bp.n] + offsets
