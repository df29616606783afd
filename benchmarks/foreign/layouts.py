"""Experiment layouts: each builder appends one family's program to a :class:`sim.Program` and returns
what it drew (a dict kept in the truth sidecar).

Labels follow docs/segments.md: one ``constant_velocity`` segment per plateau (the moves into and out of
it are ``other``), one ``ramp_presliding`` per monotonic torque ramp (the hold at its peak and the settles
are ``rest``), one ``step`` per torque jump lasting until the next input (only the settle before a group's
first step is ``rest``), one ``duty_cycle`` per cycle (its motion and its rest), ``rest`` for dwells of at
least 0.2 s, ``other`` for every move (point-to-point cruise phases too: they are not an experiment).
"""
from __future__ import annotations

import math

import numpy as np

try:
    from . import sim
except ImportError:
    import sim

CL, OL = sim.CLOSED, sim.OPEN
#: Shortest dwell labelled ``rest`` [s] (frictid's T_MIN; shorter ones are part of the move).
T_REST = 0.2


def _lu(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


# -- closed-loop primitives -------------------------------------------------------------------------

def accel(pr: sim.Program, v0: float, v1: float, a: float, label: str = "other", index: int = -1):
    """Velocity ramp v0 -> v1 [q/s] at |acceleration| a [q/s^2]."""
    n = pr.ns(abs(v1 - v0) / a)
    wr = np.linspace(v0, v1, n + 1)[1:]
    qr = pr.q_now + np.cumsum(wr) / pr.fs
    pr.add(CL, qr, wr, 0.0, label, index)


def plateau(pr: sim.Program, v: float, T: float, label: str = "constant_velocity", index: int = -1):
    """Constant velocity v [q/s] for T [s]."""
    n = pr.ns(T)
    qr = pr.q_now + v * np.arange(1, n + 1) / pr.fs
    pr.add(CL, qr, v, 0.0, label, index)


def dwell(pr: sim.Program, T: float, label: str | None = None, index: int = -1):
    """Hold the position for T [s]: ``rest`` when at least T_REST long, else ``other``."""
    label = label or ("rest" if T >= T_REST else "other")
    pr.add(CL, np.full(pr.ns(T), pr.q_now), 0.0, 0.0, label, index)


def smooth_move(pr: sim.Program, q1: float, T: float, label: str = "other", index: int = -1):
    """Minimum-jerk move to q1 [q] in T [s]."""
    n = pr.ns(T)
    s = np.arange(1, n + 1) / n
    d = q1 - pr.q_now
    qr = pr.q_now + d * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)
    wr = d / T * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4)
    pr.add(CL, qr, wr, 0.0, label, index)


def ptp(pr: sim.Program, q1: float, vmax: float, amax: float, label: str = "other", index: int = -1):
    """Trapezoidal point-to-point move to q1 [q] at vmax [q/s], amax [q/s^2] (triangular when short)."""
    d = q1 - pr.q_now
    if abs(d) < 1e-12:
        return
    s = math.copysign(1.0, d)
    v = min(vmax, math.sqrt(abs(d) * amax))
    t_c = (abs(d) - v * v / amax) / v
    accel(pr, 0.0, s * v, amax, label, index)
    if t_c > 0:
        plateau(pr, s * v, t_c, label, index)
    accel(pr, s * v, 0.0, amax, label, index)
    # land exactly on the target (the sampled ramps leave a fraction of a sample of travel)
    pr.qr[-1][-1] = q1
    pr.q_now = q1


def open_loop(pr: sim.Program, u, label: str, index: int = -1):
    """Open-loop torque u [N m] per sample (on top of the gravity torque held at the stretch's start)."""
    u = np.asarray(u, dtype=float)
    pr.add(OL, np.full(u.size, pr.q_now), 0.0, u, label, index)


# -- families --------------------------------------------------------------------------------------

def _speed_order(rng, speeds, order):
    if order == "descending":
        return speeds[::-1]
    if order == "shuffled":
        return speeds[rng.permutation(speeds.size)]
    return speeds


