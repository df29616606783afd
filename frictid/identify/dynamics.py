"""Step 5 of a joint's fit: LuGre on top of the chosen static map.

sigma0 from the presliding ramps (torque against displacement), sigma1 from the steps (simulation error)
or the critical-damping rule (:mod:`.presliding`). LuGre replaces its map as the chosen model only when its
dynamic parameters are identifiable and it predicts held-out presliding ramps (leave one ramp out) better
than the map alone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from frictid.models import static as sm
from frictid.models.params import unit_of
from frictid.result import ModelFit, ParamEstimate

from . import presliding as pre
from .prepare import JointData
from .static import predict
from .select import selectable


@dataclass
class Presliding:
    """A joint's presliding data: per ramp (position [q], friction torque [F]) with its time span and
    velocity, per step (t, q, torque less gravity, segment, source index), and the encoder resolution [q]."""

    ramps: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    ramp_t: list[list] = field(default_factory=list)
    ramp_w: list[np.ndarray] = field(default_factory=list)
    steps: list[tuple] = field(default_factory=list)
    resolution: float = 0.0
    creep: list[dict] = field(default_factory=list)  # per ramp with a held load: its drift (see _creep)


def _scalar_map(c_pos, c_neg):
    """Scalar level g(w) and viscous f(w) callables of canonical vectors (for the step simulation)."""
    def level(w):
        c = c_pos if w >= 0 else c_neg
        v = abs(w)
        out = c[0]
        if c[1] != 0.0:
            out += c[1] * math.exp(-((v / c[2]) ** c[3]))
        if c[4] != 0.0:
            out += c[4] * (1.0 - math.exp(-v / c[5]))
        return out

    def viscous(w):
        c = c_pos if w >= 0 else c_neg
        return c[6] * w + c[7] * w * abs(w) + c[8] * w**3
    return level, viscous


def static_params(mf: ModelFit) -> dict[str, ParamEstimate]:
    """Copies of a model's parameter estimates."""
    return {k: ParamEstimate(**vars(p)) for k, p in mf.params.items()}


#: Samples before a step segment that estimate the level it starts from.
PRE_SAMPLES = 10


def _pre_level(p, i0: int) -> float | None:
    """The torque less gravity [F] a step starts from: the median of the PRE_SAMPLES samples up to and
    including ``i0`` when they hold one level (none further than 4 noise deviations, the noise from their
    differences, from it), else None (the segment's first sample stands alone)."""
    j0 = max(i0 + 1 - PRE_SAMPLES, 0)
    v = np.asarray(p.log.tau[j0:i0 + 1] - p.G[j0:i0 + 1], dtype=float)
    if v.size < 3 or not np.all(np.isfinite(v)):
        return None
    med = float(np.median(v))
    noise = pre.step_noise(v)
    return med if float(np.max(np.abs(v - med))) <= 4.0 * noise else None


def presliding_data(jd: JointData) -> Presliding:
    """The ramps and steps of a joint's logs (at least 10 samples each, logs with a position only)."""
    out = Presliding()
    for p in jd.preps:
        if p.log.q is None:
            continue
        for s in p.segments:
            if s.kind == "ramp_presliding" and s.n >= 10:
                out.ramps.append((np.asarray(p.log.q[s.i0:s.i1], float), p.F[s.i0:s.i1]))
                out.ramp_t.append([float(s.t_start), float(s.t_end), p.index])
                out.ramp_w.append(p.w[s.i0:s.i1])
            elif s.kind == "step" and s.n >= 10:
                i0 = max(s.i0 - 1, 0)  # one sample before: the rest state the step starts from
                u = pre.step_input(p.log.tau[i0:s.i1] - p.G[i0:s.i1], _pre_level(p, i0))
                out.steps.append((p.log.t[i0:s.i1], np.asarray(p.log.q[i0:s.i1], float), u, s, p.index))
    res_meta = [p.log.meta.get("encoder_resolution") for p in jd.preps if p.log.meta]
    res_meta = [float(r) for r in res_meta if r]
    qcat = (np.concatenate([q for q, _ in out.ramps] + [st[1] for st in out.steps]) if (out.ramps or out.steps)
            else np.zeros(0))
    out.resolution = res_meta[0] if res_meta else (pre.encoder_resolution(qcat) if qcat.size else 0.0)
    _without_creep(out, jd)
    return out


