"""The candidate causes: for each, the extension terms it proposes and how their nonlinear settings
(period, time constant, Stribeck velocity) are chosen, on training data only.

Every proposal is made inside a held-out fold from that fold's training samples, so the choice of a
period or a time constant is part of what the held-out error judges.
"""
from __future__ import annotations

import math

import numpy as np

from ..data import finite
from ..segments import noise_sigma
from .model import Coef, Context, Evaluator, Structure, Term, load_variable
from .samples import Samples
from .signals import delay_estimate, delay_estimates, delay_map, moving_samples, rest_scales

#: The causes, in the order the issue names them (``presliding`` is judged on ramp and step segments).
CAUSES = ("temperature", "position", "load", "asymmetry", "stribeck", "presliding", "inertia", "gravity",
          "offset", "drift", "dwell", "delay", "position_torque")

#: Causes that repair the fit's own estimate (its rigid body, its base map) rather than an effect in the plant:
#: the base model should have carried them (issue 20, "a clean base before searching"). A step that chooses
#: one is reported apart from the findings (``selection.diagnosis.repairs``, ``kind: repair``), never as a
#: cause found in the plant: a wrong inertia of the fit (biased by a torque delay or a coarse encoder), a
#: Stribeck hump its velocity-only choice lacks. Its term stays in the chain's model.
REPAIRS = ("inertia", "gravity", "stribeck")

#: Extension name -> (cause, role, number of coefficients).
EXTENSIONS = {
    "thermal4": ("temperature", "whole_factor", 1),
    "thermal6": ("temperature", "thermal6", 4),
    "position_periodic": ("position", "level_factor", 2),
    "position_smooth": ("position", "level_factor", 2),
    "load_torque": ("load", "level_factor", 1),
    "load_gravity": ("load", "level_factor", 1),
    "load_payload": ("load", "level_factor", 1),
    "asym_scale": ("asymmetry", "whole_factor", 1),  # the whole w < 0 branch times (1 + gamma)
    "asym_level": ("asymmetry", "level_factor", 1),  # the w < 0 level (Coulomb, Stribeck) times (1 + gamma)
    "asym": ("asymmetry", "asym", None),  # as many as the base map's amplitudes
    "stribeck": ("stribeck", "stribeck", 1),
    "inertia": ("inertia", "additive", 1),
    "gravity": ("gravity", "additive", 2),
    "offset": ("offset", "additive", 1),
    "drift": ("drift", "whole_factor", 1),
    # causes the parameter file's friction models do not carry (OUTSIDE_MODEL): named, never exported
    "dwell": ("dwell", "level_factor", 1),          # level times 1 + k ln(1 + t_rest / t0) exp(-s / s_c)
    "delay": ("delay", "additive", 1),              # d dtau/dt: the torque logged d seconds ahead of the motion
    "position_torque": ("position_torque", "additive", 2),   # a sin + b cos of 2 pi q / P: not friction
}

#: Time constants tried for the thermal state, per decade (then refined between the best neighbours).
TAU_PER_DECADE = 3
#: Fewest periods the position range must hold for a periodic term (its period searched) ...
MIN_PERIODS = 2.0
#: ... and for a gravity harmonic of a position torque (its period fixed in advance).
HARMONIC_MIN_CYCLES = 0.5
#: A thermal state (heat balance, no measured temperature) is a slow variable only if the current velocity
#: explains at most this fraction of its variance; otherwise it is a proxy for the speed (a time constant
#: of a fraction of a second makes it the instantaneous friction power) and the data cannot resolve it.
THERMAL_R2_MAX = 0.5
#: A thermal time constant (heat balance, no measured temperature) is resolvable only when it is at least
#: this many times the mean duration of a one-sign run of the motion (slow against the excitation) ...
TAU_MIN_RUNS = 5.0
#: ... and the recording spans at least this many of the shortest resolvable time constant (a warm-up
#: must show its curvature, not only a trend): 15 half-cycles of motion at least.
SPAN_MIN_TAUS = 3.0
#: The inertia cause is tested only when the sliding samples carry at least this share of the acceleration
#: excitation (sum of a^2) of the moving samples: the fit's inertia rests on all of them, and a subset with
#: little acceleration cannot overrule it (on a pulses run it turns transients into a 56 % inertia change).
INERTIA_EXCITATION_MIN = 0.25

