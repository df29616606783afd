"""Assemble the HTML report: per joint a summary, the figures, the model table, the diagnosis and the
provenance, rendered by the jinja2 template ``templates/report.html`` into one self-contained file.

Entry points: :func:`build_report` (HTML as a string) and :func:`write_report` (atomically to a file).
The parameter file is the schema-1 dictionary of :mod:`frictid.io.params_load`; logs are
:class:`~frictid.data.JointLog` objects (re-read by the caller with the same ``--map``/``--units`` as the
fit). Sections that the data cannot support are still written, saying why they are empty.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import math
import re
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

import jinja2
import numpy as np
import yaml

from frictid.version import __version__
from frictid import segments as _seg
from frictid.data import JointLog, log_warnings
from frictid.errors import LogFormatError, combined_log_error
from frictid.identify.select import NOT_HELDOUT
from frictid.io.atomic import atomic_open
from frictid.io.logs import file_sha256
from frictid.parallel import Prefetch as _Prefetch, map_ordered, n_workers

from . import content as ct
from . import figures as fg  # matplotlib itself is imported by the figure functions only
from .robot import robot_page

#: Most logs drawn as separate timelines per joint (all logs still feed the other figures).
MAX_TIMELINES = 4
#: Why a part drawn from the logs is empty when the joint has no log.
NO_LOGS = ("No log was given for this joint: this part is drawn from the logs "
           "(frictid report PARAMS.yaml LOG... with the --map/--units the fit used).")

SECTIONS = (
    ("summary", "Summary"),
    ("timeline", "Segment timeline"),
    ("friction-map", "Friction-velocity map"),
    ("presliding", "Presliding"),
    ("thermal", "Thermal"),
    ("models", "Model comparison"),
    ("diagnosis", "Diagnosis"),
    ("provenance", "The model as YAML, and the logs drawn"),
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


def param_status(p: dict, base: dict | None = None, base_name: str = "") -> tuple[str, str]:
    """The verdict of a parameter entry and its reason, one of: ``identified`` (an estimate with its
    standard error), ``held`` (held at a stated value: ``fixed``, or an extended model's shape parameter
    held at the value of its base model ``base``), ``not
    identifiable`` (with the fit's reason) and ``no s.e.`` (a value without a standard error, with where it
    came from when the file says: the log metadata, another stage of the fit)."""
    v, se = ct.pvalue(p.get("value")), ct.pvalue(p.get("stderr"))
    if p.get("fixed"):
        return "held", str(p.get("reason") or "held fixed")
    if not p.get("identifiable", True):
        return "not identifiable", str(p.get("reason") or "the data cannot pin it down")
    if v is not None and (se is None or se <= 1e-9 * abs(v)):
        bv = ct.pvalue((base or {}).get("value")) if isinstance(base, dict) else None
        if bv is not None and abs(bv - v) <= 1e-9 * max(abs(v), 1e-300):
            return "held", f"at the value of the base model {base_name}" if base_name else "at the base model's value"
        if p.get("source") and se is None:
            return "no s.e.", f"from {p['source']}"
        return "no s.e.", "the parameter file gives no standard error"
    return "identified", ""


def param_rows(params: dict, base_params: dict | None = None, base_name: str = "") -> list[dict]:
    """Table rows of a ``params`` mapping: name, value ± stderr, unit, status (:func:`param_status`) and
    reason. ``base_params``: the parameters of the base model of an extended model."""
    rows = []
    for name, p in (params or {}).items():
        if not isinstance(p, dict):
            p = {"value": p}
        base = base_params or {}
        status, reason = param_status(p, base.get(name, base.get(re.sub(r"_(pos|neg)$", "", name))), base_name)
        se = p.get("stderr") if status == "identified" or status == "not identifiable" else None
        rows.append({"name": name, "value": fmt_pm(p.get("value"), se), "unit": p.get("unit", ""),
                     "status": status, "reason": reason, "source": p.get("source", "") or ""})
    return rows


def model_param_rows(jd: dict, name: str | None) -> list[dict]:
    """:func:`param_rows` of model ``name`` of a joint entry, judged against its base model."""
    models = jd.get("models") or {}
    md = models.get(name) or {}
    base = md.get("base")
    bmd = models.get(base) if isinstance(base, str) else None
    return param_rows(md.get("params") or {}, (bmd or {}).get("params") or {}, base or "")


def rigid_rows(jd: dict, m=None) -> list[dict]:
    """The rigid-body terms the chosen model ``m`` (:class:`FrictionModel`) is used with: its inertia,
    gravity and offset, each with the status of the entry it comes from (the model's own parameter when
    it re-estimated the term, else the joint's). Without a model, the joint's entries."""
    own = ((jd.get("models") or {}).get(jd.get("selected")) or {}).get("params") or {}
    joint = {"J": jd.get("inertia"), "offset": jd.get("offset"), **(jd.get("gravity") or {})}
    names = {"J": "J (inertia)", "Px": "Px (gravity)", "Py": "Py (gravity)", "Mx": "Mx (payload gravity)",
             "My": "My (payload gravity)", "offset": "offset"}
    rows = []
    for k, label in names.items():
        entry = own.get(k) if isinstance(own.get(k), dict) else joint.get(k)
        if not isinstance(entry, dict):
            continue
        if m is not None and k == "offset" and m.offset == 0.0 and ct.pvalue(entry.get("value")):
            tau_off = "tau_offset" in (own or {})
            entry = {"value": 0.0, "unit": entry.get("unit", ""), "fixed": True,
                     "reason": ("0 in this model: its offset is tau_offset, inside F" if tau_off else
                                "0 in this model: its per-sign or extended friction carries the constant torque "
                                f"(the fit's offset estimate {fmt_num(entry.get('value'))} is evidence, not a term "
                                "to add)")}
        rows.extend(dict(r, name=label) for r in param_rows({k: entry}))
    return rows


def _compact_params(params: dict, rows: list[dict] | None = None) -> str:
    """Parameters as one line: ``name = value ± s.e. unit`` with the status when not ``identified``."""
    parts = []
    for r in rows if rows is not None else param_rows(params):
        unit = "" if r["unit"] in ("1", None) else r["unit"]
        flag = "" if r["status"] == "identified" else f" ({r['status']})"
        parts.append(f"{r['name']} = {r['value']} {unit}".strip() + flag)
    return "; ".join(parts)


def heldout_basis(jd: dict, name: str) -> str:
    """What a model's held-out RMS was computed on, in words: the plateau means (the static maps and
    whatever the fit ranked with them), the sliding samples (the diagnosis' models), the duty cycles
    (thermal laws)."""
    models = jd.get("models") or {}
    md = models.get(name) or {}
    basis = str((jd.get("selection") or {}).get("basis") or "plateau points")
    ranked = "moving samples" if basis.startswith(("moving", "samples")) else "plateau means"
    if md.get("basis") == "moving samples":
        return "moving samples"
    if name in ct.THERMAL_LAWS:
        return "duty cycles"
    if "+" in name or "base" in md or str(md.get("method", "")).startswith("diagnosis"):
        # an extended model fitted on the sliding samples; one whose metrics are its base map's (a LuGre
        # extension keeps the plateau fit) has the ranked models' point count
        n = (md.get("metrics") or {}).get("n")
        base_n = ((models.get(md.get("base")) or {}).get("metrics") or {}).get("n")
        return ranked if n is not None and n == base_n and "sliding" not in str(md.get("method", "")) else "sliding samples"
    return ranked


def _aic_why(met: dict, basis: str) -> str:
    """Why a model has no AIC: the criterion needs n > k + 1; the diagnosis' models have none."""
    n, k = met.get("n"), met.get("k")
    if isinstance(n, (int, float)) and isinstance(k, (int, float)) and n <= k + 1:
        return "n ≤ k + 1"
    return f"not computed on {basis}"


def model_rows(jd: dict) -> list[dict]:
    """Model comparison rows, in the order of the fit's ranking, then the others. Each held-out RMS says
    what it was computed on (``basis``): numbers on different bases are not compared."""
    models = jd.get("models") or {}
    ranking = [r.get("model") for r in ((jd.get("selection") or {}).get("ranking") or []) if isinstance(r, dict)]
    order = [m for m in ranking if m in models] + [m for m in models if m not in ranking]
    check = (jd.get("selection") or {}).get("diagnosis_check") or {}
    rows = []
    for name in order:
        md = models[name]
        if not isinstance(md, dict):
            continue
        met = md.get("metrics") or {}
        extras = [f"{k} = {fmt_num(met[k])}" for k in ("rms_presliding", "rms_presliding_static",
                                                        "rms_presliding_heldout", "heldout_gain")
                  if met.get(k) is not None]
        tc = md.get("time_constant")
        if isinstance(tc, dict) and tc.get("value") is not None:
            extras.append(f"time constant = {fmt_pm(tc.get('value'), tc.get('stderr'))} {tc.get('unit', 's')}")
        prows = model_param_rows(jd, name)
        basis = heldout_basis(jd, name)
        other = ""
        if check.get("model") == name and ct.pvalue(check.get("rms_heldout")) is not None:
            other = (f"{fmt_num(check['rms_heldout'])} on plateau means (the check against "
                     f"{check.get('fit_choice')}: {fmt_num(check.get('rms_heldout_fit_choice'))})")
        rows.append({"name": name, "selected": name == jd.get("selected"), "map": md.get("map", ""),
                     "method": md.get("method", ""), "rms": fmt_num(met.get("rms")),
                     "rms_heldout": fmt_num(met.get("rms_heldout")), "basis": basis, "heldout_other": other,
                     "aic": fmt_num(met.get("aic"), 5),
                     "aic_why": "" if met.get("aic") is not None else _aic_why(met, basis),
                     "n": met.get("n", "—"), "k": met.get("k", len(prows)), "params": _compact_params({}, prows),
                     "not_identifiable": [r["name"] for r in prows if r["status"] == "not identifiable"],
                     "extras": "; ".join(extras), "notes": list(md.get("notes") or [])})
    return rows


def _rounded(x, digits: int = 7):
    """Plain data with every float rounded to ``digits`` significant digits (for reading, not for storing)."""
    if isinstance(x, dict):
        return {k: _rounded(v, digits) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_rounded(v, digits) for v in x]
    if isinstance(x, float):
        return float(f"{x:.{digits}g}") if math.isfinite(x) else None
    if isinstance(x, np.generic):
        return _rounded(x.item(), digits)
    return x


def model_head(jd: dict, m=None) -> dict | None:
    """The chosen model's head as the parameter file writes it (:meth:`FrictionModel.head`: name, formula,
    parameters, the one-line torque with exactly the rigid-body terms and offset it is used with, validity),
    or the file's own ``model:`` when the model cannot be built; None without a chosen model."""
    m = m if m is not None else ct.chosen_model(jd)
    own = jd.get("model") if isinstance(jd.get("model"), dict) else None
    if m is not None:
        head = m.head()
        if own and own.get("torque", "").startswith("tau = the rigid-body torque of"):  # a whole robot's joint
            head["torque"] = own["torque"]
        return head
    return own


def yaml_snippet(jname: str, jd: dict, m=None) -> str:
    """A copyable YAML block of the chosen model: the joint's ``model:`` head of the parameter file
    (:func:`model_head`), values to 7 significant digits."""
    head = model_head(jd, m)
    if head is None:
        return ""
    return yaml.safe_dump({"joints": {str(jname): {"model": _rounded(head)}}}, sort_keys=False,
                          default_flow_style=None, width=110, allow_unicode=True)


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


@contextlib.contextmanager
def _timed(timings: dict, key: str):
    """Add the CPU seconds spent in the ``with`` block to ``timings[key]``."""
    t0 = time.process_time()
    yield
    timings[key] = timings.get(key, 0.0) + time.process_time() - t0


@dataclass
class _Joint:
    """What the sections of one joint's report draw on: its entry ``jd`` of the parameter file, its
    prepared logs, its units, its models and the chosen one, and the plateau points and the coverage
    measured on its logs."""

    name: str
    jd: dict
    datas: list[ct.LogData]
    id: str
    units: dict
    models: dict
    sel: str | None
    selmd: dict | None
    pl: ct.PlateauSet
    cov: dict
    #: the chosen model (:class:`frictid.model.FrictionModel`), None when there is none or it is incomplete
    model: Any = None

    def salt(self, part: str, i: int = 0) -> str:
        """The prefix that makes a figure's SVG ids unique in the page."""
        return f"{self.id}-{part}-{i}"


def _gather(jname: str, jd: dict, datas: list[ct.LogData]) -> _Joint:
    """The joint's data every section draws on, with its plateau points (in the chosen model's offset
    convention, the one its curve is drawn in) and coverage."""
    models = jd.get("models") or {}
    sel = jd.get("selected")
    model = ct.chosen_model(jd)
    pl = ct.plateaus(datas, model) if datas else ct.plateaus([])
    return _Joint(name=jname, jd=jd, datas=datas, id="j-" + slug(jname), units=_units(jd, datas),
                  models=models, sel=sel, selmd=models.get(sel) if sel else None, pl=pl,
                  cov=ct.coverage(datas, pl, jd), model=model)


def _section(key: str) -> Section:
    """An empty section ``key``, titled as in :data:`SECTIONS`."""
    return Section(key, dict(SECTIONS)[key])


def joint_report(jname: str, jd: dict, datas: list[ct.LogData], timings: dict | None = None) -> dict:
    """The template context of one joint: summary, sections with their figures, tables, snippet.
    ``timings`` receives the CPU seconds spent per part."""
    timings = timings if timings is not None else {}
    with _timed(timings, "plateaus"):
        j = _gather(jname, jd, datas)
    secs = {"summary": _summary(j)}
    with _timed(timings, "timeline"):
        secs["timeline"] = _timeline(j)
    with _timed(timings, "map"):
        secs["friction-map"] = _friction_map(j)
    with _timed(timings, "presliding"):
        secs["presliding"] = _presliding(j)
    with _timed(timings, "thermal"):
        vmin = ct.min_speed(datas)  # the speed below which a sample counts as at rest (thermal, diagnosis)
        secs["thermal"] = _thermal(j, vmin)
    secs["models"] = _models(j)
    with _timed(timings, "diagnosis"):
        secs["diagnosis"] = _diagnosis(j, vmin)
    secs["provenance"] = _provenance(j)
    return _joint_context(j, secs)


def _joint_context(j: _Joint, secs: dict[str, Section]) -> dict:
    """The template context of the joint from its sections (keyed as in :data:`SECTIONS`)."""
    summary = secs["summary"].data
    findings = secs["diagnosis"].data["findings"]
    return {"name": j.name, "id": j.id, "units": j.units, "sections": [secs[k] for k, _ in SECTIONS],
            "section": secs, "selected": j.sel, "key": s_summary_key(summary["key_params"]),
            "n_findings": sum(1 for f in findings if f["adopted"]),
            "n_not_identified": len(summary["not_identified"]),
            "rms_heldout": summary["heldout"]}


#: Rigid-body terms: listed with the rigid body, not among the friction parameters.
RIGID_NAMES = ("J", "Px", "Py", "Mx", "My")


def _summary(j: _Joint) -> Section:
    """The summary section, one screen per joint: the chosen model (name, formula in words and symbols,
    the one-line torque), how sure (parameters with standard errors and verdicts), what the diagnosis
    found and gained (or what it tested), where the model is valid; then the rigid-body terms, what the
    logs cover, what could not be identified and the warnings."""
    s = _section("summary")
    selmd = j.selmd or {}
    head = model_head(j.jd, j.model) or {}
    rows = [r for r in model_param_rows(j.jd, j.sel) if r["name"] not in RIGID_NAMES]
    n_find = len([f for f in (j.jd.get("diagnosis") or [])])
    s.data = {
        "selected": j.sel, "method": selmd.get("method", ""), "map": selmd.get("map", ""),
        "words": head.get("words", ""), "friction": list(head.get("friction") or []), "torque": head.get("torque", ""),
        "selection": _selection_text(j.jd), "key_params": rows, "heldout": _heldout_line(j),
        "rigid": rigid_rows(j.jd, j.model), "coverage": _coverage_lines(j.cov, j.units),
        "validity": _validity_lines(j), "found": _found_lines(j),
        "not_identified": _not_identified(j.jd),
        "warnings": ct.clean_warnings(j.name, j.jd.get("warnings") or [], n_find, j.cov.get("cycles", 0)),
        "notes": list(selmd.get("notes") or []),
    }
    if j.sel is None:
        reason = (j.jd.get("selection") or {}).get("reason")
        s.notes.append("No model was chosen for this joint" + (f": {reason}" if reason else "."))
    return s


def _heldout_line(j: _Joint) -> str:
    """The chosen model's held-out RMS with what it was computed on (and, for a diagnosis model, its
    check on the plateau means)."""
    if not j.sel:
        return "—"
    met = (j.selmd or {}).get("metrics") or {}
    text = f"{fmt_num(met.get('rms_heldout'))} {j.units['tau']} on {heldout_basis(j.jd, j.sel)}"
    check = (j.jd.get("selection") or {}).get("diagnosis_check") or {}
    if check.get("model") == j.sel and ct.pvalue(check.get("rms_heldout")) is not None:
        text += f"; {fmt_num(check['rms_heldout'])} {j.units['tau']} on plateau means"
    return text


def _validity_lines(j: _Joint) -> list[str]:
    """Where the model is valid: the ranges the file records (:attr:`FrictionModel.validity`, the joint's
    ``validity``), else the speed range of the plateau points the report measured."""
    rec = (j.model.validity if j.model is not None else None) or j.jd.get("validity") or {}
    units = {"speed": j.units["qd"], "position": j.units["q"], "temperature": "degC"}
    lines = []
    for key in ("speed", "position", "temperature"):
        r = rec.get(key) if isinstance(rec, dict) else None
        if isinstance(r, (list, tuple)) and len(r) == 2 and None not in r:
            lines.append(f"{key} {fmt_num(r[0], 3)} to {fmt_num(r[1], 3)} {units[key]}"
                         + (" (|w|; from rest up to the highest speed)" if key == "speed" else ""))
    if lines:
        return ["Recorded by the fit: " + "; ".join(lines) + "."]
    spans = [f"{name}: {fmt_num(j.cov[k][0], 3)} to {fmt_num(j.cov[k][1], 3)} {j.units['qd']}"
             for k, name in (("pos", "w > 0"), ("neg", "w < 0")) if j.cov.get(k)]
    if spans:
        return ["Not recorded in the parameter file; the plateau points cover " + "; ".join(spans)
                + ". Outside these speeds the model is extrapolated."]
    w = np.concatenate([np.abs(d.w[np.isfinite(d.w)]) for d in j.datas]) if j.datas else np.zeros(0)
    w = w[w > ct.min_speed(j.datas)] if w.size else w
    if w.size:
        return [f"Not recorded in the parameter file, and no plateau points; the moving samples reach |w| "
                f"{fmt_num(np.percentile(w, 99.5), 3)} {j.units['qd']} (99.5th percentile). Beyond it the model "
                "is extrapolated."]
    return ["Not recorded in the parameter file, and no plateau points to measure it on."]


def _found_lines(j: _Joint) -> list[str]:
    """What the diagnosis found and gained, in one or two sentences (or that it found nothing, with what
    it tested)."""
    findings = [f for f in (j.jd.get("diagnosis") or []) if isinstance(f, dict)]
    adopted, why = ct.diagnosis_adoption(j.jd)
    tested = ct.diagnosis_tested(j.jd)
    out = []
    used = [f for f, a in zip(findings, adopted) if a]
    for f in used:
        out.append(f"Found {f.get('cause')}: {f.get('extension') if isinstance(f.get('extension'), str) else 'extension'}"
                   f" cuts the held-out RMS from {fmt_num(f.get('rms_before'))} to {fmt_num(f.get('rms_after'))} "
                   f"{j.units['tau']} ({_fmt_gain(f.get('gain'))}); in the chosen model.")
    left = len(findings) - len(used)
    if left:
        out.append(f"{left} finding{'s' if left > 1 else ''} not adopted" + (f": {why}" if why else "")
                   + " (listed under Diagnosis, marked so).")
    if not findings:
        if tested:
            names = sorted({t["extension"] for t in tested})
            out.append(f"No finding: the diagnosis tested {len(names)} extensions ({', '.join(names)}); none "
                       "cut the held-out error significantly.")
        elif isinstance((j.jd.get("selection") or {}).get("diagnosis"), dict):
            skipped = j.jd["selection"]["diagnosis"].get("skipped")
            out.append(f"Nothing tested: {skipped}." if skipped else "No finding.")
        else:
            out.append("The diagnosis has not run on this identification (frictid fit --no-diagnose?).")
    return out


def _timeline(j: _Joint) -> Section:
    """The segment timeline section: position, velocity and torque of the first :data:`MAX_TIMELINES`
    logs with their segments; absent without logs."""
    s = _section("timeline")
    if not j.datas:
        s.present, s.why = False, NO_LOGS
        return s
    for i, d in enumerate(j.datas[:MAX_TIMELINES]):
        lg = d.log
        segs = [(x.kind, float(lg.t[x.i0]), float(lg.t[x.i1 - 1])) for x in d.segments]
        title = f"Joint {j.name}: {d.label or 'log'}"
        s.figures.append(fg.timeline(lg.t, lg.q, d.w, lg.tau, segs, j.units, title, j.salt("timeline", i)))
    if len(j.datas) > MAX_TIMELINES:
        s.notes.append(f"{len(j.datas) - MAX_TIMELINES} more logs of this joint are not drawn here "
                       "(they enter every other figure).")
    if not any(d.segments for d in j.datas):
        s.notes.append("No segment was found in the logs: nothing is shaded.")
    if any(d.log.q is None for d in j.datas):
        s.notes.append("A log without position: its position panel is left out.")
    return s


def _friction_map(j: _Joint) -> Section:
    """The friction-velocity map section: the plateau points and the curves of the chosen model and the
    best alternatives (at most :data:`content.MAX_CURVES`), in one offset convention (the chosen model's),
    with notes on what is not drawn; absent with neither plateaus nor a static model."""
    s = _section("friction-map")
    grids = ct.velocity_grids(j.pl, j.datas)
    if not j.datas and not ct.static_models(j.jd):
        s.present, s.why = False, ("No static friction model in the parameter file and no log given: the map "
                                   "needs constant-velocity plateaus at several velocities of both signs "
                                   "(recipes/constant_velocity_sweep.yaml).")
        return s
    curves, left = ct.model_curves(j.jd, grids)
    if not curves and not len(j.pl):
        s.present, s.why = False, ("No constant-velocity plateau in the logs and no static model in the "
                                   "parameter file: the map needs plateaus at several constant velocities "
                                   "of both signs (recipes/constant_velocity_sweep.yaml).")
        return s
    s.figures.append(fg.friction_map(j.pl, curves, grids, j.units, j.salt("map")))
    s.notes.extend(_map_notes(j, curves, left, grids))
    s.data["n_points"] = len(j.pl)
    s.data["n_models"] = len(curves)
    return s


def _map_notes(j: _Joint, curves: list[dict], left: list[str], grids: dict) -> list[str]:
    """How to read the friction map: the offset convention its points and curves share, what is not
    drawn and why."""
    notes = []
    if j.model is not None:
        m = j.model
        off = ("the offset stays in F (tau_offset)" if "tau_offset" in m.ext else
               f"offset {fmt_num(m.offset)} {j.units['tau']} removed" if m.offset else "no offset removed")
        notes.append(f"Points and curves in the chosen model's convention: F = tau - J a - G(q) with its J, "
                     f"gravity and offset ({off}): the chosen curve is what {m.name} predicts for the points.")
        moved = [f"{c['name']} ({'+' if c['shift'] > 0 else ''}{fmt_num(c['shift'], 3)})" for c in curves
                 if c.get("shift")]
        if moved:
            notes.append("Models identified with another offset are shifted by the difference [" + j.units["tau"]
                         + "]: " + ", ".join(moved) + ".")
    if left:
        notes.append(f"{len(curves)} of {len(curves) + len(left)} static models drawn (the chosen one and the best "
                     "alternatives by held-out RMS); not drawn, see the model comparison: " + ", ".join(left) + ".")
    if not j.datas:
        notes.append("No log given: the plateau points are not drawn, and the velocity axis spans "
                     f"±{fmt_num(grids['lin'][-1], 3)} {j.units['qd']} by default.")
    elif not len(j.pl):
        notes.append("No usable constant-velocity plateau in the logs: only the model curves are drawn.")
    if not curves:
        notes.append("No static model could be evaluated: only the plateau points are drawn.")
    for side, name in (("pos", "positive"), ("neg", "negative")):
        if j.datas and len(j.pl) and j.cov.get(side) is None:
            notes.append(f"No {name}-velocity plateau: the {name} branch of every model is an extrapolation.")
    return notes


def _presliding(j: _Joint) -> Section:
    """The presliding section: LuGre's sigma0 / sigma1 rows and the figure of the ramps and steps with
    the model's curves; absent without logs, or without ramps and steps in them."""
    s = _section("presliding")
    lp = ct.lugre_params(j.jd)
    s.data["sigma"] = []
    if lp:
        s.data["sigma"] = param_rows({k: v for k, v in (j.models["lugre"].get("params") or {}).items()
                                      if k in ("sigma0", "sigma1")})
    if not j.datas:
        s.present = False
        s.why = NO_LOGS + (" The identified sigma0 / sigma1 are listed in the model table." if lp else "")
        return s
    ramps, rinfo = ct.ramp_curves(j.datas, j.jd)
    steps, sinfo = ct.step_curves(j.datas, j.jd)
    if not ramps and not steps:
        s.present = False
        s.why = ("No presliding ramp and no torque step in the logs: sigma0 needs slow open-loop torque ramps "
                 "kept below break-away (recipes/ramp_presliding.yaml), sigma1 torque steps "
                 "(recipes/torque_steps.yaml).")
        return s
    s0, s1 = (lp or {}).get("sigma0") or {}, (lp or {}).get("sigma1") or {}
    lab0 = f"LuGre, sigma0 = {fmt_pm(s0.get('value'), s0.get('stderr'))} {s0.get('unit', '')}"
    lab1 = f"LuGre, sigma1 = {fmt_pm(s1.get('value'), s1.get('stderr'))} {s1.get('unit', '')}"
    s.figures.append(fg.presliding(ramps, steps, j.units, lab0, lab1, j.salt("presliding")))
    s.notes.extend(_presliding_notes(ramps, rinfo, steps, sinfo, lp))
    return s


def _presliding_notes(ramps: list[dict], rinfo: dict, steps: list[dict], sinfo: dict, lp: dict | None
                      ) -> list[str]:
    """What the presliding figure leaves out: ramps and steps not drawn, model curves missing (and why),
    and the experiment the logs lack."""
    s0, s1 = (lp or {}).get("sigma0") or {}, (lp or {}).get("sigma1") or {}
    notes = []
    if rinfo["n_total"] > len(ramps):
        notes.append(f"{len(ramps)} of {rinfo['n_total']} ramps drawn, spread over the log.")
    if sinfo["n_total"] > len(steps):
        notes.append(f"{len(steps)} of {sinfo['n_total']} steps drawn, spread over the log.")
    if ramps and not any(r["model"] is not None for r in ramps):
        notes.append("No model curve on the ramps: " + (
            f"sigma0 is not identified ({s0.get('reason') or 'no value'})." if lp else
            "the parameter file has no LuGre model."))
    if steps and not any(x["model"] is not None for x in steps):
        notes.append("No simulated transient: " + (
            f"sigma1 is not identified ({s1.get('reason') or 'no value'})." if lp and s1.get("value") is None
            else "the inertia J is not known." if lp and not sinfo.get("J") else
            "sigma0 is not identified." if lp else "the parameter file has no LuGre model."))
    if not ramps:
        notes.append("No presliding ramp in the logs (sigma0 needs recipes/ramp_presliding.yaml).")
    if not steps:
        notes.append("No torque step in the logs (sigma1 needs recipes/torque_steps.yaml).")
    return notes


def _thermal(j: _Joint, vmin: float) -> Section:
    """The thermal section: the thermal models' parameters and the figure of the friction per duty cycle
    with each model; absent without logs or duty cycles. ``vmin``: the speed below which a sample is at
    rest [unit of qd]."""
    s = _section("thermal")
    th_reasons = [x["reason"] for x in _not_identified(j.jd) if x["what"] in ct.THERMAL_LAWS]
    th_models = [n for n in j.models if n in ct.THERMAL_LAWS]
    s.data["models"] = [{"name": n, "params": param_rows(j.models[n].get("params") or {}),
                         "notes": list(j.models[n].get("notes") or []),
                         "time_constant": j.models[n].get("time_constant")} for n in th_models]
    says = "; ".join(sorted(set(th_reasons)))  # what the fit says of the thermal models it left out
    if not j.datas:
        s.present = False
        s.why = NO_LOGS + (" The thermal parameters are listed below." if th_models else
                           (" The fit says: " + says + "." if th_reasons else ""))
        return s
    cycles, tmods, tinfo = ct.thermal_cycles(j.datas, j.jd, vmin=vmin)
    if not cycles:
        s.present = False
        s.why = ("No duty cycle in the logs: the thermal models need repeated cycles of motion and rest "
                 "from a cold start, with a temp_env channel (recipes/duty_cycle.yaml)."
                 + (" The fit says: " + says + "." if th_reasons else ""))
        return s
    s.figures.append(fg.thermal(cycles, tmods, j.units, j.salt("thermal")))
    s.notes.append(f"{len(cycles)} cycles, from {tinfo['source']}.")
    if not tmods:
        s.notes.append("No thermal model in the parameter file" + (": " + says if th_reasons else "")
                       + ". Only the measured friction per cycle is drawn.")
    for m in tmods:
        if not np.any(np.isfinite(m["T"])):
            s.notes.append(f"{m['name']}: the parameter file gives no per-cycle temperature "
                           "(cycle_temperature), so its curve is not drawn.")
    return s


def _models(j: _Joint) -> Section:
    """The model comparison section: a row per fitted model, those left out of the held-out comparison,
    and the selection rule; absent when no model was fitted."""
    s = _section("models")
    s.data["rows"] = model_rows(j.jd)
    s.data["heldout_skipped"] = [r["name"] for r in s.data["rows"] if NOT_HELDOUT in r["notes"]]
    if not s.data["rows"]:
        s.present, s.why = False, "No model was fitted for this joint."
    s.data["rule"] = (j.jd.get("selection") or {}).get("rule", "")
    return s


@dataclass
class _Findings:
    """The diagnosis entries of one joint and the model each was judged against (``befores``), with the
    replays kept for them: ``later[i]`` are the models that findings ``i`` and after replay (a replay is
    kept only while one needs it: each is three arrays of the log's length, and the first joint of a
    worker pays for fresh memory); ``cache`` holds the kept replays."""

    entries: list[dict]
    befores: list
    later: list[set]
    cache: dict = field(default_factory=dict)
    #: per log the diagnosis' sliding samples (:func:`content.diagnosis_samples`), built at the first
    #: finding drawn on them; ``rows_built`` says whether they were
    rows: list | None = None
    rows_built: bool = False


def _findings(jd: dict) -> _Findings:
    """The joint's diagnosis entries (text entries as causes) and the models each replays."""
    entries = [f if isinstance(f, dict) else {"cause": str(f)} for f in (jd.get("diagnosis") or [])]
    befores = ct.diagnosis_befores(jd, entries)
    later = [set()]
    for f, before in zip(reversed(entries), reversed(befores)):
        later.insert(0, later[0] | ct.replayed_models(jd, f, before))
    return _Findings(entries, befores, later)


def _screened_note(tested: list[dict]) -> str:
    """The footnote of the tested table when a row is screened: its numbers come from a stride of the
    sliding samples, not from a trial on all of them."""
    sc = [t["screened"] for t in tested if t.get("screened")]
    if not sc:
        return ""
    strides = sorted({str(x["stride"]) for x in sc if x.get("stride")})
    return ("* screened: the row's RMS, gain, t and p are those of a trial on a stride of the sliding samples "
            f"(every {' or '.join(strides) or 'k'}th sample), not on all of them; on that stride the most the "
            "candidate could explain stays under the bar a term must pass, so it was not tried on all samples "
            "(docs/diagnosis.md, \"Whole logs\").")


def _diagnosis(j: _Joint, vmin: float) -> Section:
    """The diagnosis section: what the diagnosis tested, a row per finding of the parameter file with its
    residual figure (findings the chosen model does not carry marked as not adopted), and the replays of
    the chosen model along the logs; absent with neither findings, tests nor replays. ``vmin``: the speed
    below which a sample is at rest [unit of qd]."""
    s = _section("diagnosis")
    fi = _findings(j.jd)
    replays, replayed = _replays(j, fi, vmin, s.notes)
    ct.drop_reference_channels(j.datas)  # the closed loops have run
    adopted, why = ct.diagnosis_adoption(j.jd)
    findings = [dict(_finding(j, fi, i, vmin), adopted=adopted[i]) for i in range(len(fi.entries))]
    fi.cache.clear()
    s.data["findings"] = findings
    s.data["not_adopted_why"] = why
    s.data["tested"] = [dict(t, gain=_fmt_gain(t["gain"]), rms_before=fmt_num(t["rms_before"]),
                             rms_after=fmt_num(t["rms_after"]), p=fmt_num(t["p"], 2), t=fmt_num(t["t"], 3))
                        for t in ct.diagnosis_tested(j.jd)]
    s.data["screened_note"] = _screened_note(s.data["tested"])
    s.data["rule"] = str(((j.jd.get("selection") or {}).get("diagnosis") or {}).get("rule") or "")
    s.data["base"] = str(((j.jd.get("selection") or {}).get("diagnosis") or {}).get("base") or "")
    s.figures = replays
    if replays and replayed:
        s.notes.append("Replay: the chosen model run along the measured motion by frictid.replay "
                       "(tau_model = J a + G(q) + offset + F_model, with the LuGre and thermal states and "
                       "Karnopp's stick law at rest); in closed loop, the position simulated with the log's "
                       "references and controller. The headline is the median absolute residual: the RMS "
                       "is dominated by the short spikes at velocity reversals, where no static map holds.")
    if not findings:
        skipped = ((j.jd.get("selection") or {}).get("diagnosis") or {}).get("skipped")
        s.notes.insert(0, "No finding." + (" Every extension tested is listed above with its held-out gain; none "
                                           "was significant." if s.data["tested"] else
                                           f" Nothing was tested: {skipped}." if skipped else
                                           " The parameter file records no diagnosis test: the diagnosis has "
                                           "not run on this identification (frictid fit --no-diagnose)."))
    if j.datas and not replays:
        s.notes.append("No replay: the chosen model cannot be run along the log.")
    if not findings and not replays and not s.data["tested"]:
        s.present = False
        s.why = " ".join(s.notes) + ("" if j.datas else " " + NO_LOGS)
        s.notes = []
    return s


def _replays(j: _Joint, fi: _Findings, vmin: float, notes: list[str]) -> tuple[list, bool]:
    """The replay figures of the chosen model along the first :data:`MAX_TIMELINES` logs (in closed loop
    where the log allows), and whether any log was replayed in full rather than with the steady-state map
    only. Their notes are added to ``notes``; the replays the findings need are kept in ``fi.cache``."""
    replays, replayed = [], False
    for k, d in enumerate(j.datas):
        r = ct.replay_log(d, j.name, j.jd, closed=k < MAX_TIMELINES, vmin=vmin)
        if r is None:
            continue
        replayed = replayed or r.how == "replay"
        if k < MAX_TIMELINES:
            replays.append(_replay_figure(j, d, k, r))
            if r.how == "static":
                notes.append(f"{d.label or 'log'}: replayed with the steady-state map of {r.model} only "
                             f"(J a + G(q) + offset + F_ss(w)); samples slower than {fmt_num(vmin, 3)} "
                             f"{j.units['qd']} are left out, as a static map cannot tell the friction at rest.")
            for n in r.notes:
                notes.append(f"{d.label or 'log'}: {n}")
        r.q_model = None  # drawn
        if j.sel in fi.later[0]:
            fi.cache[(j.sel, k, 0)] = r
        r = None  # not held past the loop
    return replays, replayed


def _replay_figure(j: _Joint, d: ct.LogData, k: int, r: ct.Replay) -> fg.Rendered:
    """The figure of replay ``r`` along log ``d`` (the joint's ``k``-th), titled with the residual's median
    absolute value (robust to the spikes at reversals), its 95th percentile and its RMS."""
    res = r.residual(d)
    # the stick zone reads the measured torque (Karnopp, every model): scored while moving only
    moving = r.still is not None and bool(np.any(~r.still))
    st = ct.residual_stats(res[~r.still] if moving else res)
    u = j.units["tau"]
    title = (f"Replay of {r.model}: median |residual| {fmt_num(st['median_abs'], 3)} {u}"
             f" (95 % below {fmt_num(st['p95_abs'], 3)}, RMS {fmt_num(st['rms'], 3)})"
             + (" while moving" if moving else ""))
    return fg.replay(d.log.t, d.log.tau, r.tau_model, j.units, title, j.salt("replay", k),
                     q=d.log.q, q_model=r.q_model, source=d.label or "the log")


def _finding_row(f: dict, prev) -> dict:
    """The table row of diagnosis entry ``f`` as text (``prev``: the model it was judged against),
    without its figure or note."""
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
    return row


def _finding(j: _Joint, fi: _Findings, i: int, vmin: float) -> dict:
    """The table row of the ``i``-th finding with its residual figure, or a note saying why none is
    drawn."""
    f, prev = fi.entries[i], fi.befores[i]
    row = _finding_row(f, prev)
    if not ct.on_sliding_samples(f):
        split = str((f.get("heldout") or {}).get("split", "")) if isinstance(f.get("heldout"), dict) else ""
        row["note"] = ("Judged on the stops and reversals of the moving samples (the fit's LuGre against its "
                       "static map, held out by time blocks), not along the sliding samples: the replay "
                       "above runs the chosen model through them." if "moving samples" in split else
                       "Judged on the presliding ramps, not along the sliding samples: see the Presliding "
                       "part (torque against displacement with LuGre's sigma0).")
    elif j.datas:
        if not fi.rows_built:
            fi.rows, fi.rows_built = ct.diagnosis_samples(j.datas, j.name, j.jd), True
        res = ct.diagnosis_residuals(j.datas, j.name, j.jd, f, before=prev, cache=fi.cache, vmin=vmin,
                                     keep=fi.later[i + 1], rows=fi.rows)
        if res is not None:
            row["figure"] = fg.diagnosis(f, res, j.units, j.salt("diagnosis", i))
            if res.get("given") is None:
                row["note"] = ("Only the residual before the extension is drawn: the parameter file holds "
                               "neither the extended model nor the binned residual after it.")
        else:
            row["note"] = "No residual drawn: the model cannot be run along the log."
    else:
        row["note"] = "No residual drawn: no log given."
    return row


def _provenance(j: _Joint) -> Section:
    """The joint's part of the provenance: the YAML snippet of the chosen model and the logs drawn."""
    s = _section("provenance")
    if j.sel:
        s.data["yaml"] = yaml_snippet(j.name, j.jd, j.model)
    else:
        s.data["yaml"] = ""
        s.notes.append("No model was chosen: there is no snippet to copy.")
    s.data["logs"] = [{"label": d.label, "sha256": d.sha256, "rows": d.log.n,
                       "source": d.source_index} for d in j.datas]
    return s


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
    if rec.get("shape_not_identifiable"):
        parts.append(f"{rec['shape_not_identifiable']}.")
    if isinstance(rec.get("lugre"), str):
        parts.append(f"LuGre: {rec['lugre']}.")
    if rec.get("reason"):
        parts.append(str(rec["reason"]))
    check = rec.get("diagnosis_check") or {}
    if isinstance(check, dict) and check.get("model") and check.get("fit_choice") != check.get("model"):
        took = check.get("kept") in (None, check.get("model")) and jd.get("selected") == check.get("model")
        parts.append(f"The diagnosis' model {check['model']} (held-out RMS {fmt_num(check.get('rms_heldout'))} on "
                     f"plateau means, against {fmt_num(check.get('rms_heldout_fit_choice'))} for the fit's choice "
                     f"{check.get('fit_choice')}) " + ("replaced that choice." if took else "was not adopted."))
    return " ".join(parts)


# ---------------------------------------------------------------------------------------------------
# the whole report


def _environment():
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
    the replay and the presliding simulation) once, ahead of forking the workers that inherit it; the
    imports here are the work, not hidden dependencies."""
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
        super().__init__(paths, file_sha256, preload)


def build_report(params: dict, logs: Iterable[JointLog] | None = None, *, params_path: str = "",
                 command: str = "", segmenter: Callable | None = None, differentiate: Callable | None = None,
                 generated: str | None = None, timings: dict | None = None, jobs: int = 0,
                 hashes: dict[str, str | None] | None = None, log_warnings_out: list[str] | None = None,
                 compensation: dict | None = None, robot_file: str | None = None) -> str:
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
    are computed here. compensation : runs of ``frictid simulate --compensate``
    (:func:`frictid.io.replay_out.read_runs`), drawn in a section of each joint they hold. robot_file : for
    a whole-robot parameter file, the robot (default: the file ``settings.robot`` names): the page then
    gains the robot's part, and the joints' sections draw each joint's friction torque
    (:mod:`frictid.report.robot`).
    """
    timings = timings if timings is not None else {}
    logs = list(logs or [])
    robot = None
    if isinstance((params.get("settings") or {}).get("robot"), dict):
        logs = [x for lg in logs for x in (lg.load() if isinstance(lg, DeferredLogs) else [lg])]
        robot, logs = robot_page(params, logs, robot_file, fmt_pm, fmt_num)
    if logs and (segmenter is None or differentiate is None):
        segmenter = segmenter or _seg.find_segments
        differentiate = differentiate or _seg.derivatives
    joints = params.get("joints") or {}
    sources = [s for s in (params.get("sources") or []) if isinstance(s, dict)]
    hashes = dict(hashes or {})
    t0 = time.process_time()
    by_joint = _logs_by_joint(logs, joints, hashes)
    timings["hash"] = time.process_time() - t0
    notes = _skipped_joints(logs, joints)
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
    jctx = [r.ctx for r in results]
    for ctx in jctx:
        if compensation and ctx["name"] in compensation:
            _add_compensation(ctx, compensation[ctx["name"]])
    _add_up(results, timings, log_warnings_out)
    inputs = _inputs(logs, _given_logs(names, results, by_joint), hashes)
    notes += _unmatched_inputs(inputs, joints, sources)
    t0 = time.process_time()
    env = _environment()
    html = env.get_template("report.html").render(
        title=params_path or "parameter file", params_path=params_path, joints=jctx, sources=sources,
        inputs=inputs, notes=notes, file_version=str(params.get("frictid", "")), version=__version__,
        schema=params.get("schema"), settings=params.get("settings") or {}, command=command,
        generated=generated or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        has_logs=bool(logs), robot=robot)
    timings["html"] = time.process_time() - t0
    return html


