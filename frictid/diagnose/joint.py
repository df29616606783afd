"""The diagnosis of one joint: the chain of findings from the base model, one extended model per finding.

:func:`diagnose_joint` starts from the base model (the best symmetric velocity-only static map, by the
fit's own choice rule: :func:`frictid.identify.select.base_model_name`), runs the chain of :mod:`.chain`
on the sliding samples of :mod:`.samples`, and turns each chosen cause into a model under ``models:`` with
its finding (:mod:`.evidence`, :mod:`.params`). ``presliding`` is judged on ramp and step segments by the
fit's LuGre comparison (leave one ramp out), since sliding samples say nothing about presliding.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..identify.select import BASE_MODELS, base_model_name, choose
from ..models import static as sm
from ..result import JointFit, ModelFit, ParamEstimate
from .causes import REPAIRS
from .chain import ALPHA, EXPLAINED_MIN, GAIN_MIN, Chain, Trial
from .evidence import evidence, fmt
from .model import (MAP_SLOTS, OUTSIDE_MODEL, Coef, Evaluator, Structure, Term, model_name, model_values,
                    term_name)
from .params import param_entries
from .samples import DiagLog, Samples, build_samples
from .structure import X_NOISE, torque_noise, unexplained

#: Folds of the held-out split.
N_FOLDS = 5


def _base_structure(jf: JointFit, name: str, S: Samples) -> Structure:
    """The base map with its shapes; for a rotary joint whose gravity the fit estimated, the gravity
    correction is re-estimated with it (the fit's offset and gravity trade off over a short range of
    angles; the offset is taken out and only enters through the ``offset`` cause)."""
    mf = jf.models[name]
    mapname = "polynomial" if name == "polynomial_ls" else mf.map
    cp, _ = sm.canonical_pair(mapname, {k: v for k, v in mf.values().items()})
    terms = ()
    px = jf.gravity.get("Px")
    if (S.axis_rotary and S.q is not None and px is not None and px.value is not None and np.ptp(S.q) > 0
            and px.source != "log metadata"):
        terms = (Term("gravity", "gravity", "additive", (), in_base=True),)
    return Structure(map=mapname, shapes=np.asarray(cp, float), terms=terms)


def bristle_length(jf: JointFit) -> float | None:
    """The bristle length [q] of the fit's LuGre, ``g(0) / sigma0`` (its static map's level at rest), where
    the fit identified sigma0 (from ramps, or from the stops and reversals); None otherwise. Within a few
    such lengths of travel after a reversal the friction's presliding state lags the motion
    (:func:`frictid.diagnose.signals.settled`)."""
    mf = jf.models.get("lugre")
    s0 = mf.params.get("sigma0") if mf is not None else None
    if s0 is None or s0.value is None or not s0.identifiable or not float(s0.value) > 0:
        return None
    try:
        cp, _ = sm.canonical_pair(mf.map, {k: v for k, v in mf.values().items()})
    except (KeyError, TypeError, ValueError):
        return None
    g0 = float(cp[0] + cp[1] + cp[4])   # the level and both Stribeck amplitudes at zero speed
    return g0 / float(s0.value) if g0 > 0 and math.isfinite(g0) else None


def _rigid(jf: JointFit) -> dict[str, float]:
    """The fit's inertia and gravity terms (0 when unknown)."""
    return {"J": jf.inertia.value if jf.inertia and jf.inertia.value is not None else 0.0,
            "Px": jf.gravity["Px"].value if "Px" in jf.gravity and jf.gravity["Px"].value is not None else 0.0,
            "Py": jf.gravity["Py"].value if "Py" in jf.gravity and jf.gravity["Py"].value is not None else 0.0}


