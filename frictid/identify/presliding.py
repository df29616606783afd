"""LuGre dynamic parameters: sigma0 from ramp-presliding segments, sigma1 from step transients
(MODELS.md sections 3-4; 000 eq 12-16, 001).

sigma0. Under a slow torque ramp below break-away the joint creeps by micro-displacements and the
bristle state ``z`` follows the LuGre equation written in the displacement domain (rate independent)::

    dz/dq = 1 - sigma0 sgn(dq) z / g

so along the measured position path ``F = sigma0 z`` (``sigma1 dz/dt + sigma2 w`` is taken out of the
torque by the caller once sigma1 is known, :func:`.dynamics._without_damping`). For small
deflections ``z ~ q - q0`` and ``sigma0`` is the slope of torque against displacement (000 eq 12-15); the
displacement-domain integration keeps that slope exact when the bristles start to saturate. The start
state is the equilibrium ``z0 = F(t0) / sigma0``. ``g`` is the static map's level at zero speed, or (with
``free_limit``) fitted on the ramps' curvature with sigma0 (:func:`_with_free_limit`).

sigma1. Each step segment is simulated (joint + LuGre, the exact linearised step of
:func:`frictid.models.lugre.lugre_step`, stable for the stiff bristle dynamics) from the measured torque, and ``sigma1`` minimises the squared difference between
simulated and measured position (simulation error). Without steps, the near-critical-damping rule of 000
eq 16 is used: ``sigma1 = 2 zeta sqrt(sigma0 J) - sigma2`` with ``zeta`` in [0.8, 1] (0.9 +- 0.058, the
standard deviation of a uniform distribution on that range), and the file says so.

Encoder resolution. When the presliding displacement spans fewer than :data:`MIN_COUNTS` encoder counts
(001's 2 pi/76800 rad encoder against a stiffness of 5e4 N m/rad) sigma0 is reported not identifiable
instead of a number fitted to quantisation steps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from frictid.models.lugre import _FM, dviscous_nb, level_slope_nb, lugre_core, lugre_step, lugre_step_ref, viscous_nb
from frictid.models.static import canonical_level, canonical_viscous

from .smallsq import least_squares

#: Minimum presliding displacement, in encoder counts, for sigma0 to be identifiable.
MIN_COUNTS = 20

#: Damping ratio range of the critical-damping rule (000 eq 16).
ZETA = (0.8, 1.0)


def encoder_resolution(q: np.ndarray) -> float:
    """Quantisation step [q] of a position signal: the smallest non-zero change when at least a third of
    the sample-to-sample changes are exactly zero (a quantised encoder), else 0 (continuous)."""
    q = np.asarray(q, dtype=float)
    d = np.abs(np.diff(q))
    d = d[np.isfinite(d)]
    if d.size < 10:
        return 0.0
    zero = d <= 1e-15 * max(1.0, float(np.max(np.abs(q))))
    if zero.mean() < 1.0 / 3.0:
        return 0.0
    nz = d[~zero]
    if nz.size == 0:
        return 0.0
    return float(np.min(nz))


def bristle_path(q: np.ndarray, z0: float, sigma0: float, g: float) -> np.ndarray:
    """Bristle deflection z [q] along a position path q [q] (LuGre in the displacement domain, exact for
    a piecewise-constant sign of motion between samples). g : bristle limit level [F] (> 0)."""
    return _bristle_path_nb(np.ascontiguousarray(q, dtype=float), float(z0), float(sigma0), float(g))


def bristle_path_ref(q: np.ndarray, z0: float, sigma0: float, g: float) -> np.ndarray:
    """Pure-python twin of :func:`bristle_path` (for tests)."""
    z = np.empty_like(q, dtype=float)
    z[0] = z0
    zmax = g / sigma0
    dq = np.diff(q)
    zi = z0
    for i in range(dq.shape[0]):
        d = dq[i]
        if d != 0.0:
            s = 1.0 if d > 0 else -1.0
            # dz/dq = 1 - s z/zmax on this step: z -> s zmax + (z - s zmax) exp(-|d|/zmax)
            zi = s * zmax + (zi - s * zmax) * math.exp(-abs(d) / zmax)
        z[i + 1] = zi
    return z


@njit(cache=True)
def _bristle_path_nb(q, z0, sigma0, g):
    n = q.shape[0]
    z = np.empty(n)
    z[0] = z0
    zmax = g / sigma0
    zi = z0
    for i in range(n - 1):
        d = q[i + 1] - q[i]
        if d != 0.0:
            s = 1.0 if d > 0 else -1.0
            zi = s * zmax + (zi - s * zmax) * math.exp(-abs(d) / zmax)
        z[i + 1] = zi
    return z


@njit(cache=True, error_model="numpy")
def _ramp_forces_nb(q, bounds, F0, g, sigma0, y, dy):
    """Bristle force ``y = sigma0 z`` [F] along each ramp's position path (ramp r is
    ``q[bounds[r]:bounds[r + 1]]``, its bristle limit g[r] [F], its start force F0[r] clipped to 0.999 of
    it) and ``dy / d log(sigma0)`` [F], into y and dy. In force units the step of :func:`bristle_path` is
    ``y -> s g + (y - s g) e``, ``e = exp(-|dq| sigma0 / g)``, and its start does not depend on sigma0,
    so the derivative follows ``dy -> dy e - (y - s g) e |dq| sigma0 / g`` from 0."""
    for r in range(bounds.shape[0] - 1):
        i0 = bounds[r]
        i1 = bounds[r + 1]
        gr = g[r]
        k = sigma0 / gr
        yi = min(max(F0[r], -0.999 * gr), 0.999 * gr)
        di = 0.0
        y[i0] = yi
        dy[i0] = 0.0
        for i in range(i0, i1 - 1):
            d = q[i + 1] - q[i]
            if d != 0.0:
                ys = gr if d > 0.0 else -gr
                ad = abs(d)
                e = math.exp(-ad * k)
                di = di * e - (yi - ys) * e * ad * k
                yi = ys + (yi - ys) * e
            y[i + 1] = yi
            dy[i + 1] = di


@dataclass
class DynamicEstimate:
    """sigma0 / sigma1 estimate: value, stderr, identifiable, reason, source and fit details."""

    value: float | None
    stderr: float | None
    identifiable: bool
    reason: str = ""
    source: str = ""
    n_segments: int = 0
    rms: float | None = None
    details: dict = field(default_factory=dict)


def _start_slope(ramps: list[tuple[np.ndarray, np.ndarray]], g0s: list[float], span: float) -> float:
    """A data-derived start for sigma0 [F/q]: the median slope of F against displacement over the lower half
    of each ramp (|F| below half its bristle limit); the limit over the span when no ramp gives one."""
    slopes = []
    for (q, F), g0 in zip(ramps, g0s):
        x = q - q[0]
        lim = 0.5 * g0
        m = np.abs(F) < lim
        if m.sum() > 5 and np.ptp(x[m]) > 0:
            slopes.append(abs(np.polyfit(x[m], F[m], 1)[0]))
    return float(np.median(slopes)) if slopes else max(g0s) / span


class _RampForces:
    """The least-squares problem of sigma0 on the ramps: all ramps in one compiled pass
    (:func:`_ramp_forces_nb`), the residual and its analytic derivative in log(sigma0) together."""

    def __init__(self, ramps: list[tuple[np.ndarray, np.ndarray]], g0s: list[float]):
        self.qs = np.concatenate([np.asarray(q, dtype=float) for q, _ in ramps])
        self.Fs = np.concatenate([np.asarray(F, dtype=float) for _, F in ramps])
        self.bounds = np.cumsum([0] + [len(q) for q, _ in ramps]).astype(np.int64)
        self.F0 = np.array([float(F[0]) for _, F in ramps])
        self.gs = np.array(g0s, dtype=float)
        self.y, self.dy = np.empty(self.qs.size), np.empty(self.qs.size)
        self.at = None

    def _eval(self, p):
        if self.at != p[0]:
            _ramp_forces_nb(self.qs, self.bounds, self.F0, self.gs, math.exp(p[0]), self.y, self.dy)
            self.at = p[0]

    def resid(self, p):
        self._eval(p)
        return self.y - self.Fs

    def jac(self, p):
        self._eval(p)
        return self.dy.reshape(-1, 1).copy()

    def with_limits(self, gs) -> "_RampForces":
        """The same ramps with the bristle limits ``gs`` [F]."""
        self.gs = np.asarray(gs, dtype=float)
        self.at = None
        return self

    def fit(self, starts):
        """The best Levenberg-Marquardt result in log(sigma0) over the starts [F/q], or None."""
        best = None
        for s_init in starts:
            try:
                r = least_squares(self.resid, [math.log(s_init)], jac=self.jac, ftol=1e-10, xtol=1e-10)
            except ValueError:
                continue
            if best is None or r.cost < best.cost:
                best = r
        return best


def fit_sigma0(ramps: list[tuple[np.ndarray, np.ndarray]], g0, resolution: float = 0.0,
               starts: tuple[float, ...] | None = None, free_limit: bool = False) -> DynamicEstimate:
    """sigma0 [F/q] from ramp-presliding segments.

    ramps : list of (q [q], F [F]) per segment, F the friction torque ``tau - G - offset`` (a ~ 0).
    g0 : static friction level at zero speed [F], one number or one per ramp (per-sign maps).
    resolution : encoder step [q] (0 when continuous).
    starts : initial sigma0 values [F/q] (e.g. a held-out refit from the full-data optimum); default the
    median slope of torque against displacement over the lower half of the ramps, times 1, 0.3 and 3.
    free_limit : fit the bristle limits too (one factor on ``g0``, :func:`_with_free_limit`); sigma0's
    error then carries the trade-off between the two, and ``details["g_ramps"]`` the limits found.
    """
    if not ramps:
        return DynamicEstimate(None, None, False, "no ramp-presliding segments", "ramps")
    g0s = list(np.broadcast_to(np.asarray(g0 if g0 is not None else np.nan, dtype=float), (len(ramps),)))
    if not all(np.isfinite(g) and g > 0 for g in g0s):
        g0s = [1.5 * float(np.max(np.abs(F))) for _, F in ramps]
    g0s = [abs(float(g)) for g in g0s]
    spans = [float(np.ptp(q)) for q, _ in ramps]
    span = max(spans)
    if span <= 0:
        return DynamicEstimate(None, None, False, "no measurable displacement during the ramps "
                               "(the encoder does not resolve the presliding displacement)", "ramps",
                               len(ramps))
    if resolution > 0 and span / resolution < MIN_COUNTS:
        return DynamicEstimate(None, None, False,
                               f"the encoder does not resolve the presliding displacement: it spans "
                               f"{span / resolution:.1f} counts of {resolution:.3g} (at least {MIN_COUNTS} needed)",
                               "ramps", len(ramps), details={"span_counts": span / resolution})
    if starts is None:
        s_start = _start_slope(ramps, g0s, span)
        starts = (s_start, 0.3 * s_start, 3.0 * s_start)
    else:
        s_start = float(starts[0])
    rf = _RampForces(ramps, g0s)
    best = rf.fit(starts)
    if best is None:
        return DynamicEstimate(None, None, False, "optimiser failed", "ramps", len(ramps))
    det = {"span": span, "start_slope": s_start, "g0": g0s}
    if free_limit:
        best = _with_free_limit(rf, best, ramps, g0s, det)
    s0 = math.exp(best.x[0])
    n = best.fun.size
    s2 = 2 * best.cost / max(n - best.x.size, 1)
    n_eff = _effective_points(ramps, rf.bounds, best.fun, resolution)
    JtJ = np.einsum("ij,ik->jk", best.jac, best.jac)  # not a BLAS product: see smallsq
    if JtJ.shape == (1, 1):
        inv00 = 1.0 / JtJ[0, 0] if JtJ[0, 0] > 0 else math.inf
    else:  # sigma0's variance with the limit free: 1 / (JtJ_00 - JtJ_01^2 / JtJ_11)
        det_ = JtJ[0, 0] * JtJ[1, 1] - JtJ[0, 1] ** 2
        inv00 = JtJ[1, 1] / det_ if det_ > 0 else math.inf
    se_log = math.sqrt(s2 * inv00 * n / max(n_eff, 1)) if math.isfinite(inv00) else math.inf
    se = s0 * se_log
    rms = math.sqrt(2 * best.cost / n)
    reason = ""
    if not np.isfinite(se) or se > s0:
        reason = f"relative error {100 * se / s0:.0f} % (above 100 %)" if np.isfinite(se) else "no sensitivity"
    if resolution > 0:
        det["span_counts"] = span / resolution
    return DynamicEstimate(s0, se, not reason, reason, "ramps: torque against displacement "
                           "(LuGre in the displacement domain)", len(ramps), rms, det)


def _effective_points(ramps, bounds, resid: np.ndarray, resolution: float) -> float:
    """Independent points of the ramps' residuals. Consecutive samples are correlated: each ramp counts as
    ~ span/resolution (or 50) points, and no more than its samples over the variance factor of its
    residuals (:func:`.samples.variance_factor`: a misfit that is smooth along the ramp, such as a bristle
    model that does not quite hold, is one error shared by its samples, not many independent ones)."""
    from .samples import variance_factor

    n_eff = 0.0
    for r, (q, _) in enumerate(ramps):
        counts = min(q.size, max(10, int(np.ptp(q) / resolution) if resolution > 0 else 50))
        part = resid[bounds[r]:bounds[r + 1]]
        n_eff += min(counts, part.size / variance_factor(part))
    return n_eff


#: The bristle limit fitted on the ramps stays above their largest load by this factor (the ramps are
#: below break-away: the bristles never reach the limit).
LIMIT_MARGIN = 1.02


def _with_free_limit(rf: _RampForces, best, ramps, g0s: list[float], det: dict):
    """sigma0 and the bristle limits fitted together: the limits ``k g0`` (one factor k for all ramps, at
    least :data:`LIMIT_MARGIN` times each ramp's largest load). In LuGre the limit is the static map's level
    at the ramp's speed; the map's level at zero speed is an extrapolation when the map has no measured
    drop (a Coulomb level, a polynomial's constant) and the ramps' curvature measures it instead: with the
    limit too low the fitted sigma0 comes out too high, and the reverse (foreign card: a `coulomb_viscous`
    base put it at the Coulomb level, 24 % below the break-away, and sigma0 came out 16 % high). Returns the
    joint least-squares result (x: log sigma0, log k) with ``det`` updated, or the fixed-limit one when the
    joint fit fails."""
    k_min = LIMIT_MARGIN * max(float(np.max(np.abs(F))) / g for (_, F), g in zip(ramps, g0s))
    lo = math.log(max(k_min, 1e-12))
    g = np.asarray(g0s, dtype=float)

    def resid(p):
        return rf.with_limits(g * math.exp(p[1])).resid(p[:1])

    out = None
    for lk in sorted({max(0.0, lo), lo + 0.5}):
        try:
            r = least_squares(resid, [best.x[0], lk], bounds=([-np.inf, lo], [np.inf, np.inf]),
                              ftol=1e-10, xtol=1e-10)
        except ValueError:
            continue
        if out is None or r.cost < out.cost:
            out = r
    rf.with_limits(g)
    if out is None or not np.all(np.isfinite(out.jac)):
        return best
    k = math.exp(out.x[1])
    det["limit_scale"] = k
    det["g_ramps"] = [float(x) for x in g * k]
    return out


@njit(cache=True, error_model="numpy", fastmath=_FM)
def _simulate_step_nb(t, u, q0, w0, J, sigma0, sigma1, c_pos, c_neg, z0, substeps):
    n = t.shape[0]
    q = np.empty(n)
    q[0] = q0
    qi = q0
    wi = w0
    zi = z0
    iJ = 1.0 / J
    for i in range(n - 1):
        h = (t[i + 1] - t[i]) / substeps
        ui = u[i]
        for _ in range(substeps):
            c = c_pos if wi >= 0.0 else c_neg
            g, dg = level_slope_nb(abs(wi), c)
            qi, wi, zi, _ = lugre_core(qi, wi, zi, ui, h, iJ, sigma0, sigma1, max(g, 1e-12), dg,
                                       viscous_nb(wi, c), dviscous_nb(wi, c))
        q[i + 1] = qi
    return q


def simulate_step(t: np.ndarray, u: np.ndarray, q0: float, w0: float, J: float, sigma0: float,
                  sigma1: float, c_pos, c_neg, z0: float, substeps: int = 2) -> np.ndarray:
    """Position [q] of ``J w' = u - sigma0 z - sigma1 z' - f(w)``, ``z' = w - sigma0 |w| z / g(w)``.

    t [s] sample times; u [F] : net driving torque (tau - gravity - offset) per sample, held between
    samples; q0 [q], w0 [q/s], z0 [q] the start state; J [F s^2/q]; sigma0 [F/q], sigma1 [F s/q].
    c_pos, c_neg : canonical static vectors (:data:`frictid.models.static.CANON`) for ``w >= 0`` and
    ``w < 0``, giving the level g [F] and the viscous part f [F] (scalar callables ``level(w)``,
    ``viscous(w)`` are accepted too and run :func:`simulate_step_ref`, the python twin). Each of the
    ``substeps`` per sample is the exact step of the system linearised at its start
    (:func:`frictid.models.lugre.lugre_core`, analytic slopes of g and f), stable for the stiff bristles.
    Compiled (numba).
    """
    if callable(c_pos):
        return _simulate_step_py(t, u, q0, w0, J, sigma0, sigma1, c_pos, c_neg, z0, substeps)
    return _simulate_step_nb(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(u, dtype=float),
                             float(q0), float(w0), float(J), float(sigma0), float(sigma1),
                             np.ascontiguousarray(c_pos, dtype=float), np.ascontiguousarray(c_neg, dtype=float),
                             float(z0), int(substeps))


def simulate_step_ref(t, u, q0, w0, J, sigma0, sigma1, c_pos, c_neg, z0, substeps=2):
    """Plain-python twin of :func:`simulate_step` (for the tests): the map from
    :mod:`frictid.models.static`'s vectorised functions, the slopes of g and f by central differences,
    the step by :func:`frictid.models.lugre.lugre_step_ref` (scipy's matrix exponential)."""
    def level(w):
        return float(canonical_level(w, c_pos if w >= 0 else c_neg))

    def viscous(w):
        return float(canonical_viscous(w, c_pos if w >= 0 else c_neg))

    return _simulate_step_py(t, u, q0, w0, J, sigma0, sigma1, level, viscous, z0, substeps, lugre_step_ref)


def _simulate_step_py(t, u, q0, w0, J, sigma0, sigma1, level, viscous, z0, substeps, step=None):
    """The step simulation as a python loop over scalar callables level(w) [F] and viscous(w) [F]."""
    if step is None:
        step = lugre_step
    n = t.shape[0]
    q = np.empty(n)
    q[0] = q0
    qi, wi, zi = float(q0), float(w0), float(z0)
    eps = 1e-7
    for i in range(n - 1):
        h = (t[i + 1] - t[i]) / substeps
        ui = float(u[i])
        for _ in range(substeps):
            # slopes by differences on the branch of wi's sign (a difference across w = 0 would mix the
            # two branches of a per-sign map)
            sg = 1.0 if wi >= 0 else -1.0
            v = abs(wi)
            g = max(level(wi), 1e-12)
            f = viscous(wi)
            lo = v - eps if v > eps else v + eps
            hi = lo + 2 * eps
            fp = (viscous(sg * hi) - viscous(sg * lo)) / (sg * 2 * eps)
            dg = (level(sg * hi) - level(sg * lo)) / (2 * eps)
            qi, wi, zi = step(qi, wi, zi, ui, h, J, sigma0, sigma1, g, dg, f, fp)
        q[i + 1] = qi
    return q


def step_noise(u: np.ndarray) -> float:
    """Robust white-noise standard deviation of a torque stretch from its sample-to-sample differences
    (1.4826 MAD / sqrt 2): a step between two levels is one difference, which the median passes over."""
    return 1.4826 * float(np.median(np.abs(np.diff(u)))) / math.sqrt(2.0)


def step_input(u: np.ndarray, pre_level: float | None = None) -> np.ndarray:
    """A step segment's torque [F] as the two-level step it was commanded to be, when the samples say so.

    The step simulation is driven by the measured torque. Its noise is an input error: the simulated
    position jitters where the measured one did not, and more damping shrinks that jitter, so a
    simulation-error fit on noisy input drifts towards a larger sigma1 (errors in variables). A torque step
    is two constant levels: the split that explains u best by two means is taken, and when what the two
    levels leave is noise (its RMS within 1.5 of the noise the sample-to-sample differences show, robust
    estimate) u is replaced by them. ``pre_level`` [F]: the level before the segment (the rest or hold the
    step starts from, estimated from more samples than the segment's first), used for the first level when
    the split is at the segment's first sample. u is returned unchanged when it is not a step plus noise.
    """
    u = np.asarray(u, dtype=float)
    n = u.size
    if n < 6:
        return u
    noise = step_noise(u)
    c1, c2 = np.cumsum(u), np.cumsum(u * u)
    k = np.arange(1, n)
    sse_l = c2[k - 1] - c1[k - 1] ** 2 / k
    sse_r = (c2[-1] - c2[k - 1]) - (c1[-1] - c1[k - 1]) ** 2 / (n - k)
    sse = sse_l + sse_r
    i = int(np.argmin(sse))
    split = int(k[i])
    if not sse[i] / n <= (1.5 * noise) ** 2:
        return u
    first = float(c1[split - 1] / split)
    if split == 1 and pre_level is not None and np.isfinite(pre_level):
        first = float(pre_level)
    out = np.empty(n)
    out[:split] = first
    out[split:] = (c1[-1] - c1[split - 1]) / (n - split)
    return out


def fit_sigma1_steps(steps: list[tuple[np.ndarray, np.ndarray, np.ndarray]], J: float, sigma0: float,
                     c_pos, c_neg, sigma2: float, resolution: float = 0.0, min_steps: int = 3,
                     starts: tuple[float, ...] | None = None) -> DynamicEstimate:
    """sigma1 [F s/q] by simulation-error fit on step segments.

    steps : list of (t [s], q [q], u [F]) per step segment, u = tau - gravity - offset.
    c_pos, c_neg : canonical vectors of the static map (or scalar callables level(w), viscous(w), which
    run the python twin of the step simulation). starts : initial sigma1 values [F s/q] (default 0.9,
    0.2 and 3 times critical damping). The step-to-step spread refits each step alone from the joint
    optimum (one start).
    """
    usable = []
    for t, q, u in steps:
        if resolution > 0 and np.ptp(q) / resolution < MIN_COUNTS:
            continue
        usable.append((t, q, u))
    if len(usable) < min_steps:
        why = ("no step segments" if not steps else
               f"{len(usable)} of {len(steps)} step segments resolved by the encoder (at least {min_steps} "
               "needed for an error estimate from their spread)")
        return DynamicEstimate(None, None, False, why, "steps", len(steps))
    crit = 2 * math.sqrt(sigma0 * J)
    hi = 20 * crit

    if callable(c_pos):
        g0 = float(c_pos(0.0))
    else:
        c_pos = np.ascontiguousarray(c_pos, dtype=float)
        c_neg = np.ascontiguousarray(c_neg, dtype=float)
        g0 = float(level_slope_nb(0.0, c_pos)[0])
    prep = []
    for t, q, u in usable:
        t = np.ascontiguousarray(t, dtype=float)
        u = np.ascontiguousarray(u, dtype=float)
        q = np.asarray(q, dtype=float)
        z0 = float(np.clip(u[0] / sigma0, -g0 / sigma0, g0 / sigma0))
        prep.append((t, q, u, z0, 1.0 / max(np.ptp(q), 1e-15)))

    def resid(p):
        s1 = p[0]
        out = []
        for t, q, u, z0, iscale in prep:
            qs = simulate_step(t, u, q[0], 0.0, J, sigma0, s1, c_pos, c_neg, z0)
            out.append((qs - q) * iscale)
        return np.concatenate(out)

    best = None
    for s in (starts if starts is not None else (0.9 * crit, 0.2 * crit, 3 * crit)):
        try:
            r = least_squares(resid, [min(max(s, 1e-9), hi * 0.99)], bounds=([0.0], [hi]), x_scale=[crit])
        except ValueError:
            continue
        if best is None or r.cost < best.cost:
            best = r
    if best is None:
        return DynamicEstimate(None, None, False, "optimiser failed", "steps", len(steps))
    s1 = float(best.x[0])
    n = best.fun.size
    n_eff = max(len(usable) * 20, 2)
    s2 = 2 * best.cost / max(n - 1, 1)
    JtJ = float(np.einsum("i,i->", best.jac[:, 0], best.jac[:, 0]))  # not a BLAS dot: see smallsq
    se = math.sqrt(s2 / JtJ * n / n_eff) if JtJ > 0 else math.inf
    spread = None
    if len(usable) >= 3:  # step-to-step spread: honest when quantisation or noise bias single steps
        singles = []
        for st in usable:
            e = fit_sigma1_steps([st], J, sigma0, c_pos, c_neg, sigma2, 0.0, min_steps=1, starts=(s1,))
            if e.value is not None:
                singles.append(e.value)
        if len(singles) >= 3:
            spread = float(np.std(singles, ddof=1) / math.sqrt(len(singles)))
            se = max(se, spread)
    reason = ""
    if best.active_mask[0] != 0 or s1 <= 1e-9 * crit or s1 >= 0.999 * hi:
        reason = "at its bound"
    elif not np.isfinite(se) or se > abs(s1):
        reason = "relative error above 100 %"
    return DynamicEstimate(s1, se, not reason, reason, "steps: simulation-error fit", len(usable),
                           math.sqrt(2 * best.cost / n), {"critical": crit, "step_spread_se": spread})


def sigma1_rule(sigma0: float, sigma0_se: float | None, J: float, J_se: float | None, sigma2: float,
                sigma2_se: float | None = None) -> DynamicEstimate:
    """sigma1 [F s/q] by the near-critical-damping rule (000 eq 16) with zeta uniform on [0.8, 1]."""
    zeta = 0.5 * (ZETA[0] + ZETA[1])
    zeta_sd = (ZETA[1] - ZETA[0]) / math.sqrt(12)
    root = math.sqrt(max(sigma0 * J, 0.0))
    val = 2 * zeta * root - sigma2
    var = (2 * root * zeta_sd) ** 2
    if sigma0_se:
        var += (zeta * math.sqrt(J / sigma0) * sigma0_se) ** 2
    if J_se:
        var += (zeta * math.sqrt(sigma0 / J) * J_se) ** 2
    if sigma2_se:
        var += sigma2_se ** 2
    return DynamicEstimate(val, math.sqrt(var), True, "",
                           "critical-damping rule sigma1 = 2 zeta sqrt(sigma0 J) - sigma2, zeta 0.8-1 "
                           "(000 eq 16): no usable step segments", 0, None, {"zeta": zeta})