#: A hold counts when its torque stays within this many noise levels of the ramp's last torque ...
HOLD_BAND = 4.0
#: ... for at least this many samples; its drift is creep when it exceeds this many encoder steps and
#: CREEP_Z standard errors of its rate (consecutive samples are correlated: 5, not 2).
HOLD_MIN_SAMPLES = 20
CREEP_COUNTS = 3.0
#: A creep slower than this many encoder steps over a hold may leave the count where it is (quantisation).
UNSEEN_COUNTS = 1.0
CREEP_Z = 5.0
#: The creep runs at the held load's rate; below it, whether it runs at all is not known: this share of the
#: ramp's creep is the uncertainty of its profile.
CREEP_PROFILE = 0.5
#: A creep-corrected ramp is kept when the uncertainty of its correction is below this share of what is left.
CREEP_SHARE = 0.25


def _drift_rate(t: np.ndarray, q: np.ndarray, dF: np.ndarray) -> tuple[float, float]:
    """The drift of the position at constant load [q/s] and its standard error: q against time and the
    load's deviation together (within the hold's band the load still moves a little, and the bristles
    follow it; that is not drift)."""
    if t.size < 6:
        return 0.0, math.inf
    X = np.column_stack([np.ones(t.size), t - t[0], dF])
    coef, *_ = np.linalg.lstsq(X, np.asarray(q, float), rcond=None)
    r = np.asarray(q, float) - X @ coef
    try:
        cov = float(r @ r) / max(t.size - 3, 1) * np.linalg.inv(X.T @ X)
    except np.linalg.LinAlgError:
        return float(coef[1]), math.inf
    return float(coef[1]), math.sqrt(max(float(cov[1, 1]), 0.0))


def _hold_drift(p, s) -> dict | None:
    """The drift of the position while the load a ramp reached is held (the samples around the ramp's end
    whose friction torque stays within HOLD_BAND noise levels of its last value, the segmenter's ramp end
    or the rest after it): rate [q/s], duration [s], displacement [q]; None without such a hold."""
    F = p.F
    seg = F[s.i0:s.i1]
    if seg.size < 10:
        return None
    # the noise of the friction torque: the scatter about the ramp's line in time (a torque ramp is linear;
    # sample differences would miss the correlated noise the acceleration estimate brings in through J a)
    tt = p.log.t[s.i0:s.i1] - p.log.t[s.i0]
    r = seg - np.polyval(np.polyfit(tt, seg, 1), tt)
    noise = 1.4826 * float(np.median(np.abs(r - np.median(r)))) + 1e-300
    # the held load is the ramp's larger end: after a loading ramp, before an unloading one
    end = s.i1 - 1 if abs(np.median(seg[-5:])) >= abs(np.median(seg[:5])) else s.i0
    F_end = float(np.median(F[max(s.i0, end - 4):end + 5]))
    band = HOLD_BAND * noise
    a = b = end
    while a > 0 and abs(F[a - 1] - F_end) < band:
        a -= 1
    while b + 1 < p.log.n and abs(F[b + 1] - F_end) < band:
        b += 1
    if b - a + 1 < HOLD_MIN_SAMPLES or not np.all(np.isfinite(p.log.q[a:b + 1])):
        return None
    t = p.log.t[a:b + 1]
    rate, se_rate = _drift_rate(t, p.log.q[a:b + 1], F[a:b + 1] - F_end)
    mid = t.size // 2
    late, se_late = _drift_rate(t[mid:], p.log.q[a + mid:b + 1], F[a + mid:b + 1] - F_end)
    # creep runs on while the load is held; a drift that dies out within the hold is the bristles settling
    # (LuGre drifts towards its steady deflection under a held load), and the ramp fit follows that itself
    settles = abs(late) <= CREEP_Z * se_late or np.sign(late) != np.sign(rate)
    # what the hold shows in the load's direction, significant or not: the late half's rate where the drift
    # settles (creep keeps its rate to the end of the hold), else the whole hold's
    shown = max(0.0, float(np.sign(F_end)) * (late if settles else rate))
    if abs(rate) <= CREEP_Z * se_rate or settles:
        rate = 0.0
    return {"rate": rate, "rate_se": CREEP_Z * se_rate, "loading": bool(end == s.i1 - 1), "duration": float(t[-1] - t[0]), "drift": rate * float(t[-1] - t[0]),
            "load_sign": float(np.sign(F_end)), "shown": shown if np.isfinite(shown) else 0.0}


