"""Hidden effects for the diagnosis scorecard (issue 20): long logs of the independent simulator with an
effect frictid's base model does not have, of a random kind, size and setting.

    from effects import make_card_logs
    paths, truth = make_card_logs(300042, "/tmp/out")

One draw (``draw_card``): the plant, controller and sensors of ``scenarios.draw`` (the rate redrawn for
long logs, below), a long program of experiments and work with rests of 0.1..60 s between them
(``CARD_FAMILIES``), and none, one or two hidden effects (``KINDS``). The physics of every effect is in the
simulator's kernel (``sim._effects``); this module draws the kinds, sizes and settings and writes the logs.

Size: the RMS change the effect makes to the torque on sliding samples (true speed above 2 % of the top
speed, outside rests, ramps and steps) over the RMS of the friction there; for friction effects that is
the change of the true friction, for non-friction torques (gravity harmonic, cogging) the torque itself,
for a delay the change of the logged torque. A draw's target size (3..40 %) sets the effect's coefficient
from the reference program (the planned motion); the size written to the truth is measured on the
simulated motion. Only the scorecard and the tests read the truth; frictid never does.

Seeds: the diagnosis scorecard uses seeds >= 300000 (the other cards 100000.. and 200000..; tests < 1000).
Random streams: ``scenarios.draw(seed)`` for the plant, controller and sensors (the same as the other
cards' draw of that seed), ``[seed, 3]`` for the card's own draws (rate, length, effects), ``[seed, 1]``
for the program, ``[seed, 2]`` (``[seed, 2, k]`` per recording) for the sensor noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

try:
    from . import layouts, scenarios, sim
except ImportError:  # run as a script from this folder
    import layouts
    import scenarios
    import sim

#: Effects on frictid's candidate list (docs/diagnosis.md) and the cause a right diagnosis names.
IN_LIST = {"temperature": ("temperature",), "temperature_logged": ("temperature",), "load": ("load",),
           "position": ("position",), "drift": ("drift",), "asymmetry": ("asymmetry",)}
#: Effects outside that list (issue 20): the names a diagnosis that gained such a candidate may give them
#: (matched as substrings of the cause); until it has one, the right answer is no name and "unexplained".
OUTSIDE = {"dwell": ("dwell",), "delay": ("delay",), "gravity2": ("harmonic", "spring", "non_friction",
                                                                  "nonfriction", "position_torque", "torque_position"),
           "cogging": ("cogging", "harmonic", "non_friction", "nonfriction", "position_torque",
                       "torque_position"),
           "cycling": ("cycl", "time_periodic", "periodic_time")}
KINDS = tuple(IN_LIST) + tuple(OUTSIDE)
#: Effects outside the list added after the card's first seeds: ``memory``, a friction level that grows with
#: the travel of the previous move and fades over the current one (a hysteresis of the lubricant film: a long
#: stroke pushes the grease to its ends, and the next move starts on a thinner film), a function of neither
#: the speed, the rest, the time nor the position. Drawn on request (``--effect memory``) and, for seeds from
#: :data:`MIX_FROM` on, in the default mix (:func:`_mixed`).
EXTRA_OUTSIDE = {"memory": ("memory", "hysteresis", "previous_move")}
ALL_OUTSIDE = {**OUTSIDE, **EXTRA_OUTSIDE}
ALL_KINDS = KINDS + tuple(EXTRA_OUTSIDE)
#: First seed whose default draw may be a kind of :data:`EXTRA_OUTSIDE` (session 22): every earlier seed draws
#: exactly what it drew before.
MIX_FROM = 320500
#: Long-log programs: experiments and work blocks with rests between them.
CARD_FAMILIES = ("sweeps_work", "work", "sweeps")
#: Card defaults: log rate [Hz] (log-uniform) and log length [min] (log-uniform).
RATE = (100.0, 500.0)
MINUTES = (15.0, 45.0)
#: Share of draws with nothing hidden, and with two effects at once.
P_CLEAN, P_TWO = 0.15, 0.2
#: Target size range [1] (uniform).
SIZE = (0.03, 0.40)


@dataclass
class CardDraw:
    """One draw of the card: the scenario, the card family, log rate [Hz], length [s], effects (dicts with
    kind, target size and settings) and, for a drift, the recordings' start times [s since the epoch]."""

    seed: int
    family: str
    sc: scenarios.Scenario
    fs: float
    seconds: float
    effects: list = field(default_factory=list)
    starts: list = field(default_factory=list)


