"""Hidden effects of a plant joint, turned into the numbers the kernel uses.

Each entry of a joint's ``effects:`` list (see :mod:`frictid.plant.config`) acts as follows:

- ``position``: level ``g`` times ``1 + amplitude sin(2 pi q / period + phase)`` (004: linear slides);
- ``load``: level times ``1 + coeff |tau| + payload_coeff m_payload`` (002 refs 18-19);
- ``asymmetry``: the whole ``w < 0`` branch of the static map times ``factor`` (001, 003, 004);
- ``torque_offset``: the logged torque carries a constant offset (current-sensor bias);
- ``drift``: static map times ``1 + per_hour t/3600 + per_run run`` (wear, oil condition; 000).
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

    def multipliers(self, t, run, payload):
        """(gmul, fmul) per sample: level and viscous multipliers from drift and payload."""
        t = np.asarray(t)
        if not (self.drift_per_hour or self.drift_per_run or self.payload_coeff):
            one = np.ones(t.shape)
            return one, one
        drift = 1.0 + self.drift_per_hour * t / 3600.0 + self.drift_per_run * np.asarray(run)
        gmul = drift * (1.0 + self.payload_coeff * np.asarray(payload))
        return np.ascontiguousarray(gmul, dtype=float), np.ascontiguousarray(drift, dtype=float)


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
    return ce