def _without_creep(out: Presliding, jd: JointData) -> None:
    """Creep (issue 19: the joint drifts while the load is held, the displacement grows at constant torque)
    is not bristle deflection. Per ramp, the drift rate of its held load, when it moves the joint by more
    than CREEP_COUNTS encoder steps in the load's direction, is taken out of the ramp's displacement
    (``q - rate (t - t0)``: the creep of a loaded joint runs at about that rate through the ramp); a ramp
    whose correction is uncertain by more than CREEP_SHARE of what is left (its rate's error times the
    ramp's duration, CREEP_PROFILE of the creep for its unknown profile at lower loads, an encoder step)
    is dropped; the kept ones' relative uncertainty enters sigma0's standard error (:func:`_creep_inflated`). ``out.creep`` records each."""
    keep = []
    k = 0
    res = max(out.resolution, 1e-300)
    resolved = any(np.ptp(q) >= pre.MIN_COUNTS * res for q, _ in out.ramps)
    for p in jd.preps:
        if p.log.q is None:
            continue
        for s in p.segments:
            if not (s.kind == "ramp_presliding" and s.n >= 10):
                continue
            q, F = out.ramps[k]
            k += 1
            h = _hold_drift(p, s)
            if h is None:
                keep.append(True)
                continue
            t = p.log.t[s.i0:s.i1]
            if abs(h["drift"]) < CREEP_COUNTS * res or np.sign(h["rate"]) != h["load_sign"]:
                # ramps the encoder does not resolve (none spans presliding.MIN_COUNTS steps) are left
                # to the encoder's rule, which says why sigma0 is not identifiable
                keep.append(_unseen_creep(h, q, t, res, out) if resolved else True)
                continue
            if not h["loading"]:  # unloading: the creep decays with the load, no constant rate to take out
                out.creep.append(dict(h, ramp_creep=float(abs(h["rate"]) * (t[-1] - t[0])), ramp_bristle=0.0,
                                      correction_se=math.inf))
                keep.append(False)
                continue
            creep = h["rate"] * (t - t[0])
            qc = q - creep
            h.update(ramp_creep=float(abs(creep[-1])), ramp_bristle=float(np.ptp(qc)),
                     correction_se=float(h["rate_se"] * (t[-1] - t[0]) + CREEP_PROFILE * abs(creep[-1])) + res)
            out.creep.append(h)
            if h["correction_se"] > CREEP_SHARE * h["ramp_bristle"]:
                h["kept"] = False
                keep.append(False)
                continue
            h["kept"] = True
            out.ramps[k - 1] = (qc, F)
            keep.append(True)
    out.ramps = [r for r, kp in zip(out.ramps, keep) if kp]
    out.ramp_t = [r for r, kp in zip(out.ramp_t, keep) if kp]
    out.ramp_w = [r for r, kp in zip(out.ramp_w, keep) if kp]


