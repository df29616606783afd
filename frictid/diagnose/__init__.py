"""Diagnosis: what the identified model gets wrong, the cause, the extended model and its measured gain.

Public entry: :func:`diagnose_joint`, called by :func:`frictid.fit` for every joint (``--no-diagnose``
skips it). It starts from the base model (the best symmetric velocity-only static map, by the fit's own
choice rule), tests the residual of the current model against every candidate cause on held-out
segments (:mod:`.chain`), extends the model with the best significant cause, and repeats. Each finding
becomes a model under ``models:`` (``stribeck+thermal6+position``), and ``selected`` names the end of the
chain. ``presliding`` is judged on ramp and step segments by the fit's LuGre comparison (leave one ramp
out), since sliding samples say nothing about presliding.

Numbers only (layer 2): arrays in, result objects out. True plant parameters are never read.
See ``docs/diagnosis.md``.
"""
from __future__ import annotations

import math

import numpy as np

from .causes import CAUSES, EXTENSIONS
from .chain import ALPHA, EXPLAINED_MIN, GAIN_MIN, Chain, Trial
from .model import Structure, model_values
from .samples import DiagLog, Samples, build_samples

__all__ = ["diagnose_joint", "DiagLog", "CAUSES", "EXTENSIONS", "base_model_name"]

#: Folds of the held-out split.
N_FOLDS = 5


def base_model_name(jf) -> str | None:
    """The base of the chain: the fit's choice rule over its symmetric velocity-only static maps."""
    from ..identify.pipeline import BASE_MODELS
    from ..identify.select import choose

    cands = [m for m in BASE_MODELS if not m.endswith("_asym") and m in jf.models
             and all(v is not None for v in jf.models[m].values().values())]
    if not cands:
        return None
    name, _ = choose(jf.models, cands)
    return name


def _base_structure(jf, name: str, S: Samples) -> Structure:
    """The base map with its shapes; for a rotary joint whose gravity the fit estimated, the gravity
    correction is re-estimated with it (the fit's offset and gravity trade off over a short range of
    angles; the offset is taken out and only enters through the ``offset`` cause)."""
    from ..models import static as sm
    from .model import Term

    mf = jf.models[name]
    mapname = "polynomial" if name == "polynomial_ls" else mf.map
    cp, _ = sm.canonical_pair(mapname, {k: v for k, v in mf.values().items()})
    terms = ()
    px = jf.gravity.get("Px")
    if (S.axis_rotary and S.q is not None and px is not None and px.value is not None and np.ptp(S.q) > 0
            and px.source != "log metadata"):
        terms = (Term("gravity", "gravity", "additive", (), in_base=True),)
    return Structure(map=mapname, shapes=np.asarray(cp, float), terms=terms)


# ---------------------------------------------------------------------------------------------------
# Units and parameter entries


def _units(axis: str) -> dict:
    from ..models.params import unit_of

    F, q = unit_of("F", axis), unit_of("Q", axis)
    return {
        "pos_amp": "1", "pos_period": q, "pos_phase": "rad", "pos_q0": q, "pos_lin": f"1/{q}",
        "pos_quad": f"1/{q}^2", "load_torque": f"1/{F}", "load_gravity": f"1/{F}", "load_payload": "1/kg",
        "drift_per_hour": "1/h", "drift_t0": "s", "alpha": "1/K", "beta": "1", "C": "J/K", "K": "W/K",
        "T0": "degC", "dc0": f"{F}/K", "dc1": f"{unit_of('D', axis)}/K", "dc2": f"{unit_of('D2', axis)}/K",
        "dc3": f"{unit_of('D3', axis)}/K", "tau_offset": F, "J": "kg m^2" if axis == "rotary" else "kg",
        "Px": F, "Py": F, "str_amp": F, "str_vs": unit_of("W", axis), "str_delta": "1",
        "sigma0": unit_of("K", axis), "sigma1": unit_of("D", axis),
    }


_FIXED = {"beta": "thermal4 scale at T0 held at 1 (the base map carries the level)",
          "K": "held at 1 W/K: without a measured joint temperature only C/K and the slopes per watt "
               "are identifiable",
          "T0": "ambient temperature at the start of the first log",
          "drift_t0": "origin of the drift clock"}


#: Settings chosen on a grid: their standard error is at least half the grid's relative step.
_GRID = {"C": 0.5 * (10 ** (1 / 9) - 1), "str_vs": 0.25}


def _param_entries(mapname: str, vals: dict, fold_vals: list[dict], axis: str):
    """ParamEstimate per value; stderr from the spread of the fold refits (grouped jackknife)."""
    from ..result import ParamEstimate
    from ..models import static as sm
    from ..models.params import unit_of

    units = _units(axis)
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