def diagnose_joint(jf: JointFit, logs: list[DiagLog], n_folds: int = N_FOLDS) -> list[dict]:
    """Run the diagnosis on one joint; updates ``jf`` in place and returns its ``diagnosis`` list.

    jf : the :class:`frictid.result.JointFit` the fit produced (its models, inertia, gravity,
    offset). logs : the joint's logs as the fit prepared them (:class:`DiagLog`).
    Adds one model per finding to ``jf.models``, sets ``jf.selected`` to the end of the chain, and records
    the base, the rule and every candidate's numbers in ``jf.selection['diagnosis']``.
    """
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
    why: dict = {}
    S = build_samples(logs, n_folds, axis=jf.axis, J=max(J, 0.0), why=why, bristle=bristle_length(jf))
    if S is None:
        rec["skipped"] = f"{why.get('reason', 'too few sliding samples')}: the fit's own choice stands"
        jf.warnings.append(f"not diagnosed: {rec['skipped']}")
        jf.diagnosis = []
        return []
    chain, base = _chain(jf, S, base, rec)
    rec["rms_heldout_base"] = chain.rms_heldout
    rec["samples"] = int(S.n)
    rec["groups"] = int(S.n_groups)
    rec["friction_rms"] = chain.F_rms
    steps = chain.run()
    findings = _findings(jf, steps, S, base, n_folds, rec)
    _structure(jf, chain, S, rec)
    last = _last_model(rec, findings) or base
    pres = _presliding(jf, last)
    if pres is not None:
        findings.append(pres)
        last = pres["model"]
    jf.diagnosis = findings
    jf.selected = last
    return findings


def base_residuals(jf: JointFit, logs: list[DiagLog], base: str, n_folds: int = N_FOLDS):
    """The diagnosis' sliding samples of ``logs`` and its base ``base`` on them, as :func:`diagnose_joint`
    judges its first finding against it (the base map's amplitudes and gravity refitted without each fold,
    the fit's offset left in the friction): ``(li, k, r)``, per sample its log, its row in that log and the
    held-out residual ``F - prediction``; None without sliding samples. For a report that draws a finding on
    the samples and against the model its numbers were measured on (:mod:`frictid.report.content`)."""
    J = jf.inertia.value if jf.inertia is not None and jf.inertia.value is not None else 0.0
    S = build_samples(logs, n_folds, axis=jf.axis, J=max(J, 0.0), bristle=bristle_length(jf))
    if S is None:
        return None
    r = None
    if base in jf.models:
        chain = Chain(S, _base_structure(jf, base, S), J=jf.inertia.value if jf.inertia is not None else None)
        r = S.F - chain.pred
    return S.li, S.k, r


def _chain(jf: JointFit, S: Samples, base: str, rec: dict) -> tuple[Chain, str]:
    """The chain from the fit's base model, or, when the sliding samples cannot refit that base
    (:func:`_not_refitted`), from the next velocity-only model by the same choice rule; each refused base
    in ``rec['base_refused']`` with why."""
    J = jf.inertia.value if jf.inertia is not None and jf.inertia.value is not None else None
    left = [m for m in BASE_MODELS if not m.endswith("_asym") and m in jf.models
            and all(v is not None for v in jf.models[m].values().values())]
    while True:
        chain = Chain(S, _base_structure(jf, base, S), J=J)
        why = _not_refitted(chain)
        left = [m for m in left if m != base]
        nxt = choose(jf.models, left)[0] if why is not None and left else None
        if nxt is None:
            return chain, base
        rec.setdefault("base_refused", []).append({"model": base, "reason": why})
        base = rec["base"] = nxt


def _not_refitted(chain: Chain) -> str | None:
    """Why the chain's base, refitted on the sliding samples, is not the fit's map, or None. Refitted by least
    squares it can only fit them better than with the fit's own amplitudes, unless the refit must hold or drop
    amplitudes (a Stribeck term the samples do not reach, an amplitude over ten times the friction): a map
    whose terms cancel (two Stribeck exponentials of nearly one velocity and opposite amplitudes of 30 times
    the friction, foreign seeds 304005 and 304007) then loses its shape, and every candidate "explains" the
    friction the broken base leaves (a thermal factor 72 %). Refused when the refit leaves more than the fit's
    own amplitudes by an RMS worth a term (:data:`EXPLAINED_MIN` of the friction RMS)."""
    st, S = chain.st, chain.S
    own = Coef({sl: float(st.shapes[sl]) for sl in MAP_SLOTS[st.map]},
               {sl: float(st.shapes[sl]) for sl in MAP_SLOTS[st.map]},
               gamma={i: np.zeros(2 if t.ext == "gravity" else 1) for i, t in enumerate(st.terms)})
    r = S.F - Evaluator(st, chain.ctx).predict(own, chain.idx_all)
    r2 = r * r
    # on all samples, and on each fold's training set (whose refit predicts that fold in every held-out test)
    fits = [("", chain.coef, float(np.sqrt(np.mean(r2))))]
    fits += [(f" without fold {f + 1}", c, float(np.sqrt(np.mean(r2[tr]))))
             for f, (tr, _te, _res, _lev, c) in enumerate(chain.train_info)]
    for where, c, rms_own in fits:
        worse = np.sqrt(max(c.rms ** 2 - rms_own ** 2, 0.0))
        if worse >= EXPLAINED_MIN * chain.F_rms:
            return (f"{st.map} refitted on the sliding samples{where} leaves an RMS of {fmt(c.rms)} against "
                    f"{fmt(rms_own)} with the fit's own amplitudes (amplitudes held or dropped: "
                    f"{', '.join(str(k) for k in c.excluded) or 'held'}): its terms cancel, the refit loses its shape")
    return None