def _unseen_creep(h: dict, q: np.ndarray, t: np.ndarray, res: float, out: Presliding) -> bool:
    """Whether a ramp whose hold shows no creep is kept. Creep is displacement that keeps growing at
    constant load; the hold rules out a creep faster than what it shows plus what it cannot resolve: the
    drift rate it shows in the load's direction (``shown``, significant or not) and the larger of its
    statistical limit (CREEP_Z standard errors of the rate) and one encoder step over the hold (a creep
    slower than that may leave the count unchanged; a faster one turns it over at least once, and that is
    in ``shown``). A creep below that limit, running through the ramp, is displacement the bristles did
    not make. Its uncertainty (CREEP_PROFILE of the limit over the ramp's duration: it may run at any rate
    up to the limit) is recorded like a creep correction's; above CREEP_SHARE of the ramp's displacement
    the ramp is dropped (a hold too short or too coarse to tell a creeping joint from a still one), below it
    enters sigma0's error (:func:`_creep_inflated`). CREEP_COUNTS is the rule for *claiming* a creep (a
    drift must exceed it), not the size of one a still hold may hide."""
    step = UNSEEN_COUNTS * res / max(h["duration"], 1e-300)
    limit = max(h["rate_se"], h.get("shown", 0.0) + step)
    unseen = CREEP_PROFILE * limit * float(t[-1] - t[0])
    h.update(rate=0.0, unseen_limit=float(limit), ramp_creep=0.0, ramp_bristle=float(np.ptp(q)),
             correction_se=float(unseen))
    h["kept"] = bool(np.isfinite(unseen) and unseen <= CREEP_SHARE * h["ramp_bristle"])
    out.creep.append(h)
    return h["kept"]


def _creep_inflated(s0: pre.DynamicEstimate, pd: Presliding) -> pre.DynamicEstimate:
    """sigma0's standard error with the uncertainty of the creep taken out of its ramps (relative: the
    correction's error over the bristle displacement left, the largest of the kept ramps)."""
    rel = _creep_share(pd)
    if not rel or s0.value is None or s0.stderr is None:
        return s0
    se = math.hypot(s0.stderr, s0.value * rel)
    reason = s0.reason or ("" if se <= s0.value else f"relative error {100 * se / s0.value:.0f} % (above 100 %)")
    return pre.DynamicEstimate(s0.value, se, not reason, reason, s0.source + "; creep taken out of the ramps",
                               s0.n_segments, s0.rms, s0.details)


def fit_lugre(jd: JointData, selected: str | None) -> None:
    """LuGre on the static map ``selected`` (the fit's choice): adds the ``lugre`` model and may make it the
    chosen one (see the module docstring)."""
    jf = jd.jf
    base_name = selected if selected in jf.models else None
    if base_name is None:
        jf.not_identified.append({"what": "lugre", "reason": "no static map to build on"})
        return
    base = jf.models[base_name]
    vals = base.values()
    if any(v is None for v in vals.values()):
        jf.not_identified.append({"what": "lugre", "reason": f"{base_name} has unknown parameters"})
        return
    c_pos, c_neg = sm.canonical_pair(base.map, vals)
    level, _ = _scalar_map(c_pos, c_neg)
    pd = presliding_data(jd)
    g_map = [abs(level(1e-12 if np.mean(F) >= 0 else -1e-12)) for _, F in pd.ramps]
    s0, sides, g_of = _sigma0_estimates(pd, g_map)
    if not pd.ramps and not pd.creep and not s0.identifiable:  # ramps dropped for creep keep their verdict
        _lugre_from_reversals(jd, base, base_name, c_pos, c_neg, s0)
        return
    jd.used.pop("step", None)
    est = _sigma1_estimates(jd, pd, s0, sides, c_pos, c_neg)
    damped = _without_damping(pd, est, g_of, c_pos, c_neg)
    measured = pd.ramps
    if damped is not None:  # the ramps' torque less the damping the first pass's sigma1 gives: once more
        first = s0.value
        pd = damped
        s0, sides, g_of = _sigma0_estimates(pd, g_map)
        jd.used.pop("step", None)
        est = _sigma1_estimates(jd, pd, s0, sides, c_pos, c_neg)
        _damping_share(est, first)
    s0, s1 = est[""]
    if pd.ramps:
        jd.used["ramp_presliding"] = pd.ramp_t
    params = static_params(base)
    for sfx, (e0, e1) in est.items():
        params["sigma0" + sfx] = ParamEstimate("sigma0" + sfx, e0.value, e0.stderr, unit_of("K", jd.axis),
                                               e0.identifiable, e0.reason, source=e0.source)
        params["sigma1" + sfx] = ParamEstimate("sigma1" + sfx, e1.value, e1.stderr, unit_of("D", jd.axis),
                                               e1.identifiable, e1.reason, source=e1.source)
    met = dict(base.metrics)
    met["k"] = int((met.get("k") or 0) + 2 * len(est))
    if s0.identifiable and pd.ramps:
        s0_of = [est["_neg" if sides is not None and np.mean(F) < 0 else ""][0].value for _, F in pd.ramps]
        met.update(_presliding_rms(pd, g_of, s0_of, base_name, vals, per_sign=sides is not None, measured=measured))
    notes = [f"static part: {base_name}"]
    if s0.details and s0.details.get("g_ramps"):
        notes.append("bristle limit from the ramps' curvature: " + ", ".join(
            f"{g:.4g}" for g in sorted(set(s0.details["g_ramps"]))) + " (the map's level at zero speed: "
            + ", ".join(f"{g:.4g}" for g in sorted(set(g_map))) + ")")
    mf = _lugre_fit(base, base_name, params, met, notes,
                    "static map on plateaus; sigma0 from ramps (torque against displacement); sigma1 "
                    + ("from steps (simulation error)" if "steps" in s1.source else
                       "by the critical-damping rule" if "rule" in s1.source else "not identified"))
    jf.models["lugre"] = mf
    for n in [p + sfx for sfx in est for p in ("sigma0", "sigma1")]:
        if not params[n].identifiable:
            jf.not_identified.append({"what": f"lugre.{n}", "reason": params[n].reason})
    _lugre_choice(jd, mf, base_name)


