"""The ranges a joint's data covered: where its identified models are valid.

A model is an interpolation of what was measured: speeds between the slowest and the fastest the static
maps were fitted on, the joint temperatures and the positions the joint went through while it moved.
:func:`validity` measures them once per joint; the parameter file records them (``validity``) and
:class:`frictid.model.FrictionModel` warns when it is evaluated outside them.
"""
from __future__ import annotations

import math

import numpy as np

from ..models.static import coulomb_viscous, stribeck
from .samples import LEVEL_TOLERANCE, speed_levels

#: Share of the moving samples left out at each end of a range measured on samples (a stray sample at a
#: reversal spike does not widen a range the data do not really cover).
TAIL = 0.005


def _range(x: np.ndarray, tail: float = 0.0) -> list[float] | None:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return None
    if tail > 0 and x.size >= 1 / tail:
        lo, hi = np.quantile(x, [tail, 1.0 - tail])
    else:
        lo, hi = x.min(), x.max()
    return [float(lo), float(hi)]


def validity(basis_w: np.ndarray, moving_q: list[np.ndarray], moving_T: list[np.ndarray]) -> dict:
    """Ranges covered by a joint's data.

    basis_w : velocities [q/s] the static maps were fitted on (plateau means, or the moving samples);
    moving_q : per log, positions [q] while moving (empty arrays for velocity-only logs); moving_T : per
    log, joint temperatures [degC] while moving (measured ``temp_joint``; empty when not logged).
    Returns ``speed`` [lo, hi] of |w| (the plateau speeds, or the moving samples without their extreme
    :data:`TAIL`), and ``position`` and ``temperature`` [lo, hi] where the logs hold them.
    """
    out: dict[str, list[float]] = {}
    w = np.abs(np.asarray(basis_w, dtype=float))
    speed = _range(w, TAIL if w.size > 1000 else 0.0)
    if speed is not None:
        out["speed"] = speed
    for key, arrays in (("position", moving_q), ("temperature", moving_T)):
        arrays = [np.asarray(a, dtype=float) for a in arrays if a is not None and np.size(a)]
        rng = _range(np.concatenate(arrays), TAIL) if arrays else None
        if rng is not None:
            out[key] = rng
    return out


def of_joint(preps, friction, min_speed: float) -> dict:
    """:func:`validity` of a joint's prepared logs (:class:`frictid.identify.prepare.Prep`) and the friction
    points its static maps were fitted on (:class:`frictid.identify.mechanics.Friction`): the plateau speeds,
    or the moving samples on the sample basis; positions and measured joint temperatures where
    ``|w| > min_speed`` [q/s]."""
    if friction.basis == "samples" and friction.S is not None:
        basis_w = friction.S.w
    else:
        basis_w = friction.plat.w
    qs, Ts = [], []
    for p in preps:
        moving = np.abs(np.nan_to_num(p.w)) > min_speed
        if p.log.q is not None:
            qs.append(np.asarray(p.log.q)[moving])
        T = p.log.channels.get("temp_joint")
        if T is not None:
            Ts.append(np.asarray(T)[moving])
    return validity(basis_w, qs, Ts)


#: A plateau speed is inside a fitted Stribeck drop when the drop still holds between these shares of its
#: amplitude there (:func:`drop_spanned`); above the upper one it is on the drop's top (the break-away level).
DROP_INSIDE = (0.05, 0.95)


#: The drop seen at the slowest plateau speed counts when beyond this many of its errors (:func:`_no_drop_seen`).
NO_DROP_Z = 2.0
#: How the reason of a break-away level with no drop above the slowest plateau begins (:func:`_no_drop_seen`,
#: :func:`_drop_significant`; the choice does not take a Stribeck map without a drop on any branch).
NO_DROP = "no Stribeck drop above the slowest plateau speed"


