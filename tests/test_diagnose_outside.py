"""Issue 20: causes outside the friction model's list (dwell, delay, position torque) are named as such,
and a residual structure that no candidate explains is stated with its numbers ("unexplained").

Each plant case hides one effect on a plant of frictid's own with random parameters (test seeds < 1000)
and names the competing explanation it must not be taken for.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import diag_synth as ds
from frictid.data import Segment
from frictid.diagnose import DiagLog, diagnose_joint
from frictid.diagnose.model import Structure
from frictid.diagnose.samples import build_samples
from frictid.models import static as sm
from test_diagnose import TRUE, Parts, _run, fake_fit, plateau_log, smooth


def _outside(jf) -> dict:
    return {o["cause"]: o for o in jf.selection["diagnosis"].get("outside_model", [])}


@pytest.mark.parametrize("seed", [41])
def test_dwell_is_found_and_not_named_temperature(seed):
    """Static friction that grows with the time at rest (30 moves after rests of 0.1-8 s, an effect of about 8-15 % of the friction RMS): before the dwell cause, the
    heat balance took it for a warm-up with a made-up time constant. Competing explanation: temperature."""
    rng = np.random.default_rng(seed)
    plant = str(rng.choice(["hydraulic", "geared_industrial"]))
    lo, hi = ds.null_plant(plant)["joints"][0]["limits"]["position"]
    eff = {"kind": "dwell", "amplitude": float(rng.uniform(0.1, 0.15)), "t0": float(rng.uniform(0.05, 0.2)),
           "distance": float(rng.uniform(0.05, 0.1) * (hi - lo))}
    jf, _ = ds.outside_case(plant, eff, seed, ds.rests_recipe("tiny", 30, (0.1, 8.0), seed))
    found = _outside(jf)
    assert "dwell" in found, (plant, eff, jf.selection["diagnosis"]["steps"])
    assert found["dwell"]["gain"] > 0.05 and "time at rest" in found["dwell"]["evidence"]
    assert not [f for f in jf.diagnosis if f["cause"] == "temperature"], jf.diagnosis
    assert "dwell" not in jf.selected and any("dwell (outside the friction model)" in w for w in jf.warnings)


@pytest.mark.parametrize("seed", [23])
def test_a_gravity_harmonic_is_a_position_torque_not_friction(seed):
    """G = a cos q + b sin 2q (a spring compensator): a torque that does not change sign with the velocity,
    named position_torque with its period, never a friction finding. Competing explanations: the level's
    position modulation (position), gravity (cos q, sin q), offset."""
    rng = np.random.default_rng(seed)
    plant = str(rng.choice(["hydraulic", "geared_industrial"]))
    k = int(rng.choice([2, 3]))
    amp = float(rng.uniform(0.2, 0.3)) * ds.friction_scale(ds.null_plant(plant))
    eff = {"kind": "position_torque", "amplitude": amp, "period": 2 * math.pi / k,
           "phase": float(rng.uniform(0, 2 * math.pi))}
    jf, _ = ds.outside_case(plant, eff, seed)
    found = _outside(jf)
    assert "position_torque" in found, (plant, eff, jf.selection["diagnosis"]["steps"])
    pt = found["position_torque"]
    assert pt["settings"]["period"] == pytest.approx(2 * math.pi / k, rel=1e-6)
    assert float(np.hypot(*pt["coefficients"])) == pytest.approx(amp, rel=0.15)
    assert "not friction" in pt["evidence"]
    assert not [f for f in jf.diagnosis if f["cause"] in ("position", "gravity", "offset")], jf.diagnosis


@pytest.mark.parametrize("seed", [5])
def test_a_vibration_at_some_speeds_is_not_a_position_torque(seed):
    """Three minutes of pick-and-place on the geared joint, nothing hidden but the warm-up: the plant's
    closed loop rings at some of the program's speeds, and on a repeated program the ringing falls at the
    same positions every cycle. Before the speed-band check the diagnosis named it a position torque
    (amplitude 2 N m, period 0.04 rad, held-out gain 4 %; on benchmarks/bench_diagnose_whole.py's log
    too). Competing explanation: a vibration at the time frequency v / P, which lives at some speeds only,
    where a torque of the position reaches the measured torque at every speed."""
    import frictid

    logs = ds.warm_pick_place(3.0, "geared_industrial", seed)
    jf = frictid.fit(logs, models=ds.FIT_MODELS)[logs[0].joint]
    assert "position_torque" not in _outside(jf), jf.warnings
    assert not any(w.startswith("position_torque") for w in jf.warnings), jf.warnings
    rejected = [r for st in jf.selection["diagnosis"]["steps"] for r in st.get("rejected", [])
                if r["extension"] == "position_torque"]
    assert rejected and "grows with the speed" in rejected[0]["reason"], jf.selection["diagnosis"]["steps"]
    assert [f["cause"] for f in jf.diagnosis] == ["temperature"], jf.diagnosis


@pytest.mark.parametrize("seed", [57])
def test_a_signal_delay_is_found_with_its_sign(seed):
    """The position logged some samples behind the torque (as a drive that timestamps its encoder late):
    named delay, the torque leading. Competing explanation: inertia (the residual of a delay follows the
    torque's rate, of an inertia error the acceleration)."""
    rng = np.random.default_rng(seed)
    d = int(rng.integers(8, 13))
    jf, logs = ds.outside_case("geared_industrial", None, seed, delay=d)
    found = _outside(jf)
    assert "delay" in found, (d, jf.selection["diagnosis"]["steps"])
    est = found["delay"]["coefficients"][0]
    dt = 1.0 / logs[0].meta["sample_rate"]
    assert 0.3 * d * dt < est < 1.5 * d * dt and "leads" in found["delay"]["evidence"]
    assert not [f for f in jf.diagnosis if f["cause"] == "inertia"], jf.diagnosis


def test_an_effect_no_candidate_explains_is_stated_as_unexplained():
    """A torque ripple in time (a pump, 7.3 s period) that no candidate carries: no named cause with a gain,
    and one sentence that says what remains and how large it is against the noise."""
    def ripple(t, q, w, F):
        return np.asarray(F) + 0.3 * np.sin(2 * np.pi * t / 7.3)

    jf, findings = _run([plateau_log(ripple, seed=5)])
    d = jf.selection["diagnosis"]
    assert not [f for f in findings if f["gain"] >= 0.05] and not d.get("outside_model"), findings
    assert len(d["unexplained"]) == 1
    text = d["unexplained"][0]
    assert text.startswith("residual varies with time") and "no candidate explains it" in text
    assert "% of the friction RMS" in text and "x the sensor noise" in text
    time = next(e for e in d["structure"]["tests"] if e["variable"] == "time")
    assert time["large"] and time["x_noise"] > 3 and 0.05 < time["of_friction_rms"] < 0.15
    assert any(w.startswith("unexplained structure: residual varies with time") for w in jf.warnings)


def test_a_clean_log_states_no_structure():
    jf, _ = _run([plateau_log(seed=2)])
    d = jf.selection["diagnosis"]
    assert d["unexplained"] == [] and not [e for e in d["structure"]["tests"] if e["large"]]
    assert not [w for w in jf.warnings if "unexplained" in w]


def test_a_position_torque_on_plateaus_is_not_a_friction_modulation():
    """The level modulation (friction, changes sign with w) and the position torque (does not) on the same
    plateau log: each named as what it is."""
    P = 0.9

    def torque(t, q, w, F):
        return np.asarray(F) + 0.4 * np.sin(2 * np.pi * q / P)

    def level(t, q, w, F):
        return F.level * (1 + 0.12 * np.sin(2 * np.pi * q / P)) + F.viscous

    jf, findings = _run([plateau_log(torque, seed=3)])
    assert not [f for f in findings if f["cause"] == "position"]
    pt = _outside(jf)["position_torque"]
    assert pt["settings"]["period"] == pytest.approx(P, rel=0.01) and pt["gain"] > 0.5
    jf, findings = _run([plateau_log(level, seed=3)])
    assert findings[0]["cause"] == "position" and "position_torque" not in _outside(jf)


def test_a_speed_effect_in_plateau_order_is_not_called_position():
    """Each plateau speed in one stretch of travel (one sweep, speeds rising): a bump of the friction at one
    speed that the base map cannot follow is a function of the position too (EMPS: "position 48 %"). Within
    a plateau the level does not change with the position, so no position cause may be named."""
    def bump(t, q, w, F):
        return np.asarray(F) + 0.5 * np.exp(-((np.abs(w) - 0.6) / 0.25) ** 2) * np.sign(w)

    jf, findings = _run([plateau_log(bump, seed=4, reps=2)])
    d = jf.selection["diagnosis"]
    assert not [f for f in findings if f["cause"] == "position"], findings
    assert "position_torque" not in _outside(jf)
    rejected = [r for st in d["steps"] for r in st.get("rejected", [])]
    assert any(r["extension"].startswith("position") and "within segments" in r["reason"] for r in rejected), d["steps"]


def test_a_warm_up_sentence_states_the_whole_fall_across_logs_that_restart_cold():
    """Two logs laid end to end (no start times), each warming from cold: the sentence compares the
    coldest and the warmest thermal state (it compared the ends of the clock, both cold: issue 20's
    "falls 0.277 N m" where the model falls from 20.4 to 16.4 N m)."""
    import re

    from frictid.diagnose.samples import heat_balance_rise

    tau_c = 60.0

    def warm(t, q, w, F):
        x = heat_balance_rise(t, F * w, np.zeros(t.size), tau_c)
        return F * (1 - 0.06 * x)

    logs = [plateau_log(warm, reps=4, alternate=True, seed=s) for s in (1, 2)]
    jf, findings = _run(logs)
    f = findings[0]
    assert f["cause"] == "temperature", findings
    lg = logs[0]
    x = heat_balance_rise(lg.t, np.asarray(lg.F) * lg.w, np.zeros(lg.n), tau_c)   # the true state, roughly
    lo, hi = np.percentile(x[np.abs(lg.w) > 0.1], [1, 99])
    true = 100 * ((1 - 0.06 * hi) / (1 - 0.06 * lo) - 1)
    said = float(re.search(r"\(([+-]\d+) %, the mean", f["evidence"]).group(1))
    assert "falls from" in f["evidence"] and said == pytest.approx(true, rel=0.3), (f["evidence"], true)


@pytest.mark.parametrize("seed", [61])
def test_a_smooth_position_torque_on_a_slide_is_not_an_offset_or_asymmetry(seed):
    """A spring-like torque over the slide's travel (a sine of period 1.5-2.5 times the travel: smooth, no
    period to search): its mean over the travel is an offset and, sampled by moves of each direction, an
    asymmetry (the foreign card's seed 300026 named a gravity harmonic on a linear axis `asymmetry`). The
    smooth position torque explains all of it and must be named first. Competing explanations: offset,
    asymmetry, position (level modulation)."""
    rng = np.random.default_rng(seed)
    pl = ds.null_plant("linear_slide")
    lo, hi = pl["joints"][0]["limits"]["position"]
    eff = {"kind": "position_torque", "amplitude": float(rng.uniform(0.3, 0.5)) * ds.friction_scale(pl),
           "period": float(rng.uniform(1.5, 2.5)) * (hi - lo), "phase": float(rng.uniform(0, 2 * math.pi))}
    jf, _ = ds.outside_case("linear_slide", eff, seed)
    steps = jf.selection["diagnosis"]["steps"]
    assert steps and steps[0]["chosen"] == "position_torque", (eff, steps)
    pt = _outside(jf)["position_torque"]
    assert pt["settings"]["period"] == 0 and "smoothly with position" in pt["evidence"] and pt["gain"] > 0.3
    assert not [f for f in jf.diagnosis if f["cause"] in ("asymmetry", "position") and f["gain"] >= 0.05], jf.diagnosis


def test_a_cause_that_does_not_beat_a_competing_explanation_is_not_named():
    """The foreign card's seed 300017 (drift + a Coulomb-level asymmetry on a map the fit took for Coulomb +
    viscous): an offset and the asymmetry are the same sliding data, and the offset was named first. Two
    candidates of different causes that make the same held-out correction leave the step ambiguous; a
    competitor that corrects differently (here, half as much) does not."""
    from dataclasses import replace

    from frictid.diagnose.chain import Chain

    S = build_samples([plateau_log(lambda t, q, w, F: np.asarray(F) + 0.2, seed=9)], 5)
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    chain = Chain(S, Structure("stribeck", cp))
    off = chain.evaluate("offset", 2)
    assert off.p < 1e-6 and off.gain > 0.5
    twin = replace(off, cause="asymmetry", ext="asym_scale")
    assert chain.choose([off, twin], 2).unresolved == ["asymmetry"]
    worse = replace(off, cause="asymmetry", ext="asym_scale", pred_after=0.5 * (off.pred_before + off.pred_after))
    worse.rms_after = float(np.sqrt(np.mean((S.F - worse.pred_after) ** 2)))
    best = chain.choose([off, worse], 2)
    assert best.ext == "offset" and best.unresolved == []
    # an explanation that is not a candidate competes too: a per-direction level (asym_level) against an
    # offset, evaluated on the same folds; here the base has a Stribeck part, and the true offset beats it
    # at low speed
    comp = chain._competitors(off, 2)
    assert [t.ext for t in comp] == ["asym_level"] and not chain.same_correction(off, comp[0])


def _rest_plateau_log(seed: int, amp: float, values: dict, dt: float = 2e-3, noise: float = 0.01,
                      cycle: tuple[float, float] = (0.0, 1.0)):
    """Moves to 8 speeds per sign, twice (each held 0.8 s, reached in 0.3 s) from rest, each after a rest of a random
    0.1-6 s, with a static friction that grows with that rest (level times ``1 + amp ln(1 + t_rest / t0)
    exp(-s / s_c)``, ``amp`` 0 for none): the dwell shows where a move starts, at low speed, where a
    Stribeck hump lives too; ``cycle`` = (amplitude, period [s]): the level also times ``1 + amplitude
    sin(2 pi t / period)``. About 2 min of data."""
    rng = np.random.default_rng(seed)
    v = np.geomspace(0.05, 1.5, 8)
    speeds = rng.permutation(np.concatenate([v, -v, v, -v]))
    rests_s = rng.uniform(0.1, 6.0, speeds.size)
    t0, s_c = 0.1, 0.04
    ws, kinds, xs = [], [], []
    for s, tr in zip(speeds, rests_s):
        n_r, n_m, n_h, n_b = int(tr / dt), int(0.3 / dt), int(0.8 / dt), int(0.3 / dt)
        up = s * smooth(np.arange(n_m) / n_m)
        move = np.concatenate([up, np.full(n_h, s), s * smooth(1 - np.arange(n_b) / n_b)])
        travel = np.abs(np.cumsum(move) * dt)
        ws += [np.zeros(n_r), move]
        xs += [np.zeros(n_r), np.log1p(tr / t0) * np.exp(-travel / s_c)]
        kinds += [("rest", n_r), ("other", n_m), ("constant_velocity", n_h), ("other", n_b)]
    w, x = np.concatenate(ws), np.concatenate(xs)
    n = w.size
    t = np.arange(n) * dt
    q = np.cumsum(w) * dt
    F = sm.stribeck(w, **values)
    cyc = 1 + cycle[0] * np.sin(2 * np.pi * t / cycle[1] + rng.uniform(0, 2 * np.pi))
    F = (F - values["sigma2"] * w) * (1 + amp * x) * cyc + values["sigma2"] * w
    F = F + noise * rng.standard_normal(n)
    segs, i = [], 0
    for kind, m in kinds:
        segs.append(Segment(kind, i, i + m, float(t[i]), float(t[i + m - 1])))
        i += m
    return DiagLog(t=t, q=q - q.mean(), w=w, a=np.gradient(w, dt), tau=F.copy(), F=F, G=np.zeros(n),
                   offset=0.0, segments=segs, channels={"temp_env": np.full(n, 25.0)}, start=None)


#: A Stribeck hump the fit's base map lacks (Fs / Fc = 1.6): the base handed over is Coulomb + viscous.
HUMP = dict(Fc=2.0, Fs=3.2, vs=0.1, delta=2.0, sigma2=1.0)


@pytest.mark.parametrize("seed", [3, 8])
def test_a_dwell_is_named_before_a_stribeck_hump_the_base_lacks(seed):
    """Issue 20, foreign card seeds 300021 / 300103: the plant has a Stribeck hump the fit's base lacks and a
    dwell effect; both corrections live where a move starts slowly after a rest, and the Stribeck term, a
    function of the speed alone (a repair the fit should have made), was named first. Where the two differ,
    at one speed between moves after short and after long rests, only the dwell shows: it is named first,
    the Stribeck repair after it."""
    jf = fake_fit({"Fc": HUMP["Fc"], "sigma2": HUMP["sigma2"]}, "coulomb_viscous")
    diagnose_joint(jf, [_rest_plateau_log(seed, 0.15, HUMP)])
    steps = [s["chosen"] for s in jf.selection["diagnosis"]["steps"] if s.get("chosen")]
    assert steps and steps[0] == "dwell", jf.selection["diagnosis"]["steps"]
    assert "stribeck" in steps, steps


@pytest.mark.parametrize("seed", [3])
def test_a_stribeck_hump_without_a_dwell_is_not_named_dwell(seed):
    """The same moves after rests of random length, the hump the base lacks and no dwell effect: the dwell
    candidate's correction (large after long rests, at the start of a move) can take part of the hump, but
    at one speed between short and long rests it does not follow the residual, so it is not named."""
    jf = fake_fit({"Fc": HUMP["Fc"], "sigma2": HUMP["sigma2"]}, "coulomb_viscous")
    findings = diagnose_joint(jf, [_rest_plateau_log(seed, 0.0, HUMP)])
    assert not [f for f in findings if f["cause"] == "dwell"], findings
    assert not [o for o in jf.selection["diagnosis"].get("outside_model", []) if o["cause"] == "dwell"]


@pytest.mark.parametrize("seed", [1, 2])
def test_a_level_cycling_in_time_is_not_named_temperature(seed):
    """Issue 20, foreign card seed 300100: a friction level cycling in time (+-15 %, a 50 s period over a
    134 s log) is outside the list; the heat balance with a time constant chosen on the data follows part
    of it and was named temperature (gain 0.12 and 0.24 on these seeds). Competing explanation: a free
    function of the time (times the velocity's sign), which explains more of what the thermal term leaves
    than the term explains: not named, and the structure is stated unexplained."""
    rng = np.random.default_rng(seed)
    ph = rng.uniform(0, 2 * np.pi)

    def cyc(t, q, w, F):
        return F.level * (1 + 0.15 * np.sin(2 * np.pi * t / 50.0 + ph)) + F.viscous

    jf, findings = _run([plateau_log(cyc, seed=seed, reps=4, alternate=True)])
    assert not [f for f in findings if f["gain"] >= 0.05], findings
    rejected = [r for s in jf.selection["diagnosis"]["steps"] for r in s.get("rejected", [])]
    assert any("not the shape of a warm-up" in r["reason"] for r in rejected), rejected
    assert jf.selection["diagnosis"]["unexplained"]


def _slow_cycle(seed: int, period: float = 40.0):
    """A plateau log whose friction level cycles in time (+-15 %, ``period`` s), the chain on the true map,
    an offset trial to dress up (its fields, another correction) and the prediction that takes the whole
    cycle."""
    from frictid.diagnose.chain import Chain

    def cyc(t, q, w, F):
        return F.level * (1 + 0.15 * np.sin(2 * np.pi * t / period)) + F.viscous

    lg = plateau_log(cyc, seed=seed, reps=4, alternate=True)
    S = build_samples([lg], 5)
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    chain = Chain(S, Structure("stribeck", cp))
    off = chain.evaluate("offset", 1)
    true_map = Parts(sm.stribeck(lg.w, **TRUE), TRUE["sigma2"] * lg.w)
    whole = chain.pred + (np.asarray(cyc(lg.t, lg.q, lg.w, true_map)) - np.asarray(true_map))[S.k]
    return S, chain, off, whole


@pytest.mark.parametrize("seed", [4])
def test_a_candidate_that_follows_part_of_a_slow_cycle_is_not_named(seed):
    """The foreign card's seed 300204 (a level cycling in time, 25 %, outside the list) was named dwell (gain
    0.06): the program's rests follow part of the cycle. A dwell or temperature candidate whose correction is
    a fifth of the cycle leaves more of the residual's course in time than it explains and is
    rejected; one that takes the whole cycle is not."""
    from dataclasses import replace

    from frictid.diagnose.chain import _not_its_time_course

    S, chain, off, whole = _slow_cycle(seed)
    for ext in ("dwell", "thermal6"):
        part = replace(off, ext=ext, pred_after=chain.pred + (whole - chain.pred) / 5)
        rb, ra = S.F - part.pred_before, S.F - part.pred_after
        part.explained = float(np.sqrt(max(np.mean(rb ** 2) - np.mean(ra ** 2), 0.0)))
        why = _not_its_time_course(S, part, 1)
        assert why is not None and "slow change that is not the shape of" in why, why
        all_of_it = replace(part, pred_after=whole)
        rb, ra = S.F - all_of_it.pred_before, S.F - all_of_it.pred_after
        all_of_it.explained = float(np.sqrt(max(np.mean(rb ** 2) - np.mean(ra ** 2), 0.0)))
        assert _not_its_time_course(S, all_of_it, 1) is None


def test_a_candidate_that_follows_the_rests_is_not_named():
    """The foreign card's seed 302046 (a dwell, 14 %, sweeps): a heat balance with a 12 s time constant, which
    cools in every rest, was named temperature first (before it, a position torque, as the moves start at
    the same places). Their competitor is a free function of the travel since a rest (times the velocity's
    sign; moves after no rest share one value): a candidate whose correction is the dwell explains nothing
    beyond it and is rejected
    (:func:`frictid.diagnose.chain._not_beyond_rests`); one whose correction is a slow change of the level
    over the log (a warm-up's shape) still explains what that function leaves, and stands."""
    from dataclasses import replace

    from frictid.diagnose.chain import Chain, _not_beyond_rests

    def truth(amp, cycle=(0.0, 1.0)):
        return _rest_plateau_log(3, amp, TRUE, noise=0.0, cycle=cycle).F

    for amp, cycle, rejected in ((0.3, (0.0, 1.0), True), (0.0, (0.15, 600.0), False)):
        lg = _rest_plateau_log(3, amp, TRUE, cycle=cycle)
        S = build_samples([lg], 5)
        cp, _ = sm.canonical_pair("stribeck", TRUE)
        chain = Chain(S, Structure("stribeck", cp))
        effect = (truth(amp, cycle) - truth(0.0))[S.k]      # the hidden correction at the sliding samples
        X = np.column_stack([np.sign(S.w), S.w])            # less what the base's level and slope take
        effect = effect - X @ np.linalg.lstsq(X, effect, rcond=None)[0]
        for ext in ("thermal4", "position_torque"):
            tr = replace(chain.evaluate("offset", 1), ext=ext, pred_after=chain.pred + effect)
            why = _not_beyond_rests(S, tr, 1)
            assert (why is not None) == rejected, why
            if rejected:
                assert "nothing beyond a free function of the travel since a rest" in why, why


def test_a_delay_is_judged_on_every_moving_sample():
    """The held-out judgement of a delay on the moving samples (transients included, where a delay shows
    most; :func:`frictid.diagnose.signals.delay_heldout`): on a plateau log whose logged torque is 10 ms
    late (a Coulomb + viscous map with a quadratic drag), the estimated shift cuts the held-out RMS of the moving samples,
    significantly over groups; no
    shift changes nothing; on the same log without the delay the estimated shift is within a sample
    of none and cuts nothing that matters."""
    from frictid.diagnose.chain import paired_t
    from frictid.diagnose.signals import delay_estimate, delay_heldout

    dt = 2e-3
    flat = dict(TRUE, Fs=TRUE["Fc"])   # no hump: the delay fit's velocity-only map carries it exactly

    def drag(t, q, w, F):   # a quadratic drag: a delay is then more than an inertia error (d F' = d (sigma2 + 1.6 |w|) a)
        return np.asarray(F) + 0.8 * w * np.abs(w)

    def late(t, q, w, F):
        return np.interp(t - 5 * dt, t, drag(t, q, w, F))

    for effect, delayed in ((late, True), (drag, False)):
        S = build_samples([plateau_log(effect, seed=8, reps=2, dt=dt, noise=0.002, values=flat)], 5)
        shifts = [delay_estimate(S, [g for g in range(5) if g != f]) for f in range(5)]
        rb, ra, d = delay_heldout(S, shifts)
        t, p = paired_t(d)
        if delayed:
            assert all(0.5 * 5 * dt < -x < 1.6 * 5 * dt for x in shifts), shifts   # the torque lags the motion
            assert ra < 0.5 * rb and p < 0.05, (rb, ra, t)
        else:
            assert all(abs(x) < dt for x in shifts), shifts
            assert ra > 0.95 * rb, (rb, ra)
        r0b, r0a, d0 = delay_heldout(S, [0.0] * 5)
        assert r0a == pytest.approx(r0b, rel=1e-12) and np.allclose(d0, 0.0, atol=1e-12 * r0b * r0b * S.n)


def test_the_delay_sums_of_several_shifts_at_once_are_those_of_each_shift_alone():
    """:func:`frictid.diagnose.signals._delay_prefetch` computes the moving samples' sums of many shifts in
    one pass (the columns once per block, the torque read at whole shifts without interpolation): per fold,
    X'y and y'y equal the sums over the samples of each shift's own ``y = F - tau + tau(t - shift)``
    (interpolated), for whole and fractional shifts of either sign, and X'X that of the columns."""
    from frictid.diagnose.signals import _delay_columns, _delay_sums, _moving_rows, shifted_torque

    dt = 2e-3
    S = build_samples([plateau_log(None, seed=3, reps=1, dt=dt, noise=0.002)], 5)
    shifts = [-7 * dt, -dt, 0.0, 2 * dt, 13 * dt, 2.37 * dt, -0.6 * dt]
    got = [_delay_sums(S, s) for s in shifts[:5]]   # whole shifts, in one pass after the first
    got += [_delay_sums(S, s) for s in shifts[5:]]
    lg = S.logs[0]
    (km, fk), = _moving_rows(S)
    X = _delay_columns(S, 0, km)
    for s, (XtX, XtY, yty) in zip(shifts, got):
        y = lg.F[km] - lg.tau[km] + shifted_torque(lg.tau, km.astype(float), s / S.dt(0))
        for f in range(5):
            m = fk == f
            assert np.allclose(XtX[f], X[m].T @ X[m], rtol=1e-10, atol=0)
            assert np.allclose(XtY[f], X[m].T @ y[m], rtol=1e-9, atol=1e-9 * np.abs(XtY[f]).max())
            assert yty[f] == pytest.approx(float(y[m] @ y[m]), rel=1e-10)


def test_the_delay_sums_of_a_fraction_of_a_sample_follow_from_its_whole_neighbours():
    """A shift between two whole shifts whose sums are cached (the search's parabola) has its X'y derived from
    theirs (:func:`frictid.diagnose.signals._derived`, no pass over the moving samples): the sums of the
    interpolated torque; y'y is not derived (NaN), and asking for it sums the shift over the samples."""
    from frictid.diagnose.signals import _delay_columns, _delay_prefetch, _delay_sums, _moving_rows, shifted_torque

    dt = 2e-3
    S = build_samples([plateau_log(None, seed=3, reps=1, dt=dt, noise=0.002)], 5)
    _delay_prefetch(S, [-3 * dt, -2 * dt, 4 * dt, 5 * dt])
    lg = S.logs[0]
    (km, fk), = _moving_rows(S)
    X = _delay_columns(S, 0, km)
    for s in (-2.3 * dt, 4.6 * dt):
        XtX, XtY, yty = _delay_sums(S, s, rss=False)
        assert np.isnan(yty).all()   # derived: no pass
        y = lg.F[km] - lg.tau[km] + shifted_torque(lg.tau, km.astype(float), s / S.dt(0))
        for f in range(5):
            m = fk == f
            assert np.allclose(XtY[f], X[m].T @ y[m], rtol=1e-9, atol=1e-9 * np.abs(XtY[f]).max())
        _, XtY2, yty2 = _delay_sums(S, s)   # y'y asked for: summed
        assert np.allclose(XtY2, XtY, rtol=1e-9, atol=1e-9 * np.abs(XtY).max())
        for f in range(5):
            m = fk == f
            assert yty2[f] == pytest.approx(float(y[m] @ y[m]), rel=1e-10)


def test_an_inertia_repair_that_leaves_a_negative_inertia_is_no_repair():
    """A torque delay biases the fit's inertia, even below zero (the foreign card's seed 301004: a 50 ms
    delay, the fit's J -2.6 against the plant's 0.48, the inertia "repair" to -0.61 chosen ahead of the
    delay): an inertia repair that leaves the fit's inertia at zero or below is refused
    (:func:`frictid.diagnose.chain.unphysical`); one that leaves it positive stands, and so does any other
    term, or an inertia repair when the fit's inertia is unknown."""
    from frictid.diagnose.chain import unphysical
    from frictid.diagnose.model import Coef, Term

    cp = np.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    st = Structure("coulomb_viscous", cp, (Term("offset", "offset", "additive", ()),
                                           Term("inertia", "inertia", "additive", ())))
    coef = Coef({0: 1.0}, {0: 1.0}, gamma={0: np.array([0.1]), 1: np.array([2.0])})
    why = unphysical(st, coef, -2.6)
    assert why is not None and "-2.6 -> -0.6" in why, why
    assert unphysical(st, coef, -1.0) is None            # -1 + 2 = 1 kg m^2
    assert unphysical(st, coef, None) is None
    coef.gamma[1] = np.array([-0.5])
    assert unphysical(st, coef, 0.4) is not None          # a positive inertia repaired below zero
    other = Structure("coulomb_viscous", cp, (Term("offset", "offset", "additive", ()),))
    assert unphysical(other, Coef({0: 1.0}, {0: 1.0}, gamma={0: np.array([-5.0])}), 0.1) is None


def test_a_dwell_whose_level_falls_with_the_rest_is_no_dwell():
    """Contacts that age at rest hold more, never less: a dwell term whose coefficient makes the level fall
    with the rest before a move is refused (:func:`frictid.diagnose.chain.unphysical`; the foreign card's
    seed 304500, a 50 ms torque delay named a dwell of -146 % after a 58 s rest); a rising one stands."""
    from frictid.diagnose.chain import unphysical
    from frictid.diagnose.model import Coef, Term

    cp = np.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    st = Structure("coulomb_viscous", cp, (Term("dwell", "dwell", "level_factor", (("t0", 0.05), ("s_c", 0.1))),))
    why = unphysical(st, Coef({0: 1.0}, {0: 1.0}, gamma={0: np.array([-0.4])}), 0.1)
    assert why is not None and "falls with the rest" in why, why
    assert unphysical(st, Coef({0: 1.0}, {0: 1.0}, gamma={0: np.array([0.4])}), 0.1) is None


def test_a_position_torque_that_is_a_constant_is_rejected():
    """A smooth position torque carries its own constant: when what varies with the position is under the
    2 % of the friction RMS a term must explain and within 3x the noise of the friction torque (the floor
    of a structure worth stating), its correction is an offset's or a level's by direction and it is
    rejected (foreign seed 302048: a Coulomb asymmetry named position_torque 0.52, a constant -0.60 N m and
    0.008 N m over the travel); a torque that varies over the travel by more than either is kept (session
    20: foreign seed 309711, a gravity harmonic on a short travel, 1.6 % of the friction RMS in shape, five
    times the noise)."""
    from types import SimpleNamespace

    from frictid.diagnose.chain import Trial, _a_constant
    from frictid.diagnose.model import Coef, Context, Term

    rng = np.random.default_rng(5)
    q = rng.uniform(-3.0, 3.0, 4000)
    S = SimpleNamespace(F=9.0 * np.sign(rng.standard_normal(q.size)), q=q)   # friction RMS 9
    ctx = SimpleNamespace(S=S, _cache={})   # the columns of the terms, as the chain's Context makes them
    ctx.term_columns = lambda term: Context.term_columns(ctx, term)
    ctx.spread = lambda term, g: Context.spread(ctx, term, g)
    smooth = Term("position_torque", "position_torque", "additive", (("period", 0.0), ("q0", 0.0), ("qs", 3.0)))
    periodic = Term("position_torque", "position_torque", "additive", (("period", 2.0),))

    def trial(term, g):
        z = np.zeros(q.size)
        coefs = [Coef({}, {}, gamma={2: np.asarray(g, float)}) for _ in range(3)]
        return Trial("position_torque", "position_torque", z, z, [term] * 3, coefs, 1.0, 0.5, 0.5, 9.0, 1e-9,
                     30, 0.8, 2, index=2)

    F_rms = float(np.sqrt(np.mean(S.F ** 2)))   # 9: 2 % is 0.18 N m
    noise = 0.02   # 3x: 0.06 N m
    why = _a_constant(ctx, trial(smooth, [-0.60, 0.004, 0.0013]), F_rms, noise)
    assert why is not None and "hardly varies with the position" in why
    assert _a_constant(ctx, trial(smooth, [-0.60, 0.2, 1.0]), F_rms, noise) is None   # 1.2 N m of shape over the travel
    assert _a_constant(ctx, trial(periodic, [0.05, 0.02]), F_rms, noise) is not None  # a harmonic of 0.05 N m (RMS 0.04)
    assert _a_constant(ctx, trial(periodic, [0.05, 0.02]), F_rms, noise / 4) is None  # the same, at a quarter of the noise
    assert _a_constant(ctx, trial(periodic, [0.5, 0.2]), F_rms, noise) is None


@pytest.mark.parametrize("lagged", ["friction", "torque"])
def test_a_delay_must_beat_a_lag_of_the_friction(lagged):
    """A torque logged late shifts the whole torque (the inertial part too), a friction that lags the
    velocity (the bristles' dynamics) only the friction: on the moving samples of a plateau program with
    an inertia, the delay's held-out correction beats the friction map taken earlier only where the torque
    itself was shifted (foreign seed 307721, a clean 131 Hz log named ``delay`` for the bristles' lag)."""
    from frictid.diagnose.chain import ALPHA, paired_t
    from frictid.diagnose.lag import friction_lag_heldout
    from frictid.diagnose.signals import delay_estimates, delay_heldout

    J, L = 2.0, 5   # inertia [kg m^2], lag [samples]
    lg = plateau_log(seed=11, reps=3, noise=0.0, move=0.1)
    F0 = lg.F.copy()   # the map, noise-free
    noise = 0.005 * np.random.default_rng(12).standard_normal(lg.n)
    if lagged == "friction":
        tau = J * lg.a + np.concatenate([np.full(L, F0[0]), F0[:-L]]) + noise
    else:
        tau0 = J * lg.a + F0
        tau = np.concatenate([np.full(L, tau0[0]), tau0[:-L]]) + noise
    lg.tau, lg.F = tau, tau - J * lg.a
    S = build_samples([lg], 5, axis="rotary", J=J)
    shifts = delay_estimates(S)
    _, ra, d = delay_heldout(S, shifts)
    lag = friction_lag_heldout(S, float(np.mean(shifts)))
    t, p = paired_t(d - (lag["ss0"] - lag["ss1"]))
    if lagged == "friction":
        assert p >= ALPHA and lag["rms_after"] < 1.1 * ra, (t, shifts, lag)
    else:   # the gain sits in the moves (a few of the groups): t about 3
        assert p < ALPHA and lag["rms_after"] > 5 * ra and abs(np.mean(shifts) / 2e-3 + L) < 1.0, (t, shifts, lag)


@pytest.mark.parametrize("lagged", ["slow", "torque"])
def test_a_delay_must_show_at_speed(lagged):
    """A torque logged late is shifted at every speed; the torque of a light joint that lags only at the
    lowest speeds of its moves (a loop that builds up the torque while the friction holds the joint near a
    reversal) only there: on the faster half of the moving samples (:func:`frictid.diagnose.lag.delay_at_speed`)
    the shift explains a material share of the friction RMS only where the whole torque was shifted (foreign
    seeds 309007 and 309247, PI velocity loops with no delay hidden, named ``delay`` for 34 and 43 ms shifts
    that live at the reversals). On the moving samples as a whole both shifts gain."""
    from frictid.diagnose.chain import ALPHA, EXPLAINED_MIN, paired_t
    from frictid.diagnose.lag import delay_at_speed
    from frictid.diagnose.signals import delay_estimates, delay_heldout

    J, L = 0.05, 5   # inertia [kg m^2] (light: the friction dominates the reversals), lag [samples]
    lg = plateau_log(seed=13, reps=2, noise=0.0, move=0.1, alternate=True)   # a reversal at every plateau
    tau0 = J * lg.a + lg.F
    late = np.concatenate([np.full(L, tau0[0]), tau0[:-L]])
    slow = np.exp(-(lg.w / 0.2) ** 2)   # the lag's weight: 1 at rest, under 2 % above a tenth of the top speed
    tau = slow * late + (1 - slow) * tau0 if lagged == "slow" else late
    tau = tau + 0.005 * np.random.default_rng(14).standard_normal(lg.n)
    lg.tau, lg.F = tau, tau - J * lg.a
    S = build_samples([lg], 5, axis="rotary", J=J)
    F_rms = float(np.sqrt(np.mean(S.F ** 2)))
    shifts = delay_estimates(S)
    rb, ra, _ = delay_heldout(S, shifts)
    fast = delay_at_speed(S, shifts)
    t, p = paired_t(fast["d"])
    expl = math.sqrt(max(fast["rms_before"] ** 2 - fast["rms_after"] ** 2, 0.0))
    assert ra < 0.7 * rb and all(x < -1.5 * 2e-3 for x in shifts), (rb, ra, shifts)
    if lagged == "slow":
        assert p >= ALPHA or expl < EXPLAINED_MIN * F_rms, (t, expl / F_rms, shifts)
    else:
        assert p < ALPHA and expl >= EXPLAINED_MIN * F_rms and fast["rms_after"] < 0.5 * fast["rms_before"], (
            t, expl / F_rms, fast)


def test_a_base_that_one_fold_cannot_refit_is_refused():
    """Foreign seed 313038 (a level cycling in time, 7.5 %, outside the list): the fit's ``stribeck_2exp`` had
    two exponentials of nearly one velocity and opposite amplitudes of 28 times the friction; refitted on all
    sliding samples it kept its shape, but without one fold the amplitudes passed the bound (10 times that
    training set's largest friction), were dropped, and that fold's held-out RMS was 307 N m against 45 in
    the others. Every candidate that steadied it "explained" it: ``thermal6`` was named temperature (0.68).
    Every held-out test predicts a fold by its training set's refit, so that refit must keep the map's shape
    too (:func:`frictid.diagnose.joint._not_refitted`). Here one torque spike in one group sets the bound of
    every training set that holds it; the one without it drops the level and the second exponential."""
    from frictid.result import ModelFit, ParamEstimate

    def spike(t, q, w, F):
        F = np.asarray(F).copy()
        i = int(np.argmin(np.abs(t - 30.3)))   # on a plateau
        F[i] += 6.0 * np.sign(w[i])
        return F

    jf = fake_fit()
    vals = dict(alpha0=62.0, alpha1=-59.0, alpha2=-60.0, alpha3=1.2, alpha4=0.0, ws1=0.02, ws2=0.021)
    jf.models["stribeck_2exp"] = ModelFit("stribeck_2exp", "stribeck_2exp",
                                          {k: ParamEstimate(k, v, None, "", True) for k, v in vals.items()},
                                          {"rms_heldout": 0.01, "aic": -10.0, "k": 7, "n": 24})
    jf, findings = _run([plateau_log(spike, seed=1)], jf)
    d = jf.selection["diagnosis"]
    assert d["base"] == "stribeck", d.get("base_refused")
    assert [r["model"] for r in d["base_refused"]] == ["stribeck_2exp"]
    assert "without fold" in d["base_refused"][0]["reason"], d["base_refused"]
    assert not [f for f in findings if f["gain"] >= 0.05], findings


@pytest.mark.parametrize("seed", [4])
def test_a_position_torque_or_load_that_follows_part_of_a_slow_cycle_is_not_named(seed):
    """Foreign seeds 313620 and 314016 (a level cycling in time, 35 % and 33 %, on sweeps): where a plateau
    runs, the position, the gravity torque and the transmitted torque advance with the time, so a position
    torque and a load-dependent level take part of the cycle within each segment (``position_torque`` 0.06:
    32 N m of a 93 N m residual; ``load_gravity`` 0.05). They face the free function of the time as the
    level's position candidates do (:data:`frictid.diagnose.chain.TIME_COURSE_EXTS`; the position torque
    after its own checks, which name a vibration or a constant first): a candidate whose correction is a
    fifth of the cycle is rejected, one that takes the whole cycle leaves nothing to it."""
    from dataclasses import replace

    from frictid.diagnose.chain import TIME_COURSE_EXTS, _not_its_time_course

    S, chain, off, whole = _slow_cycle(seed)

    def dressed(ext, pred_after):
        tr = replace(off, ext=ext, pred_after=pred_after)
        rb, ra = S.F - tr.pred_before, S.F - tr.pred_after
        tr.explained = float(np.sqrt(max(np.mean(rb ** 2) - np.mean(ra ** 2), 0.0)))
        return tr

    for ext, shape in (("position_torque", "a torque of the position"), ("load_gravity", "a load-dependent level"),
                       ("load_torque", "a load-dependent level")):
        assert ext in TIME_COURSE_EXTS
        why = _not_its_time_course(S, dressed(ext, chain.pred + (whole - chain.pred) / 5), 1)
        assert why is not None and f"not the shape of {shape}" in why, why
        assert _not_its_time_course(S, dressed(ext, whole), 1) is None


def _even_work_log(effect, minutes: float, v: float = 0.8, hold: float = 2.0, move: float = 0.4, dt: float = 5e-3,
                   seed: int = 3, noise: float = 0.01):
    """Back-and-forth moves at one speed, ``minutes`` long: work at an even power. effect(t, q, w, F) as in
    :func:`test_diagnose.plateau_log`."""
    n_m, n_h = int(move / dt), int(hold / dt)
    ws, kinds, w_prev, s = [], [], 0.0, v
    while sum(x.size for x in ws) * dt < 60.0 * minutes:
        ws.append(w_prev + (s - w_prev) * smooth(np.arange(n_m) / n_m))
        kinds.append(("other", n_m))
        ws.append(np.full(n_h, s))
        kinds.append(("constant_velocity", n_h))
        w_prev, s = s, -s
    w = np.concatenate(ws)
    n = w.size
    t = np.arange(n) * dt
    q = np.cumsum(w) * dt
    F = np.asarray(effect(t, q, w, Parts(sm.stribeck(w, **TRUE), TRUE["sigma2"] * w)), float)
    F = F + noise * np.random.default_rng(seed).standard_normal(n)
    segs, i = [], 0
    for kind, m in kinds:
        segs.append(Segment(kind, i, i + m, float(t[i]), float(t[i + m - 1])))
        i += m
    return DiagLog(t=t, q=q, w=w, a=np.gradient(w, dt), tau=F.copy(), F=F, G=np.zeros(n), offset=0.0,
                   segments=segs, channels={"temp_env": np.full(n, 25.0)}, start=None)


def test_a_thermal_state_that_follows_the_frictions_own_change_is_no_warm_up():
    """Foreign seed 314026 (a level cycling in time, 35 %, a work program): the heat balance is driven by the
    measured friction power ``F w``, which carries the cycle itself, so a state of a short time constant heats
    and cools with it (``thermal6``, 37 s, named temperature 0.31). A warm-up is the heat the motion delivers:
    with the state driven by the power of the friction the speed alone predicts
    (:meth:`frictid.diagnose.model.Context.work_power`) the candidate must still explain the residual
    (:meth:`frictid.diagnose.chain.Chain._not_from_the_work`). Work at an even power for 8 minutes, the level
    cycling by 30 % over 2 minutes: the measured power's state (12 s) is significant (t = 3.5) and rejected
    (the work's state: t = 1.7); a true warm-up, the friction falling with the heat of its own power, keeps
    both thermal candidates."""
    from frictid.diagnose.chain import Chain
    from frictid.diagnose.samples import heat_balance_rise

    def cyc(t, q, w, F):
        return F.level * (1 + 0.3 * np.sin(2 * np.pi * t / 120.0)) + F.viscous

    def warm(t, q, w, F):
        return F * (1 - 0.06 * heat_balance_rise(t, F * w, np.zeros(t.size), 60.0))

    cp, _ = sm.canonical_pair("stribeck", TRUE)
    for eff, minutes, rejected in ((cyc, 8.0, True), (warm, 6.0, False)):
        S = build_samples([_even_work_log(eff, minutes)], 5)
        chain = Chain(S, Structure("stribeck", cp))
        for ext in ("thermal4", "thermal6"):
            tr = chain.evaluate(ext, 1)
            assert tr.p < 0.01 and tr.explained >= 0.02 * chain.F_rms, (ext, tr.t)   # a worthy candidate
            why = chain._not_from_the_work(tr, 1)
            assert (why is not None) == rejected, why
            if rejected:
                assert "not the heat of the work" in why, why


def _previous_move_log(seed: int, effect: str, amp: float, dt: float = 2e-3, noise: float = 0.01, moves: int = 48):
    """48 moves of random direction, speed (0.3-1.5) and length (held 0.2-2 s, reached and left in 0.3 s), each
    after a rest of 0.1-6 s (log-uniform), on a random Stribeck plant; the level times ``1 + amp x`` with ``x``
    a dwell's ``ln(1 + t_rest / 0.1) exp(-s / 0.3)`` or a memory of the previous move,
    ``(1 - exp(-s_prev / 1)) exp(-s / 0.3)`` (``s`` the travel since the move started, ``s_prev`` the previous
    move's). About 3 min of data. Returns the log and the plant's values."""
    rng = np.random.default_rng(seed)
    values = dict(Fc=float(rng.uniform(1.0, 3.0)), vs=float(rng.uniform(0.05, 0.2)), delta=2.0,
                  sigma2=float(rng.uniform(0.5, 1.5)))
    values["Fs"] = values["Fc"] * float(rng.uniform(1.1, 1.6))
    ws, kinds, xs, s_prev = [], [], [], 0.0
    for _ in range(moves):
        v = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 1.5))
        t_rest = float(np.exp(rng.uniform(np.log(0.1), np.log(6.0))))
        n_r, n_m, n_h = int(t_rest / dt), int(0.3 / dt), int(rng.uniform(0.2, 2.0) / dt)
        move = np.concatenate([v * smooth(np.arange(n_m) / n_m), np.full(n_h, v), v * smooth(1 - np.arange(n_m) / n_m)])
        travel = np.abs(np.cumsum(move) * dt)
        height = np.log1p(t_rest / 0.1) if effect == "dwell" else 1.0 - math.exp(-s_prev / 1.0)
        ws += [np.zeros(n_r), move]
        xs += [np.zeros(n_r), height * np.exp(-travel / 0.3)]
        kinds += [("rest", n_r), ("other", n_m), ("constant_velocity", n_h), ("other", n_m)]
        s_prev = float(travel[-1])
    w, x = np.concatenate(ws), np.concatenate(xs)
    n = w.size
    t = np.arange(n) * dt
    F = (sm.stribeck(w, **values) - values["sigma2"] * w) * (1 + amp * x) + values["sigma2"] * w
    F = F + noise * rng.standard_normal(n)
    segs, i = [], 0
    for kind, m in kinds:
        segs.append(Segment(kind, i, i + m, float(t[i]), float(t[i + m - 1])))
        i += m
    q = np.cumsum(w) * dt
    return DiagLog(t=t, q=q - q.mean(), w=w, a=np.gradient(w, dt), tau=F.copy(), F=F, G=np.zeros(n), offset=0.0,
                   segments=segs, channels={"temp_env": np.full(n, 25.0)}, start=None), values


