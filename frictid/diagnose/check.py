"""The diagnosis of a fitted joint, and the check that its end model predicts held-out data no worse.

:func:`diagnose_fit` hands the fit's prepared logs (:class:`frictid.identify.prepare.Prep`) to
:func:`frictid.diagnose.joint.diagnose_joint`; :func:`check_diagnosis` then keeps the fit's own choice when
the diagnosis' end model predicts the fit's basis worse on held-out data. Both judge a model the same way:
its static map refitted without each fold to the torque it has to explain once its other terms are
replayed along the logs (:func:`frictid.replay.replay`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from frictid.errors import ConfigError, FrictidInputError
from frictid.identify import samples as smp
from frictid.identify import select as sel
from frictid.identify.prepare import REGRESSION_EXCLUDE, Prep
from frictid.identify.static import Plateaus, fit_static, plateau_points, predict
from frictid.models import static as sm
from frictid.parallel import one_blas_thread
from frictid.replay import joint_model, log_start_time, replay
from frictid.result import JointFit, ParamEstimate

from .joint import diagnose_joint
from .samples import DiagLog

#: The diagnosis' end model replaces the fit's choice only when its held-out error on the fit's own basis
#: (plateau means or moving samples, with each model's static map refitted without the held-out fold) is
#: at most this factor of the choice's.
DIAGNOSIS_TOLERANCE = 1.05
#: Diagnosis extensions that average out over the joint's travel (a periodic level factor of position):
#: when one is kept (with at most rigid-body extensions besides), the static maps are refitted on plateau
#: means with its effect taken out.
MEAN_FREE_EXTENSIONS = ("position_periodic",)
#: Extensions that re-estimate rigid-body terms (they do not change what the velocity-only map means).
RIGID_EXTENSIONS = ("offset", "inertia", "gravity")


def diagnose_fit(jf: JointFit, preps: list[Prep]) -> None:
    """Hand the prepared logs to the diagnosis, with an estimated offset left in the friction torque (it
    enters the extended models only through the diagnosis' ``offset`` cause; one from metadata stays).
    The preps' friction and gravity torques go with them (``F``, ``G`` are None afterwards)."""
    off = 0.0
    if jf.offset is not None and jf.offset.value is not None and jf.offset.source != "log metadata":
        off = jf.offset.value
    logs = []
    for p in preps:
        if p.F is None:
            continue
        # the prep's friction and gravity torques are handed over with the offset moved in place: the fit
        # does not read them again, and two offset copies were 58 MB more in the diagnosis' peak
        F, G, p.F, p.G = p.F, p.G, None, None
        F += off
        G -= off
        logs.append(DiagLog(t=p.log.t, q=p.log.q, w=p.w, a=p.a, tau=p.log.tau, F=F, G=G, offset=off,
                            segments=p.segments, channels=p.log.channels, start=log_start_time(p.log),
                            source=p.index))
    if logs:
        with one_blas_thread():
            diagnose_joint(jf, logs)


def _residuals(jf: JointFit, preps: list[Prep], name: str, cache: dict | None = None) -> list[np.ndarray]:
    """Per log, model ``name``'s torque residual with its stored parameters (``tau - tau_model``, the replay
    along the log), kept in ``cache`` by name: the check asks for each model's twice (its static targets and
    its stored RMS), and a replay of a joint-hour is a pass over 3.6 M samples."""
    if cache is not None and name in cache:
        return cache[name]
    m = joint_model(jf, name)
    # the log's scales when the fit measured them: the replay of a static map needs its velocity noise
    # (measured again, 0.13 s CPU per replay of a joint-hour)
    out = [replay(p.log, m, w=p.w, a=p.a, scales=p.scales).residual for p in preps]
    if cache is not None:
        cache[name] = out
    return out


def _static_targets(jf: JointFit, preps: list[Prep], name: str, cache: dict | None = None):
    """Per log, the torque that model ``name``'s static map has to explain once the model's other terms
    (rigid body, offset, extension factors, thermal state) are replayed: ``tau - tau_model + s(w)`` [F], s
    the model's static map at the samples' velocity. For a plain static map it is the friction torque
    ``tau - J a - G - offset``. Returns (map name, static values, [array per log])."""
    mf = jf.models[name]
    vals = mf.values()
    out = [r + predict(mf.map, vals, p.w) for p, r in zip(preps, _residuals(jf, preps, name, cache))]
    return mf.map, vals, out


def _stored_rms(jf: JointFit, preps: list[Prep], name: str, min_speed: float, cache: dict | None = None) -> float:
    """RMS [F] of model ``name``'s torque residual, with its stored parameters, over the moving samples
    (faster than min_speed) of the logs; NaN when it cannot be replayed."""
    try:
        ss, n = 0.0, 0
        for p, r in zip(preps, _residuals(jf, preps, name, cache)):
            r = r[(np.abs(p.w) > min_speed) & np.isfinite(r)]
            ss += float(np.sum(r * r))  # not BLAS: the same sum in a worker as in the parent
            n += r.size
        return math.sqrt(ss / n) if n else math.nan
    except (ConfigError, FrictidInputError, KeyError, ValueError):
        return math.nan


def _target_plateaus(preps: list[Prep], Y) -> Plateaus:
    """Plateau points of per-log target series Y (same segments, trim and batch means as the fit's)."""
    pls = [plateau_points(p.log.t, p.w, y, p.segments) for p, y in zip(preps, Y)]
    pls = [pl for pl in pls if len(pl)]
    if not pls:
        z = np.zeros(0)
        return Plateaus(z, z, z, z, z.astype(int), z, z, z.astype(int))
    return Plateaus(*(np.concatenate([getattr(c, f) for c in pls]) for f in
                      ("w", "F", "F_se", "w_se", "n", "t_start", "t_end", "seg")))


def _heldout_on_basis(jf, preps, name, basis, min_speed, excl, n_folds, like=None, cache=None):
    """Held-out RMS [F] of model ``name`` on the fit's basis: its static map refitted without each fold
    (plateau folds, or the time blocks of the sample basis) on the targets of :func:`_static_targets`, the
    rest of the model held. Returns (rms_heldout, refit ModelFit, target Plateaus or the samples' key,
    :class:`_SampleKey`). ``like``: that key from another model of the joint: its speed order is reused when
    the samples are the same (one sort of up to 2 M samples less), and its columns too when both models'
    targets are finite everywhere (:func:`_same_samples`: only the friction is gathered again)."""
    mapname, _, Y = _static_targets(jf, preps, name, cache)
    if basis == "plateaus":
        pl = _target_plateaus(preps, Y)
        if len(pl) < 4:
            return math.nan, None, pl
        mf = fit_static(mapname, pl.w, pl.F, pl.F_se, axis=jf.axis)
        rh = sel.heldout_static(mapname, pl, n_folds, axis=jf.axis, full=mf)
        return (rh if rh is not None else math.nan), mf, pl
    finite = all(bool(np.isfinite(y).all()) for y in Y)
    S = _same_samples(like, Y) if finite and isinstance(like, _SampleKey) else None
    if S is None:
        pseudo = [SimpleNamespace(log=p.log, w=p.w, F=y, segments=p.segments) for p, y in zip(preps, Y)]
        S = smp.build(pseudo, min_speed, n_folds, exclude=excl)
        if S is None:
            return math.nan, None, None
        if isinstance(like, _SampleKey):
            S.share_order(like.order)
            like.w = like.block = like.fold = like.log = like.by_speed = like.w_bins = None   # not shared: not held
    # only its held-out error is read: the fold refits' jackknife of the standard errors (two percentiles of
    # up to 2 M samples, a pass over their recordings) is left out
    mf = smp.fit_map(mapname, S, jf.axis, errors=False)
    rh = mf.metrics.get("rms_heldout")
    # the columns are kept only when another model's finite targets can take them (:func:`_same_samples`)
    cols = (S.w, S.block, S.fold, S.log) if finite else (None,) * 4
    key = _SampleKey(S.order_key(), *cols, S.stride, S.n_moving, finite,
                     S.sorted_velocity_folds() if finite else None, S.velocity_bins_cache() if finite else None)
    return (rh if rh is not None else math.nan), mf, key


@dataclass
class _SampleKey:
    """What a sample set built by :func:`_heldout_on_basis` shares with the other model's set on the same
    logs: its speed order and its columns other than the friction (the same masks take the same samples),
    sorted by speed too, and whether every target was finite (then the masks depend on the velocity and the
    segments only)."""

    order: "smp.SpeedOrder | None"
    w: np.ndarray | None
    block: np.ndarray | None
    fold: np.ndarray | None
    log: np.ndarray | None
    stride: int
    n_moving: int
    finite: bool
    #: per velocity sign, the speed-sorted velocity and folds (:meth:`~frictid.identify.samples.SampleSet.by_speed`)
    by_speed: tuple | None = None
    #: the velocity side of the binned samples (:meth:`~frictid.identify.samples.SampleSet.velocity_bins`)
    w_bins: dict | None = None


def _same_samples(key: _SampleKey, Y) -> "smp.SampleSet | None":
    """The sample set of the targets Y on the samples of ``key`` (both models' targets finite everywhere:
    :func:`frictid.identify.samples.build` keeps the same samples of the same logs, only their friction
    differs), without forming its velocity, blocks and logs again; None when that does not hold."""
    if not key.finite or key.w is None or key.order is None or len(key.order.source[1]) != len(Y):
        return None
    masks = key.order.source[1]
    if any(m.shape != y.shape for m, y in zip(masks, Y)):
        return None
    F = np.concatenate([y[m] for y, m in zip(Y, masks)])
    if key.stride > 1:
        F = F[::key.stride]
    S = smp.SampleSet(key.w, F, key.block, key.fold, key.log, key.stride, key.n_moving, key.order.n_folds,
                      source=key.order.source)
    S.share_order(key.order)
    if key.by_speed is not None:   # the speed-sorted samples: only their friction gathered
        S.share_sorted(key.by_speed, key.w_bins)
    return S


def check_diagnosis(jf: JointFit, preps: list[Prep], choice: str, basis: str, min_speed: float, excl,
                    n_folds: int = 5) -> None:
    """Keep the fit's choice when the diagnosis' end model predicts the fit's basis worse on held-out data.

    Both models are judged the same way: the static map of each is refitted without each fold (plateau
    folds by segment, or the time blocks of the sample basis) to the torque it has to explain once the
    model's other terms are replayed along the logs (:func:`_static_targets`; the extension terms stay at
    the diagnosis' values, which its own held-out test chose), and predicts the held-out fold. The
    diagnosis fits its extensions on sliding samples and starts from a symmetric map; an extension fitted
    there can be degenerate elsewhere (a polynomial refitted on two or three plateau speeds), or a
    symmetric map plus an offset can miss a per-sign map's shape. A genuine finding (a temperature or
    position effect) takes its effect out of the held-out plateaus and so predicts them better. The
    findings stay listed. When the kept model has a periodic position factor, the plateau-basis static
    maps are refitted with its effect taken out (:func:`_refit_static_maps`). With duty cycles in the
    logs the check runs on all moving samples, duty cycles included (a temperature effect shows there).
    Any failure of the replay (a model the replay cannot run) leaves the diagnosis' choice in place. A
    diagnosis' model that passes must also predict the moving samples with its stored parameters (fitted
    on sliding samples, not refitted) within the same tolerance of the fit's stored choice
    (:func:`_stored_rms`): the refits judge the structure, the file carries the parameters."""
    if jf.selected in (None, choice):
        return
    # duty cycles stay out of the fit's basis (their friction drifts with temperature) but are where a
    # temperature finding shows: with duty cycles the check runs on every moving sample of the logs
    has_duty = any(s.kind == "duty_cycle" for p in preps for s in p.segments)
    if has_duty:
        basis, excl = "samples", REGRESSION_EXCLUDE
    try:
        cache = {}  # each model's replayed residual, read again by _stored_rms below
        e_diag, mf_diag, pl_diag = _heldout_on_basis(jf, preps, jf.selected, basis, min_speed, excl, n_folds,
                                                     cache=cache)
        e_fit, _, _ = _heldout_on_basis(jf, preps, choice, basis, min_speed, excl, n_folds, like=pl_diag,
                                        cache=cache)
    except (ConfigError, FrictidInputError, KeyError, ValueError):
        return
    what = ("plateau means" if basis == "plateaus" else
            "moving samples" + (" (duty cycles included)" if has_duty and "duty_cycle" not in excl else ""))
    rec = {"model": jf.selected, "rms_heldout": e_diag, "fit_choice": choice, "rms_heldout_fit_choice": e_fit,
           "rule": f"the diagnosis' model is selected when its held-out torque RMS on {what} is at most "
                   f"{DIAGNOSIS_TOLERANCE:g} x that of the fit's choice (each model's static map refitted "
                   "without the held-out fold, its other terms replayed)"}
    worse = math.isfinite(e_diag) and math.isfinite(e_fit) and e_diag > DIAGNOSIS_TOLERANCE * e_fit
    if not worse:
        # the refits judge each model's structure; the parameters that would be selected are the stored
        # ones, fitted by the diagnosis on sliding samples: they must predict the moving samples about as
        # well as the fit's stored choice (EMPS: a polynomial refitted on two plateau speeds, 54 % force
        # error, scored like polynomial_asym once refitted)
        s_diag = _stored_rms(jf, preps, jf.selected, min_speed, cache)
        s_fit = _stored_rms(jf, preps, choice, min_speed, cache)
        rec.update(rms_stored=s_diag, rms_stored_fit_choice=s_fit)
        worse = math.isfinite(s_diag) and math.isfinite(s_fit) and s_diag > DIAGNOSIS_TOLERANCE * s_fit
        if worse:
            what, e_diag, e_fit = "moving samples (stored parameters, not refitted)", s_diag, s_fit
    if worse:
        rec["kept"] = choice
        if jf.diagnosis:  # without findings there is nothing kept as evidence: the record says it all
            jf.warnings.append(f"the diagnosis' model {jf.selected} predicts the torque of "
                               f"{'' if what.startswith('moving samples (') else 'held-out '}{what} worse "
                               f"(RMS {e_diag:.4g}) than the fit's choice {choice} ({e_fit:.4g}): {choice} stays "
                               "selected; the findings are kept as evidence")
        jf.selected = choice
    elif basis == "plateaus" and pl_diag is not None and len(pl_diag):
        ext = set((jf.models[jf.selected].extra or {}).get("extensions") or ())
        mean_free = sorted(ext & set(MEAN_FREE_EXTENSIONS))
        if mean_free and ext <= set(MEAN_FREE_EXTENSIONS) | set(RIGID_EXTENSIONS):
            rec["static_maps_refitted"] = _refit_static_maps(jf, pl_diag, n_folds, jf.selected, mean_free)
    jf.selection["diagnosis_check"] = rec


def _refit_static_maps(jf: JointFit, pl: Plateaus, n_folds: int, source: str, exts) -> list[str]:
    """Refit the plateau-basis static maps on plateau means with a mean-free extension's effect taken out.

    A periodic position factor averages to one over its period, so the velocity-only map is the friction
    averaged over position; a plateau that travels less than a period (a slow one) measures it biased by
    the factor at the positions it happens to cover (the linear slide: 0.14 periods at its lowest speed,
    7 % of the friction). The plateau means with the kept model's factor replayed out are that average.
    Models the choice did not fit on plateaus (polynomial_ls, the diagnosis' own) are left alone; LuGre
    takes the refitted values of its static map."""
    done = []
    for name, mf in list(jf.models.items()):
        if name not in sm.map_names() or (mf.extra or {}).get("basis") == "moving samples":
            continue
        new = fit_static(name, pl.w, pl.F, pl.F_se, axis=jf.axis)
        new.notes = list(new.notes) + [f"refitted on plateau means with {source}'s {', '.join(exts)} effect "
                                      "replayed out (the friction averaged over position)"]
        new.extra = dict(mf.extra or {}, refitted_without=list(exts))
        jf.models[name] = new
        done.append(name)
    sel.heldout_for_choice(jf.models, done, lambda n: sel.heldout_static(n, pl, n_folds, axis=jf.axis,
                                                                           full=jf.models[n]),
                           others=["polynomial_ls"])
    lug = jf.models.get("lugre")
    if lug is not None and (lug.extra or {}).get("static_model") in done:
        base = jf.models[lug.extra["static_model"]]
        for k, pe in base.params.items():
            lug.params[k] = ParamEstimate(**vars(pe))
        lug.notes = list(lug.notes) + [f"static part refitted with {', '.join(exts)} replayed out"]
    return done