def drop_spanned(mf, plateau_w: np.ndarray, without_drop=None, points=None, shifts=None) -> None:
    """Shape parameters identifiable only when enough distinct plateau speeds span them (issue 19): a
    Stribeck drop's level, speed and exponent are measured by steady runs inside the drop (plateaus where
    the fitted drop holds :data:`DROP_INSIDE` of its amplitude; one on its top counts for the level). With
    fewer distinct plateau speeds (10 % apart) there than free parameters of the drop, the fit placed the
    drop between and below its steady points: a few points trade amplitude against speed, and on the moving
    samples the speeds below the steady runs are crossed while the joint speeds up or slows down, where the
    friction lags its steady value (on point-to-point moves the drop came out 20 % low and 25 % wide,
    trusted). ``Fs``, ``vs`` and ``delta`` of such a branch are marked not identifiable with the reason.

    The level the drop ends at and the viscous slope of such a branch are read from the steady part of the
    map the guessed drop leaves: a drop that really reaches into the measured speeds (a slow one, a low
    exponent) moves both. ``without_drop`` (the same data's ``coulomb_viscous`` map, or its ``_asym``
    variant for ``stribeck_asym``): their change between the two maps enters their standard errors (added
    in quadrature), as the held exponent's profile does.

    ``points`` (the plateau points (w, F, F_se) the map was fitted on, on the plateau basis): the drop must
    stay in view at every exponent that fits as well (:func:`_drop_in_view_at_every_exponent`), and the
    drop must be significant (:func:`_drop_significant`) under the points' errors and ``shifts`` (their
    common errors from the inertia, gravity and offset, :func:`.mechanics.plateau_shifts`)."""
    base = mf.name[:-5] if mf.name.endswith("_asym") else mf.name
    if base != "stribeck":
        return
    w = np.asarray(plateau_w, dtype=float)
    w = w[np.isfinite(w)]
    if points is not None:
        _drop_significant(mf, points, without_drop, shifts)
    for suf, side in ((("_pos", 1.0), ("_neg", -1.0)) if mf.name.endswith("_asym") else (("", 0.0),)):
        p = {n: mf.params.get(n + suf) for n in ("Fc", "Fs", "vs", "delta")}
        if any(pe is None or pe.value is None for pe in p.values()) or p["vs"].value <= 0:
            continue
        v = np.abs(w[np.sign(w) == side] if side else w)
        _no_drop_seen(p, v)
        if p["Fs"].value <= p["Fc"].value:  # no drop: physical_shape's case, a shape the name denies (whole change)
            _level_spread(mf, without_drop, suf, 1.0)
            continue
        if points is not None:
            _drop_in_view_at_every_exponent(mf, suf, side, points)
        share = np.exp(-((v / p["vs"].value) ** p["delta"].value))
        inside = v[(share >= DROP_INSIDE[0]) & (share <= DROP_INSIDE[1])]
        have = speed_levels(inside, LEVEL_TOLERANCE) + int(bool((share > DROP_INSIDE[1]).any()))
        # a shape parameter the fit held because the data could not place it (fixed and not identifiable,
        # e.g. a rank-deficient speed held at its guess) is still a guess of the drop the plateaus must span:
        # only one held by choice (the user's, or a profiled exponent) is not
        need = sum(1 for n in ("Fs", "vs", "delta") if not p[n].fixed or not p[n].identifiable)
        if have >= need:
            continue
        lo = p["vs"].value * (-np.log(DROP_INSIDE[1])) ** (1.0 / p["delta"].value)
        hi = p["vs"].value * (-np.log(DROP_INSIDE[0])) ** (1.0 / p["delta"].value)
        why = (f"{have} distinct plateau speed(s) within the fitted drop ({lo:.3g} to {hi:.3g}) where its level, "
               f"speed and shape need {need}: the drop is not spanned by steady runs (it is placed between and "
               "below them; moving samples there are crossed while the speed changes, where the friction lags "
               "its steady value)")
        for n in ("Fs", "vs", "delta"):
            pe = p[n]
            if pe.identifiable and not pe.fixed:
                pe.identifiable, pe.reason = False, why
            elif pe.fixed and not pe.identifiable:  # held at the fit's guess: the missing plateaus are why
                pe.reason = f"{why}; {pe.reason}"
        _level_spread(mf, without_drop, suf)