#: The compensation runs' names as the report shows them.
RUN_LABELS = {"none": "no compensation", "model": "the identified model as feed-forward",
              "measured": "the identified model's static map from the measured velocity",
              "observer": "the LuGre friction observer (seed 000, eq. 17) on the identified model",
              "true": "the plant's true friction as feed-forward (ideal)"}


def _add_compensation(ctx: dict, runs: dict) -> None:
    """The compensation section of a joint's context: the runs' tracking errors overlaid and their metrics."""
    s = Section("compensation", "Compensation what-if")
    base = (runs.get("none") or {}).get("metrics", {}).get("rms_error")
    rows = []
    for name, r in runs.items():
        m = r["metrics"]
        r["label"] = RUN_LABELS.get(name, name)
        red = base / m["rms_error"] if base and m.get("rms_error") else None
        rows.append({"run": r["label"], "rms": fmt_num(m.get("rms_error")), "peak": fmt_num(m.get("peak_error")),
                     "steady": fmt_num(m.get("steady_error")), "stick": m.get("stick_slip_episodes", "-"),
                     "stick_s": fmt_num(m.get("stick_seconds"), 3), "reduction": "-" if red is None else f"{red:.3g}x"})
    s.data["rows"] = rows
    s.figures.append(fg.compensation(runs, ctx["units"], f"{ctx['id']}-compensation-0"))
    s.notes.append("The same recipe and sensor noise in every run; the feed-forward is computed along the "
                   "reference velocity and enters where the loop is closed. Stick episodes: 20 ms or more with "
                   "the reference moving and |w| < 0.1 |qd_ref|.")
    ctx["section"]["compensation"] = s
    ctx["sections"].insert(len(ctx["sections"]) - 1, s)  # before the provenance


