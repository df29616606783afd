"""Step 6 of a joint's fit: thermal4 / thermal6 from the duty cycles with ``temp_env``.

The duty cycles of each log are grouped into runs (contiguous cycles; a rest ends a run), each run is
binned by :func:`frictid.identify.thermal.prepare` and the thermal laws are fitted on all runs together
(:func:`frictid.identify.thermal.fit_thermal`). They are reported with their held-out gain over a
temperature-blind polynomial and never enter the choice (the diagnosis does).
"""
from __future__ import annotations

import numpy as np

from frictid.data import Segment
from frictid.models.params import unit_of
from frictid.result import ModelFit, ParamEstimate

from . import thermal as th
from .prepare import JointData, Prep
from .static import _aic

#: Dimensions of the polynomial coefficients c0..c3 (and their slopes dc0..dc3 per kelvin).
COEF_DIMS = ("F", "D", "D2", "D3")


def _cycles(duty: list[Segment]) -> list[tuple[int, int, int]]:
    """(first sample, end sample, cycle id) per duty cycle, in time order."""
    groups: dict[int, list[Segment]] = {}
    for k, s in enumerate(duty):
        groups.setdefault(s.cycle if s.cycle is not None else k, []).append(s)
    return sorted((min(s.i0 for s in g), max(s.i1 for s in g), cid) for cid, g in groups.items())


def _log_runs(p: Prep, duty: list[Segment], min_speed: float) -> list:
    """The thermal runs of one log: contiguous cycles; a gap between cycles is a rest that ends a run, and
    the next run is taken to start cold (T = Tenv), as in 002's protocol (a night of rest before each run)."""
    cycles = _cycles(duty)
    med = float(np.median([c[1] - c[0] for c in cycles]))
    blocks, cur = [], [cycles[0]]
    for c in cycles[1:]:
        if c[0] - cur[-1][1] > max(10, 0.002 * med):
            blocks.append(cur)
            cur = []
        cur.append(c)
    blocks.append(cur)
    runs = []
    dt = p.log.dt  # a median over the whole log: once, not twice per run
    for blk in blocks:
        run = th.prepare(p.log.t, p.w, p.F, blk, p.log.channels["temp_env"],
                         p.log.channels.get("temp_joint"), min_speed,
                         bin_s=max(med * dt / th.BINS_PER_CYCLE, dt), a=p.a)
        if run is not None:
            runs.append(run)
    return runs


def thermal_runs(jd: JointData) -> tuple[list, list[list], list[str]]:
    """The thermal runs of a joint's logs, the time spans of their cycles (with the source index) and why
    logs with duty cycles gave none."""
    runs, cyc_used, reasons = [], [], []
    for p in jd.preps:
        duty = [s for s in p.segments if s.kind == "duty_cycle"]
        if not duty:
            continue
        if "temp_env" not in p.log.channels:
            reasons.append("duty cycles without a temp_env channel")
            continue
        for run in _log_runs(p, duty, jd.min_speed):
            runs.append(run)
            cyc_used += [[float(a), float(b), p.index] for a, b in run.cycle_t]
    return runs, cyc_used, reasons


def fit_thermal_models(jd: JointData, th_wanted: list[str]) -> None:
    """Fit the wanted thermal models (thermal4 first: thermal6 starts at its optimum) and add them to the
    result, with their held-out errors (3 folds of cycles)."""
    jf = jd.jf
    runs, cyc_used, reasons = thermal_runs(jd)
    if not runs:
        why = reasons[0] if reasons else "no duty-cycle segments"
        for m in th_wanted:
            jf.not_identified.append({"what": m, "reason": why})
        return
    jd.used["duty_cycle"] = cyc_used
    if len(runs) > 1:
        jf.warnings.append(f"duty cycles form {len(runs)} runs separated by rests; each run is taken to "
                           "start cold (joint temperature = temp_env), as in 002's protocol")
    tf4 = None
    for m in sorted(th_wanted, key=th.THERMAL_MODELS.index):
        if m == "thermal6":
            # thermal4 is nested in thermal6: starting at its optimum, thermal6 fits the cycles at least as well
            tf4 = tf4 or th.fit_thermal(runs, "thermal4")
            tf = th.fit_thermal(runs, m, start=th.nested_start(tf4) if tf4 is not None else None)
        else:
            tf = tf4 = th.fit_thermal(runs, m)
        if tf is None:
            jf.not_identified.append({"what": m, "reason": "too few duty cycles with motion in both directions"})
            continue
        jf.models[m] = _thermal_model(m, tf, runs, jd.axis)
        for nm, pe in jf.models[m].params.items():
            if not pe.identifiable:
                jf.not_identified.append({"what": f"{m}.{nm}", "reason": pe.reason})


def _estimate(tf, n: str, unit: str) -> ParamEstimate:
    """A fitted thermal parameter (identifiable unless the fit gave a reason)."""
    return ParamEstimate(n, tf.values[n], tf.stderr[n], unit, n not in tf.reasons, tf.reasons.get(n, ""))


def thermal_params(m: str, tf, axis: str) -> dict[str, ParamEstimate]:
    """The parameter estimates of thermal model ``m`` from its fit ``tf``."""
    params: dict[str, ParamEstimate] = {}
    for i, dim in enumerate(COEF_DIMS):
        n = f"c{i}"
        if n in tf.fixed:
            params[n] = ParamEstimate(n, tf.fixed[n], None, unit_of(dim, axis), True,
                                      "from the cold first cycle (002: identified at T0)", fixed=True)
        else:
            params[n] = _estimate(tf, n, unit_of(dim, axis))
    if m == "thermal6":
        for i, dim in enumerate(COEF_DIMS):
            params[f"dc{i}"] = _estimate(tf, f"dc{i}", unit_of(dim, axis) + "/K")
    else:
        params["alpha"] = _estimate(tf, "alpha", "1/K")
        params["beta"] = _estimate(tf, "beta", "1")
    if "K" in tf.fixed:
        params["K"] = ParamEstimate("K", tf.fixed["K"], None, "W/K", True,
                                    "held: the joint temperature is not measured, K only sets its scale",
                                    fixed=True)
    else:
        params["K"] = _estimate(tf, "K", "W/K")
    params["C"] = _estimate(tf, "C", "J/K")
    params["T0"] = ParamEstimate("T0", tf.T0, None, "degC", True, "ambient temperature at the cold start",
                                 fixed=True)
    return params


def _thermal_model(m: str, tf, runs: list, axis: str) -> ModelFit:
    """The result's model of thermal fit ``tf``, with its held-out errors against a constant polynomial."""
    r_h, r_c = th.heldout(runs, m, n_folds=3, full=tf)
    params = thermal_params(m, tf, axis)
    n = tf.n_cycles
    rss = (tf.rms or 0.0) ** 2 * n
    met = {"rms": tf.rms, "rms_heldout": r_h, "rms_heldout_constant": r_c,
           "heldout_gain": (1 - r_h / r_c) if (r_h is not None and r_c) else None,
           "aic": _aic(rss, n, tf.k), "n": n, "k": tf.k}
    extra = {"time_constant": {"value": tf.time_constant, "stderr": tf.time_constant_se, "unit": "s"},
             "cycle_temperature": [[round(x, 4) for x in ct] for ct in tf.cycle_T]}
    return ModelFit(m, "polynomial", params, met, notes=tf.notes, success=tf.success,
                    method="cycle-by-cycle polynomial least squares, then all thermal parameters "
                           "together against the cycles' friction (002 section V)", extra=extra)