def break_away_needs_speed(mf) -> None:
    """A Stribeck branch's break-away level ``Fs`` is the drop's level at zero speed, read through the
    drop's speed ``vs``: with ``vs`` free and not identifiable by an error above its value, its interval
    reaches zero, where the whole drop lies below the slowest point, and ``Fs`` is an extrapolation by the
    shape the fit assumed (:func:`.static._drop_in_view`'s case, at a speed the data cannot rule out).
    ``Fs`` is then marked not identifiable with that reason (foreign card, a sweep with ramps and steps:
    vs 0.17 +- 0.18 by the jackknife over the time blocks, Fs 0.0476 +- 0.0019 against 0.0536, trusted).
    A speed held by the fit (a drop it could not place) has its own rules (:func:`_no_drop_seen`)."""
    if (mf.name[:-5] if mf.name.endswith("_asym") else mf.name) != "stribeck":
        return
    for suf in ("_pos", "_neg") if mf.name.endswith("_asym") else ("",):
        vs, fs = mf.params.get("vs" + suf), mf.params.get("Fs" + suf)
        if vs is None or fs is None or vs.fixed or vs.identifiable or vs.value is None or vs.stderr is None:
            continue
        if fs.identifiable and not fs.fixed and vs.stderr > abs(vs.value):
            fs.identifiable, fs.reason = False, (
                f"read at zero speed through the drop's speed vs{suf} {vs.value:.3g} +- {vs.stderr:.2g}, which "
                "is not identifiable: at speeds within its error the drop lies below the data and the "
                "break-away level is extrapolated")


def _no_drop_seen(p: dict, v: np.ndarray) -> None:
    """``Fs`` is a break-away level only when the data show a drop down from it. When the drop's speed
    ``vs`` is not identifiable, the fit did not resolve a drop if it held ``vs`` because the drop is not
    distinguishable from zero (:func:`.static._shapeless`), or if the part of the fitted drop left at the
    slowest plateau speed, ``(Fs - Fc) exp(-(v_min / vs)^delta)``, is within :data:`NO_DROP_Z` errors
    (Fs's and Fc's combined: a bound, since their errors are correlated; used only where ``vs`` is not
    measured, which on the real screw drives' sweeps would otherwise take a resolved drop for none).
    Otherwise ``Fs`` is the level of the slowest plateaus, and a break-away below the slowest plateau
    speed leaves nothing in the data: ``Fs`` is marked not identifiable with that reason (issue 19: a
    foreign draw gave Fs 0.420 +- 0.0006 against 0.500, the level at its slowest plateaus, trusted).
    ``p``: the branch's Fc, Fs, vs, delta estimates; ``v``: its plateau speeds."""
    vs, fs, fc, dl = p["vs"], p["Fs"], p["Fc"], p["delta"]
    if not fs.identifiable or fs.fixed or v.size == 0:
        return
    if vs.identifiable:  # the drop's speed is measured: the data resolve a drop
        return
    held = vs.fixed
    if not held:
        ses = [x.stderr for x in (fs, fc) if x.stderr is not None and np.isfinite(x.stderr)]
        if not ses or fs.value <= fc.value:
            return
        seen = (fs.value - fc.value) * np.exp(-((float(v.min()) / vs.value) ** dl.value))
        if seen > NO_DROP_Z * float(np.sqrt(np.sum(np.square(ses)))):
            return
    fs.identifiable, fs.reason = False, (
        f"{NO_DROP} ({float(v.min()):.3g}): the break-away, if any, lies "
        "below it" + (f" ({vs.reason})" if held else f" (the drop seen there, {seen:.3g}, is within "
                      f"{NO_DROP_Z:g} errors of zero)"))


def _drop_free_spread(mf, without_drop) -> None:
    """The data show a drop (:func:`_drop_significant`): the drop-free map's level and slope are those of a
    map the data reject, and read the drop's tail as Coulomb level and slope. Their change to the Stribeck
    map's (``mf``) enters their standard errors (added in quadrature), the mirror of the Stribeck map's
    own spread in :func:`drop_spanned` (a foreign sweep with a slow drop, exponent 0.86, whose break-away
    lay below the slowest plateau: `coulomb_viscous` selected with sigma2 0.1776 +- 0.0073 against 0.1939,
    the Stribeck map's 0.1936)."""
    for suf in ("_pos", "_neg") if mf.name.endswith("_asym") else ("",):
        _level_spread(without_drop, mf, suf)