def expected(kind: str) -> tuple:
    """Cause names a right diagnosis gives an effect of ``kind`` (substrings for effects outside the list)."""
    return IN_LIST.get(kind) or ALL_OUTSIDE[kind]


def names_effect(kind: str, cause: str) -> bool:
    """Whether a named ``cause`` is the right name of a hidden effect of ``kind``."""
    if kind in IN_LIST:
        return cause in IN_LIST[kind]
    return any(k in cause for k in ALL_OUTSIDE[kind])


def draw_card(seed: int, family: str | None = None, effect: str | None = None,
              minutes: tuple = MINUTES, rate: tuple = RATE) -> CardDraw:
    """The card's draw of ``seed``: scenario, program family, rate, length and hidden effects. ``family``
    and ``effect`` (a kind, ``none``, or ``pair``) force a choice; the seed's other draws stay the same."""
    rng = np.random.default_rng([seed, 3])
    fam = str(rng.choice(CARD_FAMILIES))
    family = family or fam
    sc = scenarios.draw(seed, "sweep", scenarios.FIT_FAMILIES)
    fs = float(round(scenarios.loguniform(rng, *rate)))
    sc.sensors.fs = fs
    seconds = 60.0 * scenarios.loguniform(rng, *minutes)
    u, k1, k2 = rng.random(), rng.integers(len(KINDS)), rng.permutation(len(IN_LIST))
    sizes = rng.uniform(*SIZE, 2)
    if effect is None:
        effect = _mixed(seed, "none" if u < P_CLEAN else ("pair" if u < P_CLEAN + P_TWO else KINDS[int(k1)]))
    if effect == "none":
        kinds = []
    elif effect == "pair":
        ins = [str(k) for k in np.array(list(IN_LIST))[k2] if k != "temperature_logged"]
        kinds = ins[:2]
    else:
        kinds = [effect]
    effects = [{"kind": k, "size_target": float(s)} for k, s in zip(kinds, sizes)]
    starts = []
    if any(e["kind"] == "drift" for e in effects):
        n_rec = int(rng.integers(2, 5))
        gaps = [3600.0 * scenarios.loguniform(rng, 1.0, 72.0) for _ in range(n_rec - 1)]
        t0 = 1.79e9 + 86400.0 * rng.uniform(0.0, 300.0)
        starts = [t0 + sum(gaps[:i]) for i in range(n_rec)]
    for e in effects:
        e.update(_settings(e["kind"], rng, sc, seconds))
    return CardDraw(seed, family, sc, fs, seconds, effects, starts)


def _mixed(seed: int, effect: str) -> str:
    """The default draw's effect with the kinds of :data:`EXTRA_OUTSIDE` in the mix, for seeds from
    :data:`MIX_FROM` on: a single effect becomes one of them with the share each of the
    ``len(KINDS) + len(EXTRA_OUTSIDE)`` kinds would have, chosen on a stream of its own (``[seed, 4]``), so the
    seed's other draws (plant, program, sizes, the other kinds) stay what they were."""
    if seed < MIX_FROM or effect not in KINDS:
        return effect
    extra = tuple(EXTRA_OUTSIDE)
    u = np.random.default_rng([seed, 4]).random() * (len(KINDS) + len(extra))
    return extra[int(u)] if u < len(extra) else effect


