"""The rigid-body torque regressor of a robot and its base parameters.

``tau = Y(q, qd, qdd) pi``: Pinocchio's joint torque regressor, 10 inertial parameters per link (mass, first
moments, inertia tensor). Many of those never show in the joint torques, and others only in fixed
combinations: the *base parameters* are the independent combinations. They are found numerically, as in
Gautier's QR method: the regressor stacked over random states, QR with column pivoting, the rank from the
diagonal of R (relative tolerance :data:`RANK_TOL`); the first ``rank`` pivoted columns span the torques,
and every other column is a fixed combination of them (``R11^-1 R12``), which the base parameters absorb.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import qr

from .description import Robot

#: Relative tolerance on |R_kk| / |R_00| for a column to count as independent.
RANK_TOL = 1e-8
#: Random states used to find the base parameters (each gives nv rows).
N_RANDOM = 200


@dataclass
class BaseParameters:
    """Which columns of the full regressor are independent (``columns``), the combination matrix
    (``combine``: base = pi[columns] + combine @ pi[others]) and the full regressor's width."""

    columns: np.ndarray
    others: np.ndarray
    combine: np.ndarray
    n_full: int

    @property
    def n(self) -> int:
        return int(self.columns.size)

    def names(self, robot: Robot) -> list[str]:
        """Each base parameter by the full parameter it starts from (link and slot), e.g. ``m2``, ``Izz3``,
        or ``Ia4`` (the drive's reflected rotor inertia); the combination it also holds is in
        :attr:`combine`."""
        slots = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
        n_links = 10 * robot.nv
        return [f"{slots[c % 10]}{robot.joints[c // 10]}" if c < n_links else f"Ia{robot.joints[c - n_links]}"
                for c in self.columns]


def full_regressor(robot: Robot, q, qd, qdd, armature: bool = False) -> np.ndarray:
    """The joint torque regressor stacked sample by sample: (n * nv, 10 * nv) for n samples, and with
    ``armature`` nv more columns ``qdd_j`` in joint j's rows (a drive's reflected rotor inertia: torque
    estimated from motor current includes it, a link-side torque sensor does not)."""
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    n, nv = q.shape
    out = np.zeros((n * nv, 10 * nv + (nv if armature else 0)))
    for k in range(n):
        out[k * nv:(k + 1) * nv, :10 * nv] = pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k])
    if armature:
        for j in range(nv):
            out[np.arange(n) * nv + j, 10 * nv + j] = qdd[:, j]
    return out


def base_parameters(robot: Robot, armature: bool = False, seed: int = 0) -> BaseParameters:
    """The base parameters of the robot's rigid-body torque (random states; a property of the robot)."""
    rng = np.random.default_rng(seed)
    nv = robot.nv
    q = rng.uniform(-np.pi, np.pi, (N_RANDOM, nv))
    W = full_regressor(robot, q, rng.normal(size=(N_RANDOM, nv)), rng.normal(size=(N_RANDOM, nv)), armature)
    _, R, piv = qr(W, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > RANK_TOL * d[0]))
    cols, others = piv[:rank], piv[rank:]
    combine = np.linalg.solve(R[:rank, :rank], R[:rank, rank:]) if others.size else np.zeros((rank, 0))
    return BaseParameters(cols, others, combine, W.shape[1])


def rigid_torque(robot: Robot, q, qd, qdd) -> np.ndarray:
    """(n, nv): the rigid-body torque of the robot's own inertial parameters (its description's links, and
    each drive's rotor inertia with ``armature``) along q [rad], qd [rad/s], qdd [rad/s^2] (n, nv), by
    Pinocchio's recursive Newton-Euler algorithm."""
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    out = np.stack([pin.rnea(model, data, q[k], qd[k], qdd[k]) for k in range(q.shape[0])]) if q.shape[0] else \
        np.zeros((0, robot.nv))
    if robot.armature and robot.rotor is not None:
        out = out + qdd * robot.rotor[None, :]
    return out
