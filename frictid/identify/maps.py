"""Steps 2-4 of a joint's fit: every static map on the friction torque's points, then the choice.

Each map of :mod:`frictid.models.static` (and its per-sign variant) is fitted on the basis the rigid-body
step chose (:class:`~.mechanics.Friction`): plateau points with a held-out error by plateau folds
(:mod:`.static`, :mod:`.select`), or every moving sample held out by time blocks (:mod:`.samples`). The
polynomial also comes from the stage-1 regression itself (``polynomial_ls``). The base model is then
chosen by held-out error and AIC (:func:`frictid.identify.select.choose`).
"""
from __future__ import annotations

import math

import numpy as np

from frictid.models import static as sm
from frictid.result import ModelFit

from . import regression as rg
from . import samples as smp
from . import select as sel
from . import validity
from .mechanics import POLY_COEFS, Friction, RigidBody, reg_estimate
from .prepare import JointData
from .static import NEGLIGIBLE, fit_static, metrics

#: The polynomial_ls model's method, on either basis.
POLY_LS_METHOD = "linear least squares on all moving samples with J, gravity and offset (002 eq 4-11)"


def static_maps(jd: JointData, rb: RigidBody, fr: Friction, wanted: list[str], n_folds: int) -> None:
    """Fit the wanted static maps and ``polynomial_ls`` on the basis of ``fr`` and give the ones the choice
    can take their held-out error; records the plateaus used and warns about the basis."""
    jf = jd.jf
    plat, keys = fr.plat, fr.keys
    jd.used["constant_velocity"] = [[float(a), float(b), jd.preps[int(k[0])].index] for a, b, k in
                                    zip(plat.t_start, plat.t_end, keys)]
    _basis_warnings(jd, fr)
    static_names = [m for m in wanted if m in sm.map_names()]
    if fr.basis == "samples":
        _sample_maps(jd, rb, fr, static_names, n_folds)
    for name in static_names if fr.basis == "plateaus" else ():
        if len(plat) == 0:
            jf.not_identified.append({"what": name, "reason": "no constant-velocity plateaus"})
            continue
        sh = fr.odd_shifts if fr.odd_shifts is not None and not name.endswith("_asym") else fr.shifts
        _guarded(jf, name, lambda n=name, sh=sh: fit_static(n, plat.w, plat.F, plat.F_se, axis=jd.axis,
                                                            shifts=sh, jackknife=True))
    if "polynomial_ls" in wanted:
        if fr.basis == "samples":
            mf = _polynomial_ls_samples(jd, rb, fr)
        else:
            mf = _polynomial_ls(jd, rb, fr, n_folds)
        if mf is not None:
            jf.models["polynomial_ls"] = mf
        else:
            jf.not_identified.append({"what": "polynomial_ls", "reason": rb.why or "no moving samples"})
    fitted = [n for n in static_names if n in jf.models]
    basis_w = fr.S.w if fr.basis == "samples" and fr.S is not None else fr.plat.w
    for n in fitted + (["polynomial_ls"] if "polynomial_ls" in jf.models else []):
        level_in_range(jf.models[n], basis_w, jd.F0)
    for n in fitted:
        two_exp_drop(jf.models[n], basis_w, jd.F0)
        physical_shape(jf.models[n], jd.w0, jd.F0)
        validity.drop_spanned(jf.models[n], fr.plat.w, jf.models.get(n.replace("stribeck", "coulomb_viscous")),
                              points=(fr.plat.w, fr.plat.F, fr.plat.F_se) if fr.basis == "plateaus" else None,
                              shifts=fr.shifts)
    if fr.basis == "plateaus":
        for n in fitted:
            if n.endswith("_asym"):
                validity.per_sign_supported(jf.models[n], jf.models.get(n[:-5]), (fr.plat.w, fr.plat.F, fr.plat.F_se),
                                            fr.shifts)
    # held-out errors of the maps the choice can take (the identifiable ones, unless none gets one)
    if fr.basis == "samples":
        sel.heldout_for_choice(jf.models, fitted, lambda n: smp.heldout_map(n, fr.S, jf.models[n], jd.axis),
                               others=["polynomial_ls"])
    else:
        sel.heldout_for_choice(jf.models, fitted, lambda n: sel.heldout_static(
            n, plat, n_folds, axis=jd.axis, full=jf.models[n]), others=["polynomial_ls"])
    for n in fitted:  # after the held-out refits, whose jackknife can take a drop's speed (samples basis)
        validity.break_away_needs_speed(jf.models[n])