def sweep(pr, sc, rng) -> dict:
    """Velocity plateaus: 6..20 log-spaced speeds from 0.3..5 % of w_top to w_top, both signs, order
    ascending / descending / shuffled, style ``reposition`` (a smooth move back and a dwell before each
    plateau), ``back_and_forth`` (+v then -v, dwells between) or ``chain`` (plateau to plateau without
    stopping, one sign after the other); plateaus 0.3..5 s, accelerations reaching w_top in 0.05..1 s."""
    n = int(rng.integers(6, 21))
    speeds = np.geomspace(sc.w_top * _lu(rng, 0.003, 0.05), sc.w_top, n)
    order = str(rng.choice(["ascending", "descending", "shuffled"]))
    style = str(rng.choice(["reposition", "back_and_forth", "chain"]))
    T = _lu(rng, 0.3, 5.0)
    a = sc.w_top / _lu(rng, 0.05, 1.0)
    t_dwell = _lu(rng, 0.05, 2.0)
    t_move = _lu(rng, 0.5, 3.0)
    speeds = _speed_order(rng, speeds, order)
    dwell(pr, _lu(rng, 0.5, 3.0))
    if style == "chain":
        for s in (1.0, -1.0):
            v_prev = 0.0
            for v in speeds:
                accel(pr, v_prev, s * v, a)
                plateau(pr, s * v, T)
                v_prev = s * v
            accel(pr, v_prev, 0.0, a)
            dwell(pr, t_dwell)
    else:
        for v in speeds:
            for s in (1.0, -1.0):
                if style == "reposition":
                    smooth_move(pr, -s * (v * T / 2 + v * v / (2 * a)), t_move)
                    dwell(pr, t_dwell)
                accel(pr, 0.0, s * v, a)
                plateau(pr, s * v, T)
                accel(pr, s * v, 0.0, a)
                dwell(pr, t_dwell)
    dwell(pr, _lu(rng, 0.5, 3.0))
    return {"speeds": speeds.tolist(), "order": order, "style": style, "plateau": T, "accel": a,
            "dwell": t_dwell, "move": t_move}


def issue19_sweep(pr, sc, rng) -> dict:
    """Issue 19 (a): 16 log-spaced speeds 0.01..2 rad/s ascending, each in both directions, 2 s plateaus,
    a smooth 1.5 s repositioning move and a short (0.2..0.5 s) dwell before each plateau."""
    speeds = np.geomspace(0.01, 2.0, 16)
    a = _lu(rng, 5.0, 20.0)
    t_dwell = rng.uniform(0.2, 0.5)
    dwell(pr, 1.0)
    for v in speeds:
        for s in (1.0, -1.0):
            smooth_move(pr, -s * (v + v * v / (2 * a)), 1.5)
            dwell(pr, t_dwell)
            accel(pr, 0.0, s * v, a)
            plateau(pr, s * v, 2.0)
            accel(pr, s * v, 0.0, a)
    dwell(pr, 1.0)
    return {"speeds": speeds.tolist(), "accel": a, "dwell": t_dwell}


def ramp_group(pr, peaks, t_up, t_hold, t_down, t_settle):
    """Open-loop ramps 0 -> P -> 0 per peak P [N m], holds and settles as ``rest``."""
    open_loop(pr, np.zeros(pr.ns(t_settle)), "rest")
    for P in peaks:
        nu, nh, nd = pr.ns(t_up), pr.ns(t_hold), pr.ns(t_down)
        open_loop(pr, P * np.arange(1, nu + 1) / nu, "ramp_presliding", pr.next_index("ramp"))
        if t_hold > 0:
            open_loop(pr, np.full(nh, P), "rest")
        open_loop(pr, P * (1.0 - np.arange(1, nd + 1) / nd), "ramp_presliding", pr.next_index("ramp"))
        open_loop(pr, np.zeros(pr.ns(t_settle)), "rest")


