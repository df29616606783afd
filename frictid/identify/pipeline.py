"""The identification pipeline behind ``frictid fit`` and :func:`frictid.fit`.

For each joint: velocity and acceleration (Savitzky-Golay), segments, then

1. inertia, gravity and torque offset with the polynomial friction by chunked least squares on the moving
   samples (002 eq 4-11), unless the log metadata gives them (:mod:`.regression`);
2. the friction torque ``F = tau - J a - G(q) - offset`` and one averaged point per constant-velocity
   plateau (:func:`.static.plateau_points`);
3. every static map and its per-sign variant on the plateau points (:mod:`.static`), each with a held-out
   error by segment folds; the polynomial also from step 1 (``polynomial_ls``);
4. the base model chosen by held-out error and AIC (:mod:`.select`);
5. LuGre on top of the chosen map: sigma0 from ramps, sigma1 from steps or the critical-damping rule
   (:mod:`.presliding`); LuGre replaces its map as the chosen model only when its dynamic parameters are
   identifiable and it predicts held-out presliding segments better than the map alone;
6. thermal4 / thermal6 from duty cycles with ``temp_env`` (:mod:`.thermal`), reported with their
   held-out gain over a temperature-blind polynomial; they never enter the choice (the diagnosis does).

Reading files is delegated to :func:`frictid.io.logs.read_logs` (imported when paths are given).
True plant parameters (``JointLog.truth``) are never read here.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np

from frictid.data import SEGMENT_KINDS, JointLog, Segment
from frictid.errors import FrictidInputError
from frictid.models import static as sm
from frictid.models.params import unit_of
from frictid.parallel import Prefetch, map_ordered, n_workers

from . import presliding as pre
from . import regression as rg
from . import samples as smp
from . import select as sel
from . import thermal as th
from frictid.result import FitResult, JointFit, ModelFit, ParamEstimate
from .static import NEGLIGIBLE, Plateaus, fit_static, metrics, plateau_points, predict

#: Velocity-only models (candidates for the choice), in the order they are reported.
BASE_MODELS = tuple(sm.map_names()) + ("polynomial_ls",)
#: Every model name `fit` knows.
ALL_MODELS = BASE_MODELS + ("lugre",) + th.THERMAL_MODELS
#: Segment kinds whose moving samples enter the inertia/gravity regression.
REGRESSION_EXCLUDE = ("ramp_presliding", "step", "rest")
#: Samples of plateaus / excitation above which duty cycles stay out of the J / gravity regression.
MIN_OTHER_SAMPLES = 2000
#: Moving samples: |w| above this fraction of the 99.5th percentile of |w|.
MIN_SPEED_FRACTION = 0.02
#: Log channels the fit never reads (the references of the drive's controller): not read from files.
UNUSED_CHANNELS = ("q_ref", "qd_ref", "tau_ref")


@dataclass
class _Prep:
    """One log of a joint, ready for fitting."""

    log: JointLog
    index: int  # source index
    w: np.ndarray
    a: np.ndarray
    segments: list[Segment]
    F: np.ndarray | None = None
    G: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    scales: object = None  # the log's frictid.segments.Scales when the default derivatives measured them
    _trig: tuple | None = None

    def trig(self) -> tuple[np.ndarray, np.ndarray]:
        """cos q and sin q, computed once: the friction torque is formed again with every new estimate of
        the gravity terms (:func:`fit_joint` drops them once the estimates are final)."""
        if self._trig is None:
            self._trig = (np.cos(self.log.q), np.sin(self.log.q))
        return self._trig


#: A log that is one steady run: its first third is the start transient ...
STEADY_START = 1 / 3
#: ... and over the rest the velocity keeps one sign (at most this fraction of samples of the other sign),
STEADY_OPPOSITE = 0.05
#: its 10 batch means stay within this fraction of their mean and the mean is this many standard errors
#: away from zero.
STEADY_SPREAD = 0.25
STEADY_Z = 5.0


def steady_run(log: JointLog, w: np.ndarray) -> list[Segment] | None:
    """Segments of a log that is a single steady run at one velocity (a test bench that logs one file per
    commanded speed): ``other`` for the first third, ``constant_velocity`` for the rest; ``None`` when the
    log is not one (its velocity changes sign or level, or is not clearly away from zero)."""
    n = log.n
    i0 = int(STEADY_START * n)
    ww = np.asarray(w[i0:], dtype=float)
    if ww.size < 20 or not np.all(np.isfinite(ww)):
        return None
    m = float(ww.mean())
    if m == 0.0 or np.mean(np.sign(ww) == -np.sign(m)) > STEADY_OPPOSITE:
        return None
    bm = np.array([b.mean() for b in np.array_split(ww, 10)])
    sd = float(np.std(bm, ddof=1))
    if sd > STEADY_SPREAD * abs(m) or abs(m) < STEADY_Z * sd / math.sqrt(bm.size):
        return None
    t = log.t
    return [Segment("other", 0, i0, float(t[0]), float(t[max(i0 - 1, 0)])),
            Segment("constant_velocity", i0, n, float(t[i0]), float(t[-1]),
                    stats={"w_mean": m})]


def parse_models(models) -> list[str]:
    """Model names from a list or a comma-separated string; ``None`` or ``all`` means every model."""
    if models is None:
        return list(ALL_MODELS)
    if isinstance(models, str):
        models = [m.strip() for m in models.split(",") if m.strip()]
    out = []
    for m in models:
        if m == "all":
            out.extend(ALL_MODELS)
        elif m in ALL_MODELS:
            out.append(m)
        else:
            raise FrictidInputError(f"--models: unknown model {m!r}; known: {', '.join(ALL_MODELS)}")
    return list(dict.fromkeys(out))


@dataclass
class _Block:
    """One joint's rows of a Parquet file (:func:`frictid.io.logs.joint_row_blocks`), read by the process
    that fits the joint: ``source`` indexes the fit's sources, ``rows`` is the block's size."""

    joint: str
    source: int
    rows: int
    load: Callable[[], list[JointLog]]


def preload() -> None:
    """Import what fitting a joint needs beyond this module (scipy.signal for the derivatives, 1.2 s in
    each of two workers at once against 0.75 s here; the diagnosis and the replay), once, ahead of forking
    the workers that inherit it."""
    import scipy.signal  # noqa: F401

    import frictid.diagnose  # noqa: F401
    import frictid.replay  # noqa: F401


def _load(paths_or_logs, mapping, units) -> tuple[list[JointLog | _Block], list[dict]]:
    """The logs to fit and the sources they come from. A Parquet file whose joints are contiguous blocks
    of rows gives one :class:`_Block` per joint, read when the joint is fitted (in its worker: the
    reading is shared out, and no process holds every joint's samples); other files are read here.
    The files' SHA-256 and :func:`preload` run in background threads meanwhile."""
    if isinstance(paths_or_logs, (str, os.PathLike, JointLog)):
        paths_or_logs = [paths_or_logs]
    from frictid.io.logs import file_sha256  # here, not at the top: `import frictid` does not load pyarrow

    prefetch = Prefetch([str(p) for p in paths_or_logs if not isinstance(p, JointLog)], file_sha256, preload)
    try:
        logs, sources, files = _read_or_plan(paths_or_logs, mapping, units)
    finally:
        hashes = prefetch.hashes()
    for k in files:
        sources[k]["sha256"] = hashes.get(sources[k]["path"])
    return logs, sources


def _read_or_plan(paths_or_logs, mapping, units) -> tuple[list[JointLog | _Block], list[dict], list[int]]:
    """:func:`_load` without the hashes (``sha256`` None), and the indices of the sources that are files."""
    import functools

    from frictid.errors import LogFormatError

    logs: list[JointLog | _Block] = []
    sources: list[dict] = []
    files: list[int] = []
    errors: list[str] = []
    for item in paths_or_logs:
        if isinstance(item, JointLog):
            logs.append(item)
            sources.append({"path": item.source or "<memory>", "sha256": None, "rows": item.n})
            item._fit_source = len(sources) - 1
            continue
        from frictid.io.logs import joint_row_blocks, read_logs
        try:
            blocks = joint_row_blocks(str(item), mapping, units) if str(item) != "-" else None
            if blocks is not None:
                k = len(sources)
                files.append(k)
                sources.append({"path": str(item), "sha256": None, "rows": int(sum(b - a for _, a, b in blocks))})
                logs.extend(_Block(j, k, b - a, functools.partial(read_logs, str(item), mapping, units,
                                                                  skip=UNUSED_CHANNELS, rows=(a, b)))
                            for j, a, b in blocks)
                continue
            got = read_logs(str(item), mapping, units, skip=UNUSED_CHANNELS)
        except LogFormatError as exc:
            errors.append(str(exc))
            continue
        files.append(len(sources))
        sources.append({"path": str(item), "sha256": None, "rows": int(sum(g.n for g in got))})
        for g in got:
            g._fit_source = len(sources) - 1
        logs.extend(got)
    if errors:
        raise LogFormatError("", errors)
    if not logs:
        raise FrictidInputError("fit: no logs given")
    return logs, sources, files


def _fit_given(given: list, fit_one: Callable[[list[JointLog]], JointFit]
               ) -> tuple[JointFit | None, list[tuple[int, int]], list[tuple[str, list[str]]]]:
    """Read a joint's :class:`_Block` items, then fit it: (the fit, rows dropped per source while reading,
    the problems of the blocks as (file, problems), the fit None then)."""
    from frictid.errors import LogFormatError

    jlogs: list[JointLog] = []
    dropped: list[tuple[int, int]] = []
    problems: list[tuple[str, list[str]]] = []
    for item in given:
        if not isinstance(item, _Block):
            jlogs.append(item)
            continue
        try:
            got = item.load()
        except LogFormatError as exc:
            problems.append((exc.path, exc.problems))
            continue
        for g in got:
            g._fit_source = item.source
        dropped.append((item.source, item.rows - sum(g.n for g in got)))
        jlogs.extend(got)
    if problems:
        return None, dropped, problems
    return fit_one(jlogs), dropped, problems


def fit(paths_or_logs, joint: str | None = None, models=None, mapping=None, units=None, *,
        n_folds: int = 5, segmenter: Callable | None = None, differentiate: Callable | None = None,
        diagnose: bool = True, jobs: int = 1) -> FitResult:
    """Identify friction models for every joint (or one) of one or more logs.

    paths_or_logs : a path, a :class:`~frictid.data.JointLog`, or a list of either (several logs of the
    same joint are fitted together). joint : only this joint. models : names or a comma list (default
    all of :data:`ALL_MODELS`). mapping, units : as ``--map`` / ``--units`` of :func:`frictid.io.logs.read_logs`.
    n_folds : folds of the held-out split. segmenter(log) -> segments and differentiate(log) -> (w, a)
    default to :func:`frictid.segments.find_segments` and :func:`frictid.segments.derivatives`.
    diagnose : run :func:`frictid.diagnose.diagnose_joint` on every joint (extensions beyond the base
    model enter only through its findings; ``selected`` then names the end of its chain).
    jobs : joints fitted at once in worker processes (forked: they share the logs read here); 0 means
    one per available core, 1 (the default) fits them one after another in this process. The result does
    not depend on it.

    Returns a :class:`~frictid.result.FitResult`; :func:`frictid.io.params.write_params` writes the parameter file.
    """
    wanted = parse_models(models)
    logs, sources = _load(paths_or_logs, mapping, units)
    by_joint: dict[str, list[JointLog | _Block]] = {}
    for lg in logs:
        by_joint.setdefault(str(lg.joint), []).append(lg)
    if joint is not None:
        if str(joint) not in by_joint:
            raise FrictidInputError(f"--joint {joint}: not in the logs; joints found: {', '.join(by_joint)}")
        by_joint = {str(joint): by_joint[str(joint)]}
    if segmenter is None or differentiate is None:
        from frictid import segments as _seg
        segmenter = segmenter or _seg.find_segments
        differentiate = differentiate or _seg.derivatives
    res = FitResult(sources=sources, settings={"models": wanted, "n_folds": n_folds,
                                                "heldout": "segment folds (plateaus sorted by velocity, "
                                                           "rank mod n_folds); duty cycles by cycle"})
    del logs  # by_joint holds them; a joint's logs are freed once it is fitted (serial path)
    names = list(by_joint)
    workers = n_workers(jobs, len(names))

    def one(j):
        return _fit_given(by_joint.pop(j) if workers <= 1 else by_joint[j],
                          lambda jlogs: fit_joint(jlogs, wanted, n_folds, segmenter, differentiate,
                                                  diagnose=diagnose))

    done = map_ordered(one, names, workers)  # in this process when workers <= 1
    from frictid.errors import combined_log_error

    bad = combined_log_error(p for _, _, probs in done for p in probs)  # every joint's, together
    if bad is not None:
        raise bad
    for _, dropped, _ in done:
        for k, n in dropped:
            sources[k]["rows"] -= n
    res.joints.update((j, jf) for j, (jf, _, _) in zip(names, done))
    res.settings["diagnose"] = bool(diagnose)
    return res


# ---------------------------------------------------------------------------------------------------


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


def _reg_estimate(name, fit_: rg.LinearFit | None, axis, F0, w0, a0, why_none="") -> ParamEstimate:
    dim = _dims(name)
    unit = _unit(dim, axis)
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
    if se is None or not np.isfinite(se):
        reason = "no error estimate (too few samples)"
    elif se > abs(v):
        if name == "J":
            impact = se * a0
        elif dim == "M":
            impact = None
        else:
            p = _speed_power(dim)
            impact = se * w0**p if p is not None else None
        if impact is None or impact > NEGLIGIBLE * F0:
            reason = f"relative error {100 * se / abs(v):.0f} % (above 100 %)" if v else "relative error above 100 %"
    if name == "J" and v <= 0 and not reason:
        reason = "not positive: the data do not determine the inertia"
    return ParamEstimate(name, v, se, unit, not reason, reason)


def _static_params_pe(mf: ModelFit) -> dict[str, ParamEstimate]:
    return {k: ParamEstimate(**vars(p)) for k, p in mf.params.items()}


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


def segment_list(source: int, rows: int, segments: list[Segment], scales=None) -> dict:
    """The parameter file's record of one log's segments (``segment_list``; cycle -1 when none), with the
    log's scales (noise levels and derivative windows, :class:`frictid.segments.Scales`) when given."""
    out = {"source": int(source), "rows": int(rows), "kind": [s.kind for s in segments],
           "i0": [int(s.i0) for s in segments], "i1": [int(s.i1) for s in segments],
           "cycle": [-1 if s.cycle is None else int(s.cycle) for s in segments]}
    if scales is not None:
        out["scales"] = scales.to_dict()
    return out


def segments_from_list(entry: dict, t: np.ndarray) -> list[Segment]:
    """The segments of a ``segment_list`` entry on a log with times ``t`` [s] (the same rows)."""
    return [Segment(str(k), int(a), int(b), float(t[int(a)]), float(t[int(b) - 1]),
                    cycle=None if int(c) < 0 else int(c))
            for k, a, b, c in zip(entry["kind"], entry["i0"], entry["i1"], entry["cycle"])]


def fit_joint(jlogs: list[JointLog], wanted: list[str], n_folds: int, segmenter, differentiate,
              diagnose: bool = False) -> JointFit:
    """Identify everything for one joint from its logs (see the module docstring)."""
    axis = jlogs[0].axis
    jf = JointFit(joint=str(jlogs[0].joint), axis=axis, units=dict(jlogs[0].units))
    if any(lg.axis != axis for lg in jlogs):
        raise FrictidInputError(f"joint {jf.joint}: logs disagree on the axis (rotary / linear)")
    preps: list[_Prep] = []
    n_steady = 0
    from frictid import segments as _seg

    scales = None
    for lg in jlogs:
        if differentiate is _seg.derivatives:  # the default: keep the scales it measures (segment_list)
            scales = _seg.estimate_scales(lg)
            w, a = _seg.derivatives(lg, scales)
        else:
            w, a = differentiate(lg)
        w, a = np.asarray(w, float), np.asarray(a, float)
        segs = steady_run(lg, w)
        n_steady += segs is not None
        if segs is None:  # the default segmenter takes the scales already measured
            segs = _seg.find_segments(lg, scales) if segmenter is _seg.find_segments and scales else segmenter(lg)
        preps.append(_Prep(lg, getattr(lg, "_fit_source", 0), w, a, list(segs), scales=scales))
        jf.warnings.extend(lg.warnings)
    if n_steady:
        jf.warnings.append(f"{n_steady} of {len(jlogs)} logs are single steady runs at one velocity: the last "
                           f"{1 - STEADY_START:.0%} of each is one constant-velocity plateau")
    jf.segments = {k: 0 for k in SEGMENT_KINDS}
    for p in preps:
        for s in p.segments:
            jf.segments[s.kind] = jf.segments.get(s.kind, 0) + 1
    jf.segment_list = [segment_list(p.index, p.log.n, p.segments, p.scales) for p in preps]
    used: dict[str, list] = {}

    # scales of the data
    w0 = _abs_percentile([p.w for p in preps])
    F0 = _abs_percentile([p.log.tau for p in preps], centre=True)
    a0 = _abs_percentile([p.a for p in preps])
    F0 = F0 if F0 > 0 else 1.0
    min_speed = MIN_SPEED_FRACTION * w0
    if w0 <= 0:
        jf.warnings.append("no motion in the logs: nothing that depends on velocity can be identified")

    # ---- 1. inertia, gravity, offset (+ polynomial) by least squares
    known = {}
    for p in preps:
        known.update(known_from_meta(p.log.meta or {}))
    has_q = all(p.log.q is not None for p in preps)
    has_payload = all("payload" in p.log.channels for p in preps)
    names = ["J", "c0", "c1", "c2", "c3"]
    if has_q and axis == "rotary":
        names += ["Px", "Py"]
    if has_payload and has_q:
        names += ["Mx"] + (["My"] if axis == "rotary" else [])
    names += ["offset"]
    free_names = tuple(n for n in names if n not in known)
    known_coef = {n: known[n][0] for n in names if n in known}
    poor = _unidentifiable(preps)
    if poor is not None:  # nothing in these logs can pin a friction number down: say so, fit nothing
        _set_mechanics(jf, None, known, names, has_q, axis, F0, w0, a0, poor, "")
        for n, pe in [("J", jf.inertia), ("offset", jf.offset), *jf.gravity.items()]:
            if not pe.identifiable:
                jf.not_identified.append({"what": n, "reason": pe.reason})
        jf.not_identified += [{"what": m, "reason": poor} for m in wanted]
        jf.warnings.append(poor)
        jf.selection = {"rule": "none: the data cannot identify any model", "reason": poor}
        return jf
    reg_fit, seg_ne = _regress(preps, free_names, known_coef, min_speed, axis)
    why_reg = "no moving samples" if reg_fit is None else ""
    _set_mechanics(jf, reg_fit, known, names, has_q, axis, F0, w0, a0, why_reg, "")

    # ---- 2. friction torque and plateaus
    plat, keys = _plateaus(jf, preps, axis)
    # the basis of the static maps: plateau points, or every moving sample when the plateaus give too few
    # distinct speeds (an excitation run; see samples.py)
    excl = _regression_exclude(preps)
    S = smp.build(preps, min_speed, n_folds, exclude=excl) if reg_fit is not None else None
    basis, why_basis = smp.choose_basis(plat.w, S.n_moving if S is not None else 0)
    # stage 2: with a static map from the plateaus, J / gravity / offset again with that map as the
    # friction (the polynomial cannot follow a Stribeck drop, which then leaks into J; see docs/fit.md)
    mech = tuple(n for n in free_names if n not in ("c0", "c1", "c2", "c3"))
    fmap = _stage2_map(plat) if mech and reg_fit is not None and basis == "plateaus" else None
    if fmap is not None:
        name2, friction, v_low = fmap
        v_low = min(max(min_speed, v_low), 0.5 * w0)
        reg2, _ = _regress(preps, mech, known_coef, v_low, axis, friction=friction)
        if reg2 is not None:
            _set_mechanics(jf, reg2, known, names, has_q, axis, F0, w0, a0, why_reg,
                           f"least squares with the plateau map {name2} as the friction, "
                           f"|w| > {v_low:.3g}")
            plat, keys = _plateaus(jf, preps, axis)
    for p in preps:  # the mechanics are final: cos q and sin q are not needed again (58 MB per joint-hour)
        p._trig = None
    for n, pe in [("J", jf.inertia), ("offset", jf.offset), *jf.gravity.items()]:
        if not pe.identifiable:
            jf.not_identified.append({"what": n, "reason": pe.reason})
    used["constant_velocity"] = [[float(a), float(b), preps[int(k[0])].index] for a, b, k in
                                 zip(plat.t_start, plat.t_end, keys)]
    npos, nneg = int((plat.w > 0).sum()), int((plat.w < 0).sum())
    if basis == "samples":
        jf.warnings.append(why_basis)
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

    # ---- 3. static maps
    static_names = [m for m in wanted if m in sm.map_names()]
    if basis == "samples":
        S = smp.build(preps, min_speed, n_folds, exclude=excl)  # the friction samples of the final mechanics
        if reg_fit is not None and all(c in reg_fit.names for c in ("c0", "c1", "c2", "c3")):
            S.inflation = smp.variance_factor(
                S.F - sm.polynomial(S.w, **{c: reg_fit.value(c) for c in ("c0", "c1", "c2", "c3")}))
        for name in static_names:
            jf.models[name] = smp.fit_map(name, S, axis, heldout=False)
    for name in static_names if basis == "plateaus" else ():
        if len(plat) == 0:
            jf.not_identified.append({"what": name, "reason": "no constant-velocity plateaus"})
            continue
        jf.models[name] = fit_static(name, plat.w, plat.F, plat.F_se, axis=axis)
    if "polynomial_ls" in wanted:
        if basis == "samples":
            mf = _polynomial_ls_samples(reg_fit, preps, free_names, known_coef, min_speed, axis, F0, w0, a0,
                                        excl, S)
        else:
            mf = _polynomial_ls(reg_fit, seg_ne, plat, keys, free_names,
                                axis, F0, w0, a0, n_folds, why_reg)
        if mf is not None:
            jf.models["polynomial_ls"] = mf
        else:
            jf.not_identified.append({"what": "polynomial_ls", "reason": why_reg or "no moving samples"})
    # held-out errors of the maps the choice can take (the identifiable ones, unless none gets one)
    fitted = [n for n in static_names if n in jf.models]
    if basis == "samples":
        sel.heldout_for_choice(jf.models, fitted, lambda n: smp.heldout_map(n, S, jf.models[n], axis),
                               others=["polynomial_ls"])
    else:
        sel.heldout_for_choice(jf.models, fitted, lambda n: sel.heldout_static(
            n, plat, n_folds, axis=axis, full=jf.models[n]), others=["polynomial_ls"])

    # ---- 4. choice among the velocity-only static models
    cands = [m for m in BASE_MODELS if m in jf.models]
    selected, rec = sel.choose(jf.models, cands)
    rec["basis"] = {"plateaus": "plateau points (held out by plateau folds)",
                    "samples": f"moving samples (held out by {smp.BLOCKS_PER_FOLD * n_folds} time blocks in "
                               f"{n_folds} folds)"}[basis]
    rec["basis_reason"] = why_basis
    jf.selected, jf.selection = selected, rec

    # ---- 5. LuGre on top of the chosen map
    if "lugre" in wanted:
        _lugre(jf, preps, selected, used, axis, F0, w0)

    # ---- 6. thermal
    th_wanted = [m for m in wanted if m in th.THERMAL_MODELS]
    if th_wanted:
        _thermal(jf, preps, th_wanted, used, axis, min_speed, n_folds)

    # ---- 7. diagnosis: every extension beyond the base model enters through a finding (frictid.diagnose)
    if diagnose and jf.selected is not None:
        choice = jf.selected
        _diagnose(jf, preps)
        _check_diagnosis(jf, preps, choice, basis, keys, min_speed, excl)

    _level_with_offset(jf, preps, min_speed)
    jf.segments_used = used
    if jf.selected is None:
        jf.warnings.append("no model could be chosen: " + str(rec.get("reason", "")))
    return jf


def _abs_percentile(arrays: list[np.ndarray], centre: bool = False) -> float:
    """The 99.5th percentile of ``|x|`` over the finite values of ``arrays`` (of ``|x - median(x)|`` when
    ``centre``); 0 when there are none. One copy of the values, worked on in place and freed on return:
    the three concatenations of every finite velocity, torque and acceleration sample that the fit kept to
    its end were 87 MB of a joint-hour's 280 MB baseline."""
    x = np.concatenate([v[np.isfinite(v)] for v in arrays])
    if not x.size:
        return 0.0
    if centre:
        x -= np.median(x, overwrite_input=True)  # an order statistic: the same value after the partition
    return float(np.percentile(np.abs(x, out=x), 99.5, overwrite_input=True))


def _unidentifiable(preps) -> str | None:
    """Why no friction parameter can be identified from a joint's logs, or None. Judged against each log's
    own scales (:func:`frictid.segments.estimate_scales`): no motion (fewer than a shortest segment's worth
    of samples, ``T_MIN``, faster than ``K_NOISE`` velocity noise levels) or a flat torque signal (its
    0.1-99.9 percentile range within one quantisation step: a dead, disconnected or saturated sensor)."""
    from frictid.segments import estimate_scales
    from frictid.segments.detect import K_NOISE, T_MIN

    moving = need = 0
    flat = True
    for p in preps:
        sc = p.scales or estimate_scales(p.log)
        moving += int(np.sum(np.abs(p.w) > K_NOISE * sc.sigma_w))
        need = max(need, int(round(T_MIN / sc.dt)))
        flat &= sc.tau_range <= sc.tau_step
    if moving < need:
        return (f"no motion: only {moving} samples move faster than {K_NOISE:g} velocity noise levels "
                f"(a shortest segment is {need}); nothing that depends on velocity can be identified")
    if flat:
        return ("flat torque signal: the torque does not change by more than one quantisation step while "
                "the joint moves (a dead, disconnected or saturated sensor?); no friction can be identified")
    return None


#: Parameters that set a static map's level at low speed: with one velocity sign only they carry the
#: torque offset, which the data cannot separate from them.
LEVEL_PARAMS = ("Fc", "Fs", "c0", "alpha0", "alpha1", "alpha2")


def _level_with_offset(jf: JointFit, preps, min_speed: float) -> None:
    """With motion in one direction only and the offset neither identified nor given in the metadata, the
    Coulomb level of every map is the level plus an unknown offset: mark those parameters not identifiable."""
    if jf.offset is None or jf.offset.identifiable or jf.offset.source == "log metadata":
        return
    w = np.concatenate([p.w[np.isfinite(p.w)] for p in preps])
    w = w[np.abs(w) > min_speed]
    if w.size == 0 or ((w > 0).any() and (w < 0).any()):
        return
    why = ("not separable from the torque offset (motion in one direction only): the value is the level plus "
           "an unknown offset")
    for mname, mf in jf.models.items():
        for n, pe in mf.params.items():
            base = n[:-4] if n.endswith(("_pos", "_neg")) else n
            if base in LEVEL_PARAMS and pe.identifiable and not pe.fixed:
                pe.identifiable, pe.reason = False, why
                jf.not_identified.append({"what": f"{mname}.{n}", "reason": why})


def _regression_exclude(preps) -> tuple[str, ...]:
    """Segment kinds kept out of the inertia/gravity regression. Duty cycles are kept out when other
    moving segments (plateaus, excitation) provide at least :data:`MIN_OTHER_SAMPLES` samples: friction
    changes with temperature during duty cycles (002 section IV) and a constant-friction regression over
    them biases J and gravity."""
    other = sum(s.n for p in preps for s in p.segments
                if s.kind not in REGRESSION_EXCLUDE and s.kind != "duty_cycle")
    has_duty = any(s.kind == "duty_cycle" for p in preps for s in p.segments)
    return REGRESSION_EXCLUDE + (("duty_cycle",) if has_duty and other >= MIN_OTHER_SAMPLES else ())


def _regress(preps, names, known_coef, min_speed, axis, friction=None):
    """Chunked least squares over the moving samples of every log; per-segment normal equations."""
    seg_ne: list[tuple[int, int, rg.NormalEquations]] = []
    excl = _regression_exclude(preps)
    for pi, p in enumerate(preps):
        ranges = [(s.i0, s.i1) for s in p.segments if s.kind not in excl]
        seg_ids = [si for si, s in enumerate(p.segments) if s.kind not in excl]
        if not p.segments:  # no segmentation: every sample is a candidate
            ranges, seg_ids = [(0, p.log.n)], [-1]
        nes = rg.accumulate(ranges, names, p.log.q, p.w, p.a, p.log.tau, p.log.channels.get("payload"),
                            known_coef, min_speed, axis, friction=friction)
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
                                                   friction=friction))
    fit_ = rg.solve(total, names, rho=rho)
    fit_.cov = rg.robust_stderr(fit_.cov, rg.cluster_covariance(fit_, [ne for *_, ne in seg_ne]))
    return fit_, seg_ne


