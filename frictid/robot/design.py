"""An excitation trajectory for whole-robot identification: band-limited Fourier motion of every joint
(Swevers et al.; Gaz et al. 2019 eq. 31), optimised for the condition number of the regressor the
identification solves (:mod:`.identify`: base parameters and each joint's Coulomb, viscous and offset
friction), within each joint's position, velocity and acceleration limits.

``q_j(t) = q0_j + sum_l a_lj / (l wf) sin(l wf t) - b_lj / (l wf) (cos(l wf t) - 1)``, ``l = 1..L``: the motion
starts at ``q0`` (the centre of the joint's range) and, because ``sum_l a_lj = 0`` and
``sum_l l b_lj = 0`` are imposed, with zero velocity and acceleration, so a controller can play it from
rest; it is periodic with period ``2 pi / wf``. Each candidate's amplitudes are scaled per joint to the
largest that keeps every limit (with a 5 % margin), so the optimiser (Powell, from the best of several
random starts) searches shapes only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .description import Robot
from .identify import RobotData, design
from .regressor import base_parameters

MARGIN = 0.95
N_EVAL = 120   # samples per period where the condition number is evaluated


@dataclass
class Limits:
    """Per joint: position range [lo, hi] [rad], speed and acceleration limits [rad/s, rad/s^2]."""

    lo: np.ndarray
    hi: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


@dataclass
class Trajectory:
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    condition: float
    condition_start: float
    period: float


def fourier(coef: np.ndarray, q0: np.ndarray, wf: float, t: np.ndarray):
    """q, qd, qdd (n, nv) of Fourier coefficients coef (2, L, nv): a and b per harmonic and joint."""
    a, b = coef
    L = a.shape[0]
    l = np.arange(1, L + 1)[:, None]
    wt = wf * np.outer(t, l.ravel())                      # (n, L)
    s, c = np.sin(wt), np.cos(wt)
    q = q0 + s @ (a / (l * wf)) - (c - 1.0) @ (b / (l * wf))
    qd = c @ a + s @ b
    qdd = -s @ (a * l * wf) + c @ (b * l * wf)
    return q, qd, qdd


def _from_rest(coef: np.ndarray) -> np.ndarray:
    """Coefficients adjusted so the motion starts with zero velocity (sum a = 0) and acceleration
    (sum l b = 0): the last harmonic takes up the rest."""
    a, b = coef.copy()
    L = a.shape[0]
    a[-1] = -a[:-1].sum(axis=0)
    b[-1] = -(np.arange(1, L)[:, None] * b[:-1]).sum(axis=0) / L
    return np.stack([a, b])


def _scaled(coef, lim: Limits, wf, t) -> np.ndarray:
    """Coefficients scaled per joint to the largest motion within the limits (times MARGIN)."""
    q0 = 0.5 * (lim.lo + lim.hi)
    q, qd, qdd = fourier(coef, q0, wf, t)
    span = np.maximum(np.max(np.abs(q - q0), axis=0) / (0.5 * (lim.hi - lim.lo)), 1e-12)
    vel = np.max(np.abs(qd), axis=0) / lim.velocity
    acc = np.max(np.abs(qdd), axis=0) / lim.acceleration
    k = MARGIN / np.maximum.reduce([span, vel, acc])
    return coef * k


def _condition(robot: Robot, bp, coef, lim: Limits, wf, t) -> float:
    """Condition number (columns scaled to unit norm) of the identification's design matrix along the motion."""
    q, qd, qdd = fourier(coef, 0.5 * (lim.lo + lim.hi), wf, t)
    A = design(robot, bp, RobotData(t, q, qd, qdd, np.zeros_like(q), 0.0))
    A = A / np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    sv = np.linalg.svd(A, compute_uv=False)
    return float(sv[0] / max(sv[-1], 1e-300))


def design_excitation(robot: Robot, lim: Limits, *, period: float = 10.0, harmonics: int = 5, starts: int = 8,
                      iterations: int = 400, rate: float = 100.0, seed: int = 0) -> Trajectory:
    """The optimised excitation over one period, sampled at ``rate`` [Hz]."""
    rng = np.random.default_rng(seed)
    nv = robot.nv
    wf = 2 * np.pi / period
    t_eval = np.linspace(0.0, period, N_EVAL, endpoint=False)
    bp = base_parameters(robot, robot.armature)
    shape = (2, harmonics, nv)

    def cost(x):
        coef = _scaled(_from_rest(x.reshape(shape)), lim, wf, t_eval)
        return np.log(_condition(robot, bp, coef, lim, wf, t_eval))

    candidates = [rng.normal(size=shape).ravel() for _ in range(starts)]
    costs = [cost(x) for x in candidates]
    x0 = candidates[int(np.argmin(costs))]
    res = minimize(cost, x0, method="Powell", options={"maxfev": iterations, "xtol": 1e-3, "ftol": 1e-4})
    best = res.x if res.fun < min(costs) else x0
    coef = _scaled(_from_rest(best.reshape(shape)), lim, wf, t_eval)
    t = np.arange(0.0, period, 1.0 / rate)
    q, qd, qdd = fourier(coef, 0.5 * (lim.lo + lim.hi), wf, t)
    return Trajectory(t, q, qd, qdd, float(np.exp(min(res.fun, min(costs)))), float(np.exp(np.median(costs))), period)


def robot_limits(robot: Robot, fraction: float = 0.5) -> Limits:
    """The robot's limits as :class:`Limits`, speeds and accelerations times ``fraction`` (a designed
    trajectory keeps a distance to the hard limits); ConfigError naming what the description lacks."""
    from ..errors import ConfigError

    missing = [f"{j}.{k}" for j in robot.joints for k in ("position", "velocity", "acceleration")
               if not (robot.limits or {}).get(j, {}).get(k)]
    if missing:
        raise ConfigError(f"robot {robot.name}: no limit {', '.join(missing)}; give position, velocity and "
                          "acceleration per joint in the robot's YAML (see recipes/robots/panda.yaml)")
    lim = [robot.limits[j] for j in robot.joints]
    return Limits(lo=np.array([x["position"][0] for x in lim], dtype=float),
                  hi=np.array([x["position"][1] for x in lim], dtype=float),
                  velocity=fraction * np.array([x["velocity"] for x in lim], dtype=float),
                  acceleration=fraction * np.array([x["acceleration"] for x in lim], dtype=float))
