"""The evidence sentence of each finding: the numbers behind it, in plain words."""
from __future__ import annotations

import math

import numpy as np

from ..models.static import canonical_friction
from .chain import Trial
from .model import canonical_vectors, low_speed_amps, term_name
from .samples import Samples
from .signals import REST_MIN, rests


def fmt(x: float) -> str:
    if x == 0 or not math.isfinite(x):
        return f"{x:.3g}"
    return f"{x:.3g}" if 1e-3 <= abs(x) < 1e5 else f"{x:.2e}"


def _duration(seconds: float) -> str:
    if seconds >= 2 * 3600:
        return f"{seconds / 3600:.1f} h"
    if seconds >= 120:
        return f"{seconds / 60:.0f} min"
    return f"{seconds:.0f} s"


def _corr(a, b) -> float:
    if a.size < 3 or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


def evidence(tr: Trial, S: Samples, step: dict, units: dict, rigid: dict) -> str:
    """One plain sentence with the numbers behind a finding (and the causes the data cannot tell from it)."""
    text = _evidence(tr, S, step, units, rigid)
    if tr.rivals:
        alt = ", ".join(f"{c} ({e}, held-out RMS {fmt(r)})" for c, e, r in tr.rivals)
        text += f"; the data cannot tell it from {alt}"
    return text


def _evidence(tr: Trial, S: Samples, step: dict, units: dict, rigid: dict) -> str:
    F_u, q_u = units["F"], units["q"]
    rb = S.F - tr.pred_before
    corr = tr.pred_after - tr.pred_before
    r = _corr(rb, corr)
    term = step["term"]
    nl = term.settings
    coef = step["coef"]
    st = step["structure"]
    i = len(st.terms) - 1
    g = np.atleast_1d(coef.gamma.get(i, np.zeros(0)))
    tail = (f"{term_name(st, coef, term.ext)} cuts held-out RMS from {fmt(tr.rms_before)} to {fmt(tr.rms_after)} "
            f"{F_u} ({100 * tr.gain:.0f} %)")
    ext = tr.ext
    if ext in ("thermal4", "thermal6"):
        return _thermal_evidence(S, nl, g if ext == "thermal4" else None, coef.dc, rb, r, F_u, tail)
    if ext == "position_periodic":
        amp = float(np.hypot(*g[:2]))
        return (f"friction level varies by +/-{100 * amp:.1f} % with position, period {fmt(nl['period'])} "
                f"{q_u} (r = {r:.2f}); a periodic position modulation: {tail}")
    if ext == "position_smooth":
        d = np.array([-1.0, 1.0])
        f = 1 + g[0] * d + g[1] * d * d
        return (f"friction level changes by {100 * (f[1] - f[0]):+.1f} % from one end of the "
                f"{fmt(2 * nl['qs'])} {q_u} of travel to the other (r = {r:.2f}); {tail}")
    if ext.startswith("load_"):
        var = {"load_torque": "load torque |J a + G(q)|", "load_gravity": "gravity torque |G(q)|",
               "load_payload": "payload"}[ext]
        unit = "kg" if ext == "load_payload" else F_u
        per = float(g[0]) / nl["scale"]
        return (f"friction level grows {100 * per * nl['scale']:+.1f} % per {fmt(nl['scale'])} {unit} of "
                f"{var} (r = {r:.2f}); a load-dependent level: {tail}")
    if ext in ("asym", "asym_scale", "asym_level"):
        v = np.abs(S.w)
        cp, cn = canonical_vectors(st, coef)
        Fp = np.abs(canonical_friction(v, cp, cp))
        Fn = np.abs(canonical_friction(-v, cn, cn))
        ratio = float(np.mean(Fn) / np.mean(Fp)) if np.mean(Fp) > 0 else float("nan")
        return (f"friction for w < 0 is {100 * abs(ratio - 1):.1f} % {'above' if ratio > 1 else 'below'} "
                f"that for w > 0 at the same speeds (r = {r:.2f}); "
                f"{ {'asym': 'per-sign parameters', 'asym_scale': 'the w < 0 branch scaled'}.get(ext, 'the w < 0 level scaled')}: {tail}")
    if ext == "stribeck":
        return _low_speed_evidence(low_speed_amps(st, coef) or [0.0], nl["vs"], r, F_u, q_u, tail)
    if ext == "inertia":
        J0 = rigid.get("J", 0.0)
        return (f"the residual tracks the acceleration (r = {r:.2f}): inertia {fmt(J0)} -> "
                f"{fmt(J0 + float(g[0]))} {units['J']}; {tail}")
    if ext == "gravity":
        return (f"the residual tracks cos q and sin q (r = {r:.2f}): gravity Px {fmt(rigid.get('Px', 0.0))} -> "
                f"{fmt(rigid.get('Px', 0.0) + float(g[0]))}, Py {fmt(rigid.get('Py', 0.0))} -> "
                f"{fmt(rigid.get('Py', 0.0) + float(g[1]))} {F_u}; {tail}")
    if ext == "offset":
        return (f"the residual carries a constant {fmt(float(g[0]))} {F_u} at both velocity signs "
                f"(r = {r:.2f}); a torque offset: {tail}")
    if ext in ("position_torque", "delay", "dwell"):
        return _outside_evidence(ext, S, nl, g, r, F_u, q_u, tail)
    if ext == "drift":
        span_h = float(np.ptp(S.th))
        return (f"friction changes {100 * float(g[0]):+.3g} % per hour ({100 * float(g[0]) * span_h:+.3g} % over "
                f"the {_duration(span_h * 3600)} between the first and last recording; r = {r:.2f}); a drift "
                f"term: {tail}")
    return f"r = {r:.2f}; {tail}"


