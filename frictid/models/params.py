"""Parameter tables: one row per model parameter, feeding the optimiser, the YAML writer and the report.

Bounds, starts and scales are given in *data units*: each parameter has a dimension (force, velocity,
damping, ...) and its numbers are multiples of the data's own scale for that dimension (the torque range,
the velocity range), so the same table works for a 0.03 N m slide and a 300 N m hydraulic joint.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Dimension code -> unit template. {F} is the force/torque unit, {q} the position unit.
UNIT_TEMPLATES: dict[str, str] = {
    "F": "{F}",
    "W": "{q}/s",
    "D": "{F} s/{q}",
    "D2": "{F} s^2/{q}^2",
    "D3": "{F} s^3/{q}^3",
    "K": "{F}/{q}",
    "1": "1",
    "Q": "{q}",
}

ROTARY = {"F": "N m", "q": "rad"}
LINEAR = {"F": "N", "q": "m"}


def unit_of(dim: str, axis: str = "rotary") -> str:
    """Unit string of a dimension code for a rotary ('N m', 'rad') or linear ('N', 'm') axis."""
    names = LINEAR if axis == "linear" else ROTARY
    return UNIT_TEMPLATES[dim].format(**names)


@dataclass(frozen=True)
class Param:
    """One model parameter.

    lower, upper, start and scale are multiples of the data scale of dimension ``dim``
    (see :func:`data_scale`); ``fixed`` parameters are held at ``start`` unless freed.
    """

    name: str
    dim: str
    lower: float
    upper: float
    start: float
    scale: float = 1.0
    doc: str = ""


def data_scale(dim: str, F0: float, w0: float, q0: float = 1.0) -> float:
    """Scale of a dimension for data with torque scale F0 [F], velocity scale w0 [q/s], position q0 [q]."""
    F0 = max(float(F0), 1e-12)
    w0 = max(float(w0), 1e-12)
    return {
        "F": F0,
        "W": w0,
        "D": F0 / w0,
        "D2": F0 / w0**2,
        "D3": F0 / w0**3,
        "K": F0 / max(q0, 1e-12),
        "1": 1.0,
        "Q": q0,
    }[dim]


def scaled_table(table: tuple[Param, ...], F0: float, w0: float, q0: float = 1.0):
    """Bounds, start and x_scale arrays for ``table`` on data of scales (F0, w0, q0)."""
    s = np.array([data_scale(p.dim, F0, w0, q0) for p in table])
    lo = np.array([p.lower for p in table]) * s
    hi = np.array([p.upper for p in table]) * s
    x0 = np.clip(np.array([p.start for p in table]) * s, lo, hi)
    xs = np.array([p.scale for p in table]) * s
    return lo, hi, x0, xs
