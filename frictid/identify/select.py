"""Model choice per joint: error on held-out segments and an information criterion.

Held-out error. The plateaus (one per constant-velocity segment) are split into ``n_folds`` folds by
segment, never by sample: sorted by velocity, plateau ``k`` goes to fold ``k mod n_folds``, so every fold
spans both signs and all speeds. Each model is refitted without a fold and predicts it;
``rms_heldout`` is the RMS of those predictions over all plateaus.

Choice (:func:`choose`). Among the base models whose parameters are all identifiable, those whose
held-out RMS is within :data:`TOLERANCE` (5 %) of the best are equally good on new data; of these the one
with the lowest AIC (small-sample corrected) is chosen, which prefers the simpler model when the data do
not need the richer one. A Stribeck map whose only unidentified parameters are its drop's shape
(:func:`shape_only`: ``Fs``, ``vs``, ``delta`` where the break-away lies below the slowest plateau, the
exponent is not pinned or the drop is not spanned by steady runs) still has a determined map within the
data's speeds: it competes on the same terms (a user compensates with the map's values there), its shape
staying marked not identifiable with the reason, recorded in the choice. A Stribeck map that rises (``Fs
< Fc``) or shows no drop above the slowest plateau on any branch is not taken. When no model is fully
identifiable or shape-only, the same rule runs over all models, with a warning, but for the Stribeck maps
that rise (:func:`rises`, unless nothing else is left: a rise is no Stribeck drop, whatever it predicts).
The held-out refits therefore run for the models the rule can take (:func:`heldout_for_choice`): a model that is neither gets
no held-out error, and a note saying so, unless no other model gets one.

Shared with the diagnosis: :data:`BASE_MODELS` and :func:`base_model_name` (the base of its chain, by this
rule). This module imports neither the fit's steps nor :mod:`frictid.diagnose`.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from frictid.models import static as sm

from .static import Plateaus, fit_static, predict, warm_start
from .validity import NO_DROP

#: Held-out RMS within this fraction of the best counts as equally good.
TOLERANCE = 0.05
#: The static maps with a Stribeck drop whose shape parameters may be unidentified in a selectable model
#: (:func:`shape_only`), and those parameters (per sign for a per-sign map).
DROP_MAPS = ("stribeck", "stribeck_asym")
DROP_SHAPE = ("Fs", "vs", "delta")
#: Velocity-only models (candidates for the choice), in the order they are reported.
BASE_MODELS = tuple(sm.map_names()) + ("polynomial_ls",)


def plateau_folds(w: np.ndarray, n_folds: int) -> np.ndarray:
    """Fold index per plateau: velocity-sorted rank modulo n_folds."""
    order = np.argsort(w, kind="stable")
    folds = np.empty(w.shape[0], dtype=int)
    folds[order] = np.arange(w.shape[0]) % n_folds
    return folds


def heldout_static(name: str, pl: Plateaus, n_folds: int = 5, axis: str = "rotary", full=None,
                   **kw) -> float | None:
    """Held-out RMS [F] of static map ``name`` over the plateaus (leave-fold-out by segment).

    full : the model fitted on all plateaus; its values warm-start the refits (each fold is a small
    perturbation of the full problem, so the multi-start search is not repeated)."""
    n = len(pl)
    if n < 2 * n_folds:
        n_folds = max(2, n // 2) if n >= 4 else 0
    if n_folds < 2:
        return None
    folds = plateau_folds(pl.w, n_folds)
    pred = np.full(n, np.nan)
    start = None
    if full is not None:  # warm start at the full-data optimum, with delta held where it was held
        start = warm_start(full)
    for f in range(n_folds):
        tr = folds != f
        m = fit_static(name, pl.w[tr], pl.F[tr], pl.F_se[tr], axis=axis, start=start, **kw)
        pred[~tr] = predict(name, m.values(), pl.w[~tr])
    r = pred - pl.F
    if not np.all(np.isfinite(r)):
        return None
    return float(math.sqrt(np.mean(r**2)))


def _branches(mf) -> tuple[str, ...]:
    return ("_pos", "_neg") if mf.map.endswith("_asym") else ("",)


def shape_only(mf) -> bool:
    """Whether ``mf`` (a Stribeck map, or LuGre on one) has unidentified parameters, all of them its drop's
    shape (``Fs``, ``vs``, ``delta`` of a branch: the exponent the data do not pin, a drop out of view at
    an exponent that fits as well, a drop not spanned by steady runs) while every other parameter is
    identifiable, drops on every branch (``Fs >= Fc``: a map that rises is no Stribeck map, whatever it
    predicts) and shows a drop above the slowest plateau on at least one (else its name describes nothing
    the data show: :data:`.validity.NO_DROP`). A degenerate drop is not taken: a shape parameter at a bound
    of the fit, or held where the fit put it because it could not be placed (foreign 204132: Fs at its
    upper bound, 30 times Fc, with a cusp-like exponent of 0.52 and a speed 20 times below the slowest
    plateau; the map's level there came out 3 % low at 5 errors). Its map within the data's speeds is then determined by the
    levels, the slope and the drop's tail; what it says below the slowest plateau is not, which the flags
    and the validity range say."""
    if mf.map not in DROP_MAPS or mf.identifiable:
        return False
    sufs = _branches(mf)
    for n, pe in mf.params.items():
        if pe.identifiable:
            continue
        if pe.fixed or _at_bound(pe) or not any(n == s + suf for s in DROP_SHAPE for suf in sufs):
            return False
    seen = False
    for suf in sufs:
        fs, fc = mf.params.get("Fs" + suf), mf.params.get("Fc" + suf)
        if fs is None or fc is None or fs.value is None or fc.value is None or fs.value < fc.value:
            return False
        seen = seen or not (fs.reason or "").startswith(NO_DROP)
    return seen


def rises(mf) -> bool:
    """Whether ``mf`` is a Stribeck map (or LuGre on one) whose friction at rest lies below its Coulomb level
    on a branch (``Fs < Fc``): a rise, which its name would call a drop (issue 19: no ``stribeck`` with
    Fs < Fc). The fallbacks of :func:`choose` do not take it while another model remains."""
    if mf.map.split("_asym")[0] == "stribeck_2exp":  # marked by the fit (maps.two_exp_drop)
        return any(pe.reason and sm.TWO_EXP_RISE in pe.reason for pe in mf.params.values())
    if mf.map not in DROP_MAPS:
        return False
    for suf in _branches(mf):
        fs, fc = mf.params.get("Fs" + suf), mf.params.get("Fc" + suf)
        if fs is not None and fc is not None and fs.value is not None and fc.value is not None and fs.value < fc.value:
            return True
    return False


def _at_bound(pe) -> bool:
    """Whether the optimiser left ``pe`` at one of its bounds (within a millionth of their span)."""
    if pe.bounds is None or pe.value is None:
        return False
    lo, hi = pe.bounds
    tol = 1e-6 * (hi - lo) if math.isfinite(hi - lo) else 1e-6 * max(1.0, abs(pe.value))
    return any(b is not None and math.isfinite(b) and abs(pe.value - b) <= tol for b in (lo, hi))


def selectable(mf) -> bool:
    """A model the choice can take: all its parameters identifiable, or only its drop's shape not
    (:func:`shape_only`)."""
    return mf.identifiable or shape_only(mf)


#: The note on a model whose held-out error is not computed (:func:`heldout_for_choice`).
NOT_HELDOUT = ("held-out RMS not computed: its parameters are not all identifiable (beyond a Stribeck drop's "
               "shape), and the choice takes such models only when no other model has a held-out RMS")


def heldout_for_choice(models: dict, names: list[str], heldout: Callable[[str], float | None],
                       others: list[str] = ()) -> list[str]:
    """Compute the held-out RMS of the models ``names`` that :func:`choose` can take: the :func:`selectable`
    ones, and the others only when no selectable candidate (of ``names`` and ``others``, whose held-out RMS
    is already known) gets one. ``heldout(name)`` gives a model's held-out RMS, stored in its metrics; a model
    left out gets ``None`` and the note :data:`NOT_HELDOUT`. Returns the names left out.

    The choice is the same as with every model's held-out RMS: the rule ranks the identifiable models only,
    unless none has a held-out RMS. The refits of a model whose parameters the data do not pin down are the
    most expensive ones (the least squares wander along the flat direction to their evaluation cap) and
    their error depends on where they stop (a one-ulp change of the inputs moved ``stribeck_2exp_asym``'s by
    5 %): on the hour's joints they were 0.25-0.39 s of 3.6 s CPU per joint-hour."""
    left = [n for n in names if not selectable(models[n])]
    for n in names:
        if n not in left:
            models[n].metrics["rms_heldout"] = heldout(n)
    known = [n for n in list(names) + list(others) if n in models and selectable(models[n])
             and models[n].metrics.get("rms_heldout") is not None]
    if not known:  # no selectable candidate has a held-out error: the choice runs over every model
        for n in left:
            models[n].metrics["rms_heldout"] = heldout(n)
        return []
    for n in left:
        models[n].metrics["rms_heldout"] = None
        if NOT_HELDOUT not in models[n].notes:
            models[n].notes = list(models[n].notes) + [NOT_HELDOUT]
    return left


def choose(models: dict, candidates: list[str] | None = None, tolerance: float = TOLERANCE
           ) -> tuple[str | None, dict]:
    """Choose a base model. models : name -> :class:`~frictid.result.ModelFit`.

    Returns (name or None, a record of the rule, the ranking and why).
    """
    names = [n for n in (candidates or list(models)) if n in models]
    ranked = []
    for n in names:
        m = models[n]
        ranked.append({"model": n, "rms_heldout": m.metrics.get("rms_heldout"), "aic": m.metrics.get("aic"),
                       "k": m.metrics.get("k"), "identifiable": m.identifiable, "shape_only": shape_only(m),
                       "one_map_for_both_signs": "per_sign_not_supported" in m.extra})
    rec: dict = {"rule": f"lowest AIC among identifiable models (or Stribeck maps whose drop's shape alone is "
                         f"not identifiable) whose held-out RMS is within {100 * tolerance:.0f} % of the best",
                 "tolerance": tolerance}
    rising = {n for n in names if rises(models[n])}
    pool = _pool(ranked, rec, rising)
    if not pool:
        pool = _not_rising([r for r in ranked if r["aic"] is not None], rec, rising)
        if not pool:
            rec["reason"] = "no model could be fitted"
            rec["ranking"] = ranked
            return None, rec
        rec["warning"] = "too few plateaus for held-out errors; chosen by AIC alone"
        best = min(pool, key=lambda r: r["aic"])
    else:
        best_rms = min(r["rms_heldout"] for r in pool)
        near = [r for r in pool if r["rms_heldout"] <= (1 + tolerance) * best_rms]
        best = min(near, key=lambda r: (r["aic"] if r["aic"] is not None else math.inf, r["k"] or 0))
        rec["best_heldout"] = min(pool, key=lambda r: r["rms_heldout"])["model"]
        rec["equally_good"] = [r["model"] for r in near]
    if best.get("shape_only"):
        flagged = [n for n, pe in models[best["model"]].params.items() if not (pe.identifiable or pe.fixed)]
        rec["shape_not_identifiable"] = (
            f"{best['model']} is chosen with {', '.join(flagged)} not identifiable (see their reasons): its map "
            "within the data's speeds is determined and predicts the held-out data "
            + ("best" if rec.get("best_heldout") == best["model"] else
               f"within {100 * tolerance:.0f} % of the best ({rec.get('best_heldout')})")
            + ", its drop's shape is not")
    ranked.sort(key=lambda r: (r["rms_heldout"] is None, r["rms_heldout"] or 0.0))
    rec["ranking"] = ranked
    return best["model"], rec


def _pool(ranked: list[dict], rec: dict, rising: set = frozenset()) -> list[dict]:
    """The models the choice ranks: those with a held-out RMS whose parameters are all identifiable or
    whose drop's shape alone is not (:func:`shape_only`), or, when none of them has one, every model with
    one (with a warning in ``rec``)."""
    pool = [r for r in ranked if (r["identifiable"] or r["shape_only"]) and r["rms_heldout"] is not None
            and not r.get("one_map_for_both_signs")]
    if not pool:
        pool = _not_rising([r for r in ranked if r["rms_heldout"] is not None], rec, rising)
        if pool:
            rec["warning"] = "no model has all its parameters identifiable; chosen among all models"
    return pool


def _not_rising(pool: list[dict], rec: dict, rising: set) -> list[dict]:
    """A fallback's pool without the Stribeck maps that rise (:func:`rises`), recorded in ``rec['not_taken']``,
    unless nothing else is left. (Session 25: Franka joint 2's file selected ``stribeck_asym`` with Fs_pos 0
    against Fc_pos 171 N m when no model was fully identifiable; joint 6's diagnosis started from a
    ``stribeck`` of Fs 1.35 < Fc 8.66 chosen by AIC alone.)"""
    keep = [r for r in pool if r["model"] not in rising]
    if keep and len(keep) < len(pool):
        rec["not_taken"] = [f"{r['model']}: friction at rest below its sliding level (Fs < Fc), a rise, no "
                            "Stribeck drop" for r in pool if r["model"] in rising]
    return keep or pool


def base_model_name(jf) -> str | None:
    """The base of the diagnosis' chain: the choice rule over a joint's symmetric velocity-only static maps
    whose parameters are all known (``jf`` a :class:`frictid.result.JointFit`)."""
    cands = [m for m in BASE_MODELS if not m.endswith("_asym") and m in jf.models
             and all(v is not None for v in jf.models[m].values().values())]
    if not cands:
        return None
    name, _ = choose(jf.models, cands)
    return name