def _settings(kind: str, rng, sc, seconds: float) -> dict:
    """The drawn settings of one effect (its coefficient is set later, from the target size)."""
    if kind.startswith("temperature"):
        return {"tau_th": seconds * rng.uniform(0.1, 0.5), "rise_K": rng.uniform(10.0, 40.0)}
    if kind == "position":
        return {"cycles": scenarios.loguniform(rng, 2.0, 30.0), "phase": rng.uniform(-math.pi, math.pi)}
    if kind == "asymmetry":
        return {"variant": str(rng.choice(["scale", "coulomb"])), "sign": float(rng.choice([-1.0, 1.0]))}
    if kind == "drift":
        return {"sign": float(rng.choice([-1.0, 1.0]))}
    if kind == "load":
        A, phi = sc.plant.Fc * scenarios.loguniform(rng, 2.0, 20.0), rng.uniform(-math.pi, math.pi)
        return {"arm": [A * math.cos(phi), A * math.sin(phi)]}
    if kind == "dwell":
        return {"t0": rng.uniform(0.05, 0.5), "s0": sc.w_top * rng.uniform(0.05, 0.5), "w_still": 0.01 * sc.w_top}
    if kind == "gravity2":
        return {"phase": rng.uniform(-math.pi, math.pi)}
    if kind == "cycling":
        return {"period": min(60.0 * scenarios.loguniform(rng, 2.0, 10.0), seconds / 3.0),
                "phase": rng.uniform(-math.pi, math.pi)}
    if kind == "memory":   # reference travel of the previous move and fading travel of the current one
        return {"s_ref": sc.w_top * rng.uniform(0.3, 3.0), "s_fade": sc.w_top * rng.uniform(0.05, 0.5),
                "w_still": 0.01 * sc.w_top}
    if kind == "cogging":
        per_rev = float(rng.integers(6, 73)) if sc.plant.axis == "rotary" else 2 * math.pi / rng.uniform(0.01, 0.05)
        return {"n": per_rev, "phase": rng.uniform(-math.pi, math.pi)}
    return {}


# -- programs -------------------------------------------------------------------------------------------

def build_program(pr: sim.Program, sc, rng, family: str, seconds: float) -> list:
    """Append blocks of ``family`` until ``seconds`` [s] of log: ``sweeps`` (random velocity sweeps),
    ``work`` (duty cycles and point-to-point programs), ``sweeps_work`` (a sweep, then work with a sweep
    every third block, and a sweep at the end); each block followed by a rest of 0.1..60 s (log-uniform).
    Returns the blocks' names."""
    blocks = []
    work = ("duty", "ptp", "ptp_excitation")
    while pr.n < seconds * pr.fs:
        if family == "sweeps" or (family == "sweeps_work" and len(blocks) % 3 == 0):
            name = "sweep"
        else:
            name = work[int(rng.integers(len(work)))]
        layouts.BUILDERS[name](pr, sc, rng)
        layouts.dwell(pr, scenarios.loguniform(rng, 0.1, 60.0))
        blocks.append(name)
    if family == "sweeps_work" and blocks[-1] != "sweep":
        layouts.sweep(pr, sc, rng)
        blocks.append("sweep")
    return blocks


# -- sizes on the planned motion -----------------------------------------------------------------------

def _sliding(w, label, w_top: float) -> np.ndarray:
    """Sliding samples: speed above 2 % of the top speed, outside rests, ramps and steps."""
    off = np.isin(label, [sim.CODE["rest"], sim.CODE["ramp_presliding"], sim.CODE["step"]])
    return (np.abs(w) > 0.02 * w_top) & ~off


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else 0.0


def _first_order(x, dt: float, tau: float) -> np.ndarray:
    """State of dy/dt = (x - y) / tau from y = 0, exact for x held per step."""
    from scipy.signal import lfilter
    a = math.exp(-dt / tau)
    return lfilter([1.0 - a], [1.0, -a], x)


def _rest_clock(w, dt: float, w_still: float):
    """Per sample: the length [s] of the rest before the current motion (or of the current rest so far)
    and the travel [q] since that motion started (0 at rest), as the kernel's dwell clock counts them."""
    still = np.abs(w) < w_still
    n = w.size
    t_rest, s = np.zeros(n), np.zeros(n)
    run_t, last, trav = 0.0, 0.0, 0.0
    for i in range(n):     # plain loop on the planned motion (a few 1e5 samples: well under a second)
        if still[i]:
            run_t += dt
            last, trav = run_t, 0.0
        else:
            run_t = 0.0
            trav += abs(w[i]) * dt
        t_rest[i], s[i] = last, trav
    return t_rest, s