#: Per map: (break-away level, level it drops to, the drop's shape parameters) of a Stribeck drop; the drop
#: must be downwards (003: Fs >= Fc), else the model's name and its shape parameters describe nothing.
#: (``stribeck_2exp`` is 001's free two-exponential form, whose amplitudes can cancel: its shape is checked on
#: the curve, :func:`two_exp_drop`.)
DROPS = {"stribeck": ("Fs", "Fc", ("Fs", "vs", "delta"))}
#: Per map: its viscous coefficient (dissipative only when >= 0), flagged when it is below zero by more
#: than VISCOUS_Z standard errors (a slope the data cannot tell from zero is a well-determined zero).
VISCOUS = {"coulomb_viscous": "sigma2", "stribeck": "sigma2"}
VISCOUS_Z = 2.0


def _not_physical(pe, why: str) -> None:
    if pe is not None and pe.identifiable and not pe.fixed:
        pe.identifiable = False
        pe.reason = why


def physical_shape(mf, w0: float = math.inf, F0: float = 0.0) -> None:
    """Names and signs that tell the truth (issue 19): a Stribeck map whose break-away level is below its
    Coulomb level on a branch, and a viscous coefficient below zero (significantly or within its errors), are marked
    not identifiable with the reason, so the choice takes a model whose shape says what the data do (the
    polynomial follows a friction that rises from zero speed) and no green badge is given to them."""
    base = mf.name[:-5] if mf.name.endswith("_asym") else mf.name
    sufs = ("_pos", "_neg") if mf.name.endswith("_asym") else ("",)
    for suf in sufs:
        p = {k[:len(k) - len(suf)] if suf else k: v for k, v in mf.params.items() if k.endswith(suf)}
        if base in DROPS:
            hi, lo, shape = DROPS[base]
            vh = p[hi].value if hi in p else None
            vl = p[lo].value if lo in p else None
            if vh is not None and vl is not None and vh < vl:
                why = f"{hi}{suf} {vh:.4g} below {lo}{suf} {vl:.4g}"
                for n in shape:
                    _not_physical(p.get(n), why + ": the friction rises from zero speed instead of dropping, "
                                  "which a Stribeck drop cannot describe (the polynomial map follows it)")
        v = p.get(VISCOUS.get(base, ""))
        if v is not None and v.value is not None and v.value < -VISCOUS_Z * (v.stderr or 0.0):
            _not_physical(v, f"negative viscous coefficient ({v.value:.4g}): the friction falls with speed "
                             "over the measured range, which a viscous term cannot be")
        elif v is not None and v.value is not None and v.value < 0 and (v.stderr or 0.0) * w0 > NEGLIGIBLE * F0:
            # a negative slope within its errors of zero: the data do not tell its sign, and a negative
            # value is no viscous coefficient (issue 19: a negative viscous term is flagged, not badged),
            # unless its uncertainty is negligible at the top speed w0 (1 % of the torque scale F0: a
            # well-determined zero, the rule of the static fits)
            _not_physical(v, f"negative viscous coefficient ({v.value:.4g} +- {v.stderr or 0.0:.2g}): the data do "
                             "not tell the slope's sign over the measured range")


#: Per map: the parameters of its level g (``F = g sgn(w) + f(w)``), flagged when g is below zero inside
#: the fitted speeds (:func:`level_in_range`).
LEVEL = {"coulomb_viscous": ("Fc",), "stribeck": ("Fc", "Fs"), "stribeck_2exp": ("alpha0", "alpha1", "alpha2"),
         "polynomial": ("c0",)}
#: Points of the speed grid on which :func:`level_in_range` looks for a negative level (besides the speeds).
LEVEL_GRID = 257


