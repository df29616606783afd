"""What the report draws, computed from a parameter file (schema 1) and the logs it came from.

numpy only: no matplotlib, no HTML. Everything here recomputes from the logs what the figures show; the
identification itself is never redone. The friction torque is ``F = tau - J a - G(q) - offset`` with the
identified inertia, gravity and offset of the parameter file, and the velocity and acceleration from the
same Savitzky-Golay derivatives the fit uses (:func:`frictid.segments.derivatives`), so the plateau points
drawn are the ones the fit saw (:func:`frictid.identify.static.plateau_points`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from frictid.data import JointLog, Segment
from frictid import replay as rp
from frictid.errors import ConfigError, FrictidInputError
from frictid.model import FrictionModel
from frictid.models import static as sm
from frictid.result import JointFit

#: Moving samples: |w| above this fraction of the 99.5th percentile of |w| (as the fit).
MIN_SPEED_FRACTION = 0.02
#: Most ramps and steps drawn per joint (the fit uses them all): at most 5 measured curves per panel, each
#: in its own colour and marker (a step also has its simulated curve, dashed in the same colour).
MAX_RAMPS_DRAWN = 5
MAX_STEPS_DRAWN = 3
#: Samples drawn per ramp / step transient at most (stride decimation of the drawn curve only).
MAX_CURVE_POINTS = 600


# ---------------------------------------------------------------------------------------------------
# reading the parameter file


def pvalue(d: Any) -> float | None:
    """The ``value`` of a parameter entry (a mapping with value/stderr/unit, or a bare number)."""
    if d is None:
        return None
    if isinstance(d, dict):
        d = d.get("value")
    try:
        v = float(d)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def pstderr(d: Any) -> float | None:
    if not isinstance(d, dict):
        return None
    return pvalue(d.get("stderr"))


def rigid_terms(jd: dict) -> dict[str, float]:
    """Inertia, gravity and offset values of a joint entry (0 where unknown): J, Px, Py, Mx, My, offset."""
    out = {"J": pvalue(jd.get("inertia")) or 0.0, "offset": pvalue(jd.get("offset")) or 0.0}
    grav = jd.get("gravity") or {}
    if isinstance(grav, dict):
        for k in ("Px", "Py", "Mx", "My"):
            out[k] = pvalue(grav.get(k)) or 0.0
    return out


def model_values(md: dict) -> dict[str, float | None]:
    """Parameter values of one model entry by name."""
    return {n: pvalue(p) for n, p in (md.get("params") or {}).items()}


def friction_model(jd: dict, name: str, jf: JointFit | None = None) -> FrictionModel | None:
    """Model ``name`` of a joint entry as the :class:`~frictid.model.FrictionModel` that evaluates it, or
    None when the file does not hold all its values (the report then leaves its curve out). jf : the entry
    already read into a :class:`JointFit`, when the caller evaluates several of its models."""
    try:
        return (jf or JointFit.from_dict("", jd)).friction_model(name)
    except (ConfigError, KeyError, TypeError, ValueError):
        return None


def static_models(jd: dict) -> list[dict]:
    """Every model of a joint that has a steady-state velocity map and all its values.

    Returns dicts: name, map, model (:class:`FrictionModel`), selected (bool), label. Thermal laws are drawn
    against temperature instead (:func:`thermal_cycles`); ``lugre`` is left out when its static part is
    another listed model (its steady state is that model's curve).
    """
    models = jd.get("models") or {}
    sel = jd.get("selected")
    try:
        jf = JointFit.from_dict("", jd)
    except (KeyError, TypeError, ValueError):  # an entry the file's reader would refuse: no curves
        return []
    out = []
    for name, md in models.items():
        if not isinstance(md, dict) or name.startswith("thermal") or name == "exponential":
            continue
        if name == "lugre" and md.get("static_model") in models and sel != "lugre":
            continue
        m = friction_model(jd, name, jf)
        if m is None:
            continue
        label = name + (" (chosen)" if name == sel else "")
        if name == "lugre":
            label += f", steady state of {md.get('static_model') or m.map}"
        out.append({"name": name, "map": m.map, "model": m, "selected": name == sel, "label": label})
    return out


def selected_static(jd: dict) -> dict | None:
    """The selected model when it has a steady-state velocity map (LuGre's static part when LuGre is
    selected): name, map, model."""
    sel = jd.get("selected")
    if sel not in (jd.get("models") or {}) or sel.startswith("thermal") or sel == "exponential":
        return None
    m = friction_model(jd, sel)
    return None if m is None else {"name": sel, "map": m.map, "model": m}


# ---------------------------------------------------------------------------------------------------
# one log of a joint


@dataclass
class LogData:
    """One log of a joint with what every figure needs: velocity, acceleration, friction torque, segments.

    w [q/s], a [q/s^2]: derivatives as the fit computes them; G [F]: gravity plus offset; F [F]: friction
    torque ``tau - J a - G`` (both :class:`PerSample`: computed on the slices the figures read, the whole
    log only where a figure needs it). label: the file it came from. sha256: of that file (None for stdin).
    """

    log: JointLog
    w: np.ndarray
    a: np.ndarray
    G: "PerSample"
    F: "PerSample"
    segments: list[Segment]
    label: str = ""
    sha256: str | None = None
    source_index: int | None = None
    #: the log's :class:`frictid.segments.Scales` when the derivatives are the fit's default ones (measured
    #: once: the replay's stick zone and the closed loop reuse them instead of measuring them again)
    scales: Any = None
    notes: list[str] = field(default_factory=list)
    #: the replay models' gravity along the log, per rigid-body terms (:func:`model_gravity`)
    gravity: dict = field(default_factory=dict)
    #: the report read the log itself (a worker's :class:`~frictid.report.build.DeferredLogs`): the
    #: channels no part still to come reads may be dropped from it (:func:`drop_reference_channels`)
    own: bool = False


def drop_reference_channels(datas: list["LogData"]) -> None:
    """Drop the closed loop's references (:data:`frictid.replay.REFERENCE_CHANNELS`) from the logs the
    report read itself, once their closed loops have run: 87 MB a joint-hour that the diagnosis' replays,
    which come next, then reuse instead of fresh memory. A caller's logs are left as they were."""
    from frictid.replay import REFERENCE_CHANNELS

    for d in datas:
        if d.own:
            for c in REFERENCE_CHANNELS:
                d.log.channels.pop(c, None)


class PerSample:
    """A per-sample quantity of a log computed only where it is read: ``x[i0:i1]`` computes those samples
    (``fn(i0, i1)``), :meth:`full` the whole log once. The plateaus, ramps, steps and duty cycles read a
    small part of an hour-long log; a whole-log array is made only for the figures that draw one."""

    def __init__(self, n: int, fn: Callable[[int, int], np.ndarray]):
        self.n = int(n)
        self._fn = fn
        self._all: np.ndarray | None = None

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, key):
        if self._all is None and isinstance(key, slice) and key.step in (None, 1):
            i0, i1, _ = key.indices(self.n)
            return self._fn(i0, max(i0, i1))
        return self.full()[key]

    def full(self) -> np.ndarray:
        if self._all is None:
            self._all = self._fn(0, self.n)
        return self._all