def _move_memory(w, dt: float, w_still: float):
    """Per sample: the travel [q] of the current move (since a rest or a reversal) and of the previous move,
    as the kernel's memory clock counts them."""
    n = w.size
    s_cur, s_prev = np.zeros(n), np.zeros(n)
    cur, prev, sg0 = 0.0, 0.0, 0.0
    for i in range(n):     # plain loop on the planned motion
        sg = 0.0 if abs(w[i]) < w_still else math.copysign(1.0, w[i])
        if sg != sg0 and cur > 0.0:
            prev, cur = cur, 0.0
        sg0 = sg
        if sg != 0.0:
            cur += abs(w[i]) * dt
        s_cur[i], s_prev[i] = cur, prev
    return s_cur, s_prev


def unit_change(kind: str, e: dict, plant: sim.Plant, ref: dict, fs: float) -> np.ndarray:
    """The torque change [N m] per unit coefficient of an effect along the planned motion ``ref`` (q, w, a:
    the program's references; G the gravity with any load arm), the scale of its coefficient."""
    q, w, a = ref["q"], ref["w"], ref["a"]
    lvl = plant.g(w) * np.sign(w)
    F = lvl + plant.sigma2 * w
    if kind.startswith("temperature"):
        return ref["theta"] * F
    if kind == "load":
        return np.abs(plant.J * a + ref["G"]) / ref["L_ref"] * lvl
    if kind == "position":
        return np.sin(2 * math.pi * q / e["period"] + e["phase"]) * lvl
    if kind == "asymmetry":
        return (w < 0) * (F if e["variant"] == "scale" else lvl)
    if kind == "dwell":
        t_rest, s = _rest_clock(w, 1.0 / fs, e["w_still"])
        return plant.Fc * np.log1p(t_rest / e["t0"]) * np.exp(-s / e["s0"]) * np.sign(w)
    if kind == "gravity2":
        return np.sin(2 * q + e["phase"])
    if kind == "cycling":
        return np.sin(2 * math.pi * np.arange(w.size) / fs / e["period"] + e["phase"]) * lvl
    if kind == "memory":
        s_cur, s_prev = _move_memory(w, 1.0 / fs, e["w_still"])
        moving = np.abs(w) >= e["w_still"]
        return moving * (1 - np.exp(-s_prev / e["s_ref"])) * np.exp(-s_cur / e["s_fade"]) * lvl
    if kind == "cogging":
        return np.sin(e["n"] * q + e["phase"])
    if kind == "delay":
        tau = plant.J * a + ref["G"] + F
        return np.gradient(tau, 1.0 / fs)   # tau(t - d) - tau(t) ~ -d dtau/dt
    raise ValueError(kind)


#: Caps of the coefficients (the largest change where the effect is largest), so that no draw is unphysical:
#: friction stays positive, the break-away at most 4 Fc; a size the cap stops short of is measured as it is.
CAPS = {"temperature": 0.6, "temperature_logged": 0.6, "load": 1.0, "position": 0.8, "asymmetry": 0.8,
        "drift": 0.6, "dwell": 3.0, "cycling": 0.6, "memory": 1.0}
#: Time constant [s] over which the friction follows the transmitted torque (a gear's contact load does
#: not follow the loop's sub-millisecond torque swings).
LOAD_FILTER = 0.02
#: Longest torque-motion delay [s].
DELAY_MAX = 0.05


def _reference(pr: sim.Program, plant: sim.Plant, fs: float) -> dict:
    """The planned motion of a program: q, w, a [q, q/s, q/s^2], gravity G [N m], labels."""
    arr = pr.arrays()
    q, w = arr["qr"], arr["wr"]
    return {"q": q, "w": w, "a": np.gradient(w, 1.0 / fs), "G": plant.Px * np.cos(q) + plant.Py * np.sin(q),
            "label": arr["label"]}