@pytest.mark.parametrize("seed", [1])
def test_a_level_that_grows_with_the_previous_move_is_not_named_dwell(seed):
    """Session 22 (foreign seeds 314400, 314403: ``memory``, outside the list, named ``dwell``): a level that
    grows with the previous move's travel rises at a move's start and fades over its travel, a dwell's shape,
    and the dwell candidate followed it through the rests (named, gain 0.35, on this log before). It faces the
    same fade from a free height of the previous move's travel (``Chain._not_the_rest``), which predicts the
    held-out data better: no dwell, nothing of gain 0.05 named but repairs. On the same program a dwell
    (rests of 0.1-6 s, independent of the moves) beats it and is named."""
    lg, values = _previous_move_log(seed, "memory", 0.4)
    jf = fake_fit(values)
    findings = diagnose_joint(jf, [lg])
    rec = jf.selection["diagnosis"]
    assert "dwell" not in _outside(jf), rec["steps"]
    assert not [f for f in findings if f.get("kind") != "repair" and f["gain"] >= 0.05], findings
    why = [r["reason"] for s in rec["steps"] for r in s.get("rejected", []) if r["extension"] == "dwell"]
    assert why and "beaten by the move before the rest" in why[0], rec["steps"]
    # what is left follows the previous move: its structure test (cells of the previous move's travel by
    # direction and travel since the move started) states it (the session-22 memory draws left silent)
    prev = next(e for e in rec["structure"]["tests"] if e["variable"] == "previous")
    assert prev["large"] and prev["p"] < 1e-6, prev
    assert rec["unexplained"] and rec["unexplained"][0].startswith("residual varies with the previous move's travel")
    lg, values = _previous_move_log(seed, "dwell", 0.08)
    jf = fake_fit(values)
    diagnose_joint(jf, [lg])
    assert _outside(jf).get("dwell", {}).get("gain", 0.0) > 0.5, jf.selection["diagnosis"]["steps"]