def _logs_by_joint(logs: list, joints: dict, hashes: dict[str, str | None]) -> dict[str, list]:
    """The logs given (:class:`JointLog` or :class:`DeferredLogs`) of each joint of the parameter file
    ``joints``, in their order; the SHA-256 of every log file not yet in ``hashes`` is added to it."""
    by_joint: dict[str, list[JointLog | DeferredLogs]] = {}
    for lg in logs:
        if lg.source and lg.source not in hashes:
            hashes[lg.source] = file_sha256(lg.source)
        if str(lg.joint) in joints:
            by_joint.setdefault(str(lg.joint), []).append(lg)
    return by_joint


def _skipped_joints(logs: list, joints: dict) -> list[str]:
    """The page's note on logs of joints that the parameter file does not hold (none if all are in it)."""
    skipped = sorted({str(lg.joint) for lg in logs} - set(map(str, joints)))
    if not skipped:
        return []
    return [f"Logs of joint(s) {', '.join(skipped)} are not drawn: the parameter file has no entry for them."]


def _add_up(results: list[_Part], timings: dict, log_warnings_out: list[str] | None) -> None:
    """Add the CPU seconds of every joint's part to ``timings``, and their logs' warnings to
    ``log_warnings_out`` (when a list)."""
    for r in results:
        if log_warnings_out is not None:
            log_warnings_out.extend(r.warnings)
        for key, v in r.timings.items():
            timings[key] = timings.get(key, 0.0) + v


