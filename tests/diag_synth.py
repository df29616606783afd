"""Logs with a hidden effect, for the diagnosis tests and ``benchmarks/diagnosis_scorecard.py``.

A *session* recipe revisits every velocity at different times, so that slow effects (temperature, drift)
are not confounded with velocity: a constant-velocity sweep (both signs), point-to-point cycles over
the travel, and the sweep again. Plants are the shipped ones with their own hidden effects and thermal
law removed (the null plant), then one effect injected with a strength ``s`` (roughly its RMS as a
fraction of the friction RMS; the exact size is measured from the plant's true friction by
:func:`effect_size`). Only tests and scorecards may read ``JointLog.truth``.
"""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: Causes the plant can inject, and the effect / law that does it.
INJECTABLE = ("temperature", "position", "load", "asymmetry", "offset", "drift")

#: Models the fit tries in these runs (the diagnosis starts from the best symmetric one of them).
import os
FIT_MODELS = os.environ.get("DIAG_FIT_MODELS", "coulomb_viscous,stribeck,polynomial,polynomial_ls")

SIZES = {
    # plateau [s], speeds per sign, cycles, cycle time [s]
    "tiny": (0.5, 6, 3, 12.0),
    "small": (0.8, 8, 4, 20.0),
    "large": (2.0, 12, 8, 45.0),
}


def session_recipe(size: str = "small", payloads=None) -> dict:
    """The diagnosis session as a recipe dict: sweep, point-to-point cycles, sweep (per payload)."""
    plateau, count, cycles, cycle_time = SIZES[size]
    sweep = {"kind": "constant_velocity", "velocities": {"min": 0.01, "max": 0.9, "count": count},
             "plateau": plateau, "min_plateau": min(0.4, plateau), "gap": 0.2, "rest": 0.5}
    ptp = {"kind": "validation_ptp", "cycles": cycles, "cycle_time": cycle_time, "slots": 1,
           "speeds": [0.2, 0.45, 0.7, 0.95], "relative_positions": True, "positions_deg": [0.1, 0.9],
           "rest": 0.5}
    exps = []
    for m in (payloads or [None]):
        part = [dict(sweep), dict(ptp), dict(sweep)]
        if m is not None:
            for e in part:
                e["payload"] = float(m)
        exps += part
    exps[0]["cold_start"] = True
    return {"name": f"diagnosis_session_{size}", "default_plant": "hydraulic", "temp_env": 25.0,
            "start_rest": 0.5, "experiments": exps}


def session_duration(size: str) -> float:
    """Rough length of a session [s] (for scaling slow effects)."""
    plateau, count, cycles, cycle_time = SIZES[size]
    return 2 * 2 * count * (plateau + 1.2) + cycles * cycle_time


def null_plant(name: str, noise: float = 1.0) -> dict:
    """A shipped plant (first joint only) without hidden effects or thermal law; sensor noise scaled."""
    from frictid.plant import load_plant

    pl = load_plant(str(ROOT / "recipes" / "plants" / f"{name}.yaml")).model_dump()
    pl["joints"] = pl["joints"][:1]
    j = pl["joints"][0]
    j["effects"] = []
    j["thermal"]["law"] = "none"
    for k in ("tau_noise", "q_noise", "qd_noise"):
        pl["sensors"][k] = pl["sensors"][k] * noise
    return pl


def friction_scale(plant: dict) -> float:
    """A typical friction level [F] of the plant's joint: its map at a third of the velocity limit."""
    from frictid.models.static import canonical_friction, canonical_pair
    from frictid.plant.config import friction_params, load_plant

    pl = load_plant(copy.deepcopy(plant))
    j = pl.joints[0]
    cp, cn = canonical_pair(j.friction.map, friction_params(j.friction))
    v = np.linspace(0.05, 0.95, 19) * j.limits.velocity
    F = np.concatenate([canonical_friction(v, cp, cn), canonical_friction(-v, cp, cn)])
    return float(np.sqrt(np.mean(F * F)))