#: A structure is worth stating when the RMS it explains is at least this many times the noise of the
#: friction torque (and EXPLAINED_MIN of the friction RMS): a systematic part the size of the sample noise
#: is what any estimated acceleration and held shape leave (clean logs of the shipped plants: 1-2x).
X_NOISE = 3.0


def torque_noise(S: Samples) -> float:
    """The noise [F] the logs show on the friction torque the diagnosis fits, ``F = tau - J a - G`` (the
    torque sensor's and that of the estimated acceleration): the largest robust white-noise level of a
    log's F (MAD of its fourth difference)."""
    return S.cached("torque_noise", lambda: max((noise_sigma(finite(lg.F)) for lg in S.logs if lg.n > 10),
                                                default=0.0))


def n_coef(ext: str, st: Structure) -> int:
    k = EXTENSIONS[ext][2]
    return len(st.slots()) if k is None else k


def candidates(S: Samples, st: Structure, ctx: Context | None = None) -> list[str]:
    """Extensions worth testing on these samples on top of structure st (one cause enters once).

    Plausibility guards (docs/diagnosis.md): temperature without a measured joint temperature needs a
    thermal time constant the data resolve (:func:`tau_grid`); inertia needs the sliding samples to carry
    a fair share of the acceleration excitation (:func:`acceleration_share`); drift needs recordings with
    known start times (logs laid end to end are one warm-up)."""
    have = {t.cause for t in st.terms}
    out = []
    span_h = float(S.th.max() - S.th.min())
    if "temperature" not in have and span_h * 3600 > 20 * _dt(S) and (
            S.temp_joint is not None or any(tau_grid(S, ctx, K).size for K in S.conductances())):
        out += ["thermal4", "thermal6"]
    if "position" not in have and S.q is not None and np.ptp(S.q) > 0:
        out.append("position_smooth")
        if _period_range(S) is not None:
            out.append("position_periodic")
    if "load" not in have:
        out.append("load_torque")
        if np.std(S.G) > 1e-9 * (np.std(S.F) + 1e-300) and np.std(S.G) > 0:
            out.append("load_gravity")
        if S.payload is not None and np.std(S.payload) > 0:
            out.append("load_payload")
    if "asymmetry" not in have and (S.w > 0).any() and (S.w < 0).any():
        # asym_level (the w < 0 level scaled) is not tested: on the direct-drive sample its per-sign export
        # (stribeck_2exp_asym) has amplitudes the folds cannot pin, and export refuses it (test_export)
        out += ["asym_scale", "asym"]
    if "stribeck" not in have and 1 not in st.slots():
        out.append("stribeck")
    if "inertia" not in have and np.std(S.a) > 0 and acceleration_share(S) >= INERTIA_EXCITATION_MIN:
        out.append("inertia")
    if "gravity" not in have and S.q is not None and S.axis_rotary and np.ptp(S.q) > 0:
        out.append("gravity")
    if "offset" not in have:
        out.append("offset")
    if "drift" not in have and len(S.logs) > 1 and span_h > 0 and S.clock_real:
        out.append("drift")
    if "dwell" not in have and S.q is not None and rest_scales(S) is not None:
        out.append("dwell")
    if "delay" not in have and moving_samples(S) >= 20 * S.n_folds:
        out.append("delay")
    if "position_torque" not in have and S.q is not None and np.ptp(S.q) > 0:
        out.append("position_torque")
    return out


def _torque_periods(S: Samples) -> list[float]:
    """Periods [q] fixed in advance for a position torque: on a rotary joint the gravity harmonics 2 pi / k
    (k = 2, 3, 4: a spring compensator, an eccentric or elliptic part; k = 1 is gravity itself) that fit
    in the range of positions at least :data:`HARMONIC_MIN_CYCLES` times (a period fixed in advance is no
    setting chosen on the data: half a cycle tells sin 2q from the gravity's cos q, sin q) ... and (0 here), in :func:`propose`, the best period of the
    residual's periodogram, when the range holds periods to search."""
    fixed = [2 * math.pi / k for k in (2, 3, 4)] if S.axis_rotary else []
    rng = float(np.ptp(S.q))
    return [P for P in fixed if P <= rng / HARMONIC_MIN_CYCLES] + ([0.0] if _period_range(S) is not None else [])