def level_in_range(mf, basis_w: np.ndarray, F0: float) -> None:
    """A level that goes negative inside the fitted speeds is no friction (issue 19): the model the parameter
    file runs (:class:`frictid.model.FrictionModel`, the replay kernel) holds g at zero there, so the fitted
    formula is not the function the file describes (Franka joint 4, ``stribeck_2exp``: g(1 rad/s) = -3.6
    N m, run as 0). On each branch, over the speeds the map was fitted on (the validity range's, and a grid
    between them), a level below zero by more than :data:`~.static.NEGLIGIBLE` of the torque scale ``F0``
    marks the level's parameters not identifiable with the reason, so the choice does not take the map."""
    base = mf.map[:-5] if mf.map.endswith("_asym") else mf.map
    vals = mf.values()
    if base not in LEVEL or any(v is None for v in vals.values()):
        return
    w = np.asarray(basis_w, dtype=float)
    w = w[np.isfinite(w) & (w != 0)]
    sides = (("_pos", w[w > 0]), ("_neg", -w[w < 0])) if mf.map.endswith("_asym") else (("", np.abs(w)),)
    for suf, v in sides:
        rng = validity._range(v, validity.TAIL if v.size > 1000 else 0.0)
        if rng is None:
            continue
        grid = np.concatenate([np.linspace(rng[0], rng[1], LEVEL_GRID), v[(v >= rng[0]) & (v <= rng[1])]])
        g = sm.level(mf.map, grid if suf != "_neg" else -grid, vals)
        k = int(np.argmin(g))
        if g[k] >= -NEGLIGIBLE * F0:
            continue
        why = (f"level g{suf} {g[k]:.4g} at {grid[k]:.4g} q/s, below zero inside the fitted speeds "
               f"[{rng[0]:.4g}, {rng[1]:.4g}]: the model the parameter file runs holds a level at zero (friction "
               "does not push the motion), so this formula is not the function the file describes")
        for n in LEVEL[base]:
            _not_physical(mf.params.get(n + suf), why)
        mf.notes = list(mf.notes) + [why]


def two_exp_drop(mf, basis_w: np.ndarray, F0: float) -> None:
    """A two-exponential map (``stribeck_2exp``, 001's Stribeck drop and second rise) whose level has no drop
    from rest on a branch is named for a drop it does not have (issue 19: no ``stribeck`` with Fs < Fc; Franka
    joint 3's `stribeck_2exp`: 1.56 N m at rest rising to 19.6, amplitudes 179 and 197 N m at nearly the same
    speed). On each branch, from zero to the top of the fitted speeds, the level's shape
    (:func:`frictid.models.static.low_speed_shape`, a dip or rise of up to :data:`~.static.NEGLIGIBLE` of the
    torque scale ``F0`` counting as none): a ``rise`` marks the drop's amplitude and speed (alpha1, ws1) not
    identifiable with the reason, so the choice takes a map whose name says what the data do."""
    if mf.map.split("_asym")[0] != "stribeck_2exp" or any(v is None for v in mf.values().values()):
        return
    w = np.asarray(basis_w, dtype=float)
    w = w[np.isfinite(w) & (w != 0)]
    cp, cn = sm.canonical_pair(mf.map, mf.values())
    sides = ((("_pos", w[w > 0], cp), ("_neg", -w[w < 0], cn)) if mf.map.endswith("_asym")
             else (("", np.abs(w), cp),))
    for suf, v, c in sides:
        if v.size == 0:
            continue
        grid = np.concatenate([[0.0], np.linspace(0.0, v.max(), LEVEL_GRID)[1:], np.sort(v)])
        grid.sort()
        if sm.low_speed_shape(c, grid, NEGLIGIBLE * F0) != "rise":
            continue
        g = sm.canonical_level(grid, c)
        why = (f"level{suf} {g[0]:.4g} at rest, {g.max():.4g} at most over the fitted speeds (up to {v.max():.4g} "
               f"q/s): the friction {sm.TWO_EXP_RISE}, the drop the two-exponential map's first term is named for "
               "(the polynomial map follows a rise)")
        for n in ("alpha1", "ws1"):
            _not_physical(mf.params.get(n + suf), why)
        mf.notes = list(mf.notes) + [why]


def _basis_warnings(jd: JointData, fr: Friction) -> None:
    """Warn about a sample basis, missing plateaus, or one velocity sign only."""
    jf, plat, S = jd.jf, fr.plat, fr.S
    npos, nneg = int((plat.w > 0).sum()), int((plat.w < 0).sum())
    if fr.basis == "samples":
        jf.warnings.append(fr.why)
        if S is not None and ((S.w > 0).sum() == 0 or (S.w < 0).sum() == 0):
            side = "positive" if (S.w < 0).sum() == 0 else "negative"
            jf.warnings.append(f"one velocity sign only ({side} velocities): symmetric maps assume the other "
                               "sign mirrors it; per-sign parameters of the other sign are not identifiable")
    elif len(plat) == 0:
        jf.warnings.append("no usable constant-velocity plateaus: the static maps cannot be fitted")
    elif nneg == 0 or npos == 0:
        side = "positive" if nneg == 0 else "negative"
        jf.warnings.append(f"one velocity sign only ({side}-velocity plateaus): symmetric maps assume the "
                           "other sign mirrors it; per-sign parameters of the other sign are not identifiable")