def gravity_torque(log: JointLog, terms: dict[str, float], i0: int = 0, i1: int | None = None) -> np.ndarray:
    """Gravity plus payload plus offset [F] along a log (as the fit models it), samples ``i0:i1``."""
    from frictid.replay import rigid_torque

    sl = slice(i0, log.n if i1 is None else i1)
    if log.q is None:
        return np.full(len(range(*sl.indices(log.n))), terms.get("offset", 0.0))
    payload = log.channels["payload"][sl] if "payload" in log.channels else None
    return rigid_torque(log.q[sl], log.axis, terms.get("Px", 0.0), terms.get("Py", 0.0), terms.get("offset", 0.0),
                        payload, terms.get("Mx", 0.0), terms.get("My", 0.0))


def recorded_segments(log: JointLog, jd: dict, sources: list[dict], sha256: str | None) -> list[Segment] | None:
    """The segments the fit recorded for this log (the joint's ``segment_list``), when the log's file has
    the SHA-256 of that source and the entry's number of rows; else None (segment the log again)."""
    entry = recorded_entry(log, jd, sources, sha256)
    if entry is None:
        return None
    from frictid.identify.pipeline import segments_from_list
    return segments_from_list(entry, log.t)


def recorded_scales(log: JointLog, jd: dict, sources: list[dict], sha256: str | None):
    """The log's :class:`frictid.segments.Scales` as the fit measured them (``scales`` of its
    ``segment_list`` entry, on the conditions of :func:`recorded_segments`); None when not recorded."""
    entry = recorded_entry(log, jd, sources, sha256)
    rec = (entry or {}).get("scales")
    if not isinstance(rec, dict):
        return None
    from frictid.segments import Scales
    try:
        sc = Scales(**{k: math.nan if v is None else v for k, v in rec.items()})  # null: NaN in the file
    except TypeError:  # other fields: written by another version
        return None
    return sc if sc.n == log.n else None


def recorded_entry(log: JointLog, jd: dict, sources: list[dict], sha256: str | None) -> dict | None:
    """The joint's ``segment_list`` entry for this log: the log's file has the entry's source SHA-256, the
    log the entry's number of rows, and the entry's segments are well formed; else None."""
    if not sha256:
        return None
    for entry in jd.get("segment_list") or []:
        if not isinstance(entry, dict):
            continue
        try:
            src = sources[int(entry["source"])]
            rows = int(entry["rows"])
        except (KeyError, IndexError, TypeError, ValueError):
            continue
        if src.get("sha256") == sha256 and rows == log.n:
            try:
                i0, i1 = np.asarray(entry["i0"], int), np.asarray(entry["i1"], int)
                ok = i0.shape == i1.shape == (len(entry["kind"]),) == (len(entry["cycle"]),)
            except (KeyError, TypeError, ValueError):
                continue
            if ok and np.all((0 <= i0) & (i0 < i1) & (i1 <= log.n)):
                return entry
    return None


def prepare_log(log: JointLog, jd: dict, segmenter: Callable, differentiate: Callable,
                segments: list[Segment] | None = None, scales=None) -> LogData:
    """Derivatives, segments (``segments`` when given, else ``segmenter(log)``) and the friction torque of
    one log for the joint entry ``jd``. ``scales``: the log's :class:`frictid.segments.Scales` when known
    (:func:`recorded_scales`; used by the default derivatives instead of measuring them again)."""
    from frictid.segments import derivatives, estimate_scales

    sc = None
    if differentiate is derivatives:
        sc = scales or estimate_scales(log)
        w, a = derivatives(log, sc)
    else:
        w, a = differentiate(log)
    w = np.asarray(w, float)
    a = np.asarray(a, float)
    segs = list(segments) if segments is not None else list(segmenter(log))
    terms = rigid_terms(jd)
    G = PerSample(log.n, lambda i0, i1: gravity_torque(log, terms, i0, i1))

    def friction(i0: int, i1: int) -> np.ndarray:
        return np.asarray(log.tau[i0:i1], float) - terms["J"] * np.nan_to_num(a[i0:i1]) - G[i0:i1]

    return LogData(log=log, w=w, a=a, G=G, F=PerSample(log.n, friction), segments=segs, label=log.source or "",
                   scales=sc)


def match_sources(datas: list[LogData], sources: list[dict]) -> None:
    """Set ``source_index`` of each log: the parameter file's source with the same hash, else the same
    file name, else (one log, one source) that one."""
    for d in datas:
        for i, s in enumerate(sources):
            if d.sha256 and s.get("sha256") and d.sha256 == s.get("sha256"):
                d.source_index = i
                break
        else:
            for i, s in enumerate(sources):
                if d.label and s.get("path") and Path(str(s["path"])).name == Path(d.label).name:
                    d.source_index = i
                    break
    if len(datas) == 1 and len(sources) == 1 and datas[0].source_index is None:
        rows = sources[0].get("rows")
        if rows is None or int(rows) == datas[0].log.n:  # e.g. the same data read from standard input
            datas[0].source_index = 0


def min_speed(datas: list[LogData]) -> float:
    w = np.concatenate([np.abs(d.w[np.isfinite(d.w)]) for d in datas]) if datas else np.zeros(0)
    return MIN_SPEED_FRACTION * float(np.percentile(w, 99.5)) if w.size else 0.0


# ---------------------------------------------------------------------------------------------------
# static map: plateau points and model curves


@dataclass
class PlateauSet:
    """Plateau points of a joint: w [q/s], F [F] and their standard errors; log index per point."""

    w: np.ndarray
    F: np.ndarray
    F_se: np.ndarray
    w_se: np.ndarray
    log_index: np.ndarray

    def __len__(self) -> int:
        return int(self.w.shape[0])


def plateaus(datas: list[LogData], model: FrictionModel | None = None) -> PlateauSet:
    """One averaged (w, F) point per constant-velocity segment of every log (as the fit computes it). With
    ``model``, the friction is in that model's convention (:func:`model_friction`: its inertia, gravity and
    offset), the one its curve is drawn in; else the joint's (``LogData.F``)."""
    from frictid.identify.static import plateau_points

    parts = []
    for k, d in enumerate(datas):
        F = d.F if model is None else model_friction(d, model)
        p = plateau_points(d.log.t, d.w, F, d.segments)
        if len(p):
            parts.append((p, np.full(len(p), k)))
    if not parts:
        z = np.zeros(0)
        return PlateauSet(z, z, z, z, z.astype(int))
    cat = lambda f: np.concatenate([getattr(p, f) for p, _ in parts])  # noqa: E731
    return PlateauSet(cat("w"), cat("F"), np.nan_to_num(cat("F_se")), np.nan_to_num(cat("w_se")),
                      np.concatenate([k for _, k in parts]))