def _lugre_fit(base: ModelFit, base_name: str, params: dict, metrics: dict, notes: list[str],
               method: str) -> ModelFit:
    """The ``lugre`` model on the chosen static map ``base_name`` (``polynomial_ls`` is a polynomial map)."""
    return ModelFit("lugre", base.map if base_name != "polynomial_ls" else "polynomial", params, metrics,
                    method=method, notes=notes, extra={"static_model": base_name})


def _sigma0_estimates(pd: Presliding, g_map: list[float]):
    """sigma0 from the ramps (pooled, with the bristle limits fitted on them, their spread and creep in its
    error) and per sign when the signs differ (else None); returns them with the limits used per ramp."""
    s0 = pre.fit_sigma0(pd.ramps, g_map, pd.resolution, free_limit=True)
    g_of = list((s0.details or {}).get("g_ramps") or g_map)
    if not pd.ramps and pd.creep and all("unseen_limit" in h for h in pd.creep):
        c = min(pd.creep, key=lambda h: h["unseen_limit"])
        s0 = pre.DynamicEstimate(None, None, False, (
            f"the holds at the ramps' loads cannot rule out creep: a drift below {c['unseen_limit']:.3g} per s "
            f"(their detection limit, from their length and the encoder step) would move a ramp by "
            f"{2 * c['correction_se']:.3g}, more than {100 * CREEP_SHARE:.0f} % of its displacement "
            f"({c['ramp_bristle']:.3g})"), "ramps", len(pd.creep))
    elif not pd.ramps and pd.creep:
        c = max(pd.creep, key=lambda h: abs(h["rate"]))
        s0 = pre.DynamicEstimate(None, None, False, (
            f"the joint creeps under load: it drifts at {abs(c['rate']):.3g} per s while the load is held "
            f"({c['ramp_creep']:.3g} over a ramp): the ramps' displacement is creep, not presliding deflection, "
            "and what the creep leaves is not known well enough to carry sigma0"), "ramps", len(pd.creep))
    s0 = _creep_inflated(_spread_floor(s0, pd, g_of), pd)
    return s0, _per_sign(pd, g_of, s0), g_of


def _sigma1_estimates(jd: JointData, pd: Presliding, s0, sides, c_pos, c_neg) -> dict:
    """Per sigma0 entry ("" and, per sign, "_neg"): (sigma0, sigma1)."""
    if sides is None:
        return {"": (s0, _sigma1(jd, pd, s0, c_pos, c_neg))}
    return {sfx: (e, _sigma1(jd, pd, e, c_pos, c_neg, sign)) for sfx, sign, e in zip(("", "_neg"), (1, -1), sides)}