def _level_spread(into, other, suf: str, weight: float | None = None) -> None:
    """``Fc`` and ``sigma2`` of branch ``suf`` of map ``into`` with their change to map ``other``'s added to
    their standard errors (the Stribeck map's by the drop-free map in :func:`drop_spanned`, and the mirror
    in :func:`_drop_free_spread`), weighted by how well ``other`` explains the same data: the model-averaged
    variance ``se^2 + w d^2`` with ``w`` the Akaike weight of ``other`` against ``into``
    (:func:`akaike_weight`). A map the data reject (a drop-free line through a drop that is there) carries
    no weight, and its level no error; the whole change was added before (session 23: the Stribeck map's
    Fc error 60-175x its own on foreign sweeps whose drop the plateaus do not span but whose level they
    measure, 234025: 0.00047 -> 0.083 N m, truth 0.0004 away). ``weight`` given: that weight instead (a
    Stribeck branch fitted as a rise, Fs below Fc, whose shape its name denies, carries the whole change)."""
    if into is None or other is None:
        return
    w = akaike_weight(other, into) if weight is None else weight
    for n in ("Fc", "sigma2"):
        pe, alt = into.params.get(n + suf), other.params.get(n + suf)
        if pe is None or alt is None or pe.value is None or alt.value is None or pe.stderr is None:
            continue
        pe.stderr = float(np.hypot(pe.stderr, math.sqrt(w) * (alt.value - pe.value)))


def akaike_weight(a, b) -> float:
    """The Akaike weight of map ``a`` against map ``b`` fitted on the same data, ``1 / (1 + exp((AIC_a -
    AIC_b) / 2))`` (their ``metrics["aic"]``: the points', or on the samples the effective count's); 1
    when either is missing (the whole change counts)."""
    ia, ib = a.metrics.get("aic"), b.metrics.get("aic")
    if ia is None or ib is None or not (math.isfinite(ia) and math.isfinite(ib)):
        return 1.0
    return 1.0 / (1.0 + math.exp(min((ia - ib) / 2.0, 700.0)))


#: A fitted drop counts as seen when the F-test of the Stribeck map against the drop-free map of the same
#: points rejects "no drop" at this level (:func:`_drop_significant`).
DROP_P = 0.05


def _branch_points(points, side: float, shifts=None):
    """One branch's plateau points (speeds > 0, friction of the branch's sign), their weights and the
    data scales of the whole set (as :func:`.static.fit_static` weighs them); with ``shifts``, also the
    branch's rows of them as the columns of a matrix (None without)."""
    from .static import _scales, _weights

    w, F, se = (np.asarray(x, dtype=float) for x in points)
    keep = (np.sign(w) == side) if side else np.isfinite(w)
    bw, bF, bse = (side or 1.0) * w[keep], (side or 1.0) * F[keep], se[keep]
    scales = _scales(w, F)
    out = bw, bF, bse, _weights(bse, scales[0], bw.size), scales
    if shifts is None:
        return out
    D = np.column_stack([(side or 1.0) * np.asarray(d, dtype=float)[keep] for d in shifts]) if len(shifts) else None
    return (*out, D)