def _low_speed_evidence(amps: list, vs: float, r: float, F_u: str, q_u: str, tail: str) -> str:
    """The sentence of a low-speed term by the sign of its amplitude on each branch: a Stribeck drop (the
    friction at rest above the sliding level), a low-speed rise (below it, rising to it), or, per sign, one
    of each (:func:`frictid.models.static.low_speed_name`)."""
    head = f"the residual concentrates at low speed, below about {fmt(3 * vs)} {q_u}/s (r = {r:.2f}); "
    if all(a >= 0 for a in amps):
        return head + f"a Stribeck term with vs = {fmt(vs)} {q_u}/s: {tail}"
    if all(a <= 0 for a in amps):
        by = " and ".join(f"{fmt(-a)} {F_u}" + (f" for {s}" if len(amps) > 1 else "")
                          for a, s in zip(amps, ("w > 0", "w < 0")))
        return (head + f"the friction there lies below the sliding level and rises to it ({by} below at rest, vs "
                f"= {fmt(vs)} {q_u}/s): a low-speed rise, not a Stribeck drop (its break-away level would be "
                f"below the Coulomb level): {tail}")
    parts = [f"{'a drop' if a > 0 else 'a rise'} of {fmt(abs(a))} {F_u} for {s}"
             for a, s in zip(amps, ("w > 0", "w < 0"))]
    return head + f"a low-speed term with vs = {fmt(vs)} {q_u}/s, {' and '.join(parts)}: {tail}"


def _thermal_evidence(S: Samples, nl: dict, g4, dc, rb, r: float, F_u: str, tail: str) -> str:
    """The sentence of a temperature finding: the model's mean friction at the coldest and the warmest
    thermal state of the recording (1st and 99th percentiles of the state, at the samples' speeds), not the
    ends of the logs laid end to end (a last log that starts cold hid a 20 % fall as 1.4 %)."""
    x = S.thermal_state(nl["tau_c"], measured=nl.get("source") == "temp_joint", K=nl.get("K", 1.0))
    lo, hi = np.percentile(x, [1, 99])
    sg = np.sign(S.w)
    L = float(np.mean(np.abs(S.F)))
    if g4 is not None:   # thermal4: the whole map times 1 + g x
        m = 1.0 + float(g4[0]) * x
        A, B = (L * (1.0 + float(g4[0]) * v) / float(np.mean(m)) for v in (lo, hi))
    else:                # thermal6: slopes of c0..c3 per unit of x
        w = S.w
        slope = float(np.mean((dc[0] * sg + dc[1] * w + dc[2] * w * np.abs(w) + dc[3] * w ** 3) * sg))
        A, B = (L + (v - float(np.mean(x))) * slope for v in (lo, hi))
    what = ("the measured joint temperature" if nl.get("source") == "temp_joint" else
            f"the estimated thermal state (time constant {_duration(nl['tau_c'])})")
    span = float(np.ptp(S.th)) * 3600
    rE = _corr(rb * sg, _cum_energy(S))
    return (f"friction {'falls' if B < A else 'rises'} from {fmt(A)} to {fmt(B)} {F_u} "
            f"({100 * (B / A - 1) if A else 0.0:+.0f} %, the mean over the recording's speeds) between the coldest "
            f"and the warmest state of {_duration(span)} of recording, tracking {what} (r = {r:.2f}; cumulative "
            f"friction energy r = {rE:.2f}); {tail}")