def _prepare(e: dict, d: CardDraw, plant: sim.Plant, refs: list, F: list, m: list) -> None:
    """Settings an effect takes from the planned motions: the warm-up's reference power ``P_ref`` [W] and
    thermal states, the load's reference torque ``L_ref`` [N m], the ripple's period [q]."""
    kind = e["kind"]
    if kind.startswith("temperature"):
        P = [np.abs(f * r["w"]) for f, r in zip(F, refs)]
        e["P_ref"] = float(np.mean(np.concatenate(P))) or 1.0
        for r, p in zip(refs, P):
            r["theta"] = _first_order(p / e["P_ref"], 1.0 / d.fs, e["tau_th"])
    elif kind == "load":
        x = np.concatenate([np.abs(plant.J * r["a"] + r["G"])[k] for r, k in zip(refs, m)])
        e["L_ref"] = _rms(x) or plant.Fc
        for r in refs:
            r["L_ref"] = e["L_ref"]
    elif kind == "position":
        span = np.ptp(np.concatenate([r["q"][k] for r, k in zip(refs, m)]))
        e["period"] = float(max(span / e["cycles"], 20.0 * d.sc.w_top / d.fs))


def _peak(kind: str, plant: sim.Plant, refs: list, units: list) -> float:
    """The largest change of the effect's factor per unit coefficient (what ``CAPS`` bounds)."""
    if kind.startswith("temperature"):
        return max(float(np.max(r["theta"])) for r in refs)
    if kind == "load":
        return max(float(np.max(np.abs(plant.J * r["a"] + r["G"]))) for r in refs) / refs[0]["L_ref"]
    if kind == "dwell":
        return max(float(np.max(np.abs(u))) for u in units) / plant.Fc
    return 1.0      # a sine, a branch or recording factor: at most the coefficient itself


def calibrate(d: CardDraw, plant: sim.Plant, refs: list) -> None:
    """Set each effect's coefficient from its target size on the planned motions ``refs`` (one per
    recording), within ``CAPS``; records ``coef`` and the planned size ``size_plan`` in the effect."""
    F = [plant.static(r["w"]) for r in refs]
    m = [_sliding(r["w"], r["label"], d.sc.w_top) for r in refs]
    R = _rms(np.concatenate([f[k] for f, k in zip(F, m)]))
    for e in d.effects:
        kind = e["kind"]
        _prepare(e, d, plant, refs, F, m)
        if kind == "drift":
            frac = (np.asarray(d.starts) - d.starts[0]) / (d.starts[-1] - d.starts[0])
            units = [fr * f for fr, f in zip(frac, F)]
        else:
            units = [unit_change(kind, e, plant, r, d.fs) for r in refs]
        per_unit = _rms(np.concatenate([u[k] for u, k in zip(units, m)])) / R if R > 0 else 0.0
        c = e["size_target"] / per_unit if per_unit > 0 else 0.0
        if kind == "delay":
            c = min(c, DELAY_MAX)
        elif kind in CAPS:
            c = min(c, CAPS[kind] / max(_peak(kind, plant, refs, units), 1e-12))
        sign = -1.0 if kind.startswith("temperature") else e.get("sign", 1.0)
        e["coef"] = float(sign * c)
        e["size_plan"] = float(c * per_unit)