def velocity_grids(pl: PlateauSet, datas: list[LogData]) -> dict[str, np.ndarray]:
    """Velocity grids [q/s] for the model curves: linear over both signs, logarithmic per sign."""
    if len(pl):
        wmax = float(np.max(np.abs(pl.w)))
        wmin = float(np.min(np.abs(pl.w[pl.w != 0]))) if np.any(pl.w != 0) else wmax / 100
    else:
        wabs = np.concatenate([np.abs(d.w) for d in datas]) if datas else np.zeros(0)
        wmax = float(np.percentile(wabs, 99.5)) if wabs.size else 1.0
        wmin = wmax / 300
    wmax = wmax if wmax > 0 else 1.0
    wmin = min(max(wmin, wmax * 1e-5), wmax / 3)
    lin = np.linspace(0.0, 1.08 * wmax, 400)[1:]
    lin = np.unique(np.concatenate([lin, np.geomspace(wmin / 3, wmax, 150)]))
    logg = np.geomspace(wmin / 3, 1.3 * wmax, 250)
    return {"lin": np.concatenate([-lin[::-1], lin]), "log": logg}


#: Most model curves on one friction map: the chosen model and the best alternatives (the rest are listed).
MAX_CURVES = 5


def chosen_model(jd: dict) -> FrictionModel | None:
    """The selected model of a joint entry as the :class:`FrictionModel` that evaluates it (None when there
    is none or its values are incomplete)."""
    sel = jd.get("selected")
    return friction_model(jd, sel) if sel in (jd.get("models") or {}) else None


def model_friction(d: "LogData", m: FrictionModel) -> "PerSample":
    """The friction torque along a log in model ``m``'s own convention: ``tau - m.J a - m.gravity(q)`` (its
    inertia, gravity and offset; for a model the diagnosis extended with ``tau_offset`` the offset stays in
    the friction, as :meth:`FrictionModel.friction` has it)."""
    log = d.log

    def friction(i0: int, i1: int) -> np.ndarray:
        pay = log.channels["payload"][i0:i1] if "payload" in log.channels else None
        G = m.gravity(None if log.q is None else np.asarray(log.q[i0:i1], float), pay)
        return np.asarray(log.tau[i0:i1], float) - m.J * np.nan_to_num(d.a[i0:i1]) - G

    return PerSample(log.n, friction)


def map_order(jd: dict, names: list[str]) -> list[str]:
    """``names`` in the order a reader compares them: the chosen model, then the fit's ranking (identifiable
    models by held-out RMS), then the others."""
    sel = jd.get("selected")
    ranking = [r.get("model") for r in ((jd.get("selection") or {}).get("ranking") or [])
               if isinstance(r, dict) and r.get("identifiable", True)]
    first = [n for n in [sel] + ranking if n in names]
    return list(dict.fromkeys(first + [n for n in names if n not in first]))


def model_curves(jd: dict, grids: dict[str, np.ndarray], most: int = MAX_CURVES) -> tuple[list[dict], list[str]]:
    """The friction of the chosen model and of the best alternatives (at most ``most`` models) on the grids,
    in the chosen model's offset convention: each model's :meth:`FrictionModel.friction` plus its offset
    (``m.offset``) less the chosen model's, so that every curve predicts the same quantity as the plateau
    points (:func:`plateaus` with the chosen model). Returns (curves: name, label, selected, lin, pos, neg
    (|F| on the log grid for w > 0 and w < 0)), and the names of the static models left out."""
    import warnings

    models = {m["name"]: m for m in static_models(jd)}
    order = map_order(jd, list(models))
    chosen = chosen_model(jd)
    ref = chosen.offset if chosen is not None else None
    out = []
    for name in order[:most]:
        m = models[name]["model"]
        shift = 0.0 if ref is None else m.offset - ref

        def F(w, m=m, shift=shift):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # a map drawn past its data, or without q: neutral, as said
                return m.friction(w) + shift

        out.append({"name": name, "label": models[name]["label"], "selected": models[name]["selected"],
                    "lin": F(grids["lin"]), "pos": F(grids["log"]), "neg": -F(-grids["log"]), "shift": shift})
    return out, order[most:]


def coverage(datas: list[LogData], pl: PlateauSet, jd: dict) -> dict:
    """What the data covered: velocity range per sign, counts of plateaus, ramps, steps and cycles."""
    out: dict[str, Any] = {"from_logs": bool(datas)}
    counts = {"constant_velocity": 0, "ramp_presliding": 0, "step": 0, "duty_cycle": 0}
    cycles = set()
    if datas:
        for k, d in enumerate(datas):
            for s in d.segments:
                if s.kind in counts:
                    counts[s.kind] += 1
                if s.kind == "duty_cycle":
                    cycles.add((k, s.cycle if s.cycle is not None else s.i0))
        out["duration"] = float(sum(d.log.t[-1] - d.log.t[0] for d in datas if d.log.n > 1))
        out["samples"] = int(sum(d.log.n for d in datas))
    else:
        seg = jd.get("segments") or {}
        for k in counts:
            counts[k] = int(seg.get(k, 0) or 0)
        used = (jd.get("segments_used") or {}).get("duty_cycle") or []
        cycles = set(range(len(used)))
    out["plateaus"] = counts["constant_velocity"]
    out["plateaus_used"] = len(pl) if datas else len((jd.get("segments_used") or {}).get("constant_velocity") or [])
    out["ramps"] = counts["ramp_presliding"]
    out["steps"] = counts["step"]
    out["cycles"] = len(cycles)
    for sign, name in ((1, "pos"), (-1, "neg")):
        sel = pl.w[np.sign(pl.w) == sign] if len(pl) else np.zeros(0)
        out[name] = (float(np.min(np.abs(sel))), float(np.max(np.abs(sel))), int(sel.size)) if sel.size else None
    return out


# ---------------------------------------------------------------------------------------------------
# presliding: ramps and steps


def _stride(n: int, most: int) -> slice:
    return slice(None, None, max(1, int(math.ceil(n / most))))


def _spread(items: list, most: int) -> list:
    """At most ``most`` items spread evenly over the list (first and last kept)."""
    if len(items) <= most:
        return items
    idx = np.unique(np.round(np.linspace(0, len(items) - 1, most)).astype(int))
    return [items[i] for i in idx]