def _sample_maps(jd: JointData, rb: RigidBody, fr: Friction, names: list[str], n_folds: int) -> None:
    """The static maps on every moving sample of the final mechanics' friction torque (``fr.S`` is
    rebuilt), their variance inflated by the residual's correlation."""
    fr.S = S = smp.build(jd.preps, jd.min_speed, n_folds, exclude=fr.excl)
    reg_fit = rb.fit
    if reg_fit is not None and all(c in reg_fit.names for c in POLY_COEFS):
        S.inflation = smp.variance_factor(S.F - sm.polynomial(S.w, **{c: reg_fit.value(c) for c in POLY_COEFS}))
    for name in names:
        _guarded(jd.jf, name, lambda n=name: smp.fit_map(n, S, jd.axis, heldout=False))
        if name in jd.jf.models:
            smp.speed_split_spread(jd.jf.models[name], name, S, jd.axis)


#: Numerical failures of one map's fit (LAPACK not converging on a degenerate Jacobian, a floating-point
#: trap): that map is not identified, with the reason; the other maps stand.
NUMERICAL_FAILURES = (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError)


def _guarded(jf, name: str, fit) -> None:
    """``jf.models[name] = fit()``, or ``name`` listed as not identified when its numerics fail."""
    try:
        jf.models[name] = fit()
    except NUMERICAL_FAILURES as exc:
        jf.not_identified.append({"what": name, "reason": f"the least-squares fit failed numerically ({exc})"})


def choose_base(jd: JointData, fr: Friction, n_folds: int) -> None:
    """Choose among the velocity-only static models (:data:`frictid.identify.select.BASE_MODELS`): sets
    ``selected`` and ``selection`` of the result."""
    jf = jd.jf
    cands = [m for m in sel.BASE_MODELS if m in jf.models]
    selected, rec = sel.choose(jf.models, cands)
    rec["basis"] = {"plateaus": "plateau points (held out by plateau folds)",
                    "samples": f"moving samples (held out by {smp.BLOCKS_PER_FOLD * n_folds} time blocks in "
                               f"{n_folds} folds)"}[fr.basis]
    rec["basis_reason"] = fr.why
    jf.selected, jf.selection = selected, rec
    if rec.get("shape_not_identifiable"):  # chosen for its map: its drop's shape listed as not identified
        jf.not_identified += [{"what": f"{selected}.{n}", "reason": pe.reason}
                              for n, pe in jf.models[selected].params.items() if not (pe.identifiable or pe.fixed)]


def _rss(b, ne: rg.NormalEquations) -> float:
    """Residual sum of squares of coefficients ``b`` on normal equations ``ne``."""
    return max(float(ne.yty - 2 * b @ ne.Xty + b @ ne.XtX @ b), 0.0)


def _sample_metrics(reg_fit, seg_ne, names, n_folds) -> dict:
    """rms, held-out rms (segments in folds by order), aic and n of a regression on its moving samples."""
    total = rg.NormalEquations.total(ne for *_, ne in seg_ne)
    k = len(names)
    r_all = _rss(reg_fit.coef, total)
    n = total.n
    met = {"rms": math.sqrt(r_all / n) if n else None, "n": int(n), "k": k,
           "aic": (n * math.log(r_all / n) + 2 * k) if n and r_all > 0 else None, "rms_heldout": None}
    blocks = [ne for *_, ne in seg_ne if ne.n > 0]
    if len(blocks) >= 2:
        nf = min(n_folds, len(blocks))
        e2 = 0.0
        nn = 0
        for f in range(nf):
            out = rg.NormalEquations.total(blocks[i] for i in range(len(blocks)) if i % nf == f)
            fit_f = rg.solve(total - out, names)
            e2 += _rss(fit_f.coef, out)
            nn += out.n
        met["rms_heldout"] = math.sqrt(e2 / nn) if nn else None
    return met