def _dt(S: Samples) -> float:
    return S.dt(0)


def _period_range(S: Samples):
    """(shortest, longest) period [q] a periodic position term may have, or None (computed once per
    samples: the median speed is a partition of every sample)."""
    return S.cached("period_range", lambda: _period_range_of(S))


def _period_range_of(S: Samples):
    rng = float(np.ptp(S.q))
    dq = float(np.median(np.abs(S.w))) * _dt(S) * max(S.decimation, 1)
    p_min = max(10 * dq, rng / 2000.0)
    p_max = rng / MIN_PERIODS
    return (p_min, p_max) if p_max > 2 * p_min else None


def acceleration_share(S: Samples) -> float:
    """Share of the acceleration excitation (sum of a^2 over the moving samples, faster than 2 % of the top
    speed) that the sliding samples carry (their decimation undone)."""
    return S.cached("acceleration_share", lambda: _acceleration_share(S))


def _acceleration_share(S: Samples) -> float:
    tot = 0.0
    for i in range(len(S.logs)):
        w, a = S.log_w(i), S.log_a(i)
        m = np.abs(w) > 0.02 * S.w0
        tot += float(np.sum(a[m] ** 2))
    if tot <= 0:
        return 0.0
    return min(1.0, float(np.sum(S.a ** 2)) * max(S.decimation, 1) / tot)


def velocity_r2(S: Samples, x: np.ndarray, basis=None) -> float:
    """Fraction of the variance of x that the current velocity explains (least squares on 1, sgn w, w,
    |w|, w|w|, w^3 and |w|^(1/2)); basis : :func:`velocity_basis` (computed when None)."""
    cols, Ginv = velocity_basis(S) if basis is None else basis
    # einsum dot products of contiguous vectors: a threaded BLAS ddot per column costs ten times more on
    # a busy machine (as in model._lstsq)
    Xx = np.array([np.einsum("i,i->", c, x) for c in cols])
    var = float(np.sum((x - x.mean()) ** 2))
    rss = float(np.einsum("i,i->", x, x) - Xx @ Ginv @ Xx)
    return 1.0 - max(rss, 0.0) / var if var > 0 else 1.0


def velocity_basis(S: Samples):
    """The columns of :func:`velocity_r2` (scaled to unit norm) and the pseudo-inverse of their Gram matrix:
    the projection of any x needs only the seven sums ``X'x`` (no n x 7 factorisation)."""
    w = S.w
    v = np.abs(w)
    cols = [np.ones_like(w), np.sign(w), w, v, w * v, w ** 3, np.sqrt(v)]
    cols = [c / max(float(np.sqrt(np.einsum("i,i->", c, c))), 1e-300) for c in cols]
    G = np.array([[np.einsum("i,i->", a, b) for b in cols] for a in cols])
    return cols, np.linalg.pinv(G, rcond=1e-12, hermitian=True)


def run_time(S: Samples) -> float:
    """Mean duration [s] of a run of one velocity sign (moving faster than 2 % of the top speed) over the
    logs: the time scale of the excitation (half a cycle of a back-and-forth motion)."""
    total, runs = 0.0, 0
    for i, lg in enumerate(S.logs):
        w = S.log_w(i)
        m = np.abs(w) > 0.02 * S.w0
        if m.sum() < 2:
            continue
        sg = np.sign(w[m])
        runs += 1 + int(np.count_nonzero(np.diff(sg)))
        dt = np.diff(lg.t)
        total += float(np.sum(dt[m[:-1]]))
    return total / runs if runs else math.inf


