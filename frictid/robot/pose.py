"""One joint moved, the others standing: the gravity its pose leaves on it, from the robot's kinematics.

When a log moves one joint of a robot while the others stand, frictid fits that joint alone (inertia,
gravity, offset and friction, :mod:`frictid.identify`). The gravity torque on a revolute joint is
``tau_g = z . (c x M g) = (g x z) . M c`` (z its axis, M c the first moment of everything it carries about a
point of the axis): with the other joints standing, ``M c`` turns with the joint about z and ``tau_g = Px cos
q + Py sin q``. Its size needs the links' masses, which a DH table does not give; its *form* needs only the
kinematics: when the axis is parallel to gravity (``|z x g| = 0``), ``tau_g`` is zero whatever the masses,
and a one-joint fit must not free ``Px, Py`` (on an oscillation the angle explains most of the acceleration,
so a free gravity trades off with the inertia: docs/realdata.md, UR10e joint 5).

:func:`one_joint_motion` reads which joints move alone; :func:`pose_gravity` the form of a joint's gravity
over its moving samples, from the robot's kinematics at the logged angles of all its joints.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .description import Robot

#: A joint moves where its speed is above this share of the log's top joint speed (99.5th percentile of
#: |qd| over every joint): the one-joint fit's own moving threshold (frictid.identify.prepare).
MOVING_SHARE = 0.02
#: A joint stands over a stretch when its logged angle stays within this many of its resolution steps
#: (the standing band of the whole-robot fit: five noise levels).
STAND_STEPS = 5
#: The kinematics' own rounding [rad]: a tilt below it is zero however finely the angles are logged.
FLOAT_TILT = 1e-9


@dataclass
class PoseGravity:
    """The gravity form of a joint moved alone: ``none`` (its axis is parallel to gravity at every moving
    sample, within what the logged angles resolve), ``angle`` (``Px cos q + Py sin q``: the other joints
    stand), ``varies`` (the other joints move while it moves: a one-joint fit's ``Px cos q + Py sin q`` is
    only an approximation) or ``offset`` (a prismatic joint: a constant force, part of the offset).
    tilt : the largest ``|z x g| / |g|`` over the moving samples; tol : the tilt the logged angles resolve
    (the sum of the resolution steps of the joints that carry the axis)."""

    joint: str
    form: str
    tilt: float
    tol: float
    note: str

    def to_dict(self) -> dict:
        return {"form": self.form, "tilt": self.tilt, "tilt_resolved": self.tol, "note": self.note}


def _matrix(robot: Robot, logs, name: str) -> np.ndarray:
    """(n, nv) signal ``name`` of the logs in the robot's joint order on the first joint's samples."""
    from .identify import align

    t0, ordered = align(robot, logs)
    cols = []
    for lg in ordered:
        x = getattr(lg, name)
        if x is None and name == "qd":
            x = np.gradient(lg.q, lg.t)
        cols.append(x if lg.n == t0.size and np.array_equal(lg.t, t0) else np.interp(t0, lg.t, x))
    return np.column_stack(cols)


def moving_mask(robot: Robot, logs) -> np.ndarray:
    """(n, nv) True where a joint moves (:data:`MOVING_SHARE` of the log's top joint speed)."""
    qd = np.abs(_matrix(robot, logs, "qd"))
    top = float(np.max(np.percentile(qd, 99.5, axis=0)))
    return qd > MOVING_SHARE * top if top > 0 else np.zeros(qd.shape, bool)


def one_joint_motion(robot: Robot, logs) -> tuple[list[str], str]:
    """The joints a one-joint fit can read, and why. A log is one-joint motion when more of its moving
    samples have one joint moving than several; the joints read are those that move alone on most of their
    own moving samples. Returns ([], why) for multi-joint motion (the whole-robot fit's)."""
    mov = moving_mask(robot, logs)
    count = mov.sum(axis=1)
    alone, together = int(np.sum(count == 1)), int(np.sum(count > 1))
    if alone == 0 or together >= alone:
        return [], (f"several joints move together on {together} samples and one alone on {alone}: "
                    "multi-joint motion")
    solo = [j for i, j in enumerate(robot.joints) if np.sum(mov[:, i] & (count == 1)) > 0.5 * mov[:, i].sum()]
    parts = [f"joint {j} {int(np.sum(mov[:, i] & (count == 1)))} of {int(mov[:, i].sum())}"
             for i, j in enumerate(robot.joints) if mov[:, i].any()]
    return solo, (f"one joint moves at a time ({alone} samples with one joint moving, {together} with several; "
                  f"moving alone / moving: {', '.join(parts)})")


def _resolution(q: np.ndarray) -> list[float]:
    """Each logged angle's resolution (columns of ``q``): the smallest change between its samples (an
    encoder step or the logged digits); for an angle that never changes, the finest of the others (one
    logger, alike encoders)."""
    out = []
    for col in np.asarray(q, float).T:
        d = np.abs(np.diff(col))
        d = d[d > 0]
        out.append(float(d.min()) if d.size else np.nan)
    finest = np.nanmin(out) if np.isfinite(out).any() else 0.0
    return [finest if not np.isfinite(r) else r for r in out]


def _axes(robot: Robot, q: np.ndarray, j: int) -> tuple[np.ndarray, bool]:
    """Joint j's axis in the base frame at each pose of ``q`` (n, nv), and whether it is revolute."""
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    v = np.zeros(model.nv)
    v[j] = 1.0
    out = np.zeros((q.shape[0], 3))
    revolute = True
    for k in range(q.shape[0]):
        pin.forwardKinematics(model, data, q[k], v)
        m = data.v[j + 1]
        ang = np.asarray(m.angular)
        if k == 0 and np.linalg.norm(ang) < 0.5:
            revolute = False
        out[k] = data.oMi[j + 1].rotation @ (ang if revolute else np.asarray(m.linear))
    return out, revolute


def pose_gravity(robot: Robot, logs, joint: str) -> PoseGravity:
    """The form of ``joint``'s gravity over its moving samples (:class:`PoseGravity`), from the robot's
    kinematics at the logged angles of all its joints (each pose once)."""
    if robot.model.nq != robot.model.nv:
        return PoseGravity(joint, "varies", float("nan"), 0.0, "the robot has joints with more than one "
                           "coordinate: the pose's gravity is not read from it")
    j = robot.joints.index(joint)
    q = _matrix(robot, logs, "q")
    mov = moving_mask(robot, logs)[:, j]
    if not mov.any():
        return PoseGravity(joint, "varies", float("nan"), 0.0, f"joint {joint} does not move")
    # the axis' direction depends only on the joints between the base and this one: each of their poses once
    carriers = _supporting(robot, j)
    held, inv = np.unique(q[mov][:, carriers], axis=0, return_inverse=True)
    poses = np.zeros((held.shape[0], q.shape[1]))
    poses[:, carriers] = held
    axes, revolute = _axes(robot, poses, j)
    if not revolute:
        return PoseGravity(joint, "offset", float("nan"), 0.0, f"joint {joint} is prismatic: gravity along it is "
                           "a constant force, part of the offset")
    g = np.asarray(robot.model.gravity.linear, float)
    tilt = float(np.max(np.linalg.norm(np.cross(axes, g / np.linalg.norm(g)), axis=1)[np.ravel(inv)]))
    res = _resolution(q)
    tol = max(float(sum(res[i] for i in carriers)), FLOAT_TILT)
    others = [i for i in range(q.shape[1]) if i != j]
    travel = {robot.joints[i]: float(np.ptp(q[mov, i])) for i in others}
    moved = {n: r for (n, r), i in zip(travel.items(), others) if r > STAND_STEPS * max(res[i], 1e-12)}
    if tilt <= tol:
        by = (f"within the {tol:.2g} rad the logged angles of joints "
              f"{', '.join(robot.joints[i] for i in carriers)} resolve" if carriers else "fixed to the base")
        return PoseGravity(joint, "none", tilt, tol, (
            f"joint {joint}'s axis is parallel to gravity at every moving sample (tilt {tilt:.2g} rad, {by}): its "
            "gravity torque is zero whatever the links' masses; Px, Py held at 0"))
    if moved:
        # each other joint's travel turns the carried links or the axis by at most that angle: the gravity
        # departs from the one-pose form by at most about the sum, as a share of its amplitude
        which = ", ".join(f"{n} over {r:.2g} rad" for n, r in moved.items())
        return PoseGravity(joint, "varies", tilt, tol, (
            f"the other joints move while joint {joint} moves ({which}): "
            f"its gravity departs from Px cos q + Py sin q by up to about {sum(moved.values()):.2g} of its "
            "amplitude; fitted as Px cos q + Py sin q"))
    return PoseGravity(joint, "angle", tilt, tol, (
        f"joint {joint}'s axis is tilted from gravity (|z x g| / |g| up to {tilt:.2g}) and the other joints "
        "stand: its gravity is Px cos q + Py sin q, fitted"))


def _supporting(robot: Robot, j: int) -> list[int]:
    """Indices of the joints between the base and joint j (they set its axis' direction)."""
    model = robot.model
    out, p = [], model.parents[j + 1]
    while p > 0:
        out.append(int(model.joints[p].idx_v))
        p = model.parents[p]
    return sorted(out)