def _given_logs(names: list[str], results: list[_Part], by_joint: dict[str, list]
                ) -> dict[int, tuple[int, int | None, bool]]:
    """Per log given (by ``id``), as its joint's part found it: its rows, the index of the parameter
    file's source it matches (or None) and whether its segments are the ones the fit recorded."""
    got: dict[int, tuple[int, int | None, bool]] = {}
    for jn, r in zip(names, results):
        for item, n, si, rec in zip(by_joint.get(jn, []), r.rows, r.source_index, r.recorded):
            got[id(item)] = (n, si, rec)
    return got


def _inputs(logs: list, got: dict[int, tuple[int, int | None, bool]], hashes: dict[str, str | None]
            ) -> list[dict]:
    """The provenance's rows of the logs given, one per file and joint: path, joint, rows, SHA-256, the
    parameter file's source it matches, and whose segments were drawn (``got``: :func:`_given_logs`)."""
    inputs = []
    for lg in logs:
        label = lg.source or "<memory>"
        if any(i["path"] == label and i["joint"] == str(lg.joint) for i in inputs):
            continue
        n, si, rec = got.get(id(lg), (getattr(lg, "n", None), None, False))
        inputs.append({"path": label, "joint": str(lg.joint), "rows": n, "sha256": hashes.get(label),
                       "source": si, "segments": "the fit's" if rec else "found again"})
    return inputs


def _unmatched_inputs(inputs: list[dict], joints: dict, sources: list[dict]) -> list[str]:
    """The page's notes on logs of the file's joints that are none of the files the fit read."""
    return [f"{i['path']}: not among the files the fit read (different hash and name); its curves are "
            "compared with parameters identified from other data."
            for i in inputs if i["source"] is None and str(i["joint"]) in joints and sources]


def write_report(path: str, params: dict, logs: Iterable[JointLog] | None = None, **kw) -> int:
    """Build the report and write it atomically to ``path`` (``-`` for standard output). Returns bytes."""
    html = build_report(params, logs, **kw)
    with atomic_open(path, "w") as fh:
        fh.write(html)
    return len(html.encode("utf-8"))