def test_the_previous_move_states_nothing_on_a_clean_program():
    """The previous move's structure test (its cells hold a few hundred samples each) finds nothing on the
    same program of rests and moves without an effect: the cells' held-out means do not fit the noise."""
    lg, values = _previous_move_log(1, "memory", 0.0)
    jf = fake_fit(values)
    diagnose_joint(jf, [lg])
    rec = jf.selection["diagnosis"]
    prev = next(e for e in rec["structure"]["tests"] if e["variable"] == "previous")
    assert not prev["significant"] and prev["explained_rms"] < 0.01 * values["Fc"], prev
    assert rec["unexplained"] == [], rec["unexplained"]


@pytest.mark.parametrize("seed", [5])
def test_a_dwell_that_lifts_the_level_beyond_3x_is_found(seed):
    """Foreign seed 322537 (a 37 % dwell, `load` named first): the plant's level grew to 4x after a 60 s
    rest, beyond the factor terms' bound (``1 + phi gamma`` at most 3 on the samples), so the dwell's
    coefficient was held at zero in 3 of 5 folds and on all samples. The dwell's bound is per unit of its
    column (``model._factor_bound``): a random Coulomb-viscous plant whose level grows 3.5-4.5x after the
    longest rest has its dwell found, first, at about its size."""
    rng = np.random.default_rng(seed)
    vals = dict(Fc=float(rng.uniform(1.0, 5.0)), sigma2=float(rng.uniform(0.5, 2.0)), vs=0.1, delta=2.0)
    vals["Fs"] = vals["Fc"]
    top = float(rng.uniform(3.5, 4.5))                     # the level's ratio after a 6 s rest (t0 0.1 s)
    amp = (top - 1.0) / math.log1p(6.0 / 0.1)
    jf = fake_fit({"Fc": vals["Fc"], "sigma2": vals["sigma2"]}, "coulomb_viscous")
    diagnose_joint(jf, [_rest_plateau_log(seed, amp, vals)])
    steps = [s["chosen"] for s in jf.selection["diagnosis"]["steps"] if s.get("chosen")]
    assert steps and steps[0] == "dwell", (top, jf.selection["diagnosis"]["steps"])
    assert _outside(jf)["dwell"]["gain"] > 0.5, _outside(jf)["dwell"]
