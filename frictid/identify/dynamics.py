"""Step 5 of a joint's fit: LuGre on top of the chosen static map.

sigma0 from the presliding ramps (torque against displacement), sigma1 from the steps (simulation error)
or the critical-damping rule (:mod:`.presliding`). LuGre replaces its map as the chosen model only when its
dynamic parameters are identifiable and it predicts held-out presliding ramps (leave one ramp out) better
than the map alone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from frictid.models import static as sm
from frictid.models.params import unit_of
from frictid.result import ModelFit, ParamEstimate

from . import presliding as pre
from .prepare import JointData
from .static import predict


@dataclass
class Presliding:
    """A joint's presliding data: per ramp (position [q], friction torque [F]) with its time span and
    velocity, per step (t, q, torque less gravity, segment, source index), and the encoder resolution [q]."""

    ramps: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    ramp_t: list[list] = field(default_factory=list)
    ramp_w: list[np.ndarray] = field(default_factory=list)
    steps: list[tuple] = field(default_factory=list)
    resolution: float = 0.0


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


def static_params(mf: ModelFit) -> dict[str, ParamEstimate]:
    """Copies of a model's parameter estimates."""
    return {k: ParamEstimate(**vars(p)) for k, p in mf.params.items()}


def presliding_data(jd: JointData) -> Presliding:
    """The ramps and steps of a joint's logs (at least 10 samples each, logs with a position only)."""
    out = Presliding()
    for p in jd.preps:
        if p.log.q is None:
            continue
        for s in p.segments:
            if s.kind == "ramp_presliding" and s.n >= 10:
                out.ramps.append((np.asarray(p.log.q[s.i0:s.i1], float), p.F[s.i0:s.i1]))
                out.ramp_t.append([float(s.t_start), float(s.t_end), p.index])
                out.ramp_w.append(p.w[s.i0:s.i1])
            elif s.kind == "step" and s.n >= 10:
                i0 = max(s.i0 - 1, 0)  # one sample before: the rest state the step starts from
                u = p.log.tau[i0:s.i1] - p.G[i0:s.i1]
                out.steps.append((p.log.t[i0:s.i1], np.asarray(p.log.q[i0:s.i1], float), u, s, p.index))
    res_meta = [p.log.meta.get("encoder_resolution") for p in jd.preps if p.log.meta]
    res_meta = [float(r) for r in res_meta if r]
    qcat = (np.concatenate([q for q, _ in out.ramps] + [st[1] for st in out.steps]) if (out.ramps or out.steps)
            else np.zeros(0))
    out.resolution = res_meta[0] if res_meta else (pre.encoder_resolution(qcat) if qcat.size else 0.0)
    return out


def fit_lugre(jd: JointData, selected: str | None) -> None:
    """LuGre on the static map ``selected`` (the fit's choice): adds the ``lugre`` model and may make it the
    chosen one (see the module docstring)."""
    jf = jd.jf
    base_name = selected if selected in jf.models else None
    if base_name is None:
        jf.not_identified.append({"what": "lugre", "reason": "no static map to build on"})
        return
    base = jf.models[base_name]
    vals = base.values()
    if any(v is None for v in vals.values()):
        jf.not_identified.append({"what": "lugre", "reason": f"{base_name} has unknown parameters"})
        return
    c_pos, c_neg = sm.canonical_pair(base.map, vals)
    level, _ = _scalar_map(c_pos, c_neg)
    pd = presliding_data(jd)
    g_of = [abs(level(1e-12 if np.mean(F) >= 0 else -1e-12)) for _, F in pd.ramps]
    s0 = pre.fit_sigma0(pd.ramps, g_of, pd.resolution)
    s1 = _sigma1(jd, pd, s0, c_pos, c_neg)
    if pd.ramps:
        jd.used["ramp_presliding"] = pd.ramp_t
    params = static_params(base)
    params["sigma0"] = ParamEstimate("sigma0", s0.value, s0.stderr, unit_of("K", jd.axis), s0.identifiable,
                                     s0.reason, source=s0.source)
    params["sigma1"] = ParamEstimate("sigma1", s1.value, s1.stderr, unit_of("D", jd.axis), s1.identifiable,
                                     s1.reason, source=s1.source)
    met = dict(base.metrics)
    met["k"] = int((met.get("k") or 0) + 2)
    if s0.identifiable and pd.ramps:
        met.update(_presliding_rms(pd, g_of, s0, base_name, vals))
    mf = ModelFit("lugre", base.map if base_name != "polynomial_ls" else "polynomial", params, met,
                  method="static map on plateaus; sigma0 from ramps (torque against displacement); sigma1 "
                         + ("from steps (simulation error)" if "steps" in s1.source else
                            "by the critical-damping rule" if "rule" in s1.source else "not identified"),
                  notes=[f"static part: {base_name}"], extra={"static_model": base_name})
    jf.models["lugre"] = mf
    for n in ("sigma0", "sigma1"):
        if not params[n].identifiable:
            jf.not_identified.append({"what": f"lugre.{n}", "reason": params[n].reason})
    _lugre_choice(jd, mf, base_name)


