"""The chosen model per joint as JSON, with a sampling distribution per parameter (domain randomisation).

Each parameter carries ``distribution``: ``{"kind": "normal", "mean", "std", "low", "high"}`` (a normal of
the estimate and its standard error, truncated to the interval the fit kept the value within when it had
one, or to ``[0, inf)`` for a parameter that cannot be negative), or ``{"kind": "fixed", "value", "reason"}``
for a number the data could not pin down (held, or not identifiable): randomising it by a made-up spread
would pretend a knowledge the fit does not have. The parameter file keeps no covariance, so the
parameters are independent here; a simulator that samples them jointly should say so.
"""
from __future__ import annotations

import math

from ..model import FrictionModel
from ..version import __version__

#: Parameters that cannot be negative whatever the model (levels, speeds, exponents, stiffness, inertia).
NON_NEGATIVE = {"Fc", "Fs", "vs", "delta", "sigma0", "sigma1", "ws1", "ws2", "J", "C", "K", "beta"}


def distribution(name: str, p) -> dict:
    """The sampling distribution of one parameter estimate (a :class:`frictid.result.ParamEstimate`)."""
    if p.value is None or p.fixed or not p.identifiable or p.stderr is None or not math.isfinite(p.stderr):
        why = p.reason or ("held at a stated value" if p.fixed else "no standard error")
        return {"kind": "fixed", "value": p.value, "reason": why}
    low, high = (p.bounds if p.bounds is not None else (None, None))
    if low is None and name in NON_NEGATIVE:
        low = 0.0
    return {"kind": "normal", "mean": p.value, "std": p.stderr, "low": low, "high": high}


def joint_document(model: FrictionModel) -> dict:
    """One joint: model name, formula, axis, parameters with units, stderr and distribution, rigid-body terms
    and validity range."""
    d = model.to_dict()
    params = {}
    for name, p in model.params.items():
        params[name] = {"value": p.value, "unit": p.unit, "stderr": p.stderr, "identifiable": bool(p.identifiable),
                        "distribution": distribution(name, p)}
    return {"model": model.name, "map": model.map, "axis": model.axis, "formula": model.formula(),
            "parameters": params, "rigid_body": d.get("rigid_body", {}), "validity": d.get("validity", {})}


def json_document(models: list[FrictionModel], source: str) -> dict:
    return {"frictid_export": 1, "frictid_version": __version__, "source": source,
            "joints": {m.joint: joint_document(m) for m in models}}