def _drop_significant(mf, points, without_drop, shifts=None) -> None:
    """A Stribeck drop is seen only when the map fits the plateau points significantly better than the
    drop-free map of the same points (``without_drop``, Coulomb + viscous, per sign for a per-sign map: the
    nested model Fs = Fc): the F-test of their residuals over the map's branches, with as many degrees of
    freedom as the drops have free parameters, must reject "no drop" at :data:`DROP_P`.
    Otherwise ``Fs``, ``vs`` and ``delta`` describe noise: a drop of 0.003 N m (Fs 2.00007 +- 0.0005 over
    Fc 1.9968 +- 0.0025, vs 0.82 +- 0.23) fitted on plateaus ten Stribeck velocities above a true
    break-away passes the other tests, as its amplitude is clear of zero with its shape held where it came
    out. The test is of the map as a whole: a per-sign map keeps a branch without a drop of its own when the
    other branch's drop is significant (the real screw drive 3: F-test p = 0.12 on its positive side).

    The points' errors are not independent: the inertia, gravity and offset subtracted from the torque
    move them all at once (``shifts``, one column per independent direction of their error, as
    :func:`.static._shift_profile` propagates it). With them, the residuals are weighed by the points'
    full covariance (generalised least squares, :func:`_gls_chi2`: the points' own errors, scaled so that
    the Stribeck map's residuals have their expected chi-square, plus the shifts): a drop the shifts'
    pattern can make is no evidence of one (foreign card: a sweep whose break-away lay below its slowest
    plateau, plateau points 3-15 of their own errors off along the gravity error's pattern, gave a "drop"
    of 0.0026 N m at p = 3e-5 and Fs 2.3 % low with an error of 0.06 %; under the full covariance p = 1)."""
    from scipy.stats import f as f_dist

    if without_drop is None:
        return
    names = ("Fc", "Fs", "vs", "delta", "sigma2")
    parts = []
    k = n_free = n_pts = 0
    flag = []
    for suf, side in (("_pos", 1.0), ("_neg", -1.0)) if mf.name.endswith("_asym") else (("", 0.0),):
        pe = {n: mf.params.get(n + suf) for n in names}
        fc0, s0 = (without_drop.params.get(n + suf) for n in ("Fc", "sigma2"))
        if any(x is None or x.value is None for x in (*pe.values(), fc0, s0)):
            return
        bw, bF, _, wts, _, D = _branch_points(points, side, shifts if shifts is not None else [])
        parts.append((stribeck(bw, **{n: pe[n].value for n in names}) - bF,
                      coulomb_viscous(bw, fc0.value, s0.value) - bF, 1.0 / wts**2, D,
                      (bw, bF, pe["vs"].value, pe["delta"].value)))
        k += sum(1 for n in ("Fs", "vs", "delta") if not pe[n].fixed)
        n_free += sum(1 for n in names if not pe[n].fixed)
        n_pts += bw.size
        flag += [pe[n] for n in ("Fs", "vs", "delta") if pe[n].identifiable and not pe[n].fixed]
    dof = n_pts - n_free
    gain = _drop_gain(parts, dof) if k and dof >= 1 else None
    if gain is None:
        return
    p = float(f_dist.sf(max(gain, 0.0) / k, k, dof))
    if p <= DROP_P:
        _drop_free_spread(mf, without_drop)
        return
    if not flag:
        return
    v_min = float(np.min(np.abs(np.asarray(points[0], dtype=float))))
    why = (f"{NO_DROP} ({v_min:.3g}): the map fits the plateaus no better "
           f"than Coulomb + viscous (F-test p = {p:.2g}); the break-away, if any, lies below it")
    for pe in flag:
        pe.identifiable, pe.reason = False, why


def _gls_chi2(r: np.ndarray, S: np.ndarray, D: np.ndarray | None) -> float:
    """``r^T (diag(S) + D D^T)^-1 r`` (Woodbury's identity: D has a few columns)."""
    a = r / S
    if D is None or D.shape[1] == 0:
        return float(r @ a)
    b = D.T @ a
    M = np.eye(D.shape[1]) + D.T @ (D / S[:, None])
    return float(r @ a - b @ np.linalg.solve(M, b))


def _gls_residuals(part, s2: float) -> tuple[np.ndarray, np.ndarray]:
    """The Stribeck map (its shape held where the fit put it) and the drop-free map refitted in their
    levels and slope by generalised least squares under ``s2 diag(S) + D D^T``: their residuals. The maps
    fitted with the points' own errors alone take up part of the shifts' pattern in their levels and
    slope; refitted under the full covariance they do not."""
    _, _, S, D, (bw, bF, vs, dl) = part
    C = np.diag(s2 * S) + D @ D.T
    L = np.linalg.cholesky(C)
    sg = np.sign(bw)
    e = np.exp(-((np.abs(bw) / vs) ** dl))
    out = []
    for X in (np.column_stack([sg * (1.0 - e), sg * e, bw]), np.column_stack([sg, bw])):
        Xw, yw = np.linalg.solve(L, X), np.linalg.solve(L, bF)
        b = np.linalg.lstsq(Xw, yw, rcond=None)[0]
        out.append(bF - X @ b)
    return out[0], out[1]