def inject(plant: dict, cause: str, s: float, size: str = "small") -> dict:
    """A copy of a null plant with one effect of strength s (about s of the friction RMS)."""
    pl = copy.deepcopy(plant)
    j = pl["joints"][0]
    Fs = friction_scale(plant)
    lo, hi = j["limits"]["position"] or (-1.0, 1.0)
    if cause == "position":
        j["effects"] = [{"kind": "position", "amplitude": min(0.9, s * math.sqrt(2)),
                         "period": 0.7 * 0.7 * (hi - lo) / 3.0, "phase": 0.4}]
    elif cause == "asymmetry":
        j["effects"] = [{"kind": "asymmetry", "factor": 1.0 - s * math.sqrt(2)}]
    elif cause == "offset":
        j["effects"] = [{"kind": "torque_offset", "value": s * Fs}]
    elif cause == "load":
        # level x (1 + coeff |u|): |u| is about the gravity amplitude plus the friction
        g = j["gravity"]
        u = math.hypot(g["Px"], g["Py"]) + Fs
        j["effects"] = [{"kind": "load", "coeff": 2.0 * s / u}]
    elif cause == "load_payload":
        # level x (1 + payload_coeff m) with payloads 0, 10, 20 kg
        j["effects"] = [{"kind": "load", "payload_coeff": s / 10.0}]
    elif cause == "drift":
        pass  # across sessions: see drift_sessions
    elif cause == "temperature":
        # thermal4: friction falls by about 2 s as the joint warms within the session
        dur = session_duration(size)
        th = j["thermal"]
        P = 0.5 * Fs * 0.4 * j["limits"]["velocity"]  # mean friction power of the session [W], rough
        K = P / 20.0                                   # a rise of about 20 K at that power
        th.update(law="thermal4", K=K, C=K * dur / 3.0, T0=25.0, Tenv=25.0, beta=1.0,
                  alpha=max(-0.9 / 100.0, -2.0 * s / 20.0))
    elif cause != "none":
        raise KeyError(cause)
    return pl


#: Sessions of a drift case, and the hours between them.
DRIFT_SESSIONS, DRIFT_GAP_H = 3, 100.0


def scale_friction(plant: dict, factor: float) -> dict:
    """A copy of a plant whose friction map amplitudes (not its shapes) are multiplied by factor."""
    from frictid.models.static import param_table

    pl = copy.deepcopy(plant)
    fr = pl["joints"][0]["friction"]
    for p in param_table(fr["map"]):
        if p.dim in ("F", "D", "D2", "D3"):
            fr[p.name] = fr[p.name] * factor
    return pl


def drift_sessions(plant: dict, s: float, size: str, seed: int):
    """Sessions recorded DRIFT_GAP_H hours apart (``start_time`` in the metadata), each from a cold joint,
    the friction growing by a factor ``1 + k d`` from one to the next (wear); the RMS change over the
    sessions is about s."""
    d = s * math.sqrt(3.0) / (DRIFT_SESSIONS - 1) * 2.0 / math.sqrt(3.0) if DRIFT_SESSIONS > 1 else 0.0
    logs = []
    for k in range(DRIFT_SESSIONS):
        lg = simulate(scale_friction(plant, 1.0 + k * d), size, seed + 1000 * k)
        for x in lg:
            x.meta["start_time"] = 1.7e9 + 3600.0 * DRIFT_GAP_H * k
        logs += lg
    return logs


def simulate(plant: dict, size: str = "small", seed: int = 0, payloads=None):
    from frictid.plant import simulate_recipe

    return simulate_recipe(session_recipe(size, payloads), plant, seed=seed)


def effect_size(null_log, log) -> float:
    """RMS of the injected change of the true friction over sliding samples, over the friction RMS."""
    w = null_log.truth["velocity"]
    w0 = np.percentile(np.abs(w), 99.5)
    m = (np.abs(w) > 0.02 * w0) & ~np.isin(null_log.truth["segment"], ["rest", "ramp_presliding", "step"])
    n = min(null_log.n, log.n)
    m = m[:n]
    F0 = null_log.truth["friction"][:n][m]
    F1 = log.truth["friction"][:n][m]
    # a torque offset changes the logged torque, not the friction: it counts as it is
    off = sum(e.get("value", 0.0) for e in log.truth["params"]["effects"] if e["kind"] == "torque_offset")
    d = F1 - F0 + off
    return float(np.sqrt(np.mean(d * d)) / np.sqrt(np.mean(F0 * F0)))


