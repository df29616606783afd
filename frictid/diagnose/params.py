"""The parameter entries of the diagnosis' models: units, held settings and standard errors.

A value's standard error is the spread of its refits without each held-out fold (a grouped jackknife);
settings chosen on a grid get at least half the grid's step.
"""
from __future__ import annotations

import math

import numpy as np

from ..models import static as sm
from ..models.params import unit_of
from ..result import ParamEstimate


def _units_of(axis: str) -> dict:
    """Unit of every parameter name the diagnosis' models can hold, on a rotary or linear axis."""
    F, q = unit_of("F", axis), unit_of("Q", axis)
    return {
        "pos_amp": "1", "pos_period": q, "pos_phase": "rad", "pos_q0": q, "pos_lin": f"1/{q}",
        "pos_quad": f"1/{q}^2", "load_torque": f"1/{F}", "load_gravity": f"1/{F}", "load_payload": "1/kg",
        "drift_per_hour": "1/h", "drift_t0": "s", "alpha": "1/K", "beta": "1", "C": "J/K", "K": "W/K",
        "T0": "degC", "dc0": f"{F}/K", "dc1": f"{unit_of('D', axis)}/K", "dc2": f"{unit_of('D2', axis)}/K",
        "dc3": f"{unit_of('D3', axis)}/K", "tau_offset": F, "J": "kg m^2" if axis == "rotary" else "kg",
        "Px": F, "Py": F, "str_amp": F, "str_amp_neg": F, "str_vs": unit_of("W", axis), "str_delta": "1",
        "sigma0": unit_of("K", axis), "sigma1": unit_of("D", axis),
    }


_FIXED = {"beta": "thermal4 scale at T0 held at 1 (the base map carries the level)",
          "K": "held at 1 W/K: without a measured joint temperature only C/K and the slopes per watt "
               "are identifiable",
          "T0": "ambient temperature at the start of the first log",
          "drift_t0": "origin of the drift clock"}


#: Settings chosen on a grid: their standard error is at least half the grid's relative step.
_GRID = {"C": 0.5 * (10 ** (1 / 9) - 1), "str_vs": 0.25}


def param_entries(mapname: str, vals: dict, fold_vals: list[dict], axis: str):
    """ParamEstimate per value; stderr from the spread of the fold refits (grouped jackknife)."""
    units = _units_of(axis)
    for p in sm.param_table(mapname):
        units[p.name] = unit_of(p.dim, axis)
    K = len(fold_vals)
    out = {}
    for name, v in vals.items():
        fixed = name in _FIXED
        se = None
        if not fixed and K >= 2:
            xs = np.array([fv.get(name, np.nan) for fv in fold_vals], float)
            if np.all(np.isfinite(xs)):
                se = float(math.sqrt((K - 1) / K * np.sum((xs - xs.mean()) ** 2)))
            if name in _GRID and se is not None:
                se = max(se, abs(float(v)) * _GRID[name])
        reason = ""
        ident = True
        if fixed:
            reason = _FIXED[name]
        elif se is not None and v is not None and abs(v) > 0 and se > abs(v):
            ident = False
            reason = f"relative error {100 * se / abs(v):.0f} % across held-out refits (above 100 %)"
        out[name] = ParamEstimate(name, float(v), se, units.get(name, ""), ident, reason, fixed=fixed,
                                  source="diagnosis (least squares on sliding samples)")
    return out