def tau_grid(S: Samples, ctx: Context | None = None, K: float = 1.0) -> np.ndarray:
    """Thermal time constants [s] tried for the heat balance, only those the data resolve: from
    :data:`TAU_MIN_RUNS` one-sign runs of the motion (and 1/100 of the recording) to the span of the
    longest log (the state starts cold in every log; a longer time constant is a trend the recording
    cannot tell from anything else slow), none when that log is shorter than :data:`SPAN_MIN_TAUS` of the
    shortest, and only those whose thermal state is a slow variable, not a proxy for the speed
    (:data:`THERMAL_R2_MAX`), for the heat balance's conductance ``K`` (:meth:`Samples.conductances`)."""
    if ctx is None:
        ctx = Context(S)
    key = ("tau_grid",) if K == 1.0 else ("tau_grid", float(K))
    if key in ctx._cache:
        return ctx._cache[key]
    # the thermal state starts cold at the start of every log: the longest log is what can resolve it
    span = max(max((float(np.ptp(S.t[S.li == i])) for i in np.unique(S.li)), default=0.0), 10 * _dt(S))
    lo, hi = max(span / 100.0, TAU_MIN_RUNS * run_time(S)), span
    if not (SPAN_MIN_TAUS * lo <= hi):
        grid = np.zeros(0)
    else:
        n = max(3, int(round(TAU_PER_DECADE * math.log10(hi / lo))) + 1)
        grid = np.geomspace(lo, hi, n)
        basis = velocity_basis(S)
        grid = np.array([tc for tc in grid if velocity_r2(S, ctx.thermal(tc, "heat_balance", K), basis)
                         <= THERMAL_R2_MAX])
    ctx._cache[key] = grid
    return grid


def _fit_rms(ctx: Context, st: Structure, idx) -> float:
    return Evaluator(st, ctx).fit(idx).rms


def propose(ext: str, ctx: Context, st: Structure, idx: np.ndarray, resid: np.ndarray, level: np.ndarray,
            coef: Coef | None = None) -> Term | None:
    """The term of extension ``ext`` on top of st, its settings chosen on the training samples idx.

    resid : the current model's residual on idx (training); level : the current model's signed level
    ``mL g`` on idx (for the periodogram of the position term); coef : the current model's coefficients
    fitted on idx (a load term's variable carries its gravity and inertia corrections, :func:`_rigid_fix`).
    """
    S = ctx.S
    cause, role, _ = EXTENSIONS[ext]
    if ext in ("thermal4", "thermal6"):
        best = None
        sources = ["heat_balance"] + (["temp_joint"] if S.temp_joint is not None else [])
        per_source = {}
        for src in sources:
            if src == "temp_joint":
                cand = [_thermal_trial(ctx, st, idx, ext, src, 1.0)]
            else:   # the time constant on its grid, for each conductance the data offer
                cand = [c for K in S.conductances() for c in _thermal_grid(ctx, st, idx, ext, K)]
                if not cand:
                    continue
            per_source[src] = min(cand, key=lambda c: c[0])
        return _thermal_source(per_source, S, idx)

    if ext == "position_periodic":
        P = best_period(S.q[idx], resid, level, _period_range(S))
        return None if P is None else Term(cause, ext, role, (("period", float(P)),))
    if ext == "position_torque":
        return _position_torque(ctx, st, idx, resid)
    if ext == "dwell":
        return _dwell(ctx, st, idx)
    if ext == "delay":   # the shift estimated on the training folds' moving samples
        f = ctx.fold_of(idx)   # a training set's fold is remembered: no gather of its folds
        folds = ([g for g in range(S.n_folds) if g != f] if f is not None and f is not False
                 else np.unique(S.fold[idx]))
        left = np.setdiff1d(np.arange(S.n_folds), folds)
        # a training set of all folds but one: the estimates of every such set at once (one pass for their maps)
        d = delay_estimates(S)[int(left[0])] if left.size == 1 else delay_estimate(S, folds)
        return Term(cause, ext, role, (("shift", d), ("beta", delay_map(S, d, folds))))
    if ext == "position_smooth":
        q0 = float(0.5 * (S.q.max() + S.q.min()))
        qs = float(0.5 * np.ptp(S.q)) or 1.0
        return Term(cause, ext, role, (("q0", q0), ("qs", qs)))
    if ext.startswith("load_"):
        fix = _rigid_fix(st, coef) if ext != "load_payload" else ()
        var = load_variable(S, ext, dict(fix))
        sc = float(np.sqrt(np.mean(var * var))) or 1.0
        return Term(cause, ext, role, (("scale", sc),) + fix)
    if ext == "stribeck":
        best = None
        grid = [Term(cause, ext, role, (("vs", float(vs)), ("delta", d)))
                for vs in np.geomspace(max(S.v_min, 1e-12), S.w0 / 3.0, 8) for d in (1.0, 2.0)]
        ctx.prefetch([st.plus(term) for term in grid])   # the grid's sums in one pass
        for term in grid:
            r = _fit_rms(ctx, st.plus(term), idx)
            if best is None or r < best[0]:
                best = (r, term)
        return best[1]
    return Term(cause, ext, role, ())


