"""A run's friction level ``F_ref`` and its standard error.

``F_ref`` is the friction at a reference speed ``w_ref`` [q/s] (the mean of the magnitudes at +w_ref and
-w_ref) that the run's selected :class:`frictid.FrictionModel` computes, at a reference temperature where
the model has a thermal law, load and position neutral. Its standard error comes from the selected model's
parameter covariance by the **delta method**: ``se^2 = g' C g`` with ``g`` the gradient of ``F_ref`` in the
model's free parameters, by central differences through ``FrictionModel`` (a step of 1e-3 of each
parameter's standard error: the level is smooth there, and a linearisation over 0.1 % of a standard error
is exact to far below the standard error itself). Sampling the covariance would give the same for these
near-linear levels at 100x the evaluations.

The covariance (``ModelFit.cov``, free parameters in table order) gives the correlations; the diagonal
is the parameters' standard errors (:func:`param_covariance`). Without one, the standard error is NaN with
the reason, and the trend falls back to the series' scatter.
"""
from __future__ import annotations

import json
import math
import warnings
from dataclasses import replace

import numpy as np

#: Central-difference step as a share of a parameter's standard error.
STEP = 1e-3


def param_covariance(mf) -> tuple[list[str], np.ndarray] | None:
    """(names, covariance) of a fitted model's free parameters, or None when the covariance is missing.

    The parameters' standard errors are authoritative: the fit widens some of them beyond its least-squares
    covariance (a held shape exponent's profile, the jackknife over time blocks, the bandwidth check), so
    the covariance returned keeps the fit's correlations and takes its diagonal from the standard errors."""
    if mf is None or mf.cov is None:
        return None
    cov = np.asarray(mf.cov, dtype=float)
    names = [n for n, p in mf.params.items() if not p.fixed]
    if cov.shape != (len(names), len(names)) or not np.isfinite(cov).all():
        return None
    se = np.array([np.nan if mf.params[n].stderr is None else mf.params[n].stderr for n in names], dtype=float)
    d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if not np.all(np.isfinite(se)) or np.any(d <= 0):
        return None
    corr = np.clip(cov / np.outer(d, d), -1.0, 1.0)
    return names, corr * np.outer(se, se)


def covariance_json(mf) -> str:
    """The covariance as the trend store keeps it: JSON ``{"names": [...], "cov": [[...]]}``, or ``""``."""
    nc = param_covariance(mf)
    return json.dumps({"names": nc[0], "cov": nc[1].tolist()}) if nc else ""


def covariance_from_json(text) -> tuple[list[str], np.ndarray] | None:
    if not isinstance(text, str) or not text:
        return None
    d = json.loads(text)
    return list(d["names"]), np.asarray(d["cov"], dtype=float)


def level(jf, model: str, w_ref: float, T_ref: float | None) -> tuple[float, bool]:
    """(F_ref [F] of model ``model`` of joint fit ``jf``, whether a thermal law normalised it)."""
    m = jf.friction_model(model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a reference outside the run's validity range is the point here
        F = m.friction(np.array([w_ref, -w_ref]), T=T_ref if m.thermal else None)
    return float((F[0] - F[1]) / 2), bool(m.thermal)


def _with_value(jf, model: str, name: str, value: float):
    mf = jf.models[model]
    params = {**mf.params, name: replace(mf.params[name], value=value)}
    return replace(jf, models={**jf.models, model: replace(mf, params=params)})


def level_with_stderr(jf, model: str, w_ref: float, T_ref: float | None,
                      cov: tuple[list[str], np.ndarray] | None) -> dict:
    """F_ref with its standard error by the delta method: ``{"value", "stderr", "thermal", "reason"}``
    (stderr NaN and a reason when there is no usable covariance)."""
    value, thermal = level(jf, model, w_ref, T_ref)
    out = {"value": value, "stderr": math.nan, "thermal": thermal, "reason": ""}
    if cov is None:
        out["reason"] = "the selected model has no parameter covariance"
        return out
    names, C = cov
    params = jf.models[model].params
    if any(n not in params or params[n].value is None for n in names):
        out["reason"] = "the covariance names parameters the model does not have"
        return out
    g = np.zeros(len(names))
    for i, n in enumerate(names):
        h = STEP * math.sqrt(max(C[i, i], 0.0))
        if h == 0.0:
            continue
        v = float(params[n].value)
        up = level(_with_value(jf, model, n, v + h), model, w_ref, T_ref)[0]
        down = level(_with_value(jf, model, n, v - h), model, w_ref, T_ref)[0]
        g[i] = (up - down) / (2 * h)
    out["stderr"] = float(math.sqrt(max(g @ C @ g, 0.0)))
    return out
