"""Sensor models: noise, encoder quantisation, torque offset and measurement delay.

The position and velocity the controller sees (``qm``, ``qdm``) are computed inside the kernel from
noise arrays drawn here, so the closed loop runs on measured signals. The logged torque is the applied
torque plus white noise and any ``torque_offset`` effect. ``delay`` shifts the logged q and qd by that
many samples behind the torque (the first samples repeat), as a drive that timestamps its encoder late.
"""
from __future__ import annotations

import numpy as np


def draw_noise(rng: np.random.Generator, n: int, sensors) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise arrays (q [q], qd [q/s], tau [F]) of length n from a seeded generator."""

    def draw(std):
        return rng.normal(0.0, std, n) if std > 0 else np.zeros(n)

    return draw(sensors.q_noise), draw(sensors.qd_noise), draw(sensors.tau_noise)


def delay(x: np.ndarray, d: int) -> np.ndarray:
    """x delayed by d samples (first value repeated)."""
    if d <= 0:
        return x
    out = np.empty_like(x)
    out[d:] = x[:-d]
    out[:d] = x[0]
    return out


def logged_signals(qm, qdm, u, tau_noise, sensors, torque_offset=0.0):
    """(q, qd, tau) as written to the log."""
    tau = u + tau_noise + torque_offset
    return delay(qm, sensors.delay), delay(qdm, sensors.delay), tau