def _without_damping(pd: Presliding, est: dict, g_of: list[float], c_pos, c_neg) -> Presliding | None:
    """The ramps with LuGre's damping torque taken out, or None when a sigma1 is not known. The friction is
    ``sigma0 z + sigma1 dz/dt + sigma2 w``; the ramp fit reads ``sigma0 z`` only, and the damping torque
    grows along a ramp as the bristles give (``dz/dt = w (1 - sgn(w) z / zmax)``, w the ramp's creeping
    speed, rising as the load nears the limit), which the fit took for stiffness (foreign card: sigma0 1.8 %
    high with an error of 0.7 %; with the damping of its own sigma1 taken out, 0.2 % high)."""
    if not pd.ramps:
        return None
    ramps = []
    for (q, F), w, g in zip(pd.ramps, pd.ramp_w, g_of):
        s1 = est["_neg" if len(est) > 1 and np.mean(F) < 0 else ""][1]
        if not s1.identifiable or s1.value is None or not g > 0:
            return None
        w = np.asarray(w, dtype=float)
        sig2 = np.where(w >= 0, c_pos[6], c_neg[6])
        dz = w * np.clip(1.0 - np.sign(w) * F / g, 0.0, 2.0)
        ramps.append((q, F - s1.value * dz - sig2 * w))
    return replace(pd, ramps=ramps)


def _damping_share(est: dict, first: float | None) -> None:
    """sigma0 (pooled) with the damping correction's uncertainty in its error: the correction's size (the
    change from the first pass) times sigma1's relative error (added in quadrature)."""
    s0, s1 = est[""]
    if first is None or s0.value is None or s0.stderr is None or not s1.value or s1.stderr is None:
        return
    s0.stderr = math.hypot(s0.stderr, abs(s0.value - first) * s1.stderr / abs(s1.value))


#: Combined standard errors by which the two signs' sigma0 must differ for the fit to keep one per sign.
PER_SIGN_Z = 3.0


def _ramp_spread(ramps: list, g_of: list[float], resolution: float) -> float:
    """The standard error of a sign's sigma0 [F/q] from the ramp-to-ramp spread: the scatter of the ramps'
    own sigma0 (each ramp fitted alone) over the root of their number; 0 with fewer than two that identify
    it. Ramps of one sign that scatter more than the fit's residuals say (a drift between ramps, bristles
    not quite at rest) make the fit's own error too small."""
    vals = []
    for r, g in zip(ramps, g_of):
        e = pre.fit_sigma0([r], [g], resolution)
        if e.identifiable:
            vals.append(e.value)
    return float(np.std(vals, ddof=1) / math.sqrt(len(vals))) if len(vals) >= 2 else 0.0


def _spread_floor(s0: pre.DynamicEstimate, pd: Presliding, g_of: list[float]) -> pre.DynamicEstimate:
    """The pooled sigma0 with a standard error no smaller than its ramp-to-ramp spread (:func:`_ramp_spread`
    over every ramp), as each sign's is in :func:`_per_sign`: the fit's error counts the residuals along
    the ramps, not what differs from one ramp to the next (a drift between ramps, bristles not quite at
    rest: the reason :func:`_per_sign` floors each sign's error so, which held only for per-sign joints)."""
    if not s0.identifiable or s0.value is None or s0.stderr is None or len(pd.ramps) < 2:
        return s0
    spread = _ramp_spread(pd.ramps, g_of, pd.resolution)
    if spread <= s0.stderr:
        return s0
    reason = "" if spread <= s0.value else f"relative error {100 * spread / s0.value:.0f} % (above 100 %)"
    return pre.DynamicEstimate(s0.value, spread, not reason, reason, s0.source, s0.n_segments, s0.rms,
                               dict(s0.details or {}, fit_se=s0.stderr, ramp_spread_se=spread))


def _creep_share(pd: Presliding) -> float:
    """The largest relative uncertainty the creep leaves in a kept ramp (what :func:`_creep_inflated` adds)."""
    rel = [h["correction_se"] / h["ramp_bristle"] for h in pd.creep if h.get("kept") and h["ramp_bristle"] > 0]
    return max(rel, default=0.0)