def fx_array(d: CardDraw, plant: sim.Plant, k: int = 0) -> np.ndarray:
    """The kernel's effect array (``sim.FX``) of the draw's effects, for recording ``k``."""
    fx = np.zeros(len(sim.FX))
    i = sim.FXI
    fx[i["on"]] = fx[i["m_all"]] = 1.0
    fx[i["tau_th"]] = fx[i["P_ref"]] = fx[i["L_ref"]] = fx[i["period"]] = 1.0
    fx[i["t0W"]] = fx[i["s0W"]] = fx[i["Tcyc"]] = 1.0
    fx[i["sM"]] = fx[i["fM"]] = 1.0
    for e in d.effects:
        kind, c = e["kind"], e["coef"]
        if kind.startswith("temperature"):
            fx[i["kT"]], fx[i["tau_th"]], fx[i["P_ref"]] = c, e["tau_th"], e["P_ref"]
        elif kind == "load":
            fx[i["kL"]], fx[i["L_ref"]], fx[i["tau_load"]] = c, e["L_ref"], LOAD_FILTER
        elif kind == "position":
            fx[i["aP"]], fx[i["period"]], fx[i["phiP"]] = c, e["period"], e["phase"]
        elif kind == "asymmetry":
            fx[i["kA_level"]] = c
            fx[i["kA_visc"]] = c if e["variant"] == "scale" else 0.0
        elif kind == "drift":
            fx[i["m_all"]] = 1.0 + c * (d.starts[k] - d.starts[0]) / (d.starts[-1] - d.starts[0])
        elif kind == "dwell":
            fx[i["kW"]], fx[i["t0W"]], fx[i["s0W"]], fx[i["w_still"]] = c, e["t0"], e["s0"], e["w_still"]
        elif kind == "gravity2":
            fx[i["bG2"]], fx[i["phiG2"]] = c, e["phase"]
        elif kind == "cogging":
            fx[i["cC"]], fx[i["nC"]], fx[i["phiC"]] = c, e["n"], e["phase"]
        elif kind == "cycling":
            fx[i["aCyc"]], fx[i["Tcyc"]], fx[i["phiCyc"]] = c, e["period"], e["phase"]
        elif kind == "memory":
            fx[i["kM"]], fx[i["sM"]], fx[i["fM"]], fx[i["w_stillM"]] = c, e["s_ref"], e["s_fade"], e["w_still"]
    return fx


def measured_change(out: dict, plant: sim.Plant, w_top: float, delay: float) -> tuple:
    """(torque change [N m], base friction [N m]) on the sliding samples of a simulated recording: the
    effects' change of the friction level and viscous part at the true state, their non-friction torque,
    and the change of the logged torque a delay makes."""
    w = out["w"]
    m = _sliding(w, out["label"], w_top)
    dT = (out["g_eff"] - plant.g(w)) * np.sign(w) + (out["mV"] - 1.0) * plant.sigma2 * w + out["E"]
    if delay > 0:
        dT = dT + np.interp(out["t"] - delay, out["t"], out["tau"]) - out["tau"]
    return dT[m], plant.static(w)[m]


def offset_distinct(out: dict, plant: sim.Plant, w_top: float, e: dict) -> np.ndarray:
    """The part [N m] of an asymmetry's torque change that no torque offset with a symmetric map can make,
    on the sliding samples of a simulated recording. The change ``coef (w < 0) g(w)`` (``coulomb``: the
    level, the Stribeck hump with it) or ``coef (w < 0) F(w)`` (``scale``), at the simulated state (times
    the other effects' level and viscous factors), less its least-squares fit by a constant and a
    symmetric map that carries those factors (sgn w, w, w|w|, w^3 and the plant's own hump ``sgn w
    exp(-(|w|/vs)^delta)``): what is left is the even part of the change that is not a constant, the
    hump's or the viscous part's shape, or what a warm-up or a drift scales of the level and not of an
    offset. Where the friction hardly changes with the speed or in time a level asymmetry is an offset to
    the sliding data, whatever its size (docs/scorecards.md)."""
    w = out["w"]
    m = _sliding(w, out["label"], w_top)
    w = w[m]
    if w.size < 10:
        return np.zeros(0)
    neg = (w < 0).astype(float)
    kL = e["coef"]
    kV = kL if e["variant"] == "scale" else 0.0
    mL = out["g_eff"][m] / plant.g(w) / (1.0 + kL * neg)     # the other effects' level factor (1 alone)
    mV = out["mV"][m] / (1.0 + kV * neg)
    s, h = np.sign(w), np.exp(-np.abs(w / plant.vs) ** plant.delta)
    dA = neg * (kL * mL * plant.g(w) * s + kV * mV * plant.sigma2 * w)
    X = np.column_stack([np.ones_like(w), mL * s, mL * s * h, mV * w, mV * w * np.abs(w), mV * w ** 3])
    X = X / np.maximum(np.sqrt(np.mean(X * X, axis=0)), 1e-300)
    return dA - X @ np.linalg.lstsq(X, dA, rcond=None)[0]