def declare_horizontal(logs, plant: dict) -> None:
    """A rotary joint without gravity is declared so in the log metadata (``gravity: [0, 0]``), as the user
    of a horizontal arm would: then a torque offset is not confounded with gravity."""
    g = plant["joints"][0]["gravity"]
    if plant.get("axis", "rotary") == "rotary" and g["Px"] == 0 and g["Py"] == 0 and not g["payload_arm"]:
        for lg in logs:
            lg.meta["gravity"] = [0.0, 0.0]


def named_causes(jf) -> list[tuple[str, str, float]]:
    """(cause, extension, gain) of every cause the diagnosis named, in the chain's order: its findings and
    the causes outside the friction model (``selection.diagnosis.outside_model``), then presliding. Repairs of
    the fit's own estimate (``kind: repair``, ``selection.diagnosis.repairs``) are no cause found in the plant
    and are left out (:func:`repairs`)."""
    d = jf.selection.get("diagnosis") or {}
    found = [f for f in jf.diagnosis if f["cause"] != "presliding"] + list(d.get("outside_model") or [])
    out = []
    for st in d.get("steps") or []:
        ext = st.get("chosen")
        f = next((f for f in found if f["extension"] == ext), None)
        if ext is None or f is None:   # nothing chosen, or an ambiguous step (its term kept, no cause named)
            continue
        found.remove(f)
        if f.get("kind") != "repair":
            out.append((f["cause"], f["extension"], float(f["gain"])))
    out += [(f["cause"], f["extension"], float(f["gain"])) for f in jf.diagnosis if f["cause"] == "presliding"]
    return out


def repairs(jf) -> list[tuple[str, str, float]]:
    """(cause, extension, held-out gain) of the diagnosis' repairs of the fit's own estimate, in order."""
    return [(r["repair"], r["extension"], float(r["heldout_gain"]))
            for r in (jf.selection.get("diagnosis") or {}).get("repairs") or []]


def top_cause(jf) -> tuple[str, float]:
    """(cause, gain) of the first cause the diagnosis named (a finding or a cause outside the friction
    model), or ('none', 0)."""
    named = named_causes(jf)
    return (named[0][0], named[0][2]) if named else ("none", 0.0)


def run_case(plant_name: str, cause: str, s: float, size: str = "small", seed: int = 0, noise: float = 1.0,
             with_effect_size: bool = False):
    """Simulate, fit with the diagnosis; returns (JointFit, effect size or None, logs)."""
    import frictid

    base = null_plant(plant_name, noise)
    pl = inject(base, cause, s, size) if cause != "none" else base
    payloads = [0.0, 10.0, 20.0] if cause.startswith("load") else None
    if cause == "drift":
        logs = drift_sessions(base, s, size, seed)
    else:
        logs = simulate(pl, size, seed, payloads)
    declare_horizontal(logs, base)
    res = frictid.fit(logs, models=FIT_MODELS)
    es = None
    if with_effect_size and cause != "none":
        if cause == "drift":
            nulls = drift_sessions(base, 0.0, size, seed)
            num = sum(effect_size(a, b) ** 2 * 1.0 for a, b in zip(nulls, logs))
            es = math.sqrt(num / len(logs))
        else:
            es = effect_size(simulate(base, size, seed, payloads)[0], logs[0])
    return res[logs[0].joint], es, logs


# ---------------------------------------------------------------------------------------------------
# Long logs (issue 20): a pick-and-place program of many short cycles between two sweeps


def pick_place_recipe(minutes: float, cycle_time: float = 7.0, size: str = "small") -> dict:
    """A sweep, ``minutes`` of pick-and-place cycles (``cycle_time`` seconds: moving half of it between 10 and
    90 % of the travel at three speeds, at rest the other half), and the sweep again; cold start."""
    rec = session_recipe(size)
    ptp = {"kind": "duty_cycle", "duty": 0.5, "slots": 2, "cycle_time": cycle_time,
           "cycles": max(1, int(round(60.0 * minutes / cycle_time))), "speeds": [0.3, 0.6, 0.95],
           "relative_positions": True, "positions_deg": [0.1, 0.9], "rest": 0.5}
    rec["experiments"][1] = ptp
    rec["name"] = f"pick_place_{minutes:g}min"
    return rec