#: Refinements of the dwell's fading travel ``s_c`` between the grid's neighbours (factors of the grid step).
DWELL_REFINE = (-0.5, -0.25, 0.25, 0.5)


def _dwell(ctx: Context, st: Structure, idx: np.ndarray) -> Term:
    """The dwell term, its ``t0`` and fading travel ``s_c`` chosen on the training samples idx: the grid of
    :func:`frictid.diagnose.signals.rest_scales` (``s_c`` a factor of 3 apart), then ``s_c`` refined between
    the best one's neighbours (:data:`DWELL_REFINE`). On the coarse grid a dwell that fades over half the
    grid step leaves a residual shaped by the rests, which a fast thermal state follows (foreign seed
    304007: ``s_c`` 0.67 rad for the plant's 0.35, then thermal6 with a 54 s time constant named after it)."""
    S = ctx.S
    t0s, scs = rest_scales(S)

    def term(t0, sc):
        return Term("dwell", "dwell", "level_factor", (("t0", float(t0)), ("s_c", float(sc))))
    grid = [(t0, sc) for t0 in t0s for sc in scs]
    ctx.prefetch([st.plus(term(t0, sc)) for t0, sc in grid])   # the grid's sums in one pass
    scored = [(_fit_rms(ctx, st.plus(term(t0, sc)), idx), t0, sc) for t0, sc in grid]
    _, t0, sc = min(scored, key=lambda x: x[0])
    step = float(scs[1] / scs[0]) if scs.size > 1 else 1.0
    ctx.prefetch([st.plus(term(t0, sc * step ** f)) for f in DWELL_REFINE])   # the refinements in one pass
    scored += [(_fit_rms(ctx, st.plus(term(t0, sc * step ** f)), idx), t0, sc * step ** f) for f in DWELL_REFINE]
    _, t0, sc = min(scored, key=lambda x: x[0])
    return term(t0, sc)


def _rigid_fix(st: Structure, coef: Coef | None) -> tuple:
    """The current model's corrections of the fit's rigid body, as settings of a load term: ``dPx``, ``dPy``
    (its gravity term's coefficients) and ``dJ`` (its inertia term's), those it has."""
    if coef is None:
        return ()
    out = []
    for i, t in enumerate(st.terms):
        g = np.atleast_1d(coef.gamma.get(i, np.zeros(0)))
        if t.ext == "gravity" and g.size == 2:
            out += [("dPx", float(g[0])), ("dPy", float(g[1]))]
        elif t.ext == "inertia" and g.size == 1:
            out.append(("dJ", float(g[0])))
    return tuple(out)


def _position_torque(ctx: Context, st: Structure, idx: np.ndarray, resid: np.ndarray) -> Term | None:
    """The position torque's period: the fixed gravity harmonics and the residual's periodogram peak
    (additive: the level is one), the best on the training samples."""
    S = ctx.S
    periods = [P for P in _torque_periods(S) if P > 0]
    if _period_range(S) is not None:
        P = best_period(None, resid, None, _period_range(S), bins=ctx.position_bins(idx, _period_range(S)[0]))
        if P is not None:
            periods.append(float(P))
    terms = [Term("position_torque", "position_torque", "additive", (("period", float(P)),)) for P in periods]
    # a torque that varies smoothly over the travel (a spring, a cable carrier, a harmonic longer than the
    # range): 1, (q - q0) and (q - q0)^2 over the half-range, period 0 (its mean over the travel is part of
    # it: without the constant, a harmonic of a short travel was split into an offset and a shape)
    q0, qs = float(0.5 * (S.q.max() + S.q.min())), float(0.5 * np.ptp(S.q)) or 1.0
    terms.append(Term("position_torque", "position_torque", "additive", (("period", 0.0), ("q0", q0), ("qs", qs))))
    ctx.prefetch([st.plus(term) for term in terms])   # their sums in one pass
    return min(terms, key=lambda term: _fit_rms(ctx, st.plus(term), idx))