def make_card_logs(seed: int, outdir, family: str | None = None, effect: str | None = None,
                   minutes: tuple = MINUTES, rate: tuple = RATE) -> tuple[list, dict]:
    """Draw, plan, calibrate, simulate, measure and write the logs of one card draw
    (``<outdir>/card_<seed>[_k]``; several recordings with ``meta.start_time`` for a drift). Returns (log
    paths, truth)."""
    d = draw_card(seed, family, effect, minutes, rate)
    plant = d.sc.plant
    for e in d.effects:
        if e["kind"] == "load" and plant.axis == "rotary" and plant.Px == 0 and plant.Py == 0:
            plant.Px, plant.Py = e["arm"]        # the load: a payload on an arm (a joint with no gravity gets one)
    n_rec = max(len(d.starts), 1)
    rng = np.random.default_rng([seed, 1])
    progs, blocks = [], []
    for _ in range(n_rec):
        pr = sim.Program(fs=d.fs)
        blocks.append(build_program(pr, d.sc, rng, d.family, d.seconds / n_rec))
        progs.append(pr)
    calibrate(d, plant, [_reference(pr, plant, d.fs) for pr in progs])
    delay = next((e["coef"] for e in d.effects if e["kind"] == "delay"), 0.0)
    paths, dTs, Fs, sim_n, dist = [], [], [], 0, []
    for k, pr in enumerate(progs):
        out = sim.simulate(plant, d.sc.ctl, pr, fx=fx_array(d, plant, k))
        dT, F0 = measured_change(out, plant, d.sc.w_top, delay)
        for e in d.effects:
            if e["kind"] == "asymmetry":
                dist.append(offset_distinct(out, plant, d.sc.w_top, e))
        dTs.append(dT)
        Fs.append(F0)
        sim_n += out["t"].size
        if delay > 0:
            out["tau"] = np.interp(out["t"] - delay, out["t"], out["tau"])
        noise = np.random.default_rng([seed, 2] if n_rec == 1 else [seed, 2, k])
        df = sim.measure(out, d.sc.sensors, noise)
        if any(e["kind"] == "temperature_logged" for e in d.effects):
            e = next(e for e in d.effects if e["kind"] == "temperature_logged")
            t_env = d.sc.sensors.temp_env if d.sc.sensors.temp_env is not None else 25.0
            temp = t_env + e["rise_K"] * out["theta"] + noise.normal(0.0, 0.05, out["t"].size)
            df["temp_joint"] = np.round(temp, 1)
        truth = sim.truth_record(plant, d.sc.ctl, d.sc.sensors, out["label"], out["index"],
                                 {"seed": seed, "card_family": d.family, "blocks": blocks[k]})
        name = f"card_{seed}" + (f"_{k}" if n_rec > 1 else "")
        path = sim.write_log(Path(outdir) / name, df, d.sc.sensors, plant.axis, truth)
        if d.starts:
            _add_meta(path, {"start_time": float(d.starts[k])})
        paths.append(path)
    dT, F0 = np.concatenate(dTs), np.concatenate(Fs)
    truth = {"seed": seed, "family": d.family, "fs": d.fs, "seconds": d.seconds, "recordings": n_rec,
             "samples": sim_n, "blocks": blocks, "effects": d.effects, "starts": d.starts,
             "size": _rms(dT) / _rms(F0) if F0.size else 0.0, "friction_rms": _rms(F0),
             "asym_distinct": _rms(np.concatenate(dist)) / _rms(F0) if dist and F0.size else None,
             "plant": {k: v for k, v in vars(plant).items()}, "controller": vars(d.sc.ctl),
             "sensors": vars(d.sc.sensors) | {"q_step": d.sc.sensors.q_step}, "w_top": d.sc.w_top}
    return paths, truth


def _add_meta(path: Path, meta: dict) -> None:
    """Merge ``meta`` into the log's sidecar ``<log>.meta.yaml`` under ``meta``."""
    side = Path(str(path) + ".meta.yaml")
    doc = yaml.safe_load(side.read_text()) if side.exists() else {}
    doc.setdefault("meta", {}).update(meta)
    side.write_text(yaml.safe_dump(doc))