def _set_mechanics(jf, reg_fit, known, names, has_q, axis, F0, w0, a0, why_reg, source):
    """Inertia, gravity and offset estimates of a joint from a regression (or the metadata)."""
    def est(name):
        if name in known:
            v, s = known[name]
            return ParamEstimate(name, v, s, _unit(_dims(name), axis), True, "", source="log metadata")
        pe = _reg_estimate(name, reg_fit, axis, F0, w0, a0, why_reg)
        pe.source = source
        return pe

    jf.inertia = est("J")
    jf.gravity = {}
    if axis == "rotary":
        if has_q:
            jf.gravity = {n: est(n) for n in ("Px", "Py")}
            px, py = jf.gravity["Px"], jf.gravity["Py"]
            if px.value is not None and py.value is not None:
                amp = math.hypot(px.value, py.value)
                se = None
                if px.stderr is not None and py.stderr is not None and amp > 0:
                    se = math.hypot(px.value * px.stderr, py.value * py.stderr) / amp
                ok = px.identifiable and py.identifiable
                jf.gravity["amplitude"] = ParamEstimate("amplitude", amp, se, _unit("F", axis), ok,
                                                        "" if ok else "Px or Py not identifiable")
        else:
            jf.gravity = {n: ParamEstimate(n, None, None, _unit("F", axis), False, "no position channel")
                          for n in ("Px", "Py")}
    elif "linear axis: a constant gravity force is part of the offset" not in jf.warnings:
        jf.warnings.append("linear axis: a constant gravity force is part of the offset")
    for n in ("Mx", "My"):
        if n in names:
            jf.gravity[n] = est(n)
    jf.offset = est("offset")