def _last_model(rec: dict, findings: list[dict]) -> str | None:
    """The model at the end of the chain: the last step's, whether it named a cause (a finding) or not (an
    ambiguous step keeps its term: the correction is measured on held-out data, only its name is not)."""
    last = None
    for step in rec.get("steps", []):
        last = step.get("model", last)
    return last if last is not None else (findings[-1]["model"] if findings else None)


def _findings(jf: JointFit, steps: list[dict], S: Samples, base: str, n_folds: int, rec: dict) -> list[dict]:
    """One finding (and one model in ``jf.models``) per step of the chain that chose a cause; every step's
    candidates are recorded in ``rec['steps']``."""
    rigid = _rigid(jf)
    units = {"F": jf.units.get("tau", "N m"), "q": jf.units.get("q", "rad"),
             "J": "kg m^2" if jf.axis == "rotary" else "kg"}
    heldout = {"folds": n_folds, "groups": int(S.n_groups), "samples": int(S.n),
               "split": "whole segments (long ones in chunks), interleaved in time; sliding samples only"}
    findings = []
    rec["steps"] = []
    for step in steps:
        rec["steps"].append({"tested": step["tested"], "candidates": step["m"],
                             "chosen": step["chosen"].ext if step.get("chosen") else None})
        if step.get("rejected"):   # degenerate extended models, never reported as findings
            rec["steps"][-1]["rejected"] = step["rejected"]
        tr: Trial | None = step.get("chosen")
        if tr is None:
            continue
        name = _named(rec["steps"][-1], step, tr)
        if tr.unresolved:   # it does not beat a competing explanation: its term and model kept, no cause named
            mf = _step_model(jf, step, tr, S, base, rigid)
            jf.models[mf.name] = mf
            rec["steps"][-1]["model"] = mf.name
            _ambiguous(jf, rec, tr, evidence(tr, S, step, units, rigid), mf.name, name)
            continue
        if tr.ext in OUTSIDE_MODEL:   # named with its numbers, never a friction model of the file
            text = evidence(tr, S, step, units, rigid)
            if tr.moving:   # a delay, judged on every moving sample too (chain.Chain.worth_it)
                text += (f"; on every moving sample (transients included) the shift cuts the held-out RMS from "
                         f"{fmt(tr.moving['rms_before'])} to {fmt(tr.moving['rms_after'])} {units['F']} "
                         f"(t = {tr.moving['t']:.1f}"
                         + (f"; a fraction of a period, judged against its mirror image about the velocity's own "
                            f"lag: {fmt(tr.moving['mirror'])}" if "mirror" in tr.moving else "") + ")")
                fast = tr.moving.get("at_speed")
                if fast:
                    text += (f", on the faster half of them from {fmt(fast['rms_before'])} to "
                             f"{fmt(fast['rms_after'])} (t = {fast['t']:.1f})")
            rec.setdefault("outside_model", []).append(
                {"cause": tr.cause, "evidence": text, "extension": tr.ext, "settings": {k: v for k, v in step["term"].settings.items() if k != "beta"},
                 "coefficients": [float(x) for x in np.atleast_1d(
                     step["coef"].gamma.get(len(step["structure"].terms) - 1, np.zeros(0)))],
                 "rms_before": tr.rms_before, "rms_after": tr.rms_after, "gain": tr.gain,
                 "statistic": {"t": tr.t, "p": tr.p, "groups": tr.groups, "threshold_p": ALPHA / max(step["m"], 1)},
                 **({"moving_samples": dict(tr.moving)} if tr.moving else {})})
            jf.warnings.append(f"{tr.cause} (outside the friction model): {text}")
            continue
        mf = _step_model(jf, step, tr, S, base, rigid)
        jf.models[mf.name] = mf
        rec["steps"][-1]["model"] = mf.name
        held = against_fit_offset(jf, S, base, tr, rec.get("friction_rms") or 0.0)
        if held is not None and held["worse"]:   # no finding: it predicts worse than the fit's own offset
            rec.setdefault("withdrawn", []).append(dict(held, cause=tr.cause, extension=name, model=mf.name,
                                                        rms_before=tr.rms_before, rms_after=tr.rms_after))
            jf.warnings.append(f"{name} not named: {held['why']}")
            continue
        text = evidence(tr, S, step, units, rigid)
        if tr.cause in REPAIRS:
            _repair(jf, rec, tr, text, mf.name, name)
        findings.append({
            "cause": tr.cause if name == tr.ext else name,
            "kind": "repair" if tr.cause in REPAIRS else "effect",
            "evidence": text,
            "statistic": {"test": "one-sided paired t over held-out groups of sum(r_before^2 - r_after^2)",
                          "t": tr.t, "p": tr.p, "groups": tr.groups,
                          "threshold_p": ALPHA / max(step["m"], 1)},
            "extension": name,
            "model": mf.name,
            "rms_before": tr.rms_before,
            "rms_after": tr.rms_after,
            "gain": tr.gain,
            "heldout": heldout,
            **({"fit_offset": {k: held[k] for k in ("fit_offset", "rms_heldout_fit_offset")}} if held else {}),
        })
    return findings