def ramps(pr, sc, rng) -> dict:
    """Presliding ramps to 30..90 % of the break-away level Fs (1..4 peaks, one or both signs), ramps
    1..6 s, holds 0..2 s, settles 0.5..2 s."""
    k = int(rng.integers(1, 5))
    frac = rng.uniform(0.3, 0.9, k)
    signs = [1.0, -1.0] if rng.random() < 0.7 else [float(rng.choice([1.0, -1.0]))]
    peaks = [s * f * sc.plant.Fs for s in signs for f in frac]
    t_up, t_down = rng.uniform(1.0, 6.0), rng.uniform(1.0, 6.0)
    t_hold = 0.0 if rng.random() < 0.2 else rng.uniform(0.2, 2.0)
    t_settle = rng.uniform(0.5, 2.0)
    dwell(pr, rng.uniform(0.5, 2.0))
    ramp_group(pr, peaks, t_up, t_hold, t_down, t_settle)
    dwell(pr, rng.uniform(0.5, 2.0))
    return {"peaks": peaks, "ramp_up": t_up, "ramp_down": t_down, "hold": t_hold, "settle": t_settle,
            "load": float(np.mean(frac)) / 2}


def issue19_ramps(pr, sc, rng) -> dict:
    """Issue 19 (b): open-loop ramps to +85 % and -85 % of the Coulomb level and back, 4 s ramps, 1 s
    holds, 1 s settles; the creep (0.2..0.6 mrad/s at the ramps' mean load) is set by the caller."""
    peaks = [0.85 * sc.plant.Fc, -0.85 * sc.plant.Fc]
    dwell(pr, 1.0)
    ramp_group(pr, peaks, 4.0, 1.0, 4.0, 1.0)
    dwell(pr, 1.0)
    return {"peaks": peaks, "ramp_up": 4.0, "ramp_down": 4.0, "hold": 1.0, "settle": 1.0, "load": 0.425}


def steps(pr, sc, rng) -> dict:
    """Open-loop torque steps to 20..80 % of Fs and back to zero (1..3 levels, one or both signs), held
    0.5..3 s, released 0.5..3 s; labels as docs/segments.md (a step lasts until the next input; the
    loop's bumpless take-over of the still joint afterwards is no input)."""
    k = int(rng.integers(1, 4))
    levels = rng.uniform(0.2, 0.8, k) * sc.plant.Fs
    signs = [1.0, -1.0] if rng.random() < 0.7 else [float(rng.choice([1.0, -1.0]))]
    t_hold, t_rel = rng.uniform(0.5, 3.0), rng.uniform(0.5, 3.0)
    dwell(pr, rng.uniform(0.5, 2.0))
    open_loop(pr, np.zeros(pr.ns(rng.uniform(0.5, 1.5))), "rest")
    for s in signs:
        for P in levels:
            open_loop(pr, np.full(pr.ns(t_hold), s * P), "step", pr.next_index("step"))
            open_loop(pr, np.zeros(pr.ns(t_rel)), "step", pr.next_index("step"))
    # the loop takes the still joint back bumplessly: nothing in the data marks it, so the last step's
    # still tail goes on (a step lasts until the next input)
    dwell(pr, rng.uniform(1.0, 3.0), label="step", index=pr.counters["step"])
    return {"levels": (levels).tolist(), "signs": signs, "hold": t_hold, "release": t_rel}


def _ptp_program(pr, sc, rng, n_moves, span, label="other", index=-1, dwell_max=2.0):
    """n_moves random point-to-point moves within +-span [q] around the current position at 10..100 %
    of w_top, reaching their speed in 0.05..0.5 s, dwells 0..dwell_max s."""
    q_c = pr.q_now
    for _ in range(n_moves):
        ptp(pr, q_c + rng.uniform(-span, span), sc.w_top * rng.uniform(0.1, 1.0),
            sc.w_top / _lu(rng, 0.05, 0.5), label, index)
        T = rng.uniform(0.0, dwell_max)
        if T * pr.fs >= 1:
            dwell(pr, T, label=None if label == "other" else label, index=index)


def ptp_family(pr, sc, rng) -> dict:
    """Random point-to-point program (no experiment): 20..60 moves over +-(0.5..3) s of travel at w_top,
    dwells 0..2 s."""
    n = int(rng.integers(20, 61))
    span = sc.w_top * rng.uniform(0.5, 3.0)
    dwell(pr, rng.uniform(0.5, 2.0))
    _ptp_program(pr, sc, rng, n, span)
    dwell(pr, rng.uniform(0.5, 2.0))
    return {"moves": n, "span": span}