def _drop_gain(parts: list, dof: int) -> float | None:
    """The drop's gain in chi-square over the drop-free map, in units of the points' noise: ``parts`` are
    per branch (Stribeck residuals, drop-free residuals, the points' squared errors, the shifts or None,
    the branch's points and the drop's shape). Without shifts it is the weighted residual sum of squares'
    drop over the Stribeck map's reduced chi-square (the F statistic times its degrees of freedom). With
    shifts the two maps' levels and slope are refitted under the full covariance
    (:func:`_gls_residuals`), the points' own errors scaled by the factor that gives the Stribeck map a
    chi-square of ``dof`` (:func:`_gls_chi2`), and the gain is the drop in that chi-square. None when
    undefined."""
    from scipy.optimize import brentq

    rss1 = sum(float(np.sum(pt[0] ** 2 / pt[2])) for pt in parts)
    rss0 = sum(float(np.sum(pt[1] ** 2 / pt[2])) for pt in parts)
    if not (rss1 > 0 and np.isfinite(rss0)):
        return None
    if all(pt[3] is None for pt in parts):
        return (rss0 - rss1) / (rss1 / dof)

    def chi(s2: float) -> tuple[float, float]:
        c1 = c0 = 0.0
        for pt in parts:
            D = pt[3] if pt[3] is not None else np.zeros((pt[2].size, 0))
            r1, r0 = _gls_residuals(pt[:3] + (D, pt[4]), s2)
            c1 += _gls_chi2(r1, s2 * pt[2], D)
            c0 += _gls_chi2(r0, s2 * pt[2], D)
        return c1, c0

    s2 = rss1 / dof
    try:
        s2 = math.exp(brentq(lambda ls: chi(math.exp(ls))[0] - dof, math.log(s2) - 12.0, math.log(s2) + 5.0,
                             xtol=1e-3))
    except (ValueError, np.linalg.LinAlgError):  # the shifts alone explain the residuals: keep the plain scale
        pass
    c1, c0 = chi(s2)
    return c0 - c1