def against_fit_offset(jf: JointFit, S: Samples, base: str, tr: Trial, F_rms: float) -> dict | None:
    """An ``offset`` finding judged against the model before it as the fit runs it. The diagnosis leaves the
    fit's offset in the friction it judges (:func:`frictid.diagnose.check.diagnose_fit`), so its base (an odd
    map) holds none, and against that base every offset the fit estimated is a finding; but the fit's own
    model carries its offset (session 25: Franka joint 3's `offset` of -17.6 N m re-estimated the fit's
    -12.3, 7.49 -> 4.71 N m held out against the base without it, while its stored model replayed at 5.51
    N m on the moving samples against 4.78 for the fit's map with its offset). The base with the fit's offset
    held (refitted without each fold on ``F - offset``, the same samples and folds) is the model before it;
    the finding is no finding (issue 20: "a finding whose extended model predicts worse than the model before
    it is no finding") when its held-out RMS exceeds that one's by an RMS worth a term (:data:`EXPLAINED_MIN`
    of the friction RMS ``F_rms``, the bar a term must pass to be named). None for another extension, or
    without an estimated offset of the fit (an offset from the log's metadata is no estimate)."""
    off = jf.offset
    if (tr.ext != "offset" or off is None or off.value is None or not off.value or off.source == "log metadata"
            or base not in jf.models):
        return None
    S2 = dataclasses.replace(S, F=S.F - off.value)
    rf = float(Chain(S2, _base_structure(jf, base, S2), J=jf.inertia.value if jf.inertia is not None else None)
               .rms_heldout)
    worse = float(np.sqrt(max(tr.rms_after ** 2 - rf ** 2, 0.0)))
    return {"fit_offset": float(off.value), "rms_heldout_fit_offset": rf, "worse": bool(worse >= EXPLAINED_MIN * F_rms),
            "why": (f"its offset re-estimates the fit's own ({fmt(off.value)}) and predicts the held-out samples "
                    f"worse than the base with the fit's offset ({fmt(tr.rms_after)} against {fmt(rf)}, worse by "
                    f"an RMS of {fmt(worse)}, at least {100 * EXPLAINED_MIN:.0f} % of the friction RMS)")}


def _named(entry: dict, step: dict, tr: Trial) -> str:
    """The name the chosen extension of a chain step is reported by (:func:`frictid.diagnose.model.term_name`:
    the ``stribeck`` candidate by the sign of its fitted amplitude, ``low_speed_rise`` where the friction at
    low speed lies below the sliding level); the step's record (``entry``: ``chosen`` and its ``tested``
    line) says the same."""
    name = term_name(step["structure"], step["coef"], tr.ext)
    if name != tr.ext:
        entry["chosen"] = name
        entry["tested"] = [dict(t, extension=name, candidate=tr.ext) if t.get("extension") == tr.ext else t
                           for t in entry["tested"]]
    return name


