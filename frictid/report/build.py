"""Assemble the HTML report: per joint a summary, the figures, the model table, the diagnosis and the
provenance, rendered by the jinja2 template ``templates/report.html`` into one self-contained file.

Entry points: :func:`build_report` (HTML as a string) and :func:`write_report` (atomically to a file).
The parameter file is the schema-1 dictionary of :mod:`frictid.io.params_load`; logs are
:class:`~frictid.data.JointLog` objects (re-read by the caller with the same ``--map``/``--units`` as the
fit). Sections that the data cannot support are still written, saying why they are empty.
"""
from __future__ import annotations

import datetime as _dt
import math
import re
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

import numpy as np

from frictid.data import JointLog, log_warnings
from frictid.parallel import Prefetch as _Prefetch, map_ordered, n_workers

from . import content as ct

#: Most logs drawn as separate timelines per joint (all logs still feed the other figures).
MAX_TIMELINES = 4

SECTIONS = (
    ("summary", "Summary"),
    ("timeline", "Segment timeline"),
    ("friction-map", "Friction-velocity map"),
    ("presliding", "Presliding"),
    ("thermal", "Thermal"),
    ("models", "Model comparison"),
    ("diagnosis", "Diagnosis"),
    ("provenance", "Provenance"),
)


# ---------------------------------------------------------------------------------------------------
# numbers as text


def fmt_num(v, digits: int = 4) -> str:
    """A number with ``digits`` significant digits ("—" when missing)."""
    if v is None:
        return "—"
    try:
        v = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(v):
        return "—"
    if v == 0:
        return "0"
    if abs(v) >= 1e6 or abs(v) < 1e-3:
        return f"{v:.{max(digits - 1, 1)}e}"
    return f"{v:.{digits}g}"


def fmt_pm(v, se) -> str:
    """``value ± stderr`` with the value rounded to the second significant digit of its error."""
    v = ct.pvalue(v)
    se = ct.pvalue(se)
    if v is None:
        return "—"
    if se is None or se <= 0:
        return fmt_num(v)
    if abs(v) >= 1e6 or (abs(v) < 1e-3 and v != 0) or se >= 1e6:
        return f"{v:.3e} ± {se:.1e}"
    dec = max(0, 1 - int(math.floor(math.log10(se))))
    dec = min(dec, 8)
    return f"{v:.{dec}f} ± {se:.{dec}f}"