def _diagnose(jf: JointFit, preps) -> None:
    """Hand the prepared logs to the diagnosis, with an estimated offset left in the friction torque (it
    enters the extended models only through the diagnosis' ``offset`` cause; one from metadata stays).
    The preps' friction and gravity torques go with them (``F``, ``G`` are None afterwards)."""
    from frictid.diagnose import DiagLog, diagnose_joint
    from frictid.replay import log_start_time

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
        diagnose_joint(jf, logs)


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


def _static_targets(jf: JointFit, preps, name: str):
    """Per log, the torque that model ``name``'s static map has to explain once the model's other terms
    (rigid body, offset, extension factors, thermal state) are replayed: ``tau - tau_model + s(w)`` [F], s
    the model's static map at the samples' velocity. For a plain static map it is the friction torque
    ``tau - J a - G - offset``. Returns (map name, static values, [array per log])."""
    from frictid.replay import joint_model, replay

    mf = jf.models[name]
    m = joint_model(jf, name)
    vals = mf.values()
    out = []
    for p in preps:
        # the log's scales when the fit measured them: the replay of a static map needs its velocity noise
        # (measured again, 0.13 s CPU per replay of a joint-hour)
        r = replay(p.log, m, w=p.w, a=p.a, scales=p.scales).residual
        r += predict(mf.map, vals, p.w)
        out.append(r)
    return mf.map, vals, out