def _drawable(datas: list[LogData], kind: str) -> list[tuple[LogData, Segment]]:
    """The (log, segment) pairs of one kind that a curve can be drawn from: logs with a position, segments of
    at least ten samples."""
    return [(d, s) for d in datas if d.log.q is not None for s in d.segments if s.kind == kind and s.n >= 10]


def lugre_params(jd: dict) -> dict | None:
    """LuGre's model (:class:`FrictionModel`, None when its values are incomplete) and its sigma0 / sigma1
    entries, or None when there is no LuGre."""
    md = (jd.get("models") or {}).get("lugre")
    if not isinstance(md, dict):
        return None
    params = md.get("params") or {}
    return {"model": friction_model(jd, "lugre"), "sigma0": params.get("sigma0") or {},
            "sigma1": params.get("sigma1") or {}}


def _rest_level(m: FrictionModel, sign: float) -> float:
    """The model's level g at rest [F] on the branch of ``sign``: the break-away level of its map."""
    return float(sm.canonical_level(np.zeros(1), m.c_pos if sign >= 0 else m.c_neg)[0])


def ramp_curves(datas: list[LogData], jd: dict) -> tuple[list[dict], dict]:
    """Torque against displacement for each ramp-presliding segment (at most :data:`MAX_RAMPS_DRAWN`),
    with LuGre's bristle path at the identified sigma0 when there is one. Returns (curves, info)."""
    from frictid.identify.presliding import bristle_path

    lp = lugre_params(jd)
    s0 = pvalue(lp["sigma0"]) if lp else None
    info = {"sigma0": lp["sigma0"] if lp else None, "n_total": 0}
    m = lp["model"] if lp and s0 else None
    items = _drawable(datas, "ramp_presliding")
    info["n_total"] = len(items)
    curves = []
    for d, s in _spread(items, MAX_RAMPS_DRAWN):
        q = np.asarray(d.log.q[s.i0:s.i1], float)
        F = d.F[s.i0:s.i1]
        model = None
        if m is not None:
            g0 = abs(_rest_level(m, np.mean(F)))
            if g0 > 0:
                z0 = float(np.clip(F[0] / s0, -g0 / s0, g0 / s0))
                model = s0 * bristle_path(q, z0, s0, g0)
        st = _stride(q.size, MAX_CURVE_POINTS)
        curves.append({"x": (q - q[0])[st], "F": F[st], "model": None if model is None else model[st],
                       "t0": float(d.log.t[s.i0])})
    return curves, info


def step_curves(datas: list[LogData], jd: dict) -> tuple[list[dict], dict]:
    """Measured step transients (position from its start against time) and LuGre's simulated ones when
    J, sigma0 and sigma1 are known (at most :data:`MAX_STEPS_DRAWN`). Returns (curves, info)."""
    from frictid.identify.presliding import simulate_step

    lp = lugre_params(jd)
    J = pvalue(jd.get("inertia"))
    s0 = pvalue(lp["sigma0"]) if lp else None
    s1 = pvalue(lp["sigma1"]) if lp else None
    info = {"sigma1": lp["sigma1"] if lp else None, "n_total": 0, "J": J}
    m = lp["model"] if lp else None
    can = bool(m is not None and J and J > 0 and s0 and s1 is not None)
    items = _drawable(datas, "step")
    info["n_total"] = len(items)
    curves = []
    for d, s in _spread(items, MAX_STEPS_DRAWN):
        t = np.asarray(d.log.t[s.i0:s.i1], float)
        q = np.asarray(d.log.q[s.i0:s.i1], float)
        u = np.asarray(d.log.tau[s.i0:s.i1], float) - d.G[s.i0:s.i1]
        model = None
        if can:
            g0 = max(_rest_level(m, 1.0), 1e-12)
            z0 = float(np.clip(u[0] / s0, -g0 / s0, g0 / s0))
            try:
                with np.errstate(all="ignore"):
                    model = simulate_step(t, u, q[0], 0.0, J, s0, s1, m.c_pos, m.c_neg, z0)
                if not np.all(np.isfinite(model)):
                    model = None
            except (ArithmeticError, ValueError):
                model = None
        st = _stride(t.size, MAX_CURVE_POINTS)
        curves.append({"t": (t - t[0])[st], "x": (q - q[0])[st], "model": None if model is None else
                       (model - q[0])[st], "t0": float(t[0])})
    return curves, info


# ---------------------------------------------------------------------------------------------------
# thermal


THERMAL_LAWS = ("thermal4", "thermal6", "exponential")


#: Canonical entries of the polynomial map's c0..c3 (a0, b1, b2, b3).
POLY_SLOTS = tuple(sm.CANON.index(k) for k in ("a0", "b1", "b2", "b3"))


def thermal_coefficients(m: FrictionModel, T: float) -> np.ndarray:
    """Polynomial coefficients c0..c3 of a thermal model at joint temperature T [degC]
    (:meth:`FrictionModel.canonical_at`)."""
    return m.canonical_at(T)[0][list(POLY_SLOTS)]


def _poly_basis(w: np.ndarray) -> np.ndarray:
    """Regressors of the polynomial friction c0 sgn(w) + c1 w + c2 w|w| + c3 w^3 (columns filled in
    place, the cube as w|w||w|: no general power, no stacking copies)."""
    X = np.empty((w.shape[0], 4))
    aw = np.abs(w)
    np.sign(w, out=X[:, 0])
    X[:, 1] = w
    np.multiply(w, aw, out=X[:, 2])
    np.multiply(X[:, 2], aw, out=X[:, 3])
    return X