#: Exponents at which a branch's Stribeck drop is refitted (:func:`_drop_in_view_at_every_exponent`: the
#: grid of the held exponent's profile, from 0.5 as real drives show, with 2 added, 000/003's value) and the
#: chi-square within which a fit is as consistent with the data as the reported one.
EXPONENTS = (0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
EXPONENT_CHI2 = 4.0


def _drop_in_view_at_every_exponent(mf, suf: str, side: float, points) -> None:
    """A break-away level is measured only when the slowest plateau sees the top of the drop
    (:data:`.static.DROP_SEEN` of it) whatever the drop's shape, among the shapes the data allow: the
    branch is refitted with its exponent held at each of :data:`EXPONENTS`; when a fit within
    :data:`EXPONENT_CHI2` of the reported one (chi-square in units of the reported fit's reduced
    chi-square) puts the slowest point below :data:`.static.DROP_SEEN` of its drop, ``Fs``, ``vs`` and
    ``delta`` are not identifiable: the data then see only the drop's tail, and its level at zero speed
    depends on a shape they do not pin down (a foreign sweep whose slowest plateau sat at 3 times the
    Stribeck velocity, exponent 0.8: a per-sign fit with a free exponent of 1.7 +- 0.6 put Fs at
    8.41 +- 0.24 against 10.29, while the same data at exponent 1 placed the drop below the slowest
    plateau). The fitted exponent's own shape is judged by :func:`.static._drop_in_view`."""
    from .static import DROP_SEEN, fit_branch

    fs, vs, dl = (mf.params.get(n + suf) for n in ("Fs", "vs", "delta"))
    # the speed is judged too where the level already is not identifiable (the held exponent's profile
    # carries it off at an exponent that fits as well): the drop's speed depends on the same shape
    if fs.fixed or not vs.identifiable or vs.fixed:
        return
    bw, bF, bse, wts, scales = _branch_points(points, side)
    names = ("Fc", "Fs", "vs", "delta", "sigma2")
    vals = {n: mf.params[n + suf].value for n in names}
    free = sum(1 for n in names if not mf.params[n + suf].fixed)
    dof = bw.size - free
    if dof < 1 or any(x is None for x in vals.values()):
        return
    cost = lambda x: 0.5 * float(np.sum(((stribeck(bw, **x) - bF) * wts) ** 2))  # noqa: E731
    s2 = 2.0 * cost(vals) / dof
    if not (s2 > 0 and np.isfinite(s2)):
        return
    v_min = float(np.abs(bw).min())
    for d in EXPONENTS:
        if abs(d - vals["delta"]) < 1e-9:
            continue
        alt = fit_branch("stribeck", bw, bF, bse, fixed={"delta": d}, scales=scales, start=dict(vals, delta=d))
        if not np.isfinite(alt.cost) or 2.0 * (alt.cost - cost(vals)) / s2 > EXPONENT_CHI2:
            continue
        a = alt.values
        if a.get("vs") is None or a["vs"] <= 0 or a["Fs"] <= a["Fc"]:
            continue
        share = float(np.exp(-((v_min / a["vs"]) ** d)))
        if share >= DROP_SEEN:
            continue
        why = (f"at exponent {d:g}, which fits the plateaus as well, the slowest point ({v_min:.3g}) holds "
               f"{100 * share:.0f} % of the drop (Fs {a['Fs']:.4g}): the data see its tail, and the break-away "
               "level and the drop's speed depend on a shape they do not pin down")
        for pe in (fs, vs, dl):
            if pe.identifiable and not pe.fixed:
                pe.identifiable, pe.reason = False, why
        return



#: A per-sign map is taken only when it fits the plateau points better than its symmetric map at this
#: level (:func:`per_sign_supported`).
SPLIT_P = 0.05


def per_sign_supported(asym, sym, points, shifts=None) -> None:
    """A per-sign map (``asym``, e.g. ``stribeck_asym``) describes a friction that differs between the
    velocity signs only when it fits the plateau points significantly better than its symmetric map
    (``sym``) under the points' full covariance: their own errors (scaled so that the per-sign map's
    residuals have their expected chi-square) plus ``shifts``, the common errors of the inertia, gravity and
    offset subtracted from the torque (:func:`.mechanics.plateau_shifts`), which move the points of the two
    signs differently where the two signs ran through different positions or accelerations. The F-test of
    the chi-square gain (:func:`_gls_chi2`, with as many degrees of freedom as the per-sign map has more
    free parameters) must reject "one map for both signs" at :data:`SPLIT_P`; otherwise the per-sign map is
    marked (``extra["per_sign_not_supported"]``, a note) and the choice does not take it
    (:func:`.select.choose`). Foreign card 204011 (a symmetric joint at 383 Hz, gravity fitted where there
    is none, not identifiable, -0.011 +- 0.013 N m): the fast plateaus of the two signs ran 0.08-0.29 rad
    from the start and carried that gravity's curvature, 4-6 of their errors; ``stribeck_asym`` was chosen
    on a held-out RMS 2.7 times below the symmetric map's with sigma2 16 % off on one branch."""
    from scipy.stats import f as f_dist

    from .static import _scales, _weights

    if asym is None or sym is None:
        return
    w, F, se = (np.asarray(x, dtype=float) for x in points)
    W = _weights(se, _scales(w, F)[0], w.size)
    D = np.column_stack([np.asarray(d, dtype=float) for d in shifts]) * W[:, None] if shifts else np.zeros((w.size, 0))
    fa, fs_ = _refit_with_shifts(asym, w, F, W, D), _refit_with_shifts(sym, w, F, W, D)
    if fa is None or fs_ is None or fa[1] <= fs_[1]:
        return
    (ca, ra), (cs, rs) = fa, fs_
    dof = w.size - ra
    if dof < 1 or not ca > 0:
        return
    k = ra - rs
    p = float(f_dist.sf(max(cs - ca, 0.0) / k / (ca / dof), k, dof))
    asym.metrics["per_sign_p"] = p
    if p <= SPLIT_P:
        return
    why = (f"the per-sign map fits the plateaus no better than {sym.name} (F-test p = {p:.2g}, beyond the patterns "
           "the inertia, gravity and offset subtracted from the torque make in the points): the data do not show "
           "a friction that differs between the signs along the speed; not taken by the choice")
    asym.extra["per_sign_not_supported"] = why
    if why not in asym.notes:
        asym.notes = list(asym.notes) + [why]


def _refit_with_shifts(mf, w, F, W, D) -> tuple[float, int] | None:
    """A map's weighted residual sum of squares when its free parameters (linearised about the fit) and the
    shifts' amplitudes (columns of ``D``, weighted; at any amplitude) are refitted together, and the rank of
    that refit. None when the map cannot be evaluated."""
    from .static import predict

    vals = mf.values()
    free = [n for n, pe in mf.params.items() if not pe.fixed and pe.value is not None]
    base = predict(mf.name, vals, w)
    if not np.all(np.isfinite(base)):
        return None
    cols = []
    for n in free:
        h = 1e-6 * max(abs(vals[n]), 1e-9)
        d = (predict(mf.name, dict(vals, **{n: vals[n] + h}), w) - base) / h
        if np.all(np.isfinite(d)):
            cols.append(d * W)
    A = np.column_stack(cols + [D]) if cols or D.shape[1] else np.zeros((w.size, 0))
    r = (base - F) * W
    if A.shape[1] == 0:
        return float(r @ r), 0
    x, *_ = np.linalg.lstsq(A, -r, rcond=None)
    e = r + A @ x
    return float(e @ e), int(np.linalg.matrix_rank(A))