def _thermal_term(ext: str, src: str, tc: float, K: float = 1.0) -> Term:
    """A thermal term: its source, time constant [s] and, when not 1, the heat balance's conductance K."""
    cause, role, _ = EXTENSIONS[ext]
    nl = (("source", src), ("tau_c", float(tc))) + ((("K", float(K)),) if K != 1.0 else ())
    return Term(cause, ext, role, nl)


def _thermal_trial(ctx: Context, st: Structure, idx, ext: str, src: str, tc: float, K: float = 1.0) -> tuple:
    """(training RMS, term) of a thermal term."""
    term = _thermal_term(ext, src, tc, K)
    return _fit_rms(ctx, st.plus(term), idx), term


def _thermal_grid(ctx: Context, st: Structure, idx, ext: str, K: float) -> list:
    """The heat balance's trials (training RMS, term) on its time-constant grid (:func:`tau_grid`) for the
    conductance K, and a third of a grid step either side of the best."""
    grid = tau_grid(ctx.S, ctx, K)
    if not grid.size:
        return []
    ctx.prefetch([st.plus(_thermal_term(ext, "heat_balance", tc, K)) for tc in grid])
    cand = [_thermal_trial(ctx, st, idx, ext, "heat_balance", tc, K) for tc in grid]
    k = int(np.argmin([c[0] for c in cand]))
    step = 10.0 ** (1.0 / TAU_PER_DECADE)
    near = [grid[k] * step ** f for f in (-1 / 3, 1 / 3) if grid[0] <= grid[k] * step ** f <= grid[-1]]
    ctx.prefetch([st.plus(_thermal_term(ext, "heat_balance", tc, K)) for tc in near])
    return cand + [_thermal_trial(ctx, st, idx, ext, "heat_balance", tc, K) for tc in near]


def _thermal_source(per_source: dict, S: Samples, idx: np.ndarray) -> Term | None:
    """The thermal term of the better source: the logged joint temperature, unless the heat balance
    (which has a time constant chosen on the same data) is better by Akaike's criterion with the training
    groups as the independent units, ``G ln(RSS_measured / RSS_balance) > 2``: a measurement is preferred to
    a model of it that explains the residual no better."""
    if not per_source:
        return None
    hb, tj = per_source.get("heat_balance"), per_source.get("temp_joint")
    if hb is None or tj is None:
        return (hb or tj)[1]
    G = _training_groups(S, idx)
    if hb[0] > 0 and tj[0] > 0 and 2.0 * G * math.log(tj[0] / hb[0]) > 2.0:   # RMS ratio squared
        return hb[1]
    return tj[1]


def _training_groups(S: Samples, idx: np.ndarray) -> int:
    """The number of groups with samples in idx."""
    return int(np.count_nonzero(np.bincount(S.group[idx], minlength=S.n_groups)))


def _score(Cr: np.ndarray, D: np.ndarray, sB: float) -> np.ndarray:
    """Explained sum of squares of ``level (a sin + b cos)(2 pi f q)`` per frequency, from ``Cr = sum r g
    e^(-i theta)``, ``D = sum g^2 e^(-2 i theta)`` and ``sB = sum g^2`` (theta = 2 pi f q)."""
    cr, sr = Cr.real, -Cr.imag
    cc, ss, sc = 0.5 * (sB + D.real), 0.5 * (sB - D.real), -0.5 * D.imag
    det = ss * cc - sc * sc
    det = np.where(det > 0, det, np.inf)
    return (cc * sr * sr - 2 * sc * sr * cr + ss * cr * cr) / det