def _target_plateaus(preps, Y) -> Plateaus:
    """Plateau points of per-log target series Y (same segments, trim and batch means as the fit's)."""
    pls = [plateau_points(p.log.t, p.w, y, p.segments) for p, y in zip(preps, Y)]
    pls = [pl for pl in pls if len(pl)]
    if not pls:
        z = np.zeros(0)
        return Plateaus(z, z, z, z, z.astype(int), z, z, z.astype(int))
    return Plateaus(*(np.concatenate([getattr(c, f) for c in pls]) for f in
                      ("w", "F", "F_se", "w_se", "n", "t_start", "t_end", "seg")))


def _heldout_on_basis(jf, preps, name, basis, min_speed, excl, n_folds, like=None):
    """Held-out RMS [F] of model ``name`` on the fit's basis: its static map refitted without each fold
    (plateau folds, or the time blocks of the sample basis) on the targets of :func:`_static_targets`, the
    rest of the model held. Returns (rms_heldout, refit ModelFit, target Plateaus or the samples' speed
    order, :meth:`~frictid.identify.samples.SampleSet.order_key`). ``like``: that speed order from another model
    of the joint, reused when the samples are the same (one sort of up to 2 M samples less)."""
    mapname, _, Y = _static_targets(jf, preps, name)
    if basis == "plateaus":
        pl = _target_plateaus(preps, Y)
        if len(pl) < 4:
            return math.nan, None, pl
        mf = fit_static(mapname, pl.w, pl.F, pl.F_se, axis=jf.axis)
        rh = sel.heldout_static(mapname, pl, n_folds, axis=jf.axis, full=mf)
        return (rh if rh is not None else math.nan), mf, pl
    from types import SimpleNamespace
    pseudo = [SimpleNamespace(log=p.log, w=p.w, F=y, segments=p.segments) for p, y in zip(preps, Y)]
    S = smp.build(pseudo, min_speed, n_folds, exclude=excl)
    if S is None:
        return math.nan, None, None
    if isinstance(like, smp.SpeedOrder):
        S.share_order(like)
    mf = smp.fit_map(mapname, S, jf.axis)
    rh = mf.metrics.get("rms_heldout")
    return (rh if rh is not None else math.nan), mf, S.order_key()