# ---------------------------------------------------------------------------------------------------
# Evidence sentences


def _fmt(x: float) -> str:
    if x == 0 or not math.isfinite(x):
        return f"{x:.3g}"
    return f"{x:.3g}" if 1e-3 <= abs(x) < 1e5 else f"{x:.2e}"


def _duration(seconds: float) -> str:
    if seconds >= 2 * 3600:
        return f"{seconds / 3600:.1f} h"
    if seconds >= 120:
        return f"{seconds / 60:.0f} min"
    return f"{seconds:.0f} s"


def _corr(a, b) -> float:
    if a.size < 3 or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


def evidence(tr: Trial, S: Samples, step: dict, units: dict, rigid: dict) -> str:
    """One plain sentence with the numbers behind a finding (and the causes the data cannot tell from it)."""
    text = _evidence(tr, S, step, units, rigid)
    if tr.rivals:
        alt = ", ".join(f"{c} ({e}, held-out RMS {_fmt(r)})" for c, e, r in tr.rivals)
        text += f"; the data cannot tell it from {alt}"
    return text


def _evidence(tr: Trial, S: Samples, step: dict, units: dict, rigid: dict) -> str:
    F_u, q_u = units["F"], units["q"]
    rb = S.F - tr.pred_before
    corr = tr.pred_after - tr.pred_before
    r = _corr(rb, corr)
    term = step["term"]
    nl = term.settings
    coef = step["coef"]
    st = step["structure"]
    i = len(st.terms) - 1
    g = np.atleast_1d(coef.gamma.get(i, np.zeros(0)))
    tail = (f"{term.ext} cuts held-out RMS from {_fmt(tr.rms_before)} to {_fmt(tr.rms_after)} {F_u} "
            f"({100 * tr.gain:.0f} %)")
    ext = tr.ext
    if ext in ("thermal4", "thermal6"):
        order = np.argsort(S.th)
        n10 = max(1, S.n // 10)
        sg = np.sign(S.w)
        early = float(np.mean((corr * sg)[order[:n10]]))
        late = float(np.mean((corr * sg)[order[-n10:]]))
        span = float(np.ptp(S.th)) * 3600
        dirn = "falls" if late < early else "rises"
        what = ("the measured joint temperature" if nl.get("source") == "temp_joint" else
                f"the estimated thermal state (time constant {_duration(nl['tau_c'])})")
        E = _cum_energy(S)
        rE = _corr(rb * sg, E)
        return (f"friction {dirn} {_fmt(abs(late - early))} {F_u} over {_duration(span)} of recording, "
                f"tracking {what} (r = {r:.2f}; cumulative friction energy r = {rE:.2f}); {tail}")
    if ext == "position_periodic":
        amp = float(np.hypot(*g[:2]))
        return (f"friction level varies by +/-{100 * amp:.1f} % with position, period {_fmt(nl['period'])} "
                f"{q_u} (r = {r:.2f}); a periodic position modulation: {tail}")
    if ext == "position_smooth":
        d = np.array([-1.0, 1.0])
        f = 1 + g[0] * d + g[1] * d * d
        return (f"friction level changes by {100 * (f[1] - f[0]):+.1f} % from one end of the "
                f"{_fmt(2 * nl['qs'])} {q_u} of travel to the other (r = {r:.2f}); {tail}")
    if ext.startswith("load_"):
        var = {"load_torque": "load torque |J a + G(q)|", "load_gravity": "gravity torque |G(q)|",
               "load_payload": "payload"}[ext]
        unit = "kg" if ext == "load_payload" else F_u
        per = float(g[0]) / nl["scale"]
        return (f"friction level grows {100 * per * nl['scale']:+.1f} % per {_fmt(nl['scale'])} {unit} of "
                f"{var} (r = {r:.2f}); a load-dependent level: {tail}")
    if ext in ("asym", "asym_scale"):
        v = np.abs(S.w)
        from .model import canonical_vectors
        from ..models.static import canonical_friction
        cp, cn = canonical_vectors(st, coef)
        Fp = np.abs(canonical_friction(v, cp, cp))
        Fn = np.abs(canonical_friction(-v, cn, cn))
        ratio = float(np.mean(Fn) / np.mean(Fp)) if np.mean(Fp) > 0 else float("nan")
        return (f"friction for w < 0 is {100 * abs(ratio - 1):.1f} % {'above' if ratio > 1 else 'below'} "
                f"that for w > 0 at the same speeds (r = {r:.2f}); "
                f"{'per-sign parameters' if ext == 'asym' else 'the w < 0 branch scaled'}: {tail}")
    if ext == "stribeck":
        return (f"the residual concentrates at low speed, below about {_fmt(3 * nl['vs'])} {q_u}/s "
                f"(r = {r:.2f}); a Stribeck term with vs = {_fmt(nl['vs'])} {q_u}/s: {tail}")
    if ext == "inertia":
        J0 = rigid.get("J", 0.0)
        return (f"the residual tracks the acceleration (r = {r:.2f}): inertia {_fmt(J0)} -> "
                f"{_fmt(J0 + float(g[0]))} {units['J']}; {tail}")
    if ext == "gravity":
        return (f"the residual tracks cos q and sin q (r = {r:.2f}): gravity Px {_fmt(rigid.get('Px', 0.0))} -> "
                f"{_fmt(rigid.get('Px', 0.0) + float(g[0]))}, Py {_fmt(rigid.get('Py', 0.0))} -> "
                f"{_fmt(rigid.get('Py', 0.0) + float(g[1]))} {F_u}; {tail}")
    if ext == "offset":
        return (f"the residual carries a constant {_fmt(float(g[0]))} {F_u} at both velocity signs "
                f"(r = {r:.2f}); a torque offset: {tail}")
    if ext == "drift":
        span_h = float(np.ptp(S.th))
        return (f"friction changes {100 * float(g[0]):+.3g} % per hour ({100 * float(g[0]) * span_h:+.3g} % over "
                f"the {_duration(span_h * 3600)} between the first and last recording; r = {r:.2f}); a drift "
                f"term: {tail}")
    return f"r = {r:.2f}; {tail}"


def _cum_energy(S: Samples) -> np.ndarray:
    """Cumulative friction energy [J] at the samples (per log, from its start, on the drift clock order)."""
    out = np.empty(S.n)
    base = 0.0
    for i, lg in enumerate(S.logs):
        # the energy P dt summed up in place in one array of the log's length (the periods, the products
        # and two sums held three at once: 87 MB over the diagnosis' arrays on a joint-hour, its peak)
        E = np.empty(lg.n)
        E[:1] = 0.0
        np.subtract(lg.t[1:], lg.t[:-1], out=E[1:])
        E *= S.power(i)
        np.cumsum(E, out=E)
        E += base
        sel = S.li == i
        out[sel] = E[S.k[sel]]
        base = float(E[-1]) if E.size else base
    return out


# ---------------------------------------------------------------------------------------------------


def diagnose_joint(jf, logs: list[DiagLog], n_folds: int = N_FOLDS) -> list[dict]:
    """Run the diagnosis on one joint; updates ``jf`` in place and returns its ``diagnosis`` list.

    jf : the :class:`frictid.result.JointFit` the fit produced (its models, inertia, gravity,
    offset). logs : the joint's logs as the fit prepared them (:class:`DiagLog`).
    Adds one model per finding to ``jf.models``, sets ``jf.selected`` to the end of the chain, and records
    the base, the rule and every candidate's numbers in ``jf.selection['diagnosis']``.
    """
    from ..result import ModelFit

    rec: dict = {"rule": (f"a cause enters when its held-out gain is significant (one-sided t over held-out "
                          f"segments, alpha {ALPHA} split over the candidates) and it explains at least "
                          f"{100 * EXPLAINED_MIN:.0f} % of the friction RMS; the lowest held-out RMS wins unless "
                          f"a candidate with fewer coefficients is not significantly worse"),
                 "folds": n_folds}
    jf.selection["diagnosis"] = rec
    base = base_model_name(jf)
    if base is None:
        rec["skipped"] = "no velocity-only model to start from"
        jf.diagnosis = []
        return []
    rec["base"] = base
    J = jf.inertia.value if jf.inertia is not None and jf.inertia.value is not None else 0.0
    S = build_samples(logs, n_folds, axis=jf.axis, J=max(J, 0.0))
    if S is None:
        rec["skipped"] = (f"fewer than {2 * n_folds} sliding segments or too few sliding samples: nothing "
                          "can be held out; the fit's own choice stands")
        jf.diagnosis = []
        return []
    st0 = _base_structure(jf, base, S)
    rigid = {"J": jf.inertia.value if jf.inertia and jf.inertia.value is not None else 0.0,
             "Px": jf.gravity["Px"].value if "Px" in jf.gravity and jf.gravity["Px"].value is not None else 0.0,
             "Py": jf.gravity["Py"].value if "Py" in jf.gravity and jf.gravity["Py"].value is not None else 0.0}
    chain = Chain(S, st0)
    rec["rms_heldout_base"] = chain.rms_heldout
    rec["samples"] = int(S.n)
    rec["groups"] = int(S.n_groups)
    rec["friction_rms"] = chain.F_rms
    steps = chain.run()
    units = {"F": jf.units.get("tau", "N m"), "q": jf.units.get("q", "rad"),
             "J": "kg m^2" if jf.axis == "rotary" else "kg"}
    heldout = {"folds": n_folds, "groups": int(S.n_groups), "samples": int(S.n),
               "split": "whole segments (long ones in chunks), interleaved in time; sliding samples only"}
    findings = []
    rec["steps"] = []
    for k, step in enumerate(steps):
        rec["steps"].append({"tested": step["tested"], "candidates": step["m"],
                             "chosen": step["chosen"].ext if step.get("chosen") else None})
        tr: Trial | None = step.get("chosen")
        if tr is None:
            continue
        st = step["structure"]
        mapname, vals = model_values(st, step["coef"], S, rigid)
        fold_vals = [model_values(step["before"].plus(t), c, S, rigid)[1]
                     for t, c in zip(tr.fold_terms, tr.fold_coefs)]
        params = _param_entries(mapname, vals, fold_vals, jf.axis)
        name = st.name
        extra = {"base": base, "extensions": [t.ext for t in st.terms if not t.in_base]}
        th = next((t for t in st.terms if t.ext in ("thermal4", "thermal6")), None)
        if th is not None:
            extra["temperature"] = th.settings.get("source", "heat_balance")
        mf = ModelFit(name, mapname, params,
                      {"rms": step["coef"].rms, "rms_heldout": tr.rms_after, "n": int(S.n),
                       "k": int(sum(1 for p in params.values() if not p.fixed))},
                      method="diagnosis: base amplitudes and extension terms by least squares (Gauss-Newton) on "
                             "the sliding samples (shapes of the base map held)",
                      extra=extra)
        jf.models[name] = mf
        findings.append({
            "cause": tr.cause,
            "evidence": evidence(tr, S, step, units, rigid),
            "statistic": {"test": "one-sided paired t over held-out groups of sum(r_before^2 - r_after^2)",
                          "t": tr.t, "p": tr.p, "groups": tr.groups,
                          "threshold_p": ALPHA / max(step["m"], 1)},
            "extension": tr.ext,
            "model": name,
            "rms_before": tr.rms_before,
            "rms_after": tr.rms_after,
            "gain": tr.gain,
            "heldout": heldout,
        })
    pres = _presliding(jf, findings[-1]["model"] if findings else base)
    if pres is not None:
        findings.append(pres)
    jf.diagnosis = findings
    jf.selected = findings[-1]["model"] if findings else base
    return findings


def _presliding(jf, prev: str) -> dict | None:
    """A presliding finding from the fit's LuGre comparison on held-out ramps, with its model."""
    from ..result import ModelFit, ParamEstimate

    lug = jf.models.get("lugre")
    if lug is None or not str(jf.selection.get("lugre", "")).startswith("chosen"):
        return None
    rs, rh = lug.metrics.get("rms_presliding_static"), lug.metrics.get("rms_presliding_heldout")
    if not rs or rh is None or not lug.identifiable:
        return None
    gain = 1.0 - rh / rs
    if gain < GAIN_MIN:
        return None
    base = jf.models[prev]
    params = {k: ParamEstimate(**vars(p)) for k, p in base.params.items()}
    for k in ("sigma0", "sigma1"):
        params[k] = ParamEstimate(**vars(lug.params[k]))
    name = prev + "+lugre"
    extra = dict(base.extra)
    extra["extensions"] = list(extra.get("extensions", [])) + ["lugre"]
    extra.setdefault("base", prev)
    jf.models[name] = ModelFit(name, base.map, params, dict(base.metrics), method=base.method + "; sigma0, "
                               "sigma1 from the fit's LuGre (ramps and steps)", extra=extra)
    u = jf.units.get("tau", "N m")
    return {"cause": "presliding",
            "evidence": (f"on presliding ramps the static map misses the bristle compliance (held-out RMS "
                         f"{_fmt(rs)} {u}); LuGre with sigma0 = {_fmt(lug.params['sigma0'].value)} cuts it to "
                         f"{_fmt(rh)} {u} ({100 * gain:.0f} %)"),
            "statistic": {"test": "held-out ramps (leave one ramp out), as the fit chose LuGre"},
            "extension": "lugre", "model": name, "rms_before": rs, "rms_after": rh, "gain": gain,
            "heldout": {"split": "leave one presliding ramp out"}}