def _cycle_polynomial(w: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A cycle's polynomial friction ``c0 sgn(w) + c1 w + c2 w|w| + c3 w^3`` fitted to (w, F) by the fit's
    own least squares (:func:`frictid.identify.regression.solve`: normal equations with the columns scaled, the
    dependent ones left out), and the Gram matrix ``X'X / n`` its RMS needs (:func:`_quad_rms`): one pass
    over the samples instead of a factorisation of them (``lstsq``, 7 ms per cycle of a joint-hour)."""
    from frictid.identify import regression as rg

    ne = rg.NormalEquations(4)
    ne.add(_poly_basis(w), F)
    return rg.solve(ne, ("c0", "c1", "c2", "c3")).coef, ne.XtX / max(ne.n, 1)


def _quad_rms(c: np.ndarray, gram: np.ndarray) -> float:
    """RMS over a cycle's samples of the polynomial friction with coefficients ``c``, from the cycle's
    Gram matrix of the regressors (the same number as the polynomial evaluated at every sample)."""
    return float(np.sqrt(max(float(c @ gram @ c), 0.0)))


def thermal_cycles(datas: list[LogData], jd: dict, vmin: float | None = None
                   ) -> tuple[list[dict], list[dict], dict]:
    """Friction per duty cycle against time, and for each thermal model its friction at its own estimated
    cycle temperature. Both are 002's ``F_rms``: the RMS over the cycle's moving samples of the polynomial
    friction, identified by least squares on the cycle (measured) or given by the law at the cycle's
    temperature (model); the noise of the torque does not enter.

    Cycles are those the fit used (``segments_used.duty_cycle``: start, end, source) when the parameter
    file lists them, else the duty-cycle segments found in the logs. Returns (cycles, models, info):
    cycles: t [s] mid-cycle, F_rms [F], temp_env, temp_joint [degC] (NaN when not logged), log index;
    models: name, selected, T [degC] per cycle (NaN where unknown), F_rms [F] per cycle.
    """
    models = jd.get("models") or {}
    th_names = [n for n in models if n in THERMAL_LAWS and isinstance(models[n], dict)]
    used = (jd.get("segments_used") or {}).get("duty_cycle") or []
    windows: list[tuple[int, float, float, int]] = []  # (log index, t0, t1, position in used)
    info = {"source": "", "n_models": len(th_names)}
    if used:
        by_src = {d.source_index: k for k, d in enumerate(datas) if d.source_index is not None}
        for pos, row in enumerate(used):
            try:
                t0, t1 = float(row[0]), float(row[1])
                src = int(row[2]) if len(row) > 2 else 0
            except (TypeError, ValueError, IndexError):
                continue
            k = by_src.get(src, 0 if len(datas) == 1 else None)
            if k is not None:
                windows.append((k, t0, t1, pos))
        info["source"] = "the cycles the fit used"
    if not windows:
        for k, d in enumerate(datas):
            groups: dict[Any, list[Segment]] = {}
            for s in d.segments:
                if s.kind == "duty_cycle":
                    groups.setdefault(s.cycle if s.cycle is not None else s.i0, []).append(s)
            for g in groups.values():
                windows.append((k, float(d.log.t[min(s.i0 for s in g)]), float(d.log.t[max(s.i1 for s in g) - 1]), -1))
        info["source"] = "the duty-cycle segments found in the logs"
    if not windows:
        return [], [], info
    vmin = min_speed(datas) if vmin is None else vmin
    cycles = []
    grams = []
    for k, t0, t1, pos in windows:
        d = datas[k]
        i0, i1 = np.searchsorted(d.log.t, [t0, t1 + 1e-9])
        if i1 - i0 < 4:
            continue
        ww = d.w[i0:i1]
        mv = np.abs(ww) > vmin
        if mv.sum() < 4:
            continue
        # the cycle's own friction, as the fit identifies it; its RMS over the samples is sqrt(c' gram c)
        coef, gram = _cycle_polynomial(ww[mv], d.F[i0:i1][mv])
        te = d.log.channels.get("temp_env")
        tj = d.log.channels.get("temp_joint")
        cycles.append({"t": 0.5 * (t0 + t1), "F_rms": _quad_rms(coef, gram),
                       "temp_env": float(np.mean(te[i0:i1])) if te is not None else math.nan,
                       "temp_joint": float(np.mean(tj[i0:i1])) if tj is not None else math.nan,
                       "log": k, "pos": pos})
        grams.append(gram)
    out_models = []
    for name in th_names:
        md = models[name]
        m = friction_model(jd, name) if md.get("map", "polynomial") == "polynomial" else None
        flat = [x for run in (md.get("cycle_temperature") or []) for x in (run if isinstance(run, list) else [run])]
        T = np.full(len(cycles), np.nan)
        Fm = np.full(len(cycles), np.nan)
        for i, (c, gram) in enumerate(zip(cycles, grams)):
            if 0 <= c["pos"] < len(flat):
                T[i] = pvalue(flat[c["pos"]]) if pvalue(flat[c["pos"]]) is not None else np.nan
            if np.isfinite(T[i]) and m is not None:
                Fm[i] = _quad_rms(thermal_coefficients(m, T[i]), gram)
        out_models.append({"name": name, "selected": name == jd.get("selected"), "T": T, "F_rms": Fm,
                           "time_constant": md.get("time_constant")})
    return cycles, out_models, info


# ---------------------------------------------------------------------------------------------------
# replay and diagnosis


def static_replay(d: LogData, jd: dict, vmin: float | None = None) -> np.ndarray | None:
    """Fallback model torque ``J a + G(q) + offset + F_ss(w)`` with the selected model's static map, used
    when :func:`frictid.replay.replay` cannot build the model. Samples slower than ``vmin`` [q/s] are NaN:
    at rest a static map cannot tell which friction between -Fs and Fs holds the joint."""
    sel = selected_static(jd)
    if sel is None:
        return None
    Fss = sel["model"].steady_state(np.nan_to_num(d.w))
    Fss[~np.isfinite(d.w)] = np.nan
    out = rigid_terms(jd)["J"] * np.nan_to_num(d.a) + d.G.full() + Fss
    if vmin is not None:
        out[np.abs(d.w) <= vmin] = np.nan
    return out


def model_gravity(d: LogData, m) -> np.ndarray | None:
    """``m.gravity`` (a :class:`frictid.replay.ReplayModel`) along the log, computed once per set of rigid-body
    terms: the models replayed for a joint share them. None for a log without position."""
    if d.log.q is None:
        return None
    key = (m.axis, m.Px, m.Py, m.Mx, m.My, m.offset)
    if key not in d.gravity:
        d.gravity[key] = m.gravity(np.asarray(d.log.q, float), d.log.channels.get("payload"))
    return d.gravity[key]


@dataclass
class Replay:
    """A model run along a log: torque (and, in closed loop, position) measured against the model."""

    model: str
    tau_model: np.ndarray
    q_model: np.ndarray | None = None
    T: np.ndarray | None = None
    how: str = ""
    notes: list[str] = field(default_factory=list)
    #: samples in the replay's stick zone, where the model reads the measured torque (None: not known)
    still: np.ndarray | None = None

    def residual(self, d: LogData) -> np.ndarray:
        return np.asarray(d.log.tau, float) - self.tau_model


def replay_log(d: LogData, jname: str, jd: dict, model: str | None = None, closed: bool = True,
               vmin: float | None = None) -> Replay | None:
    """Run a model of the joint (default: the chosen one) along a log with :mod:`frictid.replay` (LuGre
    state, thermal state, Karnopp stick at rest, diagnosis extensions); the closed loop is re-simulated
    when the log has ``q_ref`` and its metadata the controller gains. Falls back on the static map alone
    (:func:`static_replay`) when the replay cannot build the model. None when neither can."""
    name = model or jd.get("selected")
    if name:
        try:
            m = JointFit.from_dict(jname, jd).friction_model(name)
            G = model_gravity(d, m)
            with np.errstate(all="ignore"):
                r = rp.replay(d.log, m, w=d.w, a=d.a, scales=d.scales, G=G)
            T = None if r.T is None or not np.any(np.isfinite(r.T)) else np.asarray(r.T, float)
            out = Replay(name, np.asarray(r.tau_model, float), T=T, how="replay", notes=list(r.notes))
            if d.scales is not None and d.w is not None:
                out.still = np.abs(np.asarray(d.w, float)) <= rp.STICK_NOISE * d.scales.sigma_w
            del r  # its friction, bristle and residual arrays: freed before the closed loop allocates
            gains = rp.controller_from_meta(d.log.meta or {}) if closed else None
            if gains is not None and "q_ref" in d.log.channels and m.J > 0 and d.log.q is not None:
                with np.errstate(all="ignore"):
                    q_model, _, notes = rp.closed_loop(d.log, m, gains, a=d.a, G=G, velocity=False)
                if np.all(np.isfinite(q_model)):
                    out.q_model = np.asarray(q_model, float)
                    out.notes.extend(notes)
            if np.any(np.isfinite(out.tau_model)):
                return out
        except (FrictidInputError, KeyError, ValueError, TypeError, ArithmeticError):
            pass
    if model is not None and model != jd.get("selected"):
        return None
    tm = static_replay(d, jd, vmin)
    if tm is None:
        return None
    sel = selected_static(jd)
    return Replay(sel["name"], tm, how="static")


def named_extension_model(jd: dict, finding: dict) -> str | None:
    """The model of the parameter file a finding names as carrying its extension (``model``, or
    ``extension`` as a name or ``{model: ...}``), or None."""
    models = jd.get("models") or {}
    ext = finding.get("extension")
    for n in (finding.get("model"), ext if isinstance(ext, str) else None,
              ext.get("model") if isinstance(ext, dict) else None):
        if isinstance(n, str) and n in models:
            return n
    return None


def extension_model(jd: dict, finding: dict) -> tuple[str, dict] | None:
    """The model that carries a finding's extension: a model named by the finding (``model``, or
    ``extension`` as a name or ``{model: ...}``), else the chosen model with the extension's ``params``
    added. Returns (model name, joint entry to replay it from) or None."""
    models = jd.get("models") or {}
    ext = finding.get("extension")
    named = named_extension_model(jd, finding)
    if named is not None:
        return named, jd
    if isinstance(ext, dict) and isinstance(ext.get("params"), dict) and jd.get("selected") in models:
        import copy
        jd2 = copy.deepcopy(jd)
        sel = jd2["selected"]
        params = jd2["models"][sel].setdefault("params", {})
        for k, v in ext["params"].items():
            params[k] = v if isinstance(v, dict) else {"value": v}
        return sel, jd2
    return None


#: The variable a diagnosis cause is drawn against: keyword in the cause or extension -> variable.
CAUSE_VARIABLES = (
    ("load_gravity", "gravity"), ("load_payload", "payload"), ("load_tau", "load"),
    ("temp", "temperature"), ("thermal", "temperature"), ("warm", "temperature"), ("drift", "time"),
    ("wear", "time"), ("time", "time"), ("position", "q"), ("gravity", "q"), ("payload", "payload"),
    ("load", "load"), ("torque", "load"), ("asym", "w"), ("sign", "w"), ("stribeck", "w"), ("low_speed", "w"),
    ("velocity", "w"), ("offset", "w"), ("revers", "w"), ("presliding", "w"), ("stick", "w"), ("hyster", "w"),
    ("lag", "w"), ("elastic", "a"), ("inertia", "a"), ("accel", "a"),
)


def cause_variable(cause: str, extension: str = "") -> str:
    """The variable to draw a finding's residual against (``time`` when nothing fits)."""
    for text in (str(extension or "").lower(), str(cause or "").lower()):
        for key, var in CAUSE_VARIABLES:
            if key in text:
                return var
    return "time"