def warm_up_plant(plant: dict, drop: float, dT: float, recipe: dict, seed: int) -> dict:
    """A copy of a null plant whose friction falls by ``drop`` (thermal4) as the joint warms by ``dT`` kelvin
    over the recipe: the heat balance's time constant a third of the recipe's length, its conductance set
    so that the mean friction power of the recipe (measured on the null plant) would heat it by ``dT`` in
    the steady state (it reaches about 95 % of that)."""
    from frictid.plant import simulate_recipe

    lg = simulate_recipe(recipe, plant, seed=seed)[0]
    P = float(np.mean(lg.truth["friction"] * lg.truth["velocity"]))   # mean friction power [W]
    span = float(lg.t[-1] - lg.t[0])
    pl = copy.deepcopy(plant)
    K = P / dT
    pl["joints"][0]["thermal"].update(law="thermal4", K=K, C=K * span / 3.0, T0=25.0, Tenv=25.0, beta=1.0,
                                      alpha=-drop / dT)
    return pl


def warm_pick_place(minutes: float, plant: str, seed: int) -> list:
    """Logs of :func:`pick_place_recipe` on a null plant that warms up (friction -30 % over 35 K,
    :func:`warm_up_plant`), the joint temperature logged (:func:`log_joint_temperature`), declared
    horizontal: nothing hidden but the warm-up."""
    from frictid.plant import simulate_recipe

    base = null_plant(plant)
    rec = pick_place_recipe(minutes)
    logs = simulate_recipe(rec, warm_up_plant(base, 0.3, 35.0, rec, seed), seed=seed)
    log_joint_temperature(logs, seed)
    declare_horizontal(logs, base)
    return logs


def log_joint_temperature(logs, seed: int, sigma: float = 0.05, step: float = 0.1) -> None:
    """Write the true joint temperature as a logged ``temp_joint`` channel, as a sensor would: with noise
    ``sigma`` [K] and quantised to ``step`` [K]."""
    rng = np.random.default_rng(seed)
    for lg in logs:
        T = lg.truth["temp_joint"] + sigma * rng.standard_normal(lg.n)
        lg.channels["temp_joint"] = np.round(T / step) * step


# ---------------------------------------------------------------------------------------------------
# Causes outside the friction model's list (issue 20): dwell, delay, position torque


def rests_recipe(size: str = "tiny", moves: int = 24, dwell=(0.1, 12.0), seed: int = 0) -> dict:
    """The session's sweep, then ``moves`` random point-to-point moves with rests of ``dwell`` seconds (a
    range: uniform), then the sweep again: a static friction that grows with the time at rest shows after
    the long rests."""
    rec = session_recipe(size)
    rec["experiments"][1] = {"kind": "random_ptp", "moves": moves, "speed": [0.3, 0.9], "accel": [0.5, 1.0],
                             "dwell": list(dwell), "seed": seed, "rest": 0.5}
    rec["name"] = f"rests_{size}"
    return rec


def outside_case(plant_name: str, effect: dict | None, seed: int, recipe: dict | None = None,
                 delay: int = 0):
    """A null plant with one effect outside the friction model's list (an effect entry, or a sensor delay of
    ``delay`` samples of the position behind the torque), simulated and fitted with the diagnosis; returns
    (JointFit, logs)."""
    import frictid
    from frictid.plant import simulate_recipe

    pl = null_plant(plant_name)
    if effect is not None:
        pl["joints"][0]["effects"] = [effect]
    pl["sensors"]["delay"] = int(delay)
    logs = simulate_recipe(recipe or session_recipe("tiny"), pl, seed=seed)
    declare_horizontal(logs, pl)
    res = frictid.fit(logs, models=FIT_MODELS)
    return res[logs[0].joint], logs