def _per_sign(pd: Presliding, g_of: list[float], s0: pre.DynamicEstimate):
    """sigma0 per bristle sign (z > 0, z < 0: the ramps' load sign), when each sign's ramps identify it
    and the two differ by more than PER_SIGN_Z combined standard errors plus what the creep may shift one
    sign against the other (a per-sign plant, as 001's joint 1); None otherwise (one sigma0 for both).
    Each sign's standard error is the larger of its fit's and its ramp-to-ramp spread's
    (:func:`_ramp_spread`); the creep's share is a bound on a bias, not a random error, so it is added
    once, not scaled with PER_SIGN_Z."""
    if not s0.identifiable:
        return None
    sides = []
    for positive in (True, False):
        idx = [i for i, (_, F) in enumerate(pd.ramps) if (np.mean(F) >= 0) == positive]
        if len(idx) < 2:
            return None
        ramps, gs = [pd.ramps[i] for i in idx], [g_of[i] for i in idx]
        e = pre.fit_sigma0(ramps, gs, pd.resolution)
        if not e.identifiable:
            return None
        spread = _ramp_spread(ramps, gs, pd.resolution)
        e.details = dict(e.details or {}, fit_se=e.stderr, ramp_spread_se=spread)
        e.stderr = max(e.stderr, spread)
        e.source += f"; {'z > 0' if positive else 'z < 0'} ramps (per sign)"
        sides.append(e)
    bias = _creep_share(pd) * max(sides[0].value, sides[1].value)
    if abs(sides[0].value - sides[1].value) <= PER_SIGN_Z * math.hypot(sides[0].stderr, sides[1].stderr) + bias:
        return None
    sides = [_creep_inflated(e, pd) for e in sides]
    return sides if all(e.identifiable for e in sides) else None


def _step_sign(u: np.ndarray) -> int:
    """The bristle sign a step loads: the sign of its torque level of largest magnitude."""
    return 1 if float(u[int(np.argmax(np.abs(u)))]) >= 0 else -1


def _sigma1(jd: JointData, pd: Presliding, s0: pre.DynamicEstimate, c_pos, c_neg,
            sign: int = 0) -> pre.DynamicEstimate:
    """sigma1 from the steps (those loading the bristles with ``sign`` when not 0), else by the
    critical-damping rule (records the steps used)."""
    jf = jd.jf
    # a J that is not positive (the regression's, not identifiable) has no damping ratio to go with
    J = jf.inertia.value if jf.inertia and jf.inertia.value and jf.inertia.value > 0 else None
    sig2 = c_pos[6] if abs(c_pos[6]) > 0 else 0.0
    if not (s0.identifiable and J):
        why = "needs sigma0" if not s0.identifiable else "needs a positive inertia J"
        return pre.DynamicEstimate(None, None, False, f"{why}, which is not identifiable", "")
    steps = [st for st in pd.steps if not sign or _step_sign(st[2]) == sign]
    s1 = pre.fit_sigma1_steps([(t, q, u) for t, q, u, *_ in steps], J, s0.value, c_pos, c_neg, sig2,
                              pd.resolution)
    if not s1.identifiable:
        why_steps = s1.reason
        s1 = pre.sigma1_rule(s0.value, s0.stderr, J, jf.inertia.stderr, sig2)
        s1.source += f" ({why_steps})"
    else:
        jd.used.setdefault("step", []).extend([float(s.t_start), float(s.t_end), src] for *_, s, src in steps)
    return s1