def slug(s: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", str(s)).strip("-") or "joint"


def param_rows(params: dict) -> list[dict]:
    """Table rows of a ``params`` mapping: name, value ± stderr, unit, identifiable, reason, fixed."""
    rows = []
    for name, p in (params or {}).items():
        if not isinstance(p, dict):
            p = {"value": p}
        rows.append({"name": name, "value": fmt_pm(p.get("value"), p.get("stderr")), "unit": p.get("unit", ""),
                     "identifiable": bool(p.get("identifiable", True)), "fixed": bool(p.get("fixed", False)),
                     "reason": p.get("reason", "") or "", "source": p.get("source", "") or ""})
    return rows


def rigid_rows(jd: dict) -> list[dict]:
    """Inertia, gravity and offset rows."""
    params = {}
    if isinstance(jd.get("inertia"), dict):
        params["J (inertia)"] = jd["inertia"]
    for k, p in (jd.get("gravity") or {}).items():
        if isinstance(p, dict):
            params[f"{k} (gravity)"] = p
    if isinstance(jd.get("offset"), dict):
        params["offset"] = jd["offset"]
    return param_rows(params)


def _compact_params(params: dict) -> str:
    parts = []
    for name, p in (params or {}).items():
        if not isinstance(p, dict):
            continue
        flag = "" if p.get("identifiable", True) or p.get("fixed") else " (not identifiable)"
        fixed = " (fixed)" if p.get("fixed") else ""
        unit = "" if p.get("unit") in ("1", None) else p.get("unit")
        parts.append(f"{name} = {fmt_pm(p.get('value'), p.get('stderr'))} {unit}".strip() + fixed + flag)
    return "; ".join(parts)


def model_rows(jd: dict) -> list[dict]:
    """Model comparison rows, in the order of the fit's ranking, then the others."""
    models = jd.get("models") or {}
    ranking = [r.get("model") for r in ((jd.get("selection") or {}).get("ranking") or []) if isinstance(r, dict)]
    order = [m for m in ranking if m in models] + [m for m in models if m not in ranking]
    rows = []
    for name in order:
        md = models[name]
        if not isinstance(md, dict):
            continue
        met = md.get("metrics") or {}
        extras = []
        for k in ("rms_presliding", "rms_presliding_static", "rms_presliding_heldout", "heldout_gain"):
            if met.get(k) is not None:
                extras.append(f"{k} = {fmt_num(met[k])}")
        tc = md.get("time_constant")
        if isinstance(tc, dict) and tc.get("value") is not None:
            extras.append(f"time constant = {fmt_pm(tc.get('value'), tc.get('stderr'))} {tc.get('unit', 's')}")
        params = md.get("params") or {}
        ident = all(p.get("identifiable", True) or p.get("fixed") for p in params.values() if isinstance(p, dict))
        basis = ("sliding samples (diagnosis; held-out by segment groups)" if "+" in name or "base" in md
                 or str(md.get("method", "")).startswith("diagnosis") else
                 "duty cycles" if name.startswith("thermal") else
                 "all moving samples" if name == "polynomial_ls" else "plateau points")
        rows.append({"name": name, "selected": name == jd.get("selected"), "map": md.get("map", ""),
                     "method": md.get("method", ""), "rms": fmt_num(met.get("rms")),
                     "rms_heldout": fmt_num(met.get("rms_heldout")), "aic": fmt_num(met.get("aic"), 5),
                     "n": met.get("n", "—"), "k": met.get("k", len(params)), "params": _compact_params(params),
                     "identifiable": ident, "extras": "; ".join(extras), "basis": basis,
                     "notes": list(md.get("notes") or [])})
    return rows


def _round(v, digits: int = 7):
    return None if v is None else float(f"{v:.{digits}g}")


def yaml_snippet(jname: str, jd: dict) -> str:
    """A copyable YAML block of the chosen model: values with units, and the rigid-body terms."""
    import yaml

    sel = jd.get("selected")
    md = (jd.get("models") or {}).get(sel) or {}
    body: dict[str, Any] = {"model": sel, "map": md.get("map", sel)}
    if md.get("static_model"):
        body["static_model"] = md["static_model"]
    body["params"] = {n: _round(ct.pvalue(p)) for n, p in (md.get("params") or {}).items()}
    body["units"] = {n: p.get("unit", "") for n, p in (md.get("params") or {}).items() if isinstance(p, dict)}
    rig = {}
    if ct.pvalue(jd.get("inertia")) is not None:
        rig["J"] = _round(ct.pvalue(jd["inertia"]))
    for k, p in (jd.get("gravity") or {}).items():
        if k != "amplitude" and ct.pvalue(p) is not None:
            rig[k] = _round(ct.pvalue(p))
    if ct.pvalue(jd.get("offset")) is not None:
        rig["offset"] = _round(ct.pvalue(jd["offset"]))
    if rig:
        body["rigid_body"] = rig
    return yaml.safe_dump({"joints": {str(jname): body}}, sort_keys=False, default_flow_style=False, width=100,
                          allow_unicode=True)


# ---------------------------------------------------------------------------------------------------
# one joint


@dataclass
class Section:
    """One part of a joint's report: present with figures and text, or absent with the reason."""

    key: str
    title: str
    present: bool = True
    why: str = ""
    figures: list = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    data: dict = field(default_factory=dict)


def _coverage_lines(cov: dict, units: dict) -> list[str]:
    lines = []
    wu = units.get("qd", "rad/s")
    for key, name in (("pos", "w > 0"), ("neg", "w < 0")):
        r = cov.get(key)
        if r:
            lines.append(f"Velocity {name}: {fmt_num(r[0], 3)} to {fmt_num(r[1], 3)} {wu} over {r[2]} plateau points")
        elif cov.get("from_logs"):
            lines.append(f"Velocity {name}: no plateau points")
    src = "in the logs" if cov.get("from_logs") else "in the parameter file (no logs given)"
    lines.append(f"Segments {src}: {cov['plateaus']} constant-velocity plateaus ({cov['plateaus_used']} usable as "
                 f"points), {cov['ramps']} presliding ramps, {cov['steps']} steps, {cov['cycles']} duty cycles")
    if cov.get("duration") is not None:
        lines.append(f"Log duration {fmt_num(cov['duration'], 4)} s, {cov['samples']} samples")
    return lines


def _not_identified(jd: dict) -> list[dict]:
    out, seen = [], set()
    for item in jd.get("not_identified") or []:
        if isinstance(item, dict):
            key = (item.get("what"), item.get("reason"))
            if key not in seen:
                seen.add(key)
                out.append({"what": str(item.get("what", "")), "reason": str(item.get("reason", ""))})
    sel = jd.get("selected")
    md = (jd.get("models") or {}).get(sel) or {}
    for n, p in (md.get("params") or {}).items():
        if isinstance(p, dict) and not p.get("identifiable", True) and not p.get("fixed"):
            key = (f"{sel}.{n}", p.get("reason", ""))
            if key not in seen and (f"{sel}.{n}", p.get("reason")) not in seen:
                seen.add(key)
                out.append({"what": f"{sel}.{n}", "reason": str(p.get("reason", "")) or "not identifiable"})
    return out


def _units(jd: dict, datas: list[ct.LogData]) -> dict:
    if datas:
        return dict(datas[0].log.units)
    u = dict(jd.get("units") or {})
    if jd.get("axis") == "linear":
        base = {"q": "m", "qd": "m/s", "tau": "N"}
    else:
        base = {"q": "rad", "qd": "rad/s", "tau": "N m"}
    base.update({k: v for k, v in u.items() if k in base and v})
    return base


def joint_report(jname: str, jd: dict, datas: list[ct.LogData], timings: dict | None = None) -> dict:
    """The template context of one joint: summary, sections with their figures, tables, snippet."""
    from . import figures as fg

    timings = timings if timings is not None else {}
    jid = "j-" + slug(jname)
    units = _units(jd, datas)
    models = jd.get("models") or {}
    sel = jd.get("selected")
    selmd = models.get(sel) if sel else None
    secs: dict[str, Section] = {k: Section(k, t) for k, t in SECTIONS}
    no_logs = ("No log was given for this joint: this part is drawn from the logs "
               "(frictid report PARAMS.yaml LOG... with the --map/--units the fit used).")

    def salt(part, i=0):
        return f"{jid}-{part}-{i}"

    # plateau points and coverage
    t0 = time.process_time()
    pl = ct.plateaus(datas) if datas else ct.plateaus([])
    cov = ct.coverage(datas, pl, jd)
    timings["plateaus"] = timings.get("plateaus", 0.0) + time.process_time() - t0

    # ---- summary
    s = secs["summary"]
    s.data = {
        "selected": sel, "method": (selmd or {}).get("method", ""), "map": (selmd or {}).get("map", ""),
        "selection": _selection_text(jd), "key_params": param_rows((selmd or {}).get("params") or {}),
        "rigid": rigid_rows(jd), "coverage": _coverage_lines(cov, units), "not_identified": _not_identified(jd),
        "warnings": [str(w) for w in (jd.get("warnings") or [])], "notes": list((selmd or {}).get("notes") or []),
    }
    if sel is None:
        s.notes.append("No model was chosen for this joint" + (
            f": {(jd.get('selection') or {}).get('reason')}" if (jd.get("selection") or {}).get("reason") else "."))

    # ---- timeline
    s = secs["timeline"]
    t0 = time.process_time()
    if not datas:
        s.present, s.why = False, no_logs
    else:
        for i, d in enumerate(datas[:MAX_TIMELINES]):
            lg = d.log
            segs = [(x.kind, float(lg.t[x.i0]), float(lg.t[x.i1 - 1])) for x in d.segments]
            title = f"Joint {jname}: {d.label or 'log'}"
            s.figures.append(fg.timeline(lg.t, lg.q, d.w, lg.tau, segs, units, title, salt("timeline", i)))
        if len(datas) > MAX_TIMELINES:
            s.notes.append(f"{len(datas) - MAX_TIMELINES} more logs of this joint are not drawn here "
                           "(they enter every other figure).")
        if not any(d.segments for d in datas):
            s.notes.append("No segment was found in the logs: nothing is shaded.")
        if any(d.log.q is None for d in datas):
            s.notes.append("A log without position: its position panel is left out.")
    timings["timeline"] = timings.get("timeline", 0.0) + time.process_time() - t0

    # ---- friction map
    s = secs["friction-map"]
    t0 = time.process_time()
    grids = ct.velocity_grids(pl, datas)
    if not datas and not ct.static_models(jd):
        s.present, s.why = False, ("No static friction model in the parameter file and no log given: the map "
                                   "needs constant-velocity plateaus at several velocities of both signs "
                                   "(recipes/constant_velocity_sweep.yaml).")
    else:
        curves = ct.model_curves(jd, grids)
        if not curves and not len(pl):
            s.present, s.why = False, ("No constant-velocity plateau in the logs and no static model in the "
                                       "parameter file: the map needs plateaus at several constant velocities "
                                       "of both signs (recipes/constant_velocity_sweep.yaml).")
        else:
            s.figures.append(fg.friction_map(pl, curves, grids, units, salt("map")))
            if not datas:
                s.notes.append("No log given: the plateau points are not drawn, and the velocity axis spans "
                               f"±{fmt_num(grids['lin'][-1], 3)} {units['qd']} by default.")
            elif not len(pl):
                s.notes.append("No usable constant-velocity plateau in the logs: only the model curves are drawn.")
            if not curves:
                s.notes.append("No static model could be evaluated: only the plateau points are drawn.")
            for side, name in (("pos", "positive"), ("neg", "negative")):
                if datas and len(pl) and cov.get(side) is None:
                    s.notes.append(f"No {name}-velocity plateau: the {name} branch of every model is an "
                                   "extrapolation.")
            s.data["n_points"] = len(pl)
            s.data["n_models"] = len(curves)
    timings["map"] = timings.get("map", 0.0) + time.process_time() - t0

    # ---- presliding
    s = secs["presliding"]
    t0 = time.process_time()
    lp = ct.lugre_params(jd)
    s.data["sigma"] = []
    if lp:
        s.data["sigma"] = param_rows({k: v for k, v in (models["lugre"].get("params") or {}).items()
                                      if k in ("sigma0", "sigma1")})
    if not datas:
        s.present = False
        s.why = no_logs + (" The identified sigma0 / sigma1 are listed in the model table." if lp else "")
    else:
        ramps, rinfo = ct.ramp_curves(datas, jd)
        steps, sinfo = ct.step_curves(datas, jd)
        if not ramps and not steps:
            s.present = False
            s.why = ("No presliding ramp and no torque step in the logs: sigma0 needs slow open-loop torque ramps "
                     "kept below break-away (recipes/ramp_presliding.yaml), sigma1 torque steps "
                     "(recipes/torque_steps.yaml).")
        else:
            s0, s1 = (lp or {}).get("sigma0") or {}, (lp or {}).get("sigma1") or {}
            lab0 = f"LuGre, sigma0 = {fmt_pm(s0.get('value'), s0.get('stderr'))} {s0.get('unit', '')}"
            lab1 = f"LuGre, sigma1 = {fmt_pm(s1.get('value'), s1.get('stderr'))} {s1.get('unit', '')}"
            s.figures.append(fg.presliding(ramps, steps, units, lab0, lab1, salt("presliding")))
            if rinfo["n_total"] > len(ramps):
                s.notes.append(f"{len(ramps)} of {rinfo['n_total']} ramps drawn, spread over the log.")
            if sinfo["n_total"] > len(steps):
                s.notes.append(f"{len(steps)} of {sinfo['n_total']} steps drawn, spread over the log.")
            if ramps and not any(r["model"] is not None for r in ramps):
                s.notes.append("No model curve on the ramps: " + (
                    f"sigma0 is not identified ({s0.get('reason') or 'no value'})." if lp else
                    "the parameter file has no LuGre model."))
            if steps and not any(x["model"] is not None for x in steps):
                s.notes.append("No simulated transient: " + (
                    f"sigma1 is not identified ({s1.get('reason') or 'no value'})." if lp and s1.get("value") is None
                    else "the inertia J is not known." if lp and not sinfo.get("J") else
                    "sigma0 is not identified." if lp else "the parameter file has no LuGre model."))
            if not ramps:
                s.notes.append("No presliding ramp in the logs (sigma0 needs recipes/ramp_presliding.yaml).")
            if not steps:
                s.notes.append("No torque step in the logs (sigma1 needs recipes/torque_steps.yaml).")
    timings["presliding"] = timings.get("presliding", 0.0) + time.process_time() - t0

    # ---- thermal
    s = secs["thermal"]
    t0 = time.process_time()
    vmin = ct.min_speed(datas)  # the speed below which a sample counts as at rest (thermal, diagnosis)
    th_reasons = [x["reason"] for x in _not_identified(jd) if x["what"] in ct.THERMAL_LAWS]
    th_models = [n for n in models if n in ct.THERMAL_LAWS]
    s.data["models"] = [{"name": n, "params": param_rows(models[n].get("params") or {}),
                         "notes": list(models[n].get("notes") or []),
                         "time_constant": models[n].get("time_constant")} for n in th_models]
    if not datas:
        s.present = False
        s.why = no_logs + (" The thermal parameters are listed below." if th_models else
                           (" The fit says: " + "; ".join(sorted(set(th_reasons))) + "." if th_reasons else ""))
    else:
        cycles, tmods, tinfo = ct.thermal_cycles(datas, jd, vmin=vmin)
        if not cycles:
            s.present = False
            s.why = ("No duty cycle in the logs: the thermal models need repeated cycles of motion and rest "
                     "from a cold start, with a temp_env channel (recipes/duty_cycle.yaml)."
                     + (" The fit says: " + "; ".join(sorted(set(th_reasons))) + "." if th_reasons else ""))
        else:
            s.figures.append(fg.thermal(cycles, tmods, units, salt("thermal")))
            s.notes.append(f"{len(cycles)} cycles, from {tinfo['source']}.")
            if not tmods:
                s.notes.append("No thermal model in the parameter file"
                               + (": " + "; ".join(sorted(set(th_reasons))) if th_reasons else "")
                               + ". Only the measured friction per cycle is drawn.")
            for m in tmods:
                if not np.any(np.isfinite(m["T"])):
                    s.notes.append(f"{m['name']}: the parameter file gives no per-cycle temperature "
                                   "(cycle_temperature), so its curve is not drawn.")
    timings["thermal"] = timings.get("thermal", 0.0) + time.process_time() - t0

    # ---- models
    s = secs["models"]
    s.data["rows"] = model_rows(jd)
    from frictid.identify.select import NOT_HELDOUT
    s.data["heldout_skipped"] = [r["name"] for r in s.data["rows"] if NOT_HELDOUT in r["notes"]]
    if not s.data["rows"]:
        s.present, s.why = False, "No model was fitted for this joint."
    sel_rec = jd.get("selection") or {}
    s.data["rule"] = sel_rec.get("rule", "")

    # ---- diagnosis and replay
    s = secs["diagnosis"]
    t0 = time.process_time()
    entries = [f if isinstance(f, dict) else {"cause": str(f)} for f in (jd.get("diagnosis") or [])]
    befores = ct.diagnosis_befores(jd, entries)
    # the models each finding replays, and from finding i on (a replay is kept only while one needs it:
    # each is three arrays of the log's length, and the first joint of a worker pays for fresh memory)
    later = [set()]
    for f, before in zip(reversed(entries), reversed(befores)):
        later.insert(0, later[0] | ct.replayed_models(jd, f, before))
    cache: dict = {}
    replays, replayed = [], False
    for k, d in enumerate(datas):
        r = ct.replay_log(d, jname, jd, closed=k < MAX_TIMELINES, vmin=vmin)
        if r is None:
            continue
        replayed = replayed or r.how == "replay"
        if k < MAX_TIMELINES:
            res_ = r.residual(d)
            rms = float(np.sqrt(np.nanmean(res_ ** 2)))
            del res_
            title = (f"Replay of {r.model} along {d.label or 'the log'}: torque residual RMS {fmt_num(rms, 3)} "
                     f"{units['tau']}")
            replays.append(fg.replay(d.log.t, d.log.tau, r.tau_model, units, title, salt("replay", k),
                                     q=d.log.q, q_model=r.q_model))
            if r.how == "static":
                s.notes.append(f"{d.label or 'log'}: replayed with the steady-state map of {r.model} only "
                               f"(J a + G(q) + offset + F_ss(w)); samples slower than {fmt_num(vmin, 3)} "
                               f"{units['qd']} are left out, as a static map cannot tell the friction at rest.")
            for n in r.notes:
                s.notes.append(f"{d.label or 'log'}: {n}")
        r.q_model = None  # drawn
        if sel in later[0]:
            cache[(sel, k, 0)] = r
        r = None  # not held past the loop
    ct.drop_reference_channels(datas)  # the closed loops have run
    findings = []
    for i, (f, prev) in enumerate(zip(entries, befores)):
        row = {"cause": f.get("cause", ""), "evidence": f.get("evidence", ""),
               "statistic": f.get("statistic", ""), "extension": f.get("extension", ""),
               "model": f.get("model", ""), "before": prev,
               "rms_before": fmt_num(f.get("rms_before")), "rms_after": fmt_num(f.get("rms_after")),
               "gain": _fmt_gain(f.get("gain")), "heldout": _heldout_text(f.get("heldout")), "figure": None,
               "note": ""}
        if isinstance(row["statistic"], dict):
            row["statistic"] = "; ".join(f"{k} = {fmt_num(v) if isinstance(v, (int, float)) else v}"
                                         for k, v in row["statistic"].items())
        if isinstance(row["extension"], dict):
            ext = row["extension"]
            row["extension"] = " ".join(x for x in (str(ext.get("name") or ext.get("model") or ""),
                                                    _compact_params(ext.get("params") or {})) if x) or str(ext)
        if not ct.on_sliding_samples(f):
            row["note"] = ("Judged on the presliding ramps, not along the sliding samples: see the Presliding "
                           "part (torque against displacement with LuGre's sigma0).")
        elif datas:
            res = ct.diagnosis_residuals(datas, jname, jd, f, before=prev, cache=cache, vmin=vmin,
                                         keep=later[i + 1])
            if res is not None:
                row["figure"] = fg.diagnosis(f, res, units, salt("diagnosis", i))
                if res.get("given") is None:
                    row["note"] = ("Only the residual before the extension is drawn: the parameter file holds "
                                   "neither the extended model nor the binned residual after it.")
            else:
                row["note"] = "No residual drawn: the model cannot be run along the log."
        else:
            row["note"] = "No residual drawn: no log given."
        findings.append(row)
    cache.clear()
    s.data["findings"] = findings
    s.figures = replays
    if replays and replayed:
        s.notes.append("Replay: the chosen model run along the measured motion by frictid.replay "
                       "(tau_model = J a + G(q) + offset + F_model, with the LuGre and thermal states and "
                       "Karnopp's stick law at rest); in closed loop, the position simulated with the log's "
                       "references and controller.")
    if not findings:
        s.notes.append("The parameter file has no diagnosis entries: the diagnosis step has not run on this "
                       "identification, or found nothing to add.")
    if datas and not replays:
        s.notes.append("No replay: the chosen model cannot be run along the log.")
    if not findings and not replays:
        s.present = False
        s.why = " ".join(s.notes) + ("" if datas else " " + no_logs)
        s.notes = []
    timings["diagnosis"] = timings.get("diagnosis", 0.0) + time.process_time() - t0

    # ---- provenance (per joint: the snippet)
    s = secs["provenance"]
    if sel:
        s.data["yaml"] = yaml_snippet(jname, jd)
    else:
        s.data["yaml"] = ""
        s.notes.append("No model was chosen: there is no snippet to copy.")
    s.data["logs"] = [{"label": d.label, "sha256": d.sha256, "rows": d.log.n,
                       "source": d.source_index} for d in datas]

    key = s_summary_key(secs["summary"].data["key_params"])
    return {"name": jname, "id": jid, "units": units, "sections": [secs[k] for k, _ in SECTIONS],
            "section": secs, "selected": sel, "key": key, "n_findings": len(findings),
            "n_not_identified": len(secs["summary"].data["not_identified"]),
            "rms_heldout": fmt_num(((selmd or {}).get("metrics") or {}).get("rms_heldout"))}


def s_summary_key(rows: list[dict], most: int = 4) -> list[str]:
    """Up to ``most`` parameters of the chosen model as short text for the index."""
    return [f"{r['name']} = {r['value']} {r['unit']}".strip() for r in rows[:most]]


def _heldout_text(h) -> str:
    """How a finding's gain was measured: held-out (with the split) or in-sample."""
    if h is None:
        return ""
    if isinstance(h, dict):
        return "held-out" + (f" ({h['split']})" if h.get("split") else "")
    return "held-out" if h else "in-sample"


def _fmt_gain(g) -> str:
    v = ct.pvalue(g)
    if v is None:
        return "—"
    return f"{100 * v:.1f} %" if abs(v) <= 1.5 else fmt_num(v)


def _selection_text(jd: dict) -> str:
    rec = jd.get("selection") or {}
    parts = []
    if rec.get("rule"):
        parts.append(f"Rule: {rec['rule']}.")
    if rec.get("best_heldout"):
        parts.append(f"Lowest held-out RMS: {rec['best_heldout']}.")
    if isinstance(rec.get("lugre"), str):
        parts.append(f"LuGre: {rec['lugre']}.")
    if rec.get("reason"):
        parts.append(str(rec["reason"]))
    return " ".join(parts)


# ---------------------------------------------------------------------------------------------------
# the whole report


def _environment():
    import jinja2

    env = jinja2.Environment(loader=jinja2.PackageLoader("frictid.report", "templates"),
                             autoescape=jinja2.select_autoescape(["html"]), trim_blocks=True, lstrip_blocks=True,
                             undefined=jinja2.StrictUndefined)
    env.filters["num"] = fmt_num
    return env


@dataclass
class DeferredLogs:
    """Logs of one joint that the process drawing the joint reads itself, just before drawing it (a block
    of rows of a file, :func:`frictid.io.logs.joint_row_blocks`): the parent never holds them, and the
    workers read in parallel. ``load()`` returns the logs or raises
    :class:`~frictid.errors.LogFormatError`; ``joint`` and ``source`` (the file, as the logs will name it)
    say where they belong before they are read."""

    joint: str
    source: str
    load: Callable[[], list[JointLog]]


@dataclass
class _Part:
    """What a worker sends back for one joint: the template context, and per log given (a
    :class:`JointLog` or :class:`DeferredLogs`) its rows, the parameter file's source it matches, whether
    its segments came from the parameter file and its warnings; or the problems of the logs it read."""

    ctx: dict | None = None
    rows: list[int] = field(default_factory=list)
    source_index: list[int | None] = field(default_factory=list)
    recorded: list[bool] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    problems: list[tuple[str, list[str]]] = field(default_factory=list)


def _joint_part(jn: str, jd: dict, given: list, sources: list[dict], hashes: dict, segmenter,
                differentiate) -> _Part:
    """One joint of the report from the logs ``given`` for it (:class:`JointLog` or :class:`DeferredLogs`,
    read here). The joint's warnings gain those of its logs."""
    from frictid.errors import LogFormatError

    out = _Part()
    t0 = time.process_time()
    jlogs: list[JointLog] = []
    first: list[int] = []  # index in jlogs of each given item's first log
    own: set[int] = set()  # ids of the logs read here (the others are the caller's)
    for item in given:
        first.append(len(jlogs))
        if not isinstance(item, DeferredLogs):
            jlogs.append(item)
            continue
        try:
            got = item.load()
        except LogFormatError as exc:
            out.problems.append((exc.path, exc.problems))
            continue
        jlogs.extend(got)
        own.update(id(lg) for lg in got)
    if out.problems:
        return out
    first.append(len(jlogs))
    out.warnings = log_warnings(jlogs)
    if out.warnings:
        jd = {**jd, "warnings": [*(jd.get("warnings") or []), *(f"log {w}" for w in out.warnings)]}
    timings = out.timings
    timings["read"] = time.process_time() - t0
    t0 = time.process_time()
    datas, recorded = [], []
    for lg in jlogs:
        sha = hashes.get(lg.source or "")
        segs = ct.recorded_segments(lg, jd, sources, sha)
        recorded.append(segs is not None)
        d = ct.prepare_log(lg, jd, segmenter, differentiate, segments=segs,
                           scales=ct.recorded_scales(lg, jd, sources, sha))
        d.sha256 = hashes.get(d.label)
        d.own = id(lg) in own
        datas.append(d)
    ct.match_sources(datas, sources)
    timings["segments"] = time.process_time() - t0
    out.ctx = joint_report(jn, jd, datas, timings)
    for a, b in zip(first[:-1], first[1:]):
        out.rows.append(sum(lg.n for lg in jlogs[a:b]))
        out.source_index.append(datas[a].source_index if b > a else None)
        out.recorded.append(recorded[a] if b > a else False)
    return out


def preload() -> None:
    """Import what building a joint needs (matplotlib for the figures, scipy.signal for the derivatives,
    the replay and the presliding simulation) once, ahead of forking the workers that inherit it."""
    from . import figures as fg

    fg.preload()
    import scipy.signal  # noqa: F401

    import frictid.identify.pipeline  # noqa: F401
    import frictid.identify.presliding  # noqa: F401
    import frictid.result  # noqa: F401
    import frictid.plant.kernel  # noqa: F401
    import frictid.replay  # noqa: F401


class Prefetch(_Prefetch):
    """What a report needs and does not depend on the logs' contents, started in background threads while
    the caller reads the logs: the SHA-256 of every file and the imports of :func:`preload`
    (:class:`frictid.parallel.Prefetch`): ``pre = Prefetch(paths)``, read the logs, then
    ``build_report(params, logs, hashes=pre.hashes())``.
    """

    def __init__(self, paths: Iterable[str]):
        from frictid.io.logs import file_sha256  # here, as in build_report: importing the report loads no pyarrow

        super().__init__(paths, file_sha256, preload)


def build_report(params: dict, logs: Iterable[JointLog] | None = None, *, params_path: str = "",
                 command: str = "", segmenter: Callable | None = None, differentiate: Callable | None = None,
                 generated: str | None = None, timings: dict | None = None, jobs: int = 0,
                 hashes: dict[str, str | None] | None = None, log_warnings_out: list[str] | None = None) -> str:
    """The report as one HTML string.

    params : the parameter file as a dictionary (schema 1). logs : the joint logs to draw (any joints; logs
    of joints not in the file are listed and skipped): :class:`JointLog` objects, or :class:`DeferredLogs`
    that the worker drawing their joint reads (the problems of every joint's logs are raised together, as
    one :class:`~frictid.errors.LogFormatError`, and nothing is returned). Each joint's warnings gain those
    of its logs; ``log_warnings_out``, a list, receives them all. params_path, command : shown under
    provenance.
    segmenter(log) -> segments and differentiate(log) -> (w, a) default to :func:`frictid.segments.find_segments`
    and :func:`frictid.segments.derivatives` (the fit's). The segments the fit recorded in the parameter
    file (``segment_list``) are used instead of ``segmenter`` for a log whose file has the SHA-256 of that
    source and the same number of rows. generated : a timestamp text (default: now, UTC). timings : a dict
    that receives the CPU seconds spent per part (summed over the workers). jobs : joints built at once in
    forked worker processes (0: one per available core; 1: one after another in this process); each
    joint's arrays are freed before the worker takes the next. The HTML does not depend on it. hashes :
    the SHA-256 of log files already computed (path -> hash, e.g. :meth:`Prefetch.hashes`); the others
    are computed here.
    """
    from frictid import __version__
    from frictid.errors import combined_log_error
    from frictid.io.logs import file_sha256

    timings = timings if timings is not None else {}
    logs = list(logs or [])
    if logs and (segmenter is None or differentiate is None):
        from frictid import segments as _seg
        segmenter = segmenter or _seg.find_segments
        differentiate = differentiate or _seg.derivatives
    joints = params.get("joints") or {}
    sources = [s for s in (params.get("sources") or []) if isinstance(s, dict)]
    hashes = dict(hashes or {})
    notes = []
    by_joint: dict[str, list[JointLog | DeferredLogs]] = {}
    t0 = time.process_time()
    for lg in logs:
        if lg.source and lg.source not in hashes:
            hashes[lg.source] = file_sha256(lg.source)
        if str(lg.joint) in joints:
            by_joint.setdefault(str(lg.joint), []).append(lg)
    timings["hash"] = time.process_time() - t0
    skipped = sorted({str(lg.joint) for lg in logs} - set(map(str, joints)))
    if skipped:
        notes.append(f"Logs of joint(s) {', '.join(skipped)} are not drawn: the parameter file has no entry for them.")
    # joints in forked workers (one per core); in each, one joint at a time: its derivatives, friction
    # torque, replays and figures are freed before the next
    parts = [(str(jn), jd) for jn, jd in joints.items() if isinstance(jd, dict)]
    names = [jn for jn, _ in parts]

    def one(part):
        jn, jd = part
        return _joint_part(jn, jd, by_joint.get(jn, []), sources, hashes, segmenter, differentiate)

    workers = n_workers(jobs, sum(1 for jn in names if by_joint.get(jn)))
    if workers > 1:
        preload()  # imported once here, inherited by every worker
    results = map_ordered(one, parts, workers)
    bad = combined_log_error(p for r in results for p in r.problems)  # every joint's, together
    if bad is not None:
        raise bad
    jctx = []
    got: dict[int, tuple[int, int | None, bool]] = {}  # id of a given log -> rows, source index, recorded
    for jn, r in zip(names, results):
        jctx.append(r.ctx)
        for item, n, si, rec in zip(by_joint.get(jn, []), r.rows, r.source_index, r.recorded):
            got[id(item)] = (n, si, rec)
        if log_warnings_out is not None:
            log_warnings_out.extend(r.warnings)
        for key, v in r.timings.items():
            timings[key] = timings.get(key, 0.0) + v
    inputs = []
    for lg in logs:
        label = lg.source or "<memory>"
        if any(i["path"] == label and i["joint"] == str(lg.joint) for i in inputs):
            continue
        n, si, rec = got.get(id(lg), (getattr(lg, "n", None), None, False))
        inputs.append({"path": label, "joint": str(lg.joint), "rows": n, "sha256": hashes.get(label),
                       "source": si, "segments": "the fit's" if rec else "found again"})
    for i in inputs:
        if i["source"] is None and str(i["joint"]) in joints and sources:
            notes.append(f"{i['path']}: not among the files the fit read (different hash and name); its curves are "
                         "compared with parameters identified from other data.")
    t0 = time.process_time()
    env = _environment()
    html = env.get_template("report.html").render(
        title=params_path or "parameter file", params_path=params_path, joints=jctx, sources=sources,
        inputs=inputs, notes=notes, file_version=str(params.get("frictid", "")), version=__version__,
        schema=params.get("schema"), settings=params.get("settings") or {}, command=command,
        generated=generated or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        has_logs=bool(logs))
    timings["html"] = time.process_time() - t0
    return html


def write_report(path: str, params: dict, logs: Iterable[JointLog] | None = None, **kw) -> int:
    """Build the report and write it atomically to ``path`` (``-`` for standard output). Returns bytes."""
    from frictid.io.atomic import atomic_open

    html = build_report(params, logs, **kw)
    with atomic_open(path, "w") as fh:
        fh.write(html)
    return len(html.encode("utf-8"))