def best_period(q, resid, level, prange, n_keep: int = 3, bins: tuple | None = None) -> float | None:
    """Period [q] of the level modulation ``level (a sin + b cos)(2 pi q / P)`` that best explains resid.

    A least-squares periodogram over frequencies ``1/P`` from ``1/P_max`` to ``1/P_min`` at a quarter
    cycle over the range: the sums of its 2x2 normal equations come from FFTs of ``resid * level`` and
    ``level^2`` binned in position (bins of ``P_min / 8``); the best few peaks are then refined on a fine
    frequency grid with the sums of every sample over bins of ``P_min / 32``.

    bins : for a level of one (q and level then unused), the positions' lowest value, their range, each
    sample's fine bin and the samples per fine bin, as computed here
    (:meth:`frictid.diagnose.model.Context.position_bins`: kept for a training set, which the chain's
    steps search again).
    """
    if prange is None or (q.size if bins is None else bins[2].size) < 20:
        return None
    p_min, p_max = prange
    h2 = p_min / 32.0
    if bins is None:
        q = np.asarray(q, float)
        rr = np.asarray(resid, float) * np.asarray(level, float)
        gg = np.asarray(level, float) ** 2
        q0 = float(q.min())
        rng = float(np.ptp(q))
        nb2 = int(rng / h2) + 1
        j2 = np.minimum(((q - q0) / h2).astype(np.int64), nb2 - 1)
        B2 = np.bincount(j2, weights=gg, minlength=nb2)
    else:
        (q0, rng, j2, B2), rr = bins, np.asarray(resid, float)
        nb2 = B2.size
    h = p_min / 8.0
    nb = int(rng / h) + 1
    # the fine bins of the refinement (below, P_min / 32) first: a coarse bin is four of them exactly (the
    # widths differ by a power of two, so (q - q0) / h2 is 4 (q - q0) / h to the last bit), its sums theirs
    A2 = np.bincount(j2, weights=rr, minlength=nb2)
    A, B = (np.pad(x, (0, max(4 * nb - nb2, 0)))[:4 * nb].reshape(nb, 4).sum(axis=1) for x in (A2, B2))
    N = 1 << int(math.ceil(math.log2(max(8 * nb, 16))))
    FA = np.fft.rfft(A, N)
    FB = np.fft.rfft(B, N)
    k = np.arange(FA.size)
    f = k / (N * h)
    ok = (f >= 1.0 / p_max) & (f <= 1.0 / p_min) & (2 * k < FB.size)
    if not ok.any():
        return None
    k, f = k[ok], f[ok]
    qc = q0 + 0.5 * h  # bin centres q0 + (j + 1/2) h
    Cr = FA[k] * np.exp(-2j * np.pi * f * qc)
    D = FB[2 * k] * np.exp(-4j * np.pi * f * qc)
    score = _score(Cr, D, B.sum())

    df = 1.0 / (N * h)
    # the refinement: the same score on a fine frequency grid from sums over fine position bins of every
    # sample (width P_min / 32: a phase error of at most pi / 32 within a bin at the shortest period)
    used = np.flatnonzero((A2 != 0) | (B2 != 0))   # bins without samples add nothing
    qb, A2, B2 = q0 + (used + 0.5) * h2, A2[used], B2[used]

    def exact(freqs):
        # freqs are equally spaced: exp(-2 pi i f_k q) by the recurrence z_k = z_(k-1) r (two complex
        # exponentials per bin, not one per bin and frequency, and no threaded BLAS for the thin products;
        # the same sums to rounding)
        step = (freqs[-1] - freqs[0]) / max(freqs.size - 1, 1)
        z = np.exp(-2j * np.pi * freqs[0] * qb)
        r = np.exp(-2j * np.pi * step * qb)
        Cr, D = np.empty(freqs.size, complex), np.empty(freqs.size, complex)
        for k in range(freqs.size):
            if k:
                z *= r
            Cr[k] = np.einsum("i,i->", z, A2)
            D[k] = np.einsum("i,i->", z * z, B2)
        return _score(Cr, D, B2.sum())

    best_f, best_s = None, -np.inf
    for i in np.argsort(score)[::-1][:n_keep]:
        fine = np.linspace(f[i] - 2 * df, f[i] + 2 * df, 17)
        fine = fine[fine > 0]
        s2 = exact(fine)
        jj = int(np.argmax(s2))
        if s2[jj] > best_s:
            best_s, best_f = s2[jj], fine[jj]
    return None if best_f is None else 1.0 / best_f