def duty(pr, sc, rng) -> dict:
    """Duty cycles: 3..8 identical cycles of 4..40 s, rest 0..95 % of each; the moving part is
    back-and-forth point-to-point moves between two positions (1..3 s of travel at w_top apart) at
    30..100 % of w_top with 0..0.3 s dwells, repeated while they fit."""
    n_cyc = int(rng.integers(3, 9))
    period = rng.uniform(4.0, 40.0)
    rest_frac = rng.uniform(0.0, 0.95)
    d = sc.w_top * rng.uniform(1.0, 3.0)
    v, a = sc.w_top * rng.uniform(0.3, 1.0), sc.w_top / _lu(rng, 0.05, 0.5)
    t_dw = rng.uniform(0.0, 0.3)
    dwell(pr, rng.uniform(1.0, 3.0))
    n_period = pr.ns(period)
    q0 = pr.q_now
    for _ in range(n_cyc):
        k = pr.next_index("duty")
        start = pr.n
        while True:
            before = pr.n
            ptp(pr, q0 + d, v, a, "duty_cycle", k)
            dwell(pr, max(t_dw, 1.0 / pr.fs), "duty_cycle", k)
            ptp(pr, q0, v, a, "duty_cycle", k)
            dwell(pr, max(t_dw, 1.0 / pr.fs), "duty_cycle", k)
            if pr.n - start + (pr.n - before) > (1.0 - rest_frac) * n_period:
                break
        dwell(pr, max(n_period - (pr.n - start), 1) / pr.fs, "duty_cycle", k)
    dwell(pr, rng.uniform(1.0, 3.0))
    return {"cycles": n_cyc, "period": period, "rest_fraction": rest_frac, "distance": d, "speed": v}


def session(pr, sc, rng) -> dict:
    """Two to four experiments (sweep, ramps, steps, duty, ptp) in random order, each followed by an idle
    rest of 1..10 s and a smooth move back near the start."""
    names = ["sweep", "ramps", "steps", "duty", "ptp"]
    pick = [names[i] for i in rng.permutation(len(names))[:int(rng.integers(2, 5))]]
    info = {"parts": pick}
    for name in pick:
        info[name] = BUILDERS[name](pr, sc, rng)
        dwell(pr, rng.uniform(1.0, 10.0))
        smooth_move(pr, rng.uniform(-0.2, 0.2) * sc.w_top, rng.uniform(0.5, 2.0))
        dwell(pr, rng.uniform(0.5, 2.0))
    return info


def _combo(parts):
    def build(pr, sc, rng):
        info = {"parts": list(parts)}
        for name in parts:
            info[name] = BUILDERS[name](pr, sc, rng)
            dwell(pr, rng.uniform(1.0, 5.0))
        info["load"] = info.get("issue19_ramps", info.get("ramps", {})).get("load", 0.425)
        return info
    build.__doc__ = "The families " + ", ".join(parts) + " one after another, idle 1..5 s between."
    return build


def ptp_excitation(pr, sc, rng) -> dict:
    """An identification run without plateaus: 60..120 random point-to-point moves (the sample basis)."""
    n = int(rng.integers(60, 121))
    span = sc.w_top * rng.uniform(0.5, 3.0)
    dwell(pr, 1.0)
    _ptp_program(pr, sc, rng, n, span, dwell_max=0.5)
    dwell(pr, 1.0)
    return {"moves": n, "span": span}


BUILDERS = {
    "sweep": sweep, "issue19_sweep": issue19_sweep, "ramps": ramps, "issue19_ramps": issue19_ramps,
    "steps": steps, "duty": duty, "ptp": ptp_family, "session": session,
    "sweep_ramps_steps": _combo(("sweep", "ramps", "steps", "ptp")),
    "issue19_ramps_sweep": _combo(("sweep", "issue19_ramps")),
    "ptp_excitation": ptp_excitation,
}