def variable_values(var: str, d: LogData, T: np.ndarray | None = None) -> tuple[np.ndarray, str]:
    """Samples of a cause variable and its label with unit (``T``: a model's joint temperature)."""
    u = d.log.units
    if var == "q" and d.log.q is not None:
        return np.asarray(d.log.q, float), f"position [{u['q']}]"
    if var == "payload" and "payload" in d.log.channels:
        return np.asarray(d.log.channels["payload"], float), "payload [kg]"
    if var == "gravity":
        return np.abs(d.G.full()), f"|gravity torque| [{u['tau']}]"
    if var in ("load", "payload"):
        return np.abs(np.asarray(d.log.tau, float)), f"|transmitted torque| [{u['tau']}]"
    if var == "w":
        return d.w, f"velocity [{u['qd']}]"
    if var == "a":
        return d.a, f"acceleration [{u['q']}/s^2]"
    if var == "temperature":
        if T is not None and np.any(np.isfinite(T)):
            return T, "estimated joint temperature [degC]"
        if "temp_joint" in d.log.channels:
            return np.asarray(d.log.channels["temp_joint"], float), "joint temperature [degC]"
    return np.asarray(d.log.t, float), "time [s]"


def x_order(x: np.ndarray) -> np.ndarray:
    """Indices of the finite samples of ``x`` in increasing ``x`` (stable): :func:`binned`'s sort, shared by
    the residuals before and after an extension, which are binned against the same samples."""
    idx = np.flatnonzero(np.isfinite(x))
    return idx[np.argsort(x[idx], kind="stable")]