def _sigma1(jd: JointData, pd: Presliding, s0: pre.DynamicEstimate, c_pos, c_neg) -> pre.DynamicEstimate:
    """sigma1 from the steps, else by the critical-damping rule (records the steps used)."""
    jf = jd.jf
    J = jf.inertia.value if jf.inertia and jf.inertia.value else None
    sig2 = c_pos[6] if abs(c_pos[6]) > 0 else 0.0
    if not (s0.identifiable and J):
        why = "needs sigma0" if not s0.identifiable else "needs the inertia J"
        return pre.DynamicEstimate(None, None, False, f"{why}, which is not identifiable", "")
    s1 = pre.fit_sigma1_steps([(t, q, u) for t, q, u, *_ in pd.steps], J, s0.value, c_pos, c_neg, sig2,
                              pd.resolution)
    if not s1.identifiable:
        why_steps = s1.reason
        s1 = pre.sigma1_rule(s0.value, s0.stderr, J, jf.inertia.stderr, sig2)
        s1.source += f" ({why_steps})"
    else:
        jd.used["step"] = [[float(s.t_start), float(s.t_end), src] for *_, s, src in pd.steps]
    return s1


def _presliding_rms(pd: Presliding, g_of: list[float], s0: pre.DynamicEstimate, base_name: str,
                    vals: dict) -> dict:
    """The presliding prediction on the ramps: LuGre (sigma0 bristles along the measured path) against the
    static map alone, and LuGre with sigma0 refitted without each ramp (RMS [F])."""
    lug, stat, held = [], [], []
    for i, ((q, F), g0, w) in enumerate(zip(pd.ramps, g_of, pd.ramp_w)):
        z0 = float(np.clip(F[0] / s0.value, -g0 / s0.value, g0 / s0.value))
        lug.append(s0.value * pre.bristle_path(q, z0, s0.value, g0) - F)
        stat.append(predict(base_name if base_name != "polynomial_ls" else "polynomial", vals, w) - F)
        if len(pd.ramps) >= 2:
            rest = [r for k, r in enumerate(pd.ramps) if k != i]
            gr = [g for k, g in enumerate(g_of) if k != i]
            e = pre.fit_sigma0(rest, gr, pd.resolution, starts=(s0.value,))
            if e.value:
                z0h = float(np.clip(F[0] / e.value, -g0 / e.value, g0 / e.value))
                held.append(e.value * pre.bristle_path(q, z0h, e.value, g0) - F)
    return {"rms_presliding": float(np.sqrt(np.mean(np.concatenate(lug) ** 2))),
            "rms_presliding_static": float(np.sqrt(np.nanmean(np.concatenate(stat) ** 2))),
            "rms_presliding_heldout": float(np.sqrt(np.mean(np.concatenate(held) ** 2))) if held else None}


def _lugre_choice(jd: JointData, mf: ModelFit, base_name: str) -> None:
    """LuGre replaces its map when identifiable and better on held-out presliding segments."""
    jf, met = jd.jf, mf.metrics
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