def _polynomial_ls(jd: JointData, rb: RigidBody, fr: Friction, n_folds: int) -> ModelFit | None:
    """polynomial_ls on the plateau basis: the stage-1 regression's polynomial, its metrics on the plateau
    points, held out by plateau folds (the regression refitted without each fold's segments)."""
    reg_fit, seg_ne, free_names, plat = rb.fit, rb.seg_ne, rb.regs.free, fr.plat
    if reg_fit is None or not all(c in free_names for c in POLY_COEFS):
        return None
    params = {c: reg_estimate(c, reg_fit, jd) for c in POLY_COEFS}
    values = {c: params[c].value for c in params}
    if not len(plat):
        return ModelFit("polynomial_ls", "polynomial", params, _sample_metrics(reg_fit, seg_ne, free_names, n_folds),
                        method=POLY_LS_METHOD + "; no plateaus: metrics on the moving samples, held out by segment",
                        extra={"basis": "moving samples"})
    met = metrics("polynomial", values, plat.w, plat.F, 4)
    met["rms_heldout"] = None
    if len(plat) >= 4:
        nf = n_folds if len(plat) >= 2 * n_folds else max(2, len(plat) // 2)
        folds = sel.plateau_folds(plat.w, nf)
        total = rg.NormalEquations.total(ne for *_, ne in seg_ne)
        pred = np.full(len(plat), np.nan)
        lookup = {(pi, si): ne for pi, si, ne in seg_ne}
        for f in range(nf):
            out = rg.NormalEquations(total.p)
            for (pi, si), fo in zip(fr.keys, folds):
                if fo == f and (int(pi), int(si)) in lookup:
                    out = out + lookup[(int(pi), int(si))]
            fitf = rg.solve(total - out, free_names)
            vals = {c: fitf.value(c) for c in POLY_COEFS}
            pred[folds == f] = sm.polynomial(plat.w[folds == f], **vals)
        r = pred - plat.F
        if np.all(np.isfinite(r)):
            met["rms_heldout"] = float(np.sqrt(np.mean(r**2)))
    return ModelFit("polynomial_ls", "polynomial", params, met, method=POLY_LS_METHOD)


def _fold_equations(jd: JointData, rb: RigidBody, fr: Friction) -> list[rg.NormalEquations]:
    """Normal equations of the stage-1 regression per fold of the sample basis' time blocks."""
    S, free_names = fr.S, rb.regs.free
    blocks = smp.block_ranges([np.asarray(p.log.t, float) for p in jd.preps], S.n_folds)
    per_fold = [rg.NormalEquations(len(free_names)) for _ in range(S.n_folds)]
    for p, rr in zip(jd.preps, blocks):
        allowed = [(s.i0, s.i1) for s in p.segments if s.kind not in fr.excl] or [(0, p.log.n)]
        ranges, folds = [], []
        for i0, i1, b in rr:
            for a, c in allowed:
                lo, hi = max(i0, a), min(i1, c)
                if hi > lo:
                    ranges.append((lo, hi))
                    folds.append(b % S.n_folds)
        nes = rg.accumulate(ranges, free_names, p.log.q, p.w, p.a, p.log.tau, p.log.channels.get("payload"),
                            rb.regs.known_coef, jd.min_speed, jd.axis)
        for f, ne in zip(folds, nes):
            per_fold[f] = per_fold[f] + ne
    return per_fold


def _polynomial_ls_samples(jd: JointData, rb: RigidBody, fr: Friction) -> ModelFit | None:
    """polynomial_ls on the sample basis: metrics on the moving samples, held out by the time blocks of
    :mod:`.samples` (the regression refitted without each fold, from per-block normal equations)."""
    reg_fit, S, free_names = rb.fit, fr.S, rb.regs.free
    if reg_fit is None or S is None or not all(c in free_names for c in POLY_COEFS):
        return None
    params = {c: reg_estimate(c, reg_fit, jd) for c in POLY_COEFS}
    per_fold = _fold_equations(jd, rb, fr)
    total = rg.NormalEquations.total(per_fold)
    held, nn = 0.0, 0
    for ne in per_fold:
        if ne.n == 0 or total.n - ne.n <= len(free_names):
            continue
        held += _rss(rg.solve(total - ne, free_names).coef, ne)
        nn += ne.n
    met = smp.sample_metrics(_rss(reg_fit.coef, total), total.n, 4, math.sqrt(held / nn) if nn else None, S)
    return ModelFit("polynomial_ls", "polynomial", params, met,
                    method=POLY_LS_METHOD + "; metrics on the moving samples, held out by time blocks",
                    extra={"basis": "moving samples"})