def _repair(jf: JointFit, rec: dict, tr: Trial, text: str, model: str, name: str | None = None) -> None:
    """A step that repairs the fit's own estimate (:data:`frictid.diagnose.causes.REPAIRS`: its inertia,
    gravity or base map): listed in ``rec['repairs']`` and the warnings apart from the causes found in the
    plant. Its model and finding stay (``kind: repair``), so the chain's later models and the fit's check
    are unchanged; what it says is that the fit's base should have carried the term."""
    cause, ext = (tr.cause, tr.ext) if name in (None, tr.ext) else (name, name)
    rec.setdefault("repairs", []).append(
        {"repair": cause, "extension": ext, "model": model, "evidence": text, "rms_before": tr.rms_before,
         "rms_after": tr.rms_after, "heldout_gain": tr.gain})
    jf.warnings.append(f"repair of the fit's {cause} (not a cause found in the plant): {text}")


def _ambiguous(jf: JointFit, rec: dict, tr: Trial, text: str, model: str, name: str | None = None) -> None:
    """A step whose best candidate does not beat a competing explanation of another cause on held-out data:
    recorded in ``rec['ambiguous']`` and the warnings with the causes the data cannot tell apart; no cause
    is named. Its term stays in the chain's model (the next steps search a clean residual) and its model in
    ``jf.models``: the correction is measured on held-out data and the model at the end of the chain carries
    it (an offset and a per-direction level make the same prediction on sliding samples); what is withheld
    is the name."""
    ext = tr.ext if name is None else name
    causes = [tr.cause if ext == tr.ext else ext] + list(tr.unresolved)
    rec.setdefault("ambiguous", []).append(
        {"causes": causes, "extension": ext, "model": model, "evidence": text, "rms_before": tr.rms_before,
         "rms_after": tr.rms_after, "heldout_gain": tr.gain})
    jf.warnings.append(f"ambiguous: {' or '.join(causes)} explain the residual about as well on held-out data "
                       f"(held-out RMS {fmt(tr.rms_before)} -> {fmt(tr.rms_after)} with {ext}, which does not "
                       f"beat the others significantly): the data cannot tell them apart, no cause is named; "
                       f"the model {model} carries the correction")


def _step_model(jf: JointFit, step: dict, tr: Trial, S: Samples, base: str, rigid: dict) -> ModelFit:
    """The extended model of a chain step: its values, and standard errors from the fold refits."""
    st = step["structure"]
    mapname, vals = model_values(st, step["coef"], S, rigid)
    fold_vals = [model_values(step["before"].plus(t), c, S, rigid)[1]
                 for t, c in zip(tr.fold_terms, tr.fold_coefs)]
    params = param_entries(mapname, vals, fold_vals, jf.axis)
    extra = {"base": base, "extensions": [term_name(st, step["coef"], t.ext) for t in st.terms
                                          if not t.in_base and t.ext not in OUTSIDE_MODEL]}
    th = next((t for t in st.terms if t.ext in ("thermal4", "thermal6")), None)
    if th is not None:
        extra["temperature"] = th.settings.get("source", "heat_balance")
    return ModelFit(model_name(st, step["coef"]), mapname, params,
                    {"rms": step["coef"].rms, "rms_heldout": tr.rms_after, "n": int(S.n),
                     "k": int(sum(1 for p in params.values() if not p.fixed))},
                    method="diagnosis: base amplitudes and extension terms by least squares (Gauss-Newton) on "
                           "the sliding samples (shapes of the base map held)",
                    extra=extra)


def _structure(jf: JointFit, chain: Chain, S: Samples, rec: dict) -> None:
    """The residual structure tests after the chain's last model (:mod:`.structure`); a structure worth
    stating goes to ``rec['unexplained']`` and the joint's warnings."""
    units = {"F": jf.units.get("tau", "N m"), "q": jf.units.get("q", "rad"), "w": jf.units.get("qd", "rad/s")}
    name = model_name(chain.st, chain.coef)
    # the fit's inertia and its error, also where it is flagged (its error then spans what flagged it: a
    # low-pass filter's change, foreign seed 340025: 10.2 +- 0.88 for a change to 9.36)
    inertia = jf.inertia if jf.inertia is not None and jf.inertia.value is not None else None
    J, J_err = (None, None) if inertia is None or any(t.ext == "inertia" for t in chain.st.terms) else (
        inertia.value, inertia.stderr)
    tests, text = unexplained(S, S.F - chain.pred, chain.F_rms, units, f"the diagnosis' model {name}", J, J_err)
    rec["structure"] = {"noise": torque_noise(S), "model": name,
                        "rule": ("held-out bin means of the residual against each variable (training folds "
                                 f"only), one-sided paired t over held-out groups, alpha {ALPHA} split over the "
                                 f"variables; stated when the explained RMS is at least {100 * EXPLAINED_MIN:.0f} % "
                                 f"of the friction RMS, and against the velocity, the acceleration, the measured "
                                 f"torque, its rate and the segments' wander (which carry the torque's noise or the "
                                 f"map's misfit) also {X_NOISE:g}x the noise of the friction torque"),
                        "tests": tests}
    rec["unexplained"] = [text] if text else []
    if text:
        jf.warnings.append(f"unexplained structure: {text}")


