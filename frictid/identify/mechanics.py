"""Step 1 of a joint's fit: inertia, gravity and torque offset, then the friction torque and its plateaus.

Stage 1 regresses the torque on the rigid-body terms and a polynomial friction by chunked least squares on
the moving samples (002 eq 4-11, :mod:`.regression`), unless the log metadata gives them
(:func:`known_from_meta`). The friction torque ``F = tau - J a - G(q) - offset`` then gives one averaged
point per constant-velocity plateau, and the basis of the static maps is chosen (plateau points, or every
moving sample: :mod:`.samples`). Stage 2 regresses the rigid-body terms again with the best per-sign map of
the plateaus as the friction (the polynomial cannot follow a Stribeck drop, which then leaks into J; see
``docs/fit.md``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from frictid.models.params import unit_of
from frictid.result import JointFit, ParamEstimate

from . import regression as rg
from . import samples as smp
from .prepare import JointData, Prep, regression_exclude
from .static import NEGLIGIBLE, Plateaus, fit_static, plateau_column_means, plateau_points, predict

#: Maps tried for the stage-2 friction (no held-out split: only the best in-sample curve is needed).
STAGE2_MAPS = ("stribeck_asym", "stribeck_2exp_asym", "polynomial_asym")
#: The polynomial friction's coefficients in the regression.
POLY_COEFS = ("c0", "c1", "c2", "c3")


@dataclass
class Regressors:
    """The terms of the rigid-body regression: every name, those given by the log metadata (name ->
    (value, stderr or None)) and whether the logs have a position channel."""

    names: list[str]
    known: dict[str, tuple[float, float | None]]
    has_q: bool
    #: where a known term came from when not the log's own metadata (name -> a sentence: the gravity a
    #: robot's kinematics fix, frictid.robot.pose)
    sources: dict[str, str] | None = None

    @property
    def free(self) -> tuple[str, ...]:
        return tuple(n for n in self.names if n not in self.known)

    @property
    def known_coef(self) -> dict[str, float]:
        return {n: self.known[n][0] for n in self.names if n in self.known}


@dataclass
class RigidBody:
    """The stage-1 regression (None when there are no moving samples, ``why`` then says so) and its
    per-segment normal equations (prep index, segment index, equations)."""

    regs: Regressors
    fit: rg.LinearFit | None
    seg_ne: list[tuple[int, int, rg.NormalEquations]]
    why: str


@dataclass
class Friction:
    """The friction torque's points the static maps are fitted on: the plateaus (``keys[i]`` = (prep index,
    segment index) of plateau i), the moving samples ``S`` (None without a regression), the ``basis``
    chosen between them (``plateaus`` or ``samples``, with the reason) and the segment kinds kept out of
    the samples."""

    plat: Plateaus
    keys: np.ndarray
    S: smp.SampleSet | None
    basis: str
    why: str
    excl: tuple[str, ...]
    #: the plateau points' changes for one standard deviation of each independent error direction of the
    #: inertia, gravity and offset (:func:`plateau_shifts`)
    shifts: list[np.ndarray] | None = None
    #: the even part's error (:func:`plateau_even`) where the offset was set from the plateaus
    #: (:func:`_offset_from_plateaus`), else None; then :attr:`odd_shifts` are the symmetric maps' shifts
    even_se: float | None = None
    odd_shifts: list[np.ndarray] | None = None


def _meta_value(meta: dict, *keys):
    for k in keys:
        if k in meta and meta[k] is not None:
            v = meta[k]
            if isinstance(v, dict):
                return v.get("value"), v.get("stderr")
            try:
                return float(v), None
            except (TypeError, ValueError):
                continue
    return None, None


def known_from_meta(meta: dict) -> dict[str, tuple[float, float | None]]:
    """Inertia, gravity and offset given by the log metadata: name -> (value, stderr or None).

    Keys: ``inertia`` (or ``J``), ``gravity`` ({Px, Py} or [Px, Py]), ``offset`` (or ``tau_offset``); each a
    number or a mapping with ``value`` (and ``stderr``).
    """
    out = {}
    v, s = _meta_value(meta, "inertia", "J")
    if v is not None:
        out["J"] = (float(v), s)
    g = meta.get("gravity")
    if isinstance(g, dict):
        for k in ("Px", "Py"):
            if k in g:
                gv, gs = _meta_value(g, k)
                if gv is not None:
                    out[k] = (float(gv), gs)
    elif isinstance(g, (list, tuple)) and len(g) == 2:
        out["Px"], out["Py"] = (float(g[0]), None), (float(g[1]), None)
    v, s = _meta_value(meta, "offset", "tau_offset")
    if v is not None:
        out["offset"] = (float(v), s)
    return out


def regressors(jd: JointData) -> Regressors:
    """The rigid-body regression's terms for a joint's logs (and those its metadata gives)."""
    known, sources = {}, {}
    for p in jd.preps:
        meta = p.log.meta or {}
        got = known_from_meta(meta)
        known.update(got)
        if meta.get("gravity_source"):
            sources.update({n: str(meta["gravity_source"]) for n in ("Px", "Py") if n in got})
    has_q = all(p.log.q is not None for p in jd.preps)
    has_payload = all("payload" in p.log.channels for p in jd.preps)
    names = ["J", *POLY_COEFS]
    if has_q and jd.axis == "rotary":
        names += ["Px", "Py"]
    if has_payload and has_q:
        names += ["Mx"] + (["My"] if jd.axis == "rotary" else [])
    names += ["offset"]
    return Regressors(names, known, has_q, sources)


def _dims(name: str) -> str:
    return {"J": "J", "c0": "F", "c1": "D", "c2": "D2", "c3": "D3", "Px": "F", "Py": "F", "Mx": "M",
            "My": "M", "offset": "F"}[name]


def _unit(dim: str, axis: str) -> str:
    if dim == "J":
        return "kg m^2" if axis == "rotary" else "kg"
    if dim == "M":
        return "N m/kg" if axis == "rotary" else "N/kg"
    return unit_of(dim, axis)


def _speed_power(dim: str) -> int | None:
    return {"F": 0, "D": 1, "D2": 2, "D3": 3}.get(dim)


def reg_estimate(name: str, fit_: rg.LinearFit | None, jd: JointData, why_none: str = "") -> ParamEstimate:
    """The estimate of regression term ``name``: identifiable unless it is not separable from the other
    terms or its relative error is above 100 % and its effect on the torque is not negligible."""
    dim = _dims(name)
    unit = _unit(dim, jd.axis)
    if fit_ is None or name not in fit_.names:
        return ParamEstimate(name, None, None, unit, False, why_none or "not estimated")
    v = fit_.value(name)
    se = fit_.stderr(name)
    if fit_.n == 0:
        return ParamEstimate(name, None, None, unit, False, why_none or "no moving samples")
    if name in fit_.dependent:
        why = {"J": "no acceleration in the moving samples that the other terms cannot explain",
               "Px": "the joint does not move through enough of its range to separate gravity from the offset",
               "Py": "the joint does not move through enough of its range to separate gravity from the offset",
               "offset": "not separable from gravity or the Coulomb term (one velocity sign or a fixed angle)",
               }.get(name, "not separable from other regressors")
        return ParamEstimate(name, v, None, unit, False, why)
    reason = ""
    if name in BANDWIDTH_TERMS:
        se = _bandwidth_spread(name, se, v, fit_.bandwidth)
    if name == "J":
        se, reason = _inertia_checked(v, se, fit_.bandwidth)
        if not reason:
            se, reason = _inertia_split_checked(v, se, fit_.speed_split)
        se = _inertia_friction_spread(v, se, fit_.friction_change)
    if not reason:
        reason = _precision_reason(name, dim, v, se, jd)
    if name == "J" and v <= 0 and not reason:
        reason = "not positive: the data do not determine the inertia"
    return ParamEstimate(name, v, se, unit, not reason, reason)


def _precision_reason(name: str, dim: str, v: float, se: float | None, jd: JointData) -> str:
    """Why a regression term is not identifiable by its precision ("" when it is): no error estimate, or a
    relative error above 100 % whose torque matters (a well-determined zero such as the gravity of a
    horizontal arm stays identifiable; an inertia is never a well-determined zero)."""
    if se is None or not np.isfinite(se):
        return "no error estimate (too few samples)"
    if se <= abs(v):
        return ""
    p = _speed_power(dim)
    impact = se * jd.w0**p if p is not None else None
    if name == "J" or impact is None or impact > NEGLIGIBLE * jd.F0:
        return f"relative error {100 * se / abs(v):.0f} % (above 100 %)" if v else "relative error above 100 %"
    return ""


#: The inertia's change between the two bandwidths counts as significant beyond this many standard errors
#: of the change, and as material beyond this share of the inertia: the accuracy asked of J (a J that moves
#: by more than that when the torque is low-pass filtered cannot be claimed to that accuracy).
BANDWIDTH_Z = 3.0
BANDWIDTH_MATERIAL = 0.05


def _inertia_checked(v: float, se: float | None, bw: dict | None) -> tuple[float | None, str]:
    """The inertia's standard error with the bandwidth check (:func:`_bandwidth_check`) and the reason it
    is not identifiable ("" when it is). A significant, material change of J between the bandwidths: not
    identifiable; a smaller one enters the standard error as a systematic term (its part beyond the
    change's own scatter, added in quadrature). The change's scatter is the paired delete-a-segment
    jackknife's (``bw["se_change"]``) where the check has one, at most the two fits' errors combined."""
    if bw is None or se is None or not np.isfinite(se):
        return se, ""
    d = abs(bw["J"] - v)
    se2 = bw["se"] if bw["se"] is not None and np.isfinite(bw["se"]) else se
    # the change's error: the paired one (both fits on the same segments), at most the two fits' errors
    # combined (their errors are positively correlated: the paired error cannot exceed that bound)
    s_d = math.hypot(se, se2)
    if bw.get("se_change") is not None and np.isfinite(bw["se_change"]):
        s_d = min(s_d, bw["se_change"])
    sys_ = math.sqrt(max(d * d - s_d * s_d, 0.0))  # the change beyond its own scatter
    if d > BANDWIDTH_Z * s_d and d > BANDWIDTH_MATERIAL * abs(v):
        return math.hypot(se, sys_), (
            f"changes from {v:.4g} to {bw['J']:.4g} when the torque and the regressors are low-pass filtered "
            f"alike over {bw['window']} samples: the torque is not resolved at the log rate (a loop faster "
            "than the log), or the joint is not rigid")
    return math.hypot(se, sys_), ""


#: The terms solved with J whose change under the bandwidth check's filter enters their errors.
BANDWIDTH_TERMS = ("Px", "Py", "offset")


def _bandwidth_spread(name: str, se: float | None, v: float, bw: dict | None) -> float | None:
    """The standard error of a gravity or offset term with its change under the bandwidth check's filter
    (:func:`_bandwidth_check`) added in quadrature, the part beyond the two fits' errors combined. The terms
    are solved with J on the same samples: a torque the log does not resolve at the starts and stops (a
    loop faster than the log), which moves J under the filter, moves them too, and the plateau points
    then carry that gravity as friction (foreign sweeps at 138 Hz: Px -0.166 +- 0.032 N m where the plant
    has none, +0.081 under the filter, every plateau's level 0.17 N m off; at 6.3 kHz: Py 4.21 +- 0.18
    against 3.40, 3.71 under the filter). The inertia's own verdict stays :func:`_inertia_checked`'s."""
    if bw is None or se is None or not np.isfinite(se) or name not in bw.get("terms", {}):
        return se
    v2, se2 = bw["terms"][name]
    se2 = se2 if se2 is not None and np.isfinite(se2) else se
    d, s_d = abs(v2 - v), math.hypot(se, se2)
    return math.hypot(se, math.sqrt(max(d * d - s_d * s_d, 0.0)))


#: The speed-split check's thresholds, as the bandwidth check's: significant beyond this many combined
#: standard errors, material beyond this share of the inertia (the accuracy asked of J).
SPLIT_Z = 3.0
SPLIT_MATERIAL = 0.05


def _inertia_split_checked(v: float, se: float | None, sp: dict | None) -> tuple[float | None, str]:
    """The inertia's standard error with the speed-split check (:func:`_speed_split_check`) and the reason
    it is not identifiable ("" when it is): the two halves' inertias differing beyond :data:`SPLIT_Z`
    combined standard errors *and* by more than :data:`SPLIT_MATERIAL` of the inertia make it not
    identifiable; a smaller difference enters the standard error as a systematic term (half the difference
    beyond the halves' own scatter: the full fit sits between them)."""
    if sp is None or se is None or not np.isfinite(se):
        return se, ""
    d = abs(sp["J_high"] - sp["J_low"])
    s_d = math.hypot(sp["se_low"], sp["se_high"])
    sys_ = 0.5 * math.sqrt(max(d * d - s_d * s_d, 0.0))
    if d > SPLIT_Z * s_d and d > SPLIT_MATERIAL * abs(v):
        return math.hypot(se, sys_), (
            f"{sp['J_low']:.4g} on the moving samples slower than {sp['speed']:.3g} and {sp['J_high']:.4g} on "
            "the faster ones: the friction's dynamics (bristles lagging the acceleration, a Stribeck drop "
            "crossed while accelerating) or a control loop the log does not resolve go with the acceleration")
    return math.hypot(se, sys_), ""


def _inertia_friction_spread(v: float, se: float | None, fc: dict | None) -> float | None:
    """The inertia's standard error with its change between the two friction models it was solved with
    (stage 1's polynomial in the speed, stage 2's plateau map; :func:`_stage2`) added in quadrature. Both
    fit the steady friction; at the starts, stops and reversals, where the acceleration is, the data do not
    tell which holds, and J takes up the difference. The whole change enters (not only its part beyond
    the fits' scatter): on the foreign scorecard J was off by 0.3-4 % with stage 2's errors of 0.1-0.4 %,
    each time by about its change from stage 1 (docs/fit.md step 1)."""
    if fc is None or se is None or not np.isfinite(se) or fc.get("J") is None or not np.isfinite(fc["J"]):
        return se
    return math.hypot(se, fc["J"] - v)


def set_mechanics(jd: JointData, reg_fit: rg.LinearFit | None, regs: Regressors, why_reg: str,
                  source: str) -> None:
    """Inertia, gravity and offset estimates of a joint from a regression (or the metadata)."""
    jf, axis = jd.jf, jd.axis

    def est(name):
        if name in regs.known:
            v, s = regs.known[name]
            return ParamEstimate(name, v, s, _unit(_dims(name), axis), True, "",
                                 source=(regs.sources or {}).get(name, "log metadata"))
        pe = reg_estimate(name, reg_fit, jd, why_reg)
        pe.source = source
        return pe

    jf.inertia = est("J")
    jf.gravity = {}
    if axis == "rotary":
        if regs.has_q:
            jf.gravity = {n: est(n) for n in ("Px", "Py")}
            _gravity_amplitude(jf)
        else:
            jf.gravity = {n: ParamEstimate(n, None, None, _unit("F", axis), False, "no position channel")
                          for n in ("Px", "Py")}
    elif "linear axis: a constant gravity force is part of the offset" not in jf.warnings:
        jf.warnings.append("linear axis: a constant gravity force is part of the offset")
    for n in ("Mx", "My"):
        if n in regs.names:
            jf.gravity[n] = est(n)
    jf.offset = est("offset")


def _gravity_amplitude(jf: JointFit) -> None:
    px, py = jf.gravity["Px"], jf.gravity["Py"]
    if px.value is not None and py.value is not None:
        amp = math.hypot(px.value, py.value)
        se = None
        if px.stderr is not None and py.stderr is not None and amp > 0:
            se = math.hypot(px.value * px.stderr, py.value * py.stderr) / amp
        ok = px.identifiable and py.identifiable
        jf.gravity["amplitude"] = ParamEstimate("amplitude", amp, se, _unit("F", jf.axis), ok,
                                                "" if ok else "Px or Py not identifiable")


def mechanics_not_identified(jf: JointFit) -> None:
    """List the inertia, offset and gravity terms that are not identifiable."""
    for n, pe in [("J", jf.inertia), ("offset", jf.offset), *jf.gravity.items()]:
        if not pe.identifiable:
            jf.not_identified.append({"what": n, "reason": pe.reason})


def _accumulate(p: Prep, pi, ranges, seg_ids, names, known_coef, min_speed, axis, friction, within, smooth=0,
                max_speed=math.inf):
    """Per-segment normal equations of one log. The segments in ``within`` (keys (prep index, segment
    index): plateaus) have a friction level of their own, the constant column partialled out
    (:meth:`.regression.NormalEquations.within`), and take every moving sample (``within[key]`` is their
    speed floor: a level of their own is immune to a map that misses the Stribeck drop)."""
    own = [k for k, si in enumerate(seg_ids) if (pi, si) in within] if "offset" in names else []
    args = (names, p.log.q, p.w, p.a, p.log.tau, p.log.channels.get("payload"), known_coef)
    trig = _trig(p, names, known_coef)
    rest = [k for k in range(len(ranges)) if k not in set(own)]
    out = [None] * len(ranges)
    for k, ne in zip(rest, rg.accumulate([ranges[k] for k in rest], *args, min_speed, axis, friction=friction,
                                         smooth=smooth, max_speed=max_speed, trig=trig)):
        out[k] = ne
    j = list(names).index("offset") if own else 0
    for k in own:
        ne, = rg.accumulate([ranges[k]], *args, within[(pi, seg_ids[k])], axis, friction=friction, smooth=smooth,
                            max_speed=max_speed, trig=trig)
        out[k] = ne.within(j)
    if "J" in names:
        var = acceleration_noise(p, smooth)
        jj = list(names).index("J")
        for ne in out:
            ne.XtX[jj, jj] -= ne.n * var
    return out


def acceleration_noise(p: Prep, smooth: int = 0) -> float:
    """Variance [(q/s^2)^2] of the noise the acceleration column carries per sample (after the parallel
    filter of ``smooth`` samples): the log's position (or logged velocity) noise through the
    Savitzky-Golay derivative that made it (the scales' ``sigma_a``, :func:`frictid.segments.estimate_scales`),
    0 without the scales. Noise in a regressor is not averaged out by least squares: it adds its variance
    to the column's ``X^T X`` and pulls the coefficient towards zero by the noise's share of the column's
    variance (errors in variables). The regression takes it out of ``X^T X`` (bias-corrected least
    squares). Foreign card 204012 (12-bit encoder, 118 Hz, no velocity column): the acceleration's noise
    was 22 % of its variance on the moving samples and J came out 22 % low.
    Only for an acceleration made from the positions: a logged velocity is either exact (no noise to speak
    of) or a drive's difference of counts, whose noise is the counts' differenced, not white, and which the
    white-noise formula overstates many times (foreign card: 6-9 kHz logs with such a velocity had J 14 %
    and 72 % high after the correction, not identifiable before it)."""
    sc = p.scales
    if (sc is None or getattr(sc, "qd_logged", True) or not getattr(sc, "window_a", None)
            or not np.isfinite(getattr(sc, "sigma_a", np.nan))):
        return 0.0
    if smooth <= 1:
        return float(sc.sigma_a) ** 2
    from scipy.signal import savgol_coeffs

    c = savgol_coeffs(sc.window_a, 2, deriv=2, delta=sc.dt)
    cf = np.convolve(c, np.full(smooth, 1.0 / smooth))
    return float(sc.sigma_a) ** 2 * float(np.sum(cf * cf)) / float(np.sum(c * c))


def _trig(p: Prep, names, known) -> tuple | None:
    """The prep's cos q and sin q (:meth:`.prepare.Prep.trig`, computed once) when a gravity or payload column
    is among ``names`` or the known terms, else None (the regression then computes nothing of q)."""
    return p.trig() if any(n in GRAVITY_COLUMNS for n in (*names, *(known or ()))) else None


#: The regressors that are functions of the angle q.
GRAVITY_COLUMNS = ("Px", "Py", "Mx", "My")


def regress(preps: list[Prep], names, known_coef, min_speed, axis, friction=None, within=None):
    """Chunked least squares over the moving samples of every log; per-segment normal equations.
    ``within``: {(prep index, segment index): speed floor} of plateaus whose friction is a free constant
    each (only their variation along the plateau enters: the torque's change with the angle is gravity)."""
    within = within or {}
    seg_ne: list[tuple[int, int, rg.NormalEquations]] = []
    excl = regression_exclude(preps)
    for pi, p in enumerate(preps):
        ranges = [(s.i0, s.i1) for s in p.segments if s.kind not in excl]
        seg_ids = [si for si, s in enumerate(p.segments) if s.kind not in excl]
        if not p.segments:  # no segmentation: every sample is a candidate
            ranges, seg_ids = [(0, p.log.n)], [-1]
        nes = _accumulate(p, pi, ranges, seg_ids, names, known_coef, min_speed, axis, friction, within)
        seg_ne += [(pi, si, ne) for si, ne in zip(seg_ids, nes)]
    if not seg_ne or not names:
        return None, seg_ne
    total = rg.NormalEquations.total(ne for *_, ne in seg_ne)
    if total.n <= len(names):
        return None, seg_ne
    fit_ = rg.solve(total, names)
    rho = 0.0
    for p in preps:
        ranges = [(s.i0, s.i1) for s in p.segments if s.kind not in excl] or [(0, p.log.n)]
        rho = max(rho, rg.residual_autocorrelation(fit_, ranges, p.log.q, p.w, p.a, p.log.tau,
                                                   p.log.channels.get("payload"), known_coef, min_speed, axis,
                                                   friction=friction, trig=_trig(p, names, known_coef)))
    fit_ = rg.solve(total, names, rho=rho)
    fit_.cov = rg.robust_stderr(fit_.cov, rg.cluster_covariance(fit_, [ne for *_, ne in seg_ne]))
    fit_.bandwidth = _bandwidth_check(preps, fit_, names, known_coef, min_speed, axis, friction, excl, within,
                                      raw=[ne for *_, ne in seg_ne])
    fit_.speed_split = _speed_split_check(preps, fit_, names, known_coef, min_speed, axis, friction, excl, within)
    return fit_, seg_ne


#: The parallel filter of the bandwidth check spans this many acceleration windows.
BANDWIDTH_WINDOWS = 3


def _bandwidth_check(preps, fit_, names, known_coef, min_speed, axis, friction, excl,
                     within=None, raw=None) -> dict | None:
    """The regression again with the torque and every regressor low-pass filtered alike over
    :data:`BANDWIDTH_WINDOWS` times the logs' acceleration window (parallel filtering: exact for a rigid
    joint whose torque is resolved at the log rate). A rigid-body fit that the data support gives the same
    inertia at both bandwidths; a torque sampled from a loop faster than the log, or a joint that is not
    rigid, does not. ``raw``: the raw regression's per-segment normal equations (for the change's paired
    error). None without the logs' scales (derivatives given by the caller) or an inertia term."""
    wins = [getattr(p.scales, "window_a", None) for p in preps]
    if "J" not in names or "J" in fit_.dependent or any(w is None for w in wins):
        return None
    win = int(BANDWIDTH_WINDOWS * max(wins)) | 1
    parts = []
    for pi, p in enumerate(preps):
        ranges = [(s.i0, s.i1) for s in p.segments if s.kind not in excl] or [(0, p.log.n)]
        seg_ids = [si for si, s in enumerate(p.segments) if s.kind not in excl] or [-1]
        parts += _accumulate(p, pi, ranges, seg_ids, names, known_coef, min_speed, axis, friction, within or {},
                             smooth=win)
    filt = parts
    parts = [ne for ne in parts if ne.n > 0]
    if not parts or sum(ne.n for ne in parts) <= len(names):
        return None
    f2 = rg.solve(rg.NormalEquations.total(parts), names, rho=fit_.rho)
    if "J" in f2.dependent:
        return None
    f2.cov = rg.robust_stderr(f2.cov, rg.cluster_covariance(f2, parts))
    return {"window": win, "J": f2.value("J"), "se": f2.stderr("J"),
            "se_change": _paired_change_se(raw, filt, names),
            "terms": {n: (f2.value(n), f2.stderr(n)) for n in BANDWIDTH_TERMS if n in names and n not in f2.dependent}}


def _paired_change_se(raw, filt, names) -> float | None:
    """The standard error of the inertia's change between the raw and the filtered regression, from the
    delete-a-segment jackknife of the change: both fits are solved on the same segments, so their errors are
    correlated and the two standard errors combined misstate the change's scatter (a bias common to every
    segment cancels in the change; one that differs from segment to segment shows in it). ``raw`` and
    ``filt`` are the per-segment normal equations, in the same order. None with fewer than
    :data:`.regression.MIN_CLUSTERS` segments that both fits use, or when a deleted segment leaves J
    inseparable."""
    if raw is None or len(raw) != len(filt):
        return None
    keep = [k for k in range(len(raw)) if raw[k].n > 0 and filt[k].n > 0]
    G = len(keep)
    if G < rg.MIN_CLUSTERS:
        return None
    A = rg.NormalEquations.total(raw[k] for k in keep)
    B = rg.NormalEquations.total(filt[k] for k in keep)
    j = list(names).index("J")
    dd = []
    for k in keep:
        fa, fb = rg.solve(A - raw[k], names), rg.solve(B - filt[k], names)
        if "J" in fa.dependent or "J" in fb.dependent:
            return None
        dd.append(fb.coef[j] - fa.coef[j])
    dd = np.asarray(dd)
    return float(math.sqrt((G - 1) / G * np.sum((dd - dd.mean()) ** 2)))


def _speed_split_check(preps, fit_, names, known_coef, min_speed, axis, friction, excl, within) -> dict | None:
    """The regression again on the slower and on the faster half of its moving samples (split at their
    median speed), each with all its terms. A rigid joint whose friction the model follows gives one
    inertia on both; a friction whose dynamics go with the acceleration (LuGre's bristles lag it, the
    Stribeck drop is crossed while accelerating) or a loop the log does not resolve moves it between the
    halves. None without an inertia term or when a half cannot separate it."""
    if "J" not in names or "J" in fit_.dependent:
        return None
    speeds = []
    for p in preps:
        for s in (s for s in p.segments if s.kind not in excl) if p.segments else ():
            v = np.abs(p.w[s.i0:s.i1])
            speeds.append(v[np.isfinite(v) & (v > min_speed)])
    speeds = np.concatenate(speeds) if speeds else np.zeros(0)
    if speeds.size < 4 * len(names):
        return None
    mid = float(np.median(speeds))
    halves = []
    for lo, hi in ((min_speed, mid), (mid, math.inf)):
        parts = []
        for pi, p in enumerate(preps):
            ranges = [(s.i0, s.i1) for s in p.segments if s.kind not in excl]
            seg_ids = [si for si, s in enumerate(p.segments) if s.kind not in excl]
            parts += _accumulate(p, pi, ranges, seg_ids, names, known_coef, lo, axis, friction,
                                 {k: max(v, lo) for k, v in within.items()}, max_speed=hi)
        parts = [ne for ne in parts if ne.n > 0]
        if not parts or sum(ne.n for ne in parts) <= len(names):
            return None
        f = rg.solve(rg.NormalEquations.total(parts), names, rho=fit_.rho)
        if "J" in f.dependent or f.stderr("J") is None:
            return None
        f.cov = rg.robust_stderr(f.cov, rg.cluster_covariance(f, parts))
        halves.append((f.value("J"), f.stderr("J")))
    return {"speed": mid, "J_low": halves[0][0], "se_low": halves[0][1], "J_high": halves[1][0],
            "se_high": halves[1][1]}


def rigid_body(jd: JointData, regs: Regressors, n_folds: int) -> tuple[RigidBody, Friction]:
    """Inertia, gravity and offset of a joint (stage 1, then stage 2 when the plateaus allow it), and the
    friction torque's points for the static maps. Sets ``inertia``, ``gravity`` and ``offset`` of the
    result and lists those not identifiable."""
    reg_fit, seg_ne = regress(jd.preps, regs.free, regs.known_coef, jd.min_speed, jd.axis)
    rb = RigidBody(regs, reg_fit, seg_ne, "no moving samples" if reg_fit is None else "")
    set_mechanics(jd, reg_fit, regs, rb.why, "")
    confound_warning(jd.jf, angle_share(seg_ne, regs.free, reg_fit))
    plat, keys = plateaus(jd)
    # the basis of the static maps: plateau points, or every moving sample when the plateaus give too few
    # distinct speeds (an excitation run; see samples.py)
    excl = regression_exclude(jd.preps)
    S = smp.build(jd.preps, jd.min_speed, n_folds, exclude=excl) if reg_fit is not None else None
    basis, why_basis = smp.choose_basis(plat.w, S.n_moving if S is not None else 0)
    fr = Friction(plat, keys, S, basis, why_basis, excl)
    final = _stage2(jd, rb, fr) or reg_fit
    if final is not None and fr.basis == "plateaus":
        fr.shifts = plateau_shifts(jd, final, fr.keys)
        fr.odd_shifts = odd_shifts(fr.plat, fr.shifts, fr.even_se)
    for p in jd.preps:  # the mechanics are final: cos q and sin q are not needed again (58 MB per joint-hour)
        p._trig = None
    mechanics_not_identified(jd.jf)
    return rb, fr


#: The share of the acceleration's variance that the angle explains on the regression's samples beyond
#: which the fit warns that the inertia and the gravity trade off: more than half of J's column is then the
#: gravity columns' and the offset's (their collinearity alone more than doubles J's variance).
CONFOUND_SHARE = 0.5


def angle_share(seg_ne, names, fit_: rg.LinearFit | None) -> float | None:
    """The share of the acceleration's variance (about its mean) that the gravity columns and the offset
    explain over the regression's samples, from its normal equations (no pass over the samples): on an
    oscillation ``a = -w^2 (q - q_c)`` it is near 1, and J and gravity are then separated only by the rest of
    the motion. None unless J, Px, Py and the offset are all solved and separable."""
    need = ("J", "Px", "Py", "offset")
    if fit_ is None or not seg_ne or any(n not in names or n in fit_.dependent for n in need):
        return None
    ne = rg.NormalEquations.total(e for *_, e in seg_ne)
    names = list(names)
    j, o = names.index("J"), names.index("offset")
    g = [names.index(n) for n in ("Px", "Py", "offset")]
    if ne.n < 2 * len(g):
        return None
    aa, ga = ne.XtX[j, j], ne.XtX[g, j]
    tss = aa - ne.XtX[o, j] ** 2 / ne.n
    if not tss > 0:
        return None
    rss = aa - ga @ np.linalg.lstsq(ne.XtX[np.ix_(g, g)], ga, rcond=None)[0]
    return float(min(max(1.0 - rss / tss, 0.0), 1.0))


def confound_warning(jf: JointFit, share: float | None) -> None:
    """Warn when the angle explains more than :data:`CONFOUND_SHARE` of the acceleration (:func:`angle_share`):
    J and gravity then trade off, and a friction the model misses at the reversals (where an oscillation's
    acceleration peaks) biases both together (UR10e joint 5 in its jointwise run, an oscillation about a
    vertical axis: 82 % of the acceleration is the angle's; J 1.07 with a gravity of 0.36 N m the pose does
    not have, 0.48 without it, which the run's last 30 % confirms; docs/realdata.md "UR10e joints 5 and 6:
    the inertia")."""
    if share is None or share <= CONFOUND_SHARE:
        return
    jf.warnings.append(
        f"inertia and gravity trade off: the angle explains {100 * share:.0f} % of the acceleration on the moving "
        "samples (an oscillation's acceleration follows its angle), so J and Px, Py rest on the rest of the "
        "motion and take up the friction's misfit at the reversals together; declare the gravity in the "
        "mapping file's meta where the pose fixes it (an axis vertical in this pose: gravity: [0, 0]), or add "
        "moves with other accelerations at the same angles")


def _stage2(jd: JointData, rb: RigidBody, fr: Friction) -> rg.LinearFit | None:
    """With a static map from the plateaus, J / gravity / offset again with that map as the friction (the
    polynomial cannot follow a Stribeck drop, which then leaks into J; see docs/fit.md); the plateaus of
    the new friction torque replace ``fr``'s. Returns the regression (None when stage 2 did not run)."""
    mech = tuple(n for n in rb.regs.free if n not in POLY_COEFS)
    fmap = _stage2_map(fr.plat, odd="offset" in mech) if mech and rb.fit is not None and fr.basis == "plateaus" \
        else None
    if fmap is None:
        return None
    name2, friction, v_low = fmap
    v_low = min(max(jd.min_speed, v_low), 0.5 * jd.w0)
    # the map is fitted on plateau points that carry stage 1's gravity and offset errors, and gives them
    # back as the friction: each plateau's level is left free (only its change along the plateau enters)
    # (only for gravity: along a plateau the acceleration is nil and the offset is what a level absorbs)
    own = {tuple(k): jd.min_speed for k in fr.keys.tolist()} if "Px" in mech or "Py" in mech else {}
    reg2, _ = regress(jd.preps, mech, rb.regs.known_coef, v_low, jd.axis, friction=friction, within=own)
    how = ", each plateau at a level of its own" if own else ""
    if reg2 is not None and "offset" in reg2.dependent:  # no moves outside the plateaus to set the offset
        reg2, _ = regress(jd.preps, mech, rb.regs.known_coef, v_low, jd.axis, friction=friction)
        how = ""
    if reg2 is not None and _stage2_lost(rb.fit, reg2):
        _keep_stage1(jd.jf, rb.fit, reg2)
        return None
    if reg2 is not None:
        if "J" in rb.fit.names and "J" not in rb.fit.dependent and "J" in reg2.names:
            reg2.friction_change = {"J": rb.fit.value("J")}
        set_mechanics(jd, reg2, rb.regs, rb.why,
                      f"least squares with the plateau map {name2} as the friction{how}, |w| > {v_low:.3g}")
        fr.plat, fr.keys = plateaus(jd)
        if "offset" in reg2.names and "offset" not in reg2.dependent:
            _offset_from_plateaus(jd, fr)
    return reg2


def _determined(fit_: rg.LinearFit, name: str) -> bool | None:
    """Whether the regression's own error of term ``name`` is below its value (None when not solved)."""
    if name not in fit_.names or name in fit_.dependent or fit_.n == 0:
        return None
    v, se = fit_.value(name), fit_.stderr(name)
    return bool(se is not None and np.isfinite(se) and se < abs(v))


def _stage2_lost(fit1: rg.LinearFit, fit2: rg.LinearFit) -> bool:
    """Stage 2 no longer determines the inertia that stage 1 determined: its own error of J is above J
    (the 100 % rule of :func:`_precision_reason`) where stage 1's is below. The plateaus' free levels and
    the map then take up the moves between the plateaus, and J, gravity and offset trade off without bound
    (foreign sweeps at 364 Hz with a cogging torque of 1.36 N m: stage 1 J 0.631, Py -0.036 +- 0.040,
    offset 0.092 +- 0.030; stage 2 J -19 +- 144, Py -416 +- 265 and offset -617 +- 210 trusted, and a
    Coulomb level of 684 N m against a torque within +-15 N m)."""
    return _determined(fit1, "J") is True and _determined(fit2, "J") is False


def _keep_stage1(jf: JointFit, fit1: rg.LinearFit, fit2: rg.LinearFit) -> None:
    """Stage 1's inertia, gravity and offset stand (:func:`_stage2_lost`); the inertia is not identifiable:
    stage 1's friction polynomial is what stage 2 exists to check, and stage 2 cannot."""
    j1, j2, se2 = fit1.value("J"), fit2.value("J"), fit2.stderr("J")
    pe = jf.inertia
    if pe is not None and pe.identifiable:
        pe.identifiable = False
        pe.reason = (f"with the plateau map as the friction the data do not determine it ({j2:.4g} +- {se2:.2g}; "
                     f"{j1:.4g} with the polynomial): the torque between the plateaus is not the map's (a torque "
                     "along the angle such as cogging, or friction dynamics), so the polynomial's bias is not "
                     "checked")
    jf.warnings.append(
        f"the rigid-body terms are stage 1's (the friction polynomial): with the plateau map as the friction "
        f"J is {j2:.4g} +- {se2:.2g}, the torque between the plateaus is not the map's")


def _offset_from_plateaus(jd: JointData, fr: Friction) -> None:
    """The offset as the part of the steady friction that does not change sign (stage 1's convention, an
    odd friction), measured on the plateaus: stage 2 sets the offset from the moves between plateaus with
    the map as the friction, where the friction's transients and the inertia's error also enter. The
    plateau points' even part (:func:`plateau_even`) is moved into the offset, and its size, the two
    estimates' disagreement, enters the offset's error with the even part's own error (a foreign sweep with
    no torque bias: stage 2's offset -0.085 +- 0.018 N m, the plateaus' 0.000; per-sign maps then carried
    0.085 as a difference between their Coulomb levels, selected over the symmetric truth)."""
    pe = jd.jf.offset
    even = plateau_even(fr.plat)
    if even is None or pe is None or pe.value is None or pe.stderr is None:
        return
    e, se = even
    fr.even_se = se
    pe.value += e
    pe.stderr = math.sqrt(pe.stderr**2 + se**2 + e**2)
    reason = _precision_reason("offset", "F", pe.value, pe.stderr, jd)
    pe.identifiable, pe.reason = not reason, reason
    fr.plat, fr.keys = plateaus(jd)


def odd_shifts(plat: Plateaus, shifts: list[np.ndarray] | None, even_se: float | None) -> list[np.ndarray] | None:
    """The shifts a symmetric map's points take when the offset was set from the plateaus' even part
    (:func:`_offset_from_plateaus`, ``even_se`` its error; None otherwise): the offset is then what makes
    the points odd, so an error of the inertia or gravity changes it with them and each shift loses its
    even part (:func:`plateau_even` of the shifted points); the offset's own error, as the points see it,
    is the even part's error, one constant shift. The stage-2 regression's offset error (the moves between
    the plateaus) otherwise entered whole: a symmetric map moves under an even shift only through its
    points' unequal weights at mirrored speeds, and foreign 224025 had Fc 7.1784 +- 0.083 against 7.1764,
    0.0011 before the shifts, 0.073 of them the offset's."""
    if even_se is None or not shifts:
        return None
    base = plateau_even(plat)
    if base is None:
        return None
    out = []
    for d in shifts:
        moved = plateau_even(replace(plat, F=plat.F + d))
        if moved is None:
            return None
        out.append(d - (moved[0] - base[0]))
    return out + [np.full(len(plat), float(even_se))]


def plateau_even(plat: Plateaus) -> tuple[float, float] | None:
    """The mean even part ``(F(v) + F(-v)) / 2`` [F] of plateau points and its standard error: each plateau
    of the sign with fewer plateaus against the other sign's points interpolated at its speed, where one of
    them lies within 10 % of it (:data:`.samples.LEVEL_TOLERANCE`); weighted by the pairs' errors, the error
    inflated by their scatter beyond it. None with fewer than 3 pairs."""
    w, F, se = (np.asarray(x, dtype=float) for x in (plat.w, plat.F, plat.F_se))
    ok = np.isfinite(w) & np.isfinite(F) & (w != 0)
    pos, neg = ok & (w > 0), ok & (w < 0)
    a, b = (pos, neg) if pos.sum() <= neg.sum() else (neg, pos)
    vb, o = np.abs(w[b]), np.argsort(np.abs(w[b]))
    vb, Fb, sb = vb[o], np.abs(F[b])[o], se[b][o]
    va, Fa, sa = np.abs(w[a]), np.abs(F[a]), se[a]
    near = np.array([vb.size > 0 and np.min(np.abs(vb - v)) <= smp.LEVEL_TOLERANCE * v for v in va], dtype=bool)
    near &= (va >= vb[0]) & (va <= vb[-1]) if vb.size else near
    if near.sum() < 3:
        return None
    # signed: F(+v) + F(-v) = |F_pos| - |F_neg|
    d = (Fa[near] - np.interp(va[near], vb, Fb)) * (1.0 if a is pos else -1.0) / 2.0
    s = 0.5 * np.hypot(sa[near], np.interp(va[near], vb, sb))
    s = np.where(np.isfinite(s) & (s > 0), s, np.nanmedian(s[s > 0]) if np.any(s > 0) else 1.0)
    wt = 1.0 / s**2
    e = float(np.sum(wt * d) / np.sum(wt))
    se_e = 1.0 / math.sqrt(float(np.sum(wt)))
    chi2 = float(np.sum(wt * (d - e) ** 2)) / max(d.size - 1, 1)
    return e, se_e * math.sqrt(max(chi2, 1.0))


def plateau_shifts(jd: JointData, fit_: rg.LinearFit, keys: np.ndarray) -> list[np.ndarray]:
    """How the plateau points move for one standard deviation of each independent error direction of the
    rigid-body terms subtracted from the torque (inertia, gravity, payload, offset): the plateau means of
    their regressors times the eigenvectors of their covariance (correlations from the regression, standard
    errors from the reported estimates, which carry the bandwidth check's systematic term). Empty when a
    plateau's regressors are not finite or a plateau is not found again (``keys``: per point, (log, segment))."""
    jf = jd.jf
    est = {"J": jf.inertia, "offset": jf.offset, **jf.gravity}
    names = [n for n in fit_.names if n not in POLY_COEFS and n not in fit_.dependent and n in est]
    if not names or len(keys) == 0:
        return []
    idx = [fit_.names.index(n) for n in names]
    C = np.asarray(fit_.cov, dtype=float)[np.ix_(idx, idx)]
    se_c = np.sqrt(np.maximum(np.diag(C), 0.0))
    se = np.array([est[n].stderr if est[n].stderr is not None and np.isfinite(est[n].stderr) else s_
                   for n, s_ in zip(names, se_c)])
    if not (np.all(np.isfinite(C)) and np.all(np.isfinite(se))):
        return []
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = np.nan_to_num(C / np.outer(se_c, se_c))
    np.fill_diagonal(corr, 1.0)
    lam, V = np.linalg.eigh(corr * np.outer(se, se))
    rows = {}
    for pi_, p in enumerate(jd.preps):
        cols = [np.nan_to_num(rg.column(n, p.log.q, p.w, p.a, p.log.channels.get("payload"), jd.axis,
                                        _trig(p, names, {}))) for n in names]
        seg, xb = plateau_column_means(p.w, p.F, p.segments, cols)
        rows.update({(pi_, int(k)): x for k, x in zip(seg, xb)})
    if any((int(a), int(b)) not in rows for a, b in keys):
        return []
    Xbar = np.array([rows[(int(a), int(b))] for a, b in keys], dtype=float).reshape(len(keys), len(names))
    if not np.all(np.isfinite(Xbar)):
        return []
    return [-(Xbar @ (V[:, i] * math.sqrt(l))) for i, l in enumerate(lam) if l > 0]


def plateaus(jd: JointData) -> tuple[Plateaus, np.ndarray]:
    """Friction torque per sample (stored on each prep, with the gravity torque) and the plateau points of
    all logs; keys[i] = (prep index, segment index) of plateau i."""
    jf, axis = jd.jf, jd.axis
    coef = {n: (pe.value if pe.value is not None else 0.0) for n, pe in
            [("J", jf.inertia), ("offset", jf.offset), *jf.gravity.items()] if n != "amplitude"}
    pls = []
    for pi_, p in enumerate(jd.preps):
        p.G = _gravity_torque(p, coef, axis)
        F = coef.get("J", 0.0) * np.nan_to_num(p.a)
        np.subtract(p.log.tau, F, out=F)
        F -= p.G
        p.F = F
        pls.append((pi_, plateau_points(p.log.t, p.w, p.F, p.segments)))
    pls = _sliding_only(jd, pls)
    cat = [(pi_, pl) for pi_, pl in pls if len(pl)]
    if cat:
        keys = np.array([(pi_, si) for pi_, pl in cat for si in pl.seg], dtype=int).reshape(-1, 2)
        plat = Plateaus(*(np.concatenate([getattr(c, f) for _, c in cat]) for f in
                          ("w", "F", "F_se", "w_se", "n", "t_start", "t_end", "seg")))
    else:
        keys = np.zeros((0, 2), int)
        z = np.zeros(0)
        plat = Plateaus(z, z, z, z, z.astype(int), z, z, z.astype(int))
    return plat, keys


def presliding_travel(jd: JointData) -> float:
    """The displacement [q] a load below break-away makes on this joint: the largest travel (position
    range) of its presliding-ramp segments, creep included (what such a load has been seen to do; the
    median let holds of 0.25-0.4 mrad through as plateaus on foreign 224078, where four of eleven ramps
    crept 0.75-1.33 mrad and the rest moved 0.16-0.24, and their loads took the Stribeck drop's Fs 7.8 %
    low, trusted); 0 without ramps or positions."""
    d = [float(np.ptp(p.log.q[s.i0:s.i1])) for p in jd.preps if p.log.q is not None
         for s in p.segments if s.kind == "ramp_presliding" and s.i1 - s.i0 > 1]
    d = [x for x in d if np.isfinite(x)]
    return float(np.max(d)) if d else 0.0


def _sliding_only(jd: JointData, pls: list) -> list:
    """The plateaus whose travel (mean speed times duration) exceeds the joint's presliding travel
    (:func:`presliding_travel`): a slower "plateau" is a hold in which the joint creeps or its bristles
    deflect under the load, whose torque is that load, anywhere below break-away, not the sliding
    friction at its speed (foreign card: holds at 0.2 mrad/s after each slow plateau, 0.09 mrad of travel
    against ramps of 0.7-3.7 mrad, pulled the Stribeck map's Fs 15 % low). Without ramps every plateau
    stays. Noted once in the joint's warnings."""
    scale = presliding_travel(jd)
    if scale <= 0:
        return pls
    out, dropped = [], 0
    for pi_, pl in pls:
        keep = np.abs(pl.w) * (pl.t_end - pl.t_start) > scale
        dropped += int(np.sum(~keep))
        out.append((pi_, pl.subset(keep) if not keep.all() else pl))
    msg = (f"{dropped} constant-velocity segment(s) travel less than the presliding ramps ({scale:.3g}): holds "
           "under load (creep or bristle deflection), not sliding; left out of the plateau points")
    if dropped and msg not in jd.jf.warnings:
        jd.jf.warnings.append(msg)
    return out


def _gravity_torque(p: Prep, coef: dict, axis: str) -> np.ndarray:
    """Gravity (and payload) torque plus the offset along a log [F]."""
    q = p.log.q
    G = np.zeros(p.log.n)
    if q is not None and axis == "rotary":
        cos_q, sin_q = p.trig()
        G = coef.get("Px", 0.0) * cos_q
        G += coef.get("Py", 0.0) * sin_q
    if "payload" in p.log.channels and q is not None:
        pl_ = p.log.channels["payload"]
        G += coef.get("Mx", 0.0) * pl_ * (p.trig()[0] if axis == "rotary" else 1.0)
        if axis == "rotary":
            G += coef.get("My", 0.0) * pl_ * p.trig()[1]
    G += coef.get("offset", 0.0)
    return G


def _stage2_map(plat, odd: bool = False):
    """The best-fitting per-sign static map on the plateaus, as a callable w -> F, or None when the
    plateaus do not cover both signs well enough.

    ``odd`` (the offset is estimated again): the map's even level, the mean of ``(F(v) + F(-v)) / 2`` over
    the plateau speeds stage 2 takes samples at (above ``v_low``; the fastest plateau when none is), is
    taken out. A per-sign map's two levels and the offset are not separable:
    fitted on plateau points that carry stage 1's offset error, the map carries it as a difference between
    its signs, and stage 2 with that map as the known friction gives the same offset back with a small
    error (a foreign sweep with no torque bias: offset 0.311 +- 0.018 N m, Fc_pos and Fc_neg 2.4 % either
    side of a symmetric truth, selected). Stage 1's convention holds instead: the part of the torque that
    does not change sign with the velocity is the offset."""
    if (plat.w > 0).sum() < 6 or (plat.w < 0).sum() < 6:
        return None
    best = None
    for name in STAGE2_MAPS:
        mf = fit_static(name, plat.w, plat.F, plat.F_se)
        vals = mf.values()
        if any(v is None for v in vals.values()) or mf.metrics.get("rms") is None:
            continue
        r = predict(name, vals, plat.w, True) - plat.F  # the formula's fit (its metrics score the file's model)
        rms = math.sqrt(float(np.mean(r[np.isfinite(r)] ** 2)))
        if best is None or rms < best[1]:
            best = (name, rms, vals)
    if best is None:
        return None
    name, _, vals = best
    # below ~3 Stribeck velocities the friction is dominated by the Stribeck drop and presliding lag,
    # which a static map does not follow through reversals: those samples do not enter stage 2
    speeds = [v for k, v in vals.items() if k.split("_")[0] in ("vs", "ws1", "ws2")]
    v_low = 3.0 * max(speeds) if speeds else 0.0
    even = 0.0
    if odd:
        v = np.abs(plat.w[np.isfinite(plat.w) & (plat.w != 0)])
        v = v[v >= min(v_low, v.max())] if v.size else v
        even = float(np.mean(predict(name, vals, v, True) + predict(name, vals, -v, True))) / 2.0 if v.size else 0.0
    # the map as fitted (a curve through the plateau points, which no parameter file runs)
    return name, (lambda w, _n=name, _v=vals, _e=even: predict(_n, _v, w, True) - _e), v_low