def _check_diagnosis(jf: JointFit, preps, choice: str, basis: str, keys, min_speed: float, excl,
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
    Any failure of the replay (a model the replay cannot run) leaves the diagnosis' choice in place."""
    if jf.selected in (None, choice):
        return
    from frictid.errors import ConfigError

    # duty cycles stay out of the fit's basis (their friction drifts with temperature) but are where a
    # temperature finding shows: with duty cycles the check runs on every moving sample of the logs
    if any(s.kind == "duty_cycle" for p in preps for s in p.segments):
        basis, excl = "samples", REGRESSION_EXCLUDE
    try:
        e_diag, mf_diag, pl_diag = _heldout_on_basis(jf, preps, jf.selected, basis, min_speed, excl, n_folds)
        e_fit, _, _ = _heldout_on_basis(jf, preps, choice, basis, min_speed, excl, n_folds, like=pl_diag)
    except (ConfigError, FrictidInputError, KeyError, ValueError):
        return
    what = ("plateau means" if basis == "plateaus" else
            "moving samples" + (" (duty cycles included)" if "duty_cycle" not in excl else ""))
    rec = {"model": jf.selected, "rms_heldout": e_diag, "fit_choice": choice, "rms_heldout_fit_choice": e_fit,
           "rule": f"the diagnosis' model is selected when its held-out torque RMS on {what} is at most "
                   f"{DIAGNOSIS_TOLERANCE:g} x that of the fit's choice (each model's static map refitted "
                   "without the held-out fold, its other terms replayed)"}
    if math.isfinite(e_diag) and math.isfinite(e_fit) and e_diag > DIAGNOSIS_TOLERANCE * e_fit:
        rec["kept"] = choice
        jf.warnings.append(f"the diagnosis' model {jf.selected} predicts the torque of held-out {what} worse "
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


def _plateaus(jf, preps, axis):
    """Friction torque per sample (stored on each prep) and the plateau points of all logs."""
    coef = {n: (pe.value if pe.value is not None else 0.0) for n, pe in
            [("J", jf.inertia), ("offset", jf.offset), *jf.gravity.items()] if n != "amplitude"}
    pls = []
    for pi_, p in enumerate(preps):
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
        p.G = G
        F = coef.get("J", 0.0) * np.nan_to_num(p.a)
        np.subtract(p.log.tau, F, out=F)
        F -= G
        p.F = F
        pls.append((pi_, plateau_points(p.log.t, p.w, p.F, p.segments)))
    # one Plateaus for all logs; keys[i] = (prep index, segment index) of plateau i
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


#: Maps tried for the stage-2 friction (no held-out split: only the best in-sample curve is needed).
STAGE2_MAPS = ("stribeck_asym", "stribeck_2exp_asym", "polynomial_asym")


def _stage2_map(plat):
    """The best-fitting per-sign static map on the plateaus, as a callable w -> F, or None when the
    plateaus do not cover both signs well enough."""
    if (plat.w > 0).sum() < 6 or (plat.w < 0).sum() < 6:
        return None
    best = None
    for name in STAGE2_MAPS:
        mf = fit_static(name, plat.w, plat.F, plat.F_se)
        vals = mf.values()
        if any(v is None for v in vals.values()) or mf.metrics.get("rms") is None:
            continue
        if best is None or mf.metrics["rms"] < best[1]:
            best = (name, mf.metrics["rms"], vals)
    if best is None:
        return None
    name, _, vals = best
    # below ~3 Stribeck velocities the friction is dominated by the Stribeck drop and presliding lag,
    # which a static map does not follow through reversals: those samples do not enter stage 2
    speeds = [v for k, v in vals.items() if k.split("_")[0] in ("vs", "ws1", "ws2")]
    v_low = 3.0 * max(speeds) if speeds else 0.0
    return name, (lambda w, _n=name, _v=vals: predict(_n, _v, w)), v_low



def _sample_metrics(reg_fit, seg_ne, names, n_folds) -> dict:
    """rms, held-out rms (segments in folds by order), aic and n of a regression on its moving samples."""
    total = rg.NormalEquations.total(ne for *_, ne in seg_ne)
    k = len(names)

    def rss(b, ne):
        return max(float(ne.yty - 2 * b @ ne.Xty + b @ ne.XtX @ b), 0.0)

    r_all = rss(reg_fit.coef, total)
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
            e2 += rss(fit_f.coef, out)
            nn += out.n
        met["rms_heldout"] = math.sqrt(e2 / nn) if nn else None
    return met


def _polynomial_ls(reg_fit, seg_ne, plat, keys, free_names, axis, F0, w0, a0, n_folds, why) -> ModelFit | None:
    if reg_fit is None or not all(c in free_names for c in ("c0", "c1", "c2", "c3")):
        return None
    params = {c: _reg_estimate(c, reg_fit, axis, F0, w0, a0) for c in ("c0", "c1", "c2", "c3")}
    values = {c: params[c].value for c in params}
    if not len(plat):
        return ModelFit("polynomial_ls", "polynomial", params, _sample_metrics(reg_fit, seg_ne, free_names, n_folds),
                        method="linear least squares on all moving samples with J, gravity and offset "
                               "(002 eq 4-11); no plateaus: metrics on the moving samples, held out by segment",
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
            for (pi, si), fo in zip(keys, folds):
                if fo == f and (int(pi), int(si)) in lookup:
                    out = out + lookup[(int(pi), int(si))]
            fitf = rg.solve(total - out, free_names)
            vals = {c: fitf.value(c) for c in ("c0", "c1", "c2", "c3")}
            pred[folds == f] = sm.polynomial(plat.w[folds == f], **vals)
        r = pred - plat.F
        if np.all(np.isfinite(r)):
            met["rms_heldout"] = float(np.sqrt(np.mean(r**2)))
    return ModelFit("polynomial_ls", "polynomial", params, met,
                    method="linear least squares on all moving samples with J, gravity and offset (002 eq 4-11)")


def _polynomial_ls_samples(reg_fit, preps, free_names, known_coef, min_speed, axis, F0, w0, a0, excl,
                           S) -> ModelFit | None:
    """polynomial_ls on the sample basis: metrics on the moving samples, held out by the time blocks of
    :mod:`.samples` (the regression refitted without each fold, from per-block normal equations)."""
    if reg_fit is None or S is None or not all(c in free_names for c in ("c0", "c1", "c2", "c3")):
        return None
    params = {c: _reg_estimate(c, reg_fit, axis, F0, w0, a0) for c in ("c0", "c1", "c2", "c3")}
    blocks = smp.block_ranges([np.asarray(p.log.t, float) for p in preps], S.n_folds)
    per_fold = [rg.NormalEquations(len(free_names)) for _ in range(S.n_folds)]
    for p, rr in zip(preps, blocks):
        allowed = [(s.i0, s.i1) for s in p.segments if s.kind not in excl] or [(0, p.log.n)]
        ranges, folds = [], []
        for i0, i1, b in rr:
            for a, c in allowed:
                lo, hi = max(i0, a), min(i1, c)
                if hi > lo:
                    ranges.append((lo, hi))
                    folds.append(b % S.n_folds)
        nes = rg.accumulate(ranges, free_names, p.log.q, p.w, p.a, p.log.tau, p.log.channels.get("payload"),
                            known_coef, min_speed, axis)
        for f, ne in zip(folds, nes):
            per_fold[f] = per_fold[f] + ne
    total = rg.NormalEquations.total(per_fold)

    def rss(b, ne):
        return max(float(ne.yty - 2 * b @ ne.Xty + b @ ne.XtX @ b), 0.0)

    held, nn = 0.0, 0
    for ne in per_fold:
        if ne.n == 0 or total.n - ne.n <= len(free_names):
            continue
        held += rss(rg.solve(total - ne, free_names).coef, ne)
        nn += ne.n
    met = smp.sample_metrics(rss(reg_fit.coef, total), total.n, 4, math.sqrt(held / nn) if nn else None, S)
    return ModelFit("polynomial_ls", "polynomial", params, met,
                    method="linear least squares on all moving samples with J, gravity and offset "
                           "(002 eq 4-11); metrics on the moving samples, held out by time blocks",
                    extra={"basis": "moving samples"})


def _lugre(jf: JointFit, preps, selected, used, axis, F0, w0) -> None:
    base_name = selected if selected in jf.models else None
    if base_name is None:
        jf.not_identified.append({"what": "lugre", "reason": "no static map to build on"})
        return
    base = jf.models[base_name]
    vals = base.values()
    smap_name = base.map
    if any(v is None for v in vals.values()):
        jf.not_identified.append({"what": "lugre", "reason": f"{base_name} has unknown parameters"})
        return
    c_pos, c_neg = sm.canonical_pair(smap_name, vals)
    level, viscous = _scalar_map(c_pos, c_neg)
    ramps, ramp_t, ramp_w = [], [], []
    steps = []
    for p in preps:
        if p.log.q is None:
            continue
        for s in p.segments:
            if s.kind == "ramp_presliding" and s.n >= 10:
                ramps.append((np.asarray(p.log.q[s.i0:s.i1], float), p.F[s.i0:s.i1]))
                ramp_t.append([float(s.t_start), float(s.t_end), p.index])
                ramp_w.append(p.w[s.i0:s.i1])
            elif s.kind == "step" and s.n >= 10:
                i0 = max(s.i0 - 1, 0)  # one sample before: the rest state the step starts from
                u = p.log.tau[i0:s.i1] - p.G[i0:s.i1]
                steps.append((p.log.t[i0:s.i1], np.asarray(p.log.q[i0:s.i1], float), u, s, p.index))
    res_meta = [p.log.meta.get("encoder_resolution") for p in preps if p.log.meta]
    res_meta = [float(r) for r in res_meta if r]
    qcat = np.concatenate([q for q, _ in ramps] + [st[1] for st in steps]) if (ramps or steps) else np.zeros(0)
    resolution = res_meta[0] if res_meta else (pre.encoder_resolution(qcat) if qcat.size else 0.0)
    g_of = [abs(level(1e-12 if np.mean(F) >= 0 else -1e-12)) for _, F in ramps]
    s0 = pre.fit_sigma0(ramps, g_of, resolution)
    J = jf.inertia.value if jf.inertia and jf.inertia.value else None
    sig2 = c_pos[6] if abs(c_pos[6]) > 0 else 0.0
    if s0.identifiable and J:
        s1 = pre.fit_sigma1_steps([(t, q, u) for t, q, u, *_ in steps], J, s0.value, c_pos, c_neg, sig2,
                                  resolution)
        if not s1.identifiable:
            why_steps = s1.reason
            s1 = pre.sigma1_rule(s0.value, s0.stderr, J, jf.inertia.stderr, sig2)
            s1.source += f" ({why_steps})"
        else:
            used["step"] = [[float(s.t_start), float(s.t_end), src] for *_, s, src in steps]
    else:
        why = "needs sigma0" if not s0.identifiable else "needs the inertia J"
        s1 = pre.DynamicEstimate(None, None, False, f"{why}, which is not identifiable", "")
    if ramps:
        used["ramp_presliding"] = ramp_t
    params = _static_params_pe(base)
    params["sigma0"] = ParamEstimate("sigma0", s0.value, s0.stderr, unit_of("K", axis), s0.identifiable,
                                     s0.reason, source=s0.source)
    params["sigma1"] = ParamEstimate("sigma1", s1.value, s1.stderr, unit_of("D", axis), s1.identifiable,
                                     s1.reason, source=s1.source)
    met = dict(base.metrics)
    met["k"] = int((met.get("k") or 0) + 2)
    notes = [f"static part: {base_name}"]
    # presliding prediction: LuGre (sigma0 bristles along the measured path) against the static map alone
    if s0.identifiable and ramps:
        lug, stat, held = [], [], []
        for i, ((q, F), g0, w) in enumerate(zip(ramps, g_of, ramp_w)):
            z0 = float(np.clip(F[0] / s0.value, -g0 / s0.value, g0 / s0.value))
            lug.append(s0.value * pre.bristle_path(q, z0, s0.value, g0) - F)
            stat.append(predict(base_name if base_name != "polynomial_ls" else "polynomial", vals, w) - F)
            if len(ramps) >= 2:
                rest = [r for k, r in enumerate(ramps) if k != i]
                gr = [g for k, g in enumerate(g_of) if k != i]
                e = pre.fit_sigma0(rest, gr, resolution, starts=(s0.value,))
                if e.value:
                    z0h = float(np.clip(F[0] / e.value, -g0 / e.value, g0 / e.value))
                    held.append(e.value * pre.bristle_path(q, z0h, e.value, g0) - F)
        rl = float(np.sqrt(np.mean(np.concatenate(lug) ** 2)))
        rs = float(np.sqrt(np.nanmean(np.concatenate(stat) ** 2)))
        met["rms_presliding"] = rl
        met["rms_presliding_static"] = rs
        met["rms_presliding_heldout"] = float(np.sqrt(np.mean(np.concatenate(held) ** 2))) if held else None
    mf = ModelFit("lugre", smap_name if base_name != "polynomial_ls" else "polynomial", params, met,
                  method="static map on plateaus; sigma0 from ramps (torque against displacement); sigma1 "
                         + ("from steps (simulation error)" if "steps" in s1.source else
                            "by the critical-damping rule" if "rule" in s1.source else "not identified"),
                  notes=notes, extra={"static_model": base_name})
    jf.models["lugre"] = mf
    for n in ("sigma0", "sigma1"):
        if not params[n].identifiable:
            jf.not_identified.append({"what": f"lugre.{n}", "reason": params[n].reason})
    # the choice: LuGre replaces its map when identifiable and better on held-out presliding segments
    rh = met.get("rms_presliding_heldout")
    if mf.identifiable and rh is not None and rh < met["rms_presliding_static"]:
        jf.selection["lugre"] = (f"chosen: held-out presliding RMS {rh:.4g} against {met['rms_presliding_static']:.4g} "
                                 f"for {base_name} alone")
        jf.selected = "lugre"
    else:
        why = ("not all dynamic parameters identifiable" if not mf.identifiable else
               "fewer than two ramp segments: no held-out presliding error" if rh is None else
               "no better than the static map on held-out presliding segments")
        jf.selection["lugre"] = f"not chosen: {why}"


def _thermal(jf: JointFit, preps, th_wanted, used, axis, min_speed, n_folds) -> None:
    runs = []
    cyc_used = []
    reasons = []
    for p in preps:
        duty = [s for s in p.segments if s.kind == "duty_cycle"]
        if not duty:
            continue
        if "temp_env" not in p.log.channels:
            reasons.append("duty cycles without a temp_env channel")
            continue
        groups: dict[int, list[Segment]] = {}
        for k, s in enumerate(duty):
            groups.setdefault(s.cycle if s.cycle is not None else k, []).append(s)
        cycles = sorted((min(s.i0 for s in g), max(s.i1 for s in g), cid) for cid, g in groups.items())
        # runs: contiguous cycles; a gap between cycles is a rest that ends a run, and the next run is
        # taken to start cold (T = Tenv), as in 002's protocol (a night of rest before each run)
        med = float(np.median([c[1] - c[0] for c in cycles]))
        blocks, cur = [], [cycles[0]]
        for c in cycles[1:]:
            if c[0] - cur[-1][1] > max(10, 0.002 * med):
                blocks.append(cur)
                cur = []
            cur.append(c)
        blocks.append(cur)
        for blk in blocks:
            run = th.prepare(p.log.t, p.w, p.F, blk, p.log.channels["temp_env"],
                             p.log.channels.get("temp_joint"), min_speed,
                             bin_s=max(med * p.log.dt / th.BINS_PER_CYCLE, p.log.dt), a=p.a)
            if run is not None:
                runs.append(run)
                cyc_used += [[float(a), float(b), p.index] for a, b in run.cycle_t]
    if not runs:
        why = reasons[0] if reasons else "no duty-cycle segments"
        for m in th_wanted:
            jf.not_identified.append({"what": m, "reason": why})
        return
    used["duty_cycle"] = cyc_used
    if len(runs) > 1:
        jf.warnings.append(f"duty cycles form {len(runs)} runs separated by rests; each run is taken to "
                           "start cold (joint temperature = temp_env), as in 002's protocol")
    F_unit = unit_of("F", axis)
    tf4 = None
    for m in sorted(th_wanted, key=th.THERMAL_MODELS.index):
        if m == "thermal6":
            # thermal4 is nested in thermal6: starting at its optimum, thermal6 fits the cycles at least as well
            tf4 = tf4 or th.fit_thermal(runs, "thermal4")
            tf = th.fit_thermal(runs, m, start=th.nested_start(tf4) if tf4 is not None else None)
        else:
            tf = tf4 = th.fit_thermal(runs, m)
        if tf is None:
            jf.not_identified.append({"what": m, "reason": "too few duty cycles with motion in both directions"})
            continue
        r_h, r_c = th.heldout(runs, m, n_folds=3, full=tf)
        params: dict[str, ParamEstimate] = {}
        cdims = ("F", "D", "D2", "D3")
        for i, dim in enumerate(cdims):
            n = f"c{i}"
            if n in tf.fixed:
                params[n] = ParamEstimate(n, tf.fixed[n], None, unit_of(dim, axis), True,
                                          "from the cold first cycle (002: identified at T0)", fixed=True)
            else:
                params[n] = ParamEstimate(n, tf.values[n], tf.stderr[n], unit_of(dim, axis),
                                          n not in tf.reasons, tf.reasons.get(n, ""))
        if m == "thermal6":
            for i, dim in enumerate(cdims):
                n = f"dc{i}"
                params[n] = ParamEstimate(n, tf.values[n], tf.stderr[n], unit_of(dim, axis) + "/K",
                                          n not in tf.reasons, tf.reasons.get(n, ""))
        else:
            params["alpha"] = ParamEstimate("alpha", tf.values["alpha"], tf.stderr["alpha"], "1/K",
                                            "alpha" not in tf.reasons, tf.reasons.get("alpha", ""))
            params["beta"] = ParamEstimate("beta", tf.values["beta"], tf.stderr["beta"], "1",
                                           "beta" not in tf.reasons, tf.reasons.get("beta", ""))
        if "K" in tf.fixed:
            params["K"] = ParamEstimate("K", tf.fixed["K"], None, "W/K", True,
                                        "held: the joint temperature is not measured, K only sets its scale",
                                        fixed=True)
        else:
            params["K"] = ParamEstimate("K", tf.values["K"], tf.stderr["K"], "W/K", "K" not in tf.reasons,
                                        tf.reasons.get("K", ""))
        params["C"] = ParamEstimate("C", tf.values["C"], tf.stderr["C"], "J/K", "C" not in tf.reasons,
                                    tf.reasons.get("C", ""))
        params["T0"] = ParamEstimate("T0", tf.T0, None, "degC", True, "ambient temperature at the cold start",
                                     fixed=True)
        n = tf.n_cycles
        rss = (tf.rms or 0.0) ** 2 * n
        aic = sel_aic(rss, n, tf.k)
        met = {"rms": tf.rms, "rms_heldout": r_h, "rms_heldout_constant": r_c,
               "heldout_gain": (1 - r_h / r_c) if (r_h is not None and r_c) else None,
               "aic": aic, "n": n, "k": tf.k}
        extra = {"time_constant": {"value": tf.time_constant, "stderr": tf.time_constant_se, "unit": "s"},
                 "cycle_temperature": [[round(x, 4) for x in ct] for ct in tf.cycle_T]}
        jf.models[m] = ModelFit(m, "polynomial", params, met, notes=tf.notes, success=tf.success,
                                method="cycle-by-cycle polynomial least squares, then all thermal parameters "
                                       "together against the cycles' friction (002 section V)", extra=extra)
        for nm, pe in params.items():
            if not pe.identifiable:
                jf.not_identified.append({"what": f"{m}.{nm}", "reason": pe.reason})


def sel_aic(rss, n, k):
    from .static import _aic
    return _aic(rss, n, k)