def binned(x: np.ndarray, y: np.ndarray, nbins: int = 30, order: np.ndarray | None = None) -> dict:
    """Mean of y in equal-count bins of x: centre, mean, standard error, count. ``order``: :func:`x_order`
    of ``x`` when the caller has it."""
    order = x_order(x) if order is None else order
    ys = y[order]
    ok = np.isfinite(ys)
    xs, ys = x[order][ok], ys[ok]
    if xs.size < 2 * nbins:
        nbins = max(1, xs.size // 2)
    if xs.size == 0:
        z = np.zeros(0)
        return {"x": z, "mean": z, "se": z, "n": z}
    edges = np.linspace(0, xs.size, nbins + 1).astype(int)
    cx, m, se, n = [], [], [], []
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a < 1:
            continue
        cx.append(float(np.mean(xs[a:b])))
        m.append(float(np.mean(ys[a:b])))
        se.append(float(np.std(ys[a:b], ddof=1) / math.sqrt(b - a)) if b - a > 1 else 0.0)
        n.append(b - a)
    return {"x": np.array(cx), "mean": np.array(m), "se": np.array(se), "n": np.array(n)}


def on_sliding_samples(finding: dict) -> bool:
    """Whether a finding's residual is drawn along the sliding samples (a presliding or LuGre finding is
    judged on the presliding ramps instead)."""
    return not (str(finding.get("cause", "")) == "presliding" or finding.get("extension") == "lugre")


def diagnosis_befores(jd: dict, findings: list[dict]) -> list[str | None]:
    """The model each finding is measured against: the diagnosis base (else the chosen model) for the
    first, then the model of the finding before (when the parameter file has it)."""
    models = jd.get("models") or {}
    diag = (jd.get("selection") or {}).get("diagnosis")
    prev = (diag.get("base") if isinstance(diag, dict) else None) or jd.get("selected")
    out = []
    for f in findings:
        out.append(prev)
        if isinstance(f.get("model"), str) and f["model"] in models:
            prev = f["model"]
    return out


def replayed_models(jd: dict, finding: dict, before: str | None) -> set[str]:
    """The models of the parameter file that :func:`diagnosis_residuals` replays for a finding (those it
    can take from, or leave in, its cache)."""
    if not on_sliding_samples(finding):
        return set()
    out = {before if before in (jd.get("models") or {}) else jd.get("selected")}
    named = named_extension_model(jd, finding)  # a model built from the extension's params is never cached
    if named is not None:
        out.add(named)
    return out


def diagnosis_offset(jd: dict) -> float:
    """The joint's offset that the diagnosis leaves in the friction torque it judges (it enters the
    diagnosis' models only through its ``offset`` cause; :func:`frictid.diagnose.check.diagnose_fit`): the
    fit's estimate, none when the offset comes from the log's metadata."""
    off = jd.get("offset") if isinstance(jd.get("offset"), dict) else {}
    v = pvalue(off)
    return 0.0 if v is None or off.get("source") == "log metadata" else v


def as_diagnosis_base(jd: dict, name: str | None) -> dict:
    """The joint entry with model ``name`` run as the diagnosis ran its base: a fit's own model without the
    joint's offset (:func:`diagnosis_offset` is left in the friction the diagnosis judges, so its first
    finding is measured against the base without it); ``jd`` itself when the model is a diagnosis model
    already (``extensions``), absent, or the diagnosis left no offset out."""
    md = (jd.get("models") or {}).get(name)
    if not isinstance(md, dict) or "extensions" in md or diagnosis_offset(jd) == 0.0:
        return jd
    import copy
    jd2 = copy.copy(jd)
    jd2["models"] = dict(jd["models"])
    jd2["models"][name] = dict(md, extensions=[])   # a diagnosis model: its offset is its own (none)
    return jd2


@dataclass
class DiagnosisSamples:
    """The diagnosis' sliding samples of a joint's logs, where its findings' held-out numbers are measured:
    per log the rows (increasing), and the held-out residual of the diagnosis' base ``base`` on them (its
    amplitudes and gravity refitted without each fold, the fit's offset left in: what the first finding is
    judged against), or None when the base cannot be rebuilt."""

    rows: list[np.ndarray]
    base: str | None = None
    base_residual: list[np.ndarray] | None = None


def diagnosis_samples(datas: list[LogData], jname: str, jd: dict) -> DiagnosisSamples | None:
    """:class:`DiagnosisSamples` of the logs (:func:`frictid.diagnose.joint.base_residuals` on the logs as the
    fit handed them to the diagnosis: the joint's inertia, gravity and :func:`diagnosis_offset` left in the
    friction torque); None when the logs give no sliding samples."""
    from frictid.diagnose.joint import N_FOLDS, base_residuals
    from frictid.diagnose.samples import DiagLog

    off = diagnosis_offset(jd)
    logs = [DiagLog(t=d.log.t, q=d.log.q, w=d.w, a=d.a, tau=d.log.tau, F=d.F.full() + off, G=d.G.full() - off,
                    offset=off, segments=d.segments, channels=d.log.channels) for d in datas]
    rec = (jd.get("selection") or {}).get("diagnosis")
    rec = rec if isinstance(rec, dict) else {}
    base = rec.get("base") if isinstance(rec.get("base"), str) else None
    try:
        got = base_residuals(JointFit.from_dict(jname, jd), logs, base or "", int(rec.get("folds") or N_FOLDS))
    except (FrictidInputError, KeyError, ValueError, TypeError, ArithmeticError):
        return None
    if got is None:
        return None
    li, k, r = got
    rows, res = [], []
    for i in range(len(datas)):
        sel = np.flatnonzero(li == i)
        order = np.argsort(k[sel], kind="stable")
        rows.append(k[sel][order])
        if r is not None:
            res.append(r[sel][order])
    return DiagnosisSamples(rows, base if r is not None else None, res if r is not None else None)


def diagnosis_residuals(datas: list[LogData], jname: str, jd: dict, finding: dict, before: str | None = None,
                        cache: dict | None = None, vmin: float | None = None,
                        keep: set[str] | None = None, rows: DiagnosisSamples | None = None) -> dict | None:
    """Residual ``tau - tau_model`` against the finding's cause variable, binned, before (model ``before``,
    default the chosen one; on the samples ``rows`` the diagnosis' base as the diagnosis ran it,
    :func:`as_diagnosis_base`; on the moving samples the model as the fit runs it, with its offset) and
    after the extension (the finding's ``model``, or the chosen model with the extension's ``params``; else
    the finding's own ``binned: {x, after}``), on the samples ``rows`` (the diagnosis' sliding samples,
    :func:`diagnosis_samples`: where the finding's numbers were measured; there the diagnosis' base is its
    own held-out residual, the model the first finding was judged against), else on the moving samples;
    with the RMS of each residual over those samples (``rms_before``, ``rms_after``).
    ``cache`` keeps replays per (model, log index); ``keep``: the models whose replays stay in it (the
    others are dropped once used, each as soon as its residual is taken: None keeps all); ``vmin``:
    :func:`min_speed` of ``datas`` when known."""
    cache = {} if cache is None else cache
    var = cause_variable(str(finding.get("cause", "")), str(finding.get("extension", "")))
    vmin = min_speed(datas) if vmin is None else vmin
    ext = extension_model(jd, finding)
    before = before if before in (jd.get("models") or {}) else jd.get("selected")
    # moving samples: with the fit's offset (Franka joint 3's offset: 5.51 against 13.2 without it, 4.78 with)
    jd_before = as_diagnosis_base(jd, before) if rows is not None else jd

    def key(name, entry, k):   # the base run without the offset: its own tag (the copy is made per call)
        return name, k, 0 if entry is jd else "base" if entry is jd_before else id(entry)

    def run(name, entry, k, d):
        kk = key(name, entry, k)
        if kk not in cache:
            cache[kk] = replay_log(d, jname, entry, model=name, closed=False, vmin=vmin)
        return cache[kk]

    def release(kk, unless=None):
        if keep is not None and kk != unless and (kk[2] != 0 or kk[0] not in keep):
            cache.pop(kk, None)

    own_base = rows is not None and rows.base_residual is not None and before == rows.base
    xs, rb, ra, label = [], [], [], ""
    for k, d in enumerate(datas):
        mv = np.abs(d.w) > vmin if rows is None else rows.rows[k]
        k_after = key(ext[0], ext[1], k) if ext is not None else None
        if own_base:
            rb.append(rows.base_residual[k])
            T_before = None
        else:
            rb_k = run(before, jd_before, k, d)
            if rb_k is None:
                return None
            rb.append(rb_k.residual(d)[mv])
            T_before = rb_k.T
            del rb_k
            release(key(before, jd_before, k), unless=k_after)
        ra_k = run(ext[0], ext[1], k, d) if ext is not None else None
        T = ra_k.T if ra_k is not None and ra_k.T is not None else T_before
        x, label = variable_values(var, d, T)
        xs.append(x[mv])
        if ext is not None:
            ra.append(ra_k.residual(d)[mv] if ra_k is not None else np.full(rb[-1].size, np.nan))
            del ra_k
            release(k_after)
        del T, T_before, x
    if not xs:
        return None
    x = np.concatenate(xs)
    order = x_order(x)
    rb = np.concatenate(rb)
    out = {"variable": var, "label": label, "before": binned(x, rb, order=order), "before_model": before,
           "before_base": "refitted" if own_base else "without offset" if jd_before is not jd else "",
           "samples": "moving" if rows is None else "sliding",
           "rms_before": _rms(rb), "rms_after": None}
    ra = np.concatenate(ra) if ra else None
    if ra is not None and np.any(np.isfinite(ra)):
        aft = binned(x, ra, order=order)
        out["given"] = {"x": aft["x"], "after": aft["mean"], "before": None, "model": ext[0]}
        out["rms_after"] = _rms(ra)
    if "given" not in out:
        out["given"] = _given_binned(finding)
        if out["given"] is None:
            del out["given"]
    return out


def _given_binned(finding: dict) -> dict | None:
    """The finding's own binned residual after its extension (``binned: {x, after[, before]}``), or None."""
    given = finding.get("binned")
    if not (isinstance(given, dict) and given.get("x") is not None and given.get("after") is not None):
        return None
    try:
        return {"x": np.asarray(given["x"], float), "after": np.asarray(given["after"], float),
                "before": np.asarray(given["before"], float) if given.get("before") is not None else None,
                "model": None}
    except (TypeError, ValueError):
        return None


def _rms(r: np.ndarray) -> float | None:
    """RMS of the finite values of ``r`` (None without any)."""
    r = r[np.isfinite(r)]
    return float(np.sqrt(np.mean(r * r))) if r.size else None


# ---------------------------------------------------------------------------------------------------
# what the diagnosis found, tested and whether its model was adopted


def diagnosis_adoption(jd: dict) -> tuple[list[bool], str]:
    """For each diagnosis entry, whether the chosen model carries it (its ``model`` is the chosen model or
    one the chosen model extends), and when the diagnosis' model was not adopted, why (from
    ``selection.diagnosis_check``), else ""."""
    findings = [f if isinstance(f, dict) else {} for f in (jd.get("diagnosis") or [])]
    sel = str(jd.get("selected") or "")
    check = (jd.get("selection") or {}).get("diagnosis_check") or {}
    why = ""
    if isinstance(check, dict) and check.get("kept") and check.get("kept") != check.get("model"):
        why = (f"the diagnosis' model {check.get('model')} predicts the held-out torque worse (RMS "
               f"{_num(check.get('rms_heldout'))}) than {check.get('kept')} "
               f"({_num(check.get('rms_heldout_fit_choice'))}), which stays selected")
    out = []
    for f in findings:
        m = f.get("model")
        if isinstance(m, str) and m:
            out.append(sel == m or sel.startswith(m + "+"))
        else:
            out.append(not why)
    return out, why


def _num(v) -> str:
    v = pvalue(v)
    return "—" if v is None else f"{v:.4g}"


def _screened(sc) -> dict | None:
    """A tested entry's ``screened`` record as ``{stride, samples}`` (ints), or None when it has none."""
    if not isinstance(sc, dict):
        return None
    out = {}
    for k in ("stride", "samples"):
        try:
            out[k] = int(sc.get(k))
        except (TypeError, ValueError):
            out[k] = None
    return out


def diagnosis_tested(jd: dict) -> list[dict]:
    """Every candidate the diagnosis tested, per step (``selection.diagnosis.steps``): step, extension,
    rms_before, rms_after, gain, t, p, chosen (bool) and screened: None for a trial on all sliding samples,
    else ``{stride, samples}`` of the stride whose numbers the entry carries (a long log's candidate the
    screen found unable to pass, :mod:`frictid.diagnose.screen`)."""
    diag = (jd.get("selection") or {}).get("diagnosis")
    rows = []
    for k, step in enumerate((diag or {}).get("steps") or [] if isinstance(diag, dict) else []):
        if not isinstance(step, dict):
            continue
        for c in step.get("tested") or []:
            if isinstance(c, dict):
                rows.append({"step": k + 1, "extension": str(c.get("extension", "")),
                             "rms_before": pvalue(c.get("rms_before")), "rms_after": pvalue(c.get("rms_after")),
                             "gain": pvalue(c.get("gain")), "t": pvalue(c.get("t")), "p": pvalue(c.get("p")),
                             "chosen": c.get("extension") == step.get("chosen"),
                             "screened": _screened(c.get("screened"))})
    return rows


def clean_warnings(jname: str, warnings: list, n_findings: int, n_cycles: int) -> list[str]:
    """The fit's warnings of a joint as the report lists them under that joint: without a ``joint <name>:``
    prefix (the report says which joint), without the diagnosis' "findings are kept as evidence" when
    there are no findings, and without "duty cycles included" when the data have none."""
    out = []
    for w in warnings or []:
        w = str(w)
        for pre in (f"joint {jname}: ", f"log joint {jname}: "):
            while w.startswith(pre) or w.startswith("log " + pre):
                w = ("log " if w.startswith("log ") and pre.startswith("joint") else "") + w[w.index(pre) + len(pre):]
        if n_findings == 0 and "findings are kept as evidence" in w:
            continue
        if n_cycles == 0:
            w = w.replace(" (duty cycles included)", "")
        out.append(w)
    return out


def residual_stats(r: np.ndarray) -> dict:
    """Robust statistics of a residual [F]: median absolute, 95th percentile of the absolute value, RMS and
    the count of finite samples (the RMS alone is dominated by the spikes at reversals)."""
    a = np.abs(np.asarray(r, float))
    a = a[np.isfinite(a)]
    if not a.size:
        return {"median_abs": math.nan, "p95_abs": math.nan, "rms": math.nan, "n": 0}
    return {"median_abs": float(np.median(a)), "p95_abs": float(np.percentile(a, 95)),
            "rms": float(np.sqrt(np.mean(a * a))), "n": int(a.size)}
