"""Hidden effects of a plant joint, turned into the numbers the kernel uses.

Each entry of a joint's ``effects:`` list (see :mod:`frictid.plant.config`) acts as follows:

- ``position``: level ``g`` times ``1 + amplitude sin(2 pi q / period + phase)`` (004: linear slides);
- ``load``: level times ``1 + coeff |tau| + payload_coeff m_payload`` (002 refs 18-19);
- ``asymmetry``: the whole ``w < 0`` branch of the static map times ``factor`` (001, 003, 004);
- ``torque_offset``: the logged torque carries a constant offset (current-sensor bias);
- ``drift``: static map times ``1 + per_hour t/3600 + per_run run`` (wear, oil condition; 000);
- ``position_torque``: a torque ``amplitude sin(2 pi q / period + phase)`` acting like gravity (a gravity
  harmonic, a spring compensator, cogging): not friction, it does not change sign with the velocity;
- ``dwell``: level times ``1 + amplitude ln(1 + t_rest / t0) exp(-s / distance)``, static friction that grows
  with the time at rest before a move and fades over the travel ``s`` since it started (contact ageing).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class CompiledEffects:
    pos_amp: float = 0.0
    pos_period: float = 1.0
    pos_phase: float = 0.0
    load_coeff: float = 0.0
    payload_coeff: float = 0.0
    neg_factor: float = 1.0
    torque_offset: float = 0.0
    drift_per_hour: float = 0.0
    drift_per_run: float = 0.0
    ptq_amp: float = 0.0
    ptq_period: float = 1.0
    ptq_phase: float = 0.0
    dwell_amp: float = 0.0
    dwell_t0: float = 1.0
    dwell_distance: float = 1.0

    def multipliers(self, t, run, payload, q_ref=None, qd_ref=None):
        """(gmul, fmul) per sample: level and viscous multipliers from drift, payload and dwell (the dwell
        factor from the program's reference position q_ref [q] and velocity qd_ref [q/s])."""
        t = np.asarray(t)
        if not (self.drift_per_hour or self.drift_per_run or self.payload_coeff or self.dwell_amp):
            one = np.ones(t.shape)
            return one, one
        drift = 1.0 + self.drift_per_hour * t / 3600.0 + self.drift_per_run * np.asarray(run)
        gmul = drift * (1.0 + self.payload_coeff * np.asarray(payload))
        if self.dwell_amp:
            gmul = gmul * dwell_factor(t, q_ref, qd_ref, self.dwell_amp, self.dwell_t0, self.dwell_distance)
        return np.ascontiguousarray(gmul, dtype=float), np.ascontiguousarray(drift, dtype=float)


def dwell_factor(t, q_ref, qd_ref, amp: float, t0: float, distance: float) -> np.ndarray:
    """``1 + amp ln(1 + t_rest / t0) exp(-s / distance)`` per sample: at rest (``qd_ref == 0``) t_rest is the
    time at rest so far and s = 0; moving, t_rest is the length of the rest just before the move (0 after
    a reversal without rest) and s the reference travel since the move started."""
    t = np.asarray(t, float)
    q_ref = np.asarray(q_ref, float)
    sg = np.sign(np.asarray(qd_ref, float))
    moving = sg != 0.0
    n = t.size
    # the index where the current run (at rest, or moving one way) started, and where the run before it did
    start = prev = np.zeros(n, dtype=np.int64)
    if n:
        brk = np.flatnonzero(sg[1:] != sg[:-1]) + 1
        edges = np.concatenate(([0], brk))
        lens = np.diff(np.concatenate((edges, [n])))
        start = np.repeat(edges, lens)
        prev = np.repeat(np.concatenate(([-1], edges[:-1])), lens)
    t_rest = np.where(moving, 0.0, t - t[start])
    s = np.where(moving, np.abs(q_ref - q_ref[start]), 0.0)
    # moving after a rest: the rest's length (the run before started at prev, ended at start)
    after_rest = moving & (start > 0)
    after_rest[after_rest] &= ~moving[start[after_rest] - 1]
    t_rest[after_rest] = t[start[after_rest]] - t[prev[after_rest]]
    return 1.0 + amp * np.log1p(t_rest / t0) * np.exp(-s / distance)


def compile_effects(effects) -> CompiledEffects:
    """Fold a joint's effect list into one :class:`CompiledEffects` (repeated kinds combine)."""
    ce = CompiledEffects()
    for e in effects:
        if e.kind == "position":
            if ce.pos_amp:
                raise ValueError("only one position effect per joint")
            ce.pos_amp, ce.pos_period, ce.pos_phase = e.amplitude, e.period, e.phase
        elif e.kind == "load":
            ce.load_coeff += e.coeff
            ce.payload_coeff += e.payload_coeff
        elif e.kind == "asymmetry":
            ce.neg_factor *= e.factor
        elif e.kind == "torque_offset":
            ce.torque_offset += e.value
        elif e.kind == "drift":
            ce.drift_per_hour += e.per_hour
            ce.drift_per_run += e.per_run
        elif e.kind == "position_torque":
            if ce.ptq_amp:
                raise ValueError("only one position_torque effect per joint")
            ce.ptq_amp, ce.ptq_period, ce.ptq_phase = e.amplitude, e.period, e.phase
        elif e.kind == "dwell":
            if ce.dwell_amp:
                raise ValueError("only one dwell effect per joint")
            ce.dwell_amp, ce.dwell_t0, ce.dwell_distance = e.amplitude, e.t0, e.distance
    return ce