def _outside_evidence(ext: str, S: Samples, nl: dict, g: np.ndarray, r: float, F_u: str, q_u: str, tail: str) -> str:
    """The sentence of a cause outside the friction model (position torque, delay, dwell)."""
    if ext == "position_torque" and nl["period"] == 0:   # smooth over the travel
        d = np.linspace(-1.0, 1.0, 201)
        E = float(g[1]) * d + float(g[2]) * d * d
        return (f"a torque that does not change sign with the velocity varies smoothly with position: "
                f"{fmt(float(E.max() - E.min()))} {F_u} from end to end of the travel (a quadratic in q over "
                f"{fmt(2 * nl['qs'])} {q_u}; r = {r:.2f}); a spring, a cable carrier or a gravity harmonic "
                f"longer than the travel, not friction: the friction model does not carry it; {tail}")
    if ext == "position_torque":
        amp = float(np.hypot(*g[:2]))
        k = 2 * math.pi / nl["period"] if S.axis_rotary else 0.0
        kind = (f"a gravity harmonic (sin {k:.0f}q), a spring compensator or cogging" if abs(k - round(k)) < 1e-6
                and round(k) >= 2 else "cogging, a spring or a gravity harmonic")
        return (f"a torque that does not change sign with the velocity varies with position: amplitude "
                f"{fmt(amp)} {F_u}, period {fmt(nl['period'])} {q_u} (r = {r:.2f}); {kind}, not friction: the "
                f"friction model does not carry it; {tail}")
    if ext == "delay":
        d = float(nl.get("shift") or g[0])
        return (f"the residual tracks the rate of the measured torque (r = {r:.2f}): the torque "
                f"{'leads' if d > 0 else 'lags'} the motion by {1e3 * abs(d):.3g} ms (the shift that best fits "
                f"the friction torque of every moving sample; the sliding samples' coefficient "
                f"{1e3 * float(g[0]):.3g} ms; a signal delay, not friction: shift the torque or the position by "
                f"it before fitting); {tail}")
    tr = rests(S)[0]    # dwell
    tr = tr[tr >= REST_MIN]
    lo, hi = float(tr.min()), float(tr.max())
    x = np.log1p(np.array([lo, hi]) / nl["t0"])
    return (f"static friction grows with the time at rest before a move: the friction level just after a "
            f"rest of {fmt(hi)} s is {100 * float(g[0]) * (x[1] - x[0]):+.1f} % of that after {fmt(lo)} s "
            f"(ln(1 + t_rest / {fmt(nl['t0'])} s), fading over {fmt(nl['s_c'])} {q_u} of travel; r = {r:.2f}); "
            f"the friction model does not carry it; {tail}")


def _cum_energy(S: Samples) -> np.ndarray:
    """Cumulative friction energy [J] at the samples (per log, from its start, on the drift clock order)."""
    out = np.empty(S.n)
    base = 0.0
    for i, lg in enumerate(S.logs):
        # the energy P dt summed up in place in one array of the log's length (the periods, the products
        # and two sums held three at once: 87 MB over the diagnosis' arrays on a joint-hour, its peak)
        E = np.empty(lg.n)
        E[:1] = 0.0
        np.subtract(lg.t[1:], lg.t[:-1], out=E[1:])
        E *= S.power(i)
        np.cumsum(E, out=E)
        E += base
        sel = S.li == i
        out[sel] = E[S.k[sel]]
        base = float(E[-1]) if E.size else base
    return out