def _presliding(jf: JointFit, prev: str) -> dict | None:
    """A presliding finding from the fit's LuGre comparison on held-out ramps, with its model."""
    lug = jf.models.get("lugre")
    if lug is None or not str(jf.selection.get("lugre", "")).startswith("chosen"):
        return None
    rs, rh = lug.metrics.get("rms_presliding_static"), lug.metrics.get("rms_presliding_heldout")
    ramps = bool(rs) and rh is not None
    if not ramps:  # sigma0 from the stops and reversals of the moving samples (identify/reversals.py)
        rs, rh = lug.metrics.get("rms_heldout_static_reversals"), lug.metrics.get("rms_heldout_reversals")
    if not rs or rh is None or not lug.params["sigma0"].identifiable:
        return None
    gain = 1.0 - rh / rs
    if gain < GAIN_MIN:
        return None
    base = jf.models[prev]
    params = {k: ParamEstimate(**vars(p)) for k, p in base.params.items()}
    # the bristles, and (from the reversals) the rigid terms fitted with them where the chain has none and the
    # low-speed term chosen under them
    for k in ("sigma0", "sigma1", "sigma0_neg", "sigma1_neg") + (() if ramps else ("J", "Px", "Py", "tau_offset",
                                                                                   "str_amp", "str_vs", "str_delta")):
        if k in lug.params and (k.startswith("sigma") or k not in params):
            params[k] = ParamEstimate(**vars(lug.params[k]))
    if (not ramps and "tau_offset" in lug.params and "tau_offset" not in base.params and jf.offset is not None
            and (base.extra or {}).get("extensions") is None):
        # LuGre's is the change of the joint's offset; a chained model carries the whole offset as tau_offset.
        # Only on a fit's own base, which runs with the joint's offset: a diagnosis model's terms were fitted
        # on the friction with that offset left in, so they hold it already (EMPS: asym's per-sign levels;
        # adding it again put the replay of coulomb_viscous+asym+lugre at 3.6 N against 1.9 without it)
        params["tau_offset"].value += jf.offset.value or 0.0
    name = prev + "+lugre"
    extra = dict(base.extra)
    extra["extensions"] = list(extra.get("extensions", [])) + ["lugre"]
    extra.setdefault("base", prev)
    where = ("ramps and steps" if ramps else "stops and reversals of the moving samples, with the rigid "
             "terms fitted again")
    jf.models[name] = ModelFit(name, base.map, params, dict(base.metrics), method=base.method + "; sigma0, "
                               f"sigma1 from the fit's LuGre ({where})", extra=extra)
    u = jf.units.get("tau", "N m")
    data = "presliding ramps" if ramps else "the moving samples including the stops"
    return {"cause": "presliding",
            "evidence": (f"on {data} the static map misses the bristle compliance (held-out RMS "
                         f"{fmt(rs)} {u}); LuGre with sigma0 = {fmt(lug.params['sigma0'].value)}"
                         + (f" and a low-speed term under the bristles ({fmt(lug.params['str_amp'].value)} {u})"
                            if "str_amp" in lug.params else "") + " cuts it to "
                         f"{fmt(rh)} {u} ({100 * gain:.0f} %)"),
            "statistic": {"test": ("held-out ramps (leave one ramp out)" if ramps else "held-out time blocks")
                          + ", as the fit chose LuGre"},
            "extension": "lugre", "model": name, "rms_before": rs, "rms_after": rh, "gain": gain,
            "heldout": {"split": "leave one presliding ramp out" if ramps else "time blocks of the moving samples"}}