def _presliding_rms(pd: Presliding, g_of: list[float], s0_of: list[float], base_name: str,
                    vals: dict, per_sign: bool = False, measured: list | None = None) -> dict:
    """The presliding prediction on the ramps: LuGre (sigma0 bristles along the measured path, s0_of per
    ramp) against the static map alone, and LuGre with sigma0 refitted without each ramp (RMS [F]; with
    ``per_sign`` on the other ramps of its load sign). ``pd.ramps`` carry the torque LuGre's bristles
    make (its damping taken out, :func:`_without_damping`); the static map is judged on the ``measured``
    ramps (default the same)."""
    lug, stat, held = [], [], []
    measured = pd.ramps if measured is None else measured
    for i, ((q, F), g0, w, s0, (_, Fm)) in enumerate(zip(pd.ramps, g_of, pd.ramp_w, s0_of, measured)):
        z0 = float(np.clip(F[0] / s0, -g0 / s0, g0 / s0))
        lug.append(s0 * pre.bristle_path(q, z0, s0, g0) - F)
        stat.append(predict(base_name if base_name != "polynomial_ls" else "polynomial", vals, w) - Fm)
        same = [k for k, (_, Fk) in enumerate(pd.ramps)
                if k != i and (not per_sign or (np.mean(Fk) >= 0) == (np.mean(F) >= 0))]
        if same:
            rest = [pd.ramps[k] for k in same]
            gr = [g_of[k] for k in same]
            e = pre.fit_sigma0(rest, gr, pd.resolution, starts=(s0,))
            if e.value:
                z0h = float(np.clip(F[0] / e.value, -g0 / e.value, g0 / e.value))
                held.append(e.value * pre.bristle_path(q, z0h, e.value, g0) - F)
    return {"rms_presliding": float(np.sqrt(np.mean(np.concatenate(lug) ** 2))),
            "rms_presliding_static": float(np.sqrt(np.nanmean(np.concatenate(stat) ** 2))),
            "rms_presliding_heldout": float(np.sqrt(np.mean(np.concatenate(held) ** 2))) if held else None}


def _lugre_choice(jd: JointData, mf: ModelFit, base_name: str) -> None:
    """LuGre replaces its map when identifiable (or only its static map's drop shape is not, the choice's
    rule: :func:`.select.selectable`) and better on held-out presliding segments."""
    jf, met = jd.jf, mf.metrics
    rh = met.get("rms_presliding_heldout")
    if selectable(mf) and rh is not None and rh < met["rms_presliding_static"]:
        jf.selection["lugre"] = (f"chosen: held-out presliding RMS {rh:.4g} against {met['rms_presliding_static']:.4g} "
                                 f"for {base_name} alone")
        jf.selected = "lugre"
    else:
        why = ("not all dynamic parameters identifiable" if not selectable(mf) else
               "fewer than two ramp segments: no held-out presliding error" if rh is None else
               "no better than the static map on held-out presliding segments")
        jf.selection["lugre"] = f"not chosen: {why}"


def _lugre_from_reversals(jd: JointData, base: ModelFit, base_name: str, c_pos, c_neg,
                          ramps: pre.DynamicEstimate) -> None:
    """LuGre on the chosen map with sigma0 from the stops and reversals of the moving samples
    (:func:`.reversals.reversal_lugre`), for joints without ramps; it replaces its map as the chosen model
    when sigma0 is identifiable, which includes beating the map on the held-out time blocks."""
    from .reversals import reversal_lugre

    jf = jd.jf
    dyn, met, note = reversal_lugre(jd, base, c_pos, c_neg)
    s0 = dyn["sigma0"]
    if not s0.identifiable:
        s0.reason = f"{ramps.reason}; from the stops and reversals: {s0.reason}"
    params = static_params(base)
    params.update(dyn)
    metrics = dict(base.metrics)
    metrics.update({f"{k}_reversals": v for k, v in met.items()})
    mf = _lugre_fit(base, base_name, params, metrics, [f"static part: {base_name}"] + ([note] if note else []),
                    "static map as chosen; sigma0 from the stops and reversals of the moving samples (bristle "
                    "length by the held-out error of time blocks, inertia, gravity and offset fitted again with "
                    "it); sigma1 by a damping ratio chosen with the length")
    jf.models["lugre"] = mf
    if not s0.identifiable:
        jf.not_identified.append({"what": "lugre.sigma0", "reason": s0.reason})
        jf.selection["lugre"] = "not chosen: sigma0 not identifiable"
        return
    jf.selection["lugre"] = (f"chosen: held-out RMS of the moving samples including the stops "
                             f"{met['rms_heldout']:.4g} against {met['rms_heldout_static']:.4g} for {base_name} "
                             "alone (the same time blocks and refit of the rigid terms)")
    jf.selected = "lugre"
