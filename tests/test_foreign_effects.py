"""The hidden effects of the foreign simulator (``benchmarks/foreign/effects.py``, issue 20's diagnosis card).

Small and fast. Seeds here are < 1000 (the card uses seeds >= 300000). Nothing here asserts frictid's
diagnosis (that is the scorecard's job): only that each effect does to the joint what it says, that an
effect-free draw is the plain simulator's, that sizes land where they were aimed, and that the logs are
deterministic and carry what a user's log would (``temp_joint``, ``start_time``).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

FOREIGN = Path(__file__).resolve().parents[1] / "benchmarks" / "foreign"
sys.path.insert(0, str(FOREIGN))

import effects  # noqa: E402
import layouts  # noqa: E402
import sim  # noqa: E402


def _joint():
    """A soft, fast-to-simulate joint with gravity and a PID loop."""
    J, s0, s2 = 0.2, 2.0e3, 0.3
    pl = sim.Plant(J=J, Fc=1.0, Fs=1.3, vs=0.05, delta=2.0, sigma2=s2, sigma0=s0,
                   sigma1=2 * 0.7 * math.sqrt(s0 * J) - s2, Px=3.0, Py=1.0)
    ctl = sim.Controller("pid", Kp=400.0, Kd=2 * 0.8 * math.sqrt(400.0 * J), Ki=400.0 * math.sqrt(400.0 / J) / 5)
    return pl, ctl


def _program(fs=200.0, rests=(0.5, 20.0)):
    """Moves both ways at two speeds, with the given rests before them."""
    pr = sim.Program(fs=fs)
    layouts.dwell(pr, 1.0)
    for T in rests:
        for v in (0.5, -1.0):
            layouts.dwell(pr, T)
            layouts.accel(pr, 0.0, v, 5.0)
            layouts.plateau(pr, v, 1.5, label="other")
            layouts.accel(pr, v, 0.0, 5.0)
    layouts.dwell(pr, 0.5)
    return pr


def _fx(**kw):
    fx = np.zeros(len(sim.FX))
    for k in ("on", "m_all", "tau_th", "P_ref", "L_ref", "period", "t0W", "s0W"):
        fx[sim.FXI[k]] = 1.0
    for k, v in kw.items():
        fx[sim.FXI[k]] = v
    return fx


def _sliding(out, w_min=0.05):
    return np.abs(out["w"]) > w_min


def test_no_effect_is_the_plain_simulator_bit_for_bit():
    pl, ctl = _joint()
    pr = _program()
    plain = sim.simulate(pl, ctl, pr)
    fx = _fx()        # effects on, every coefficient zero
    hooked = sim.simulate(pl, ctl, pr, fx=fx)
    for k in ("q", "w", "z", "tau", "F"):
        assert np.array_equal(plain[k], sim.simulate(pl, ctl, pr, fx=None)[k])
        np.testing.assert_allclose(hooked[k], plain[k], rtol=1e-12, atol=1e-12)


def test_position_ripple_and_asymmetry_scale_the_level_as_stated():
    pl, ctl = _joint()
    out = sim.simulate(pl, ctl, _program(), fx=_fx(aP=0.2, period=0.3, phiP=0.4, kA_level=0.25))
    m = _sliding(out)
    q, w = out["q"][m], out["w"][m]
    want = (1 + 0.2 * np.sin(2 * np.pi * q / 0.3 + 0.4)) * np.where(w < 0, 1.25, 1.0) * pl.g(w)
    np.testing.assert_allclose(out["g_eff"][m], want, rtol=1e-12)
    assert np.all(out["mV"][m][w > 0] == 1.0) and np.all(out["mV"][m][w < 0] == 1.0)   # kA_visc = 0


def test_warm_up_follows_the_friction_power_and_lowers_friction():
    pl, ctl = _joint()
    out = sim.simulate(pl, ctl, _program(), fx=_fx(kT=-0.3, tau_th=5.0, P_ref=0.5))
    th = out["theta"]
    assert th[0] == 0.0 and th.max() > 0.5
    rest = np.abs(out["w"]) < 1e-3
    assert np.all(np.diff(th)[rest[1:] & rest[:-1]] <= 1e-12)    # it cools at rest
    m = _sliding(out)
    np.testing.assert_allclose(out["g_eff"][m], (1 - 0.3 * th[m]) * pl.g(out["w"][m]), rtol=1e-12)
    np.testing.assert_allclose(out["mV"][m], 1 - 0.3 * th[m], rtol=1e-12)


def test_dwell_raises_break_away_with_the_rest_before_a_move():
    pl, ctl = _joint()
    kw, t0 = 0.3, 0.2
    out = sim.simulate(pl, ctl, _program(rests=(0.5, 20.0)), fx=_fx(kW=kw, t0W=t0, s0W=0.05, w_still=0.01))
    extra = out["g_eff"] - pl.g(out["w"])
    moving = np.abs(out["w"]) >= 0.01
    planned = np.abs(out["wr"]) > 0
    starts = np.flatnonzero(planned[1:] & ~planned[:-1]) + 1          # where the program starts a move
    peaks = [extra[i - 5:i + 40].max() for i in starts]               # the break-away excess of that move
    assert len(peaks) == 4
    # the rest before the second and the later moves: 0.5 s then 20 s (the first follows the 1 s hold + 0.5 s)
    assert peaks[2] > peaks[1] * 1.5 and peaks[2] == pytest.approx(kw * math.log1p(20.0 / t0), rel=0.05)
    mids = (starts + np.flatnonzero(planned[:-1] & ~planned[1:])) // 2     # the middle of each move
    assert moving[mids].all()
    assert np.all(np.abs(extra[mids]) < 1e-3 * np.array(peaks))   # >= 0.4 rad of travel (8 s0): exp(-8)


def test_non_friction_torque_is_the_stated_harmonics():
    pl, ctl = _joint()
    out = sim.simulate(pl, ctl, _program(), fx=_fx(bG2=0.4, phiG2=0.3, cC=0.1, nC=24.0, phiC=-1.0))
    q = out["q"]
    np.testing.assert_allclose(out["E"], 0.4 * np.sin(2 * q + 0.3) + 0.1 * np.sin(24 * q - 1.0), atol=1e-12)
    np.testing.assert_allclose(out["g_eff"], pl.g(out["w"]), rtol=1e-12)     # friction untouched


def test_cycling_scales_the_level_with_time_alone():
    pl, ctl = _joint()
    out = sim.simulate(pl, ctl, _program(), fx=_fx(aCyc=0.3, Tcyc=7.0, phiCyc=0.5))
    want = (1 + 0.3 * np.sin(2 * np.pi * out["t"] / 7.0 + 0.5)) * pl.g(out["w"])
    np.testing.assert_allclose(out["g_eff"], want, rtol=1e-12)


def test_memory_raises_the_level_after_a_long_move_and_fades_over_the_next():
    """The ``memory`` kind (outside the list): a move's level grows with the travel of the previous move (rest
    or reversal to rest or reversal) and fades over its own travel."""
    pl, ctl = _joint()
    k, s_ref, s_fade, still = 0.4, 0.5, 0.1, 0.01
    out = sim.simulate(pl, ctl, _program(), fx=_fx(kM=k, sM=s_ref, fM=s_fade, w_stillM=still))
    cur, prev = effects._move_memory(out["w"], float(out["t"][1] - out["t"][0]), still)
    moving = np.abs(out["w"]) >= still
    want = (1 + k * moving * (1 - np.exp(-prev / s_ref)) * np.exp(-cur / s_fade)) * pl.g(out["w"])
    np.testing.assert_allclose(out["g_eff"], want, rtol=0.05)   # the kernel's clock runs on its sub-steps
    extra = out["g_eff"] / pl.g(out["w"]) - 1
    assert extra.max() > 0.5 * k * (1 - math.exp(-0.75 / s_ref)) and abs(extra[:50]).max() == 0.0
    assert "memory" in effects.ALL_KINDS and "memory" not in effects.KINDS   # in the mix from MIX_FROM only


def test_the_default_mix_draws_memory_from_new_seeds_only_and_leaves_every_other_draw(monkeypatch):
    """Session 22: the card's default mix holds ``memory`` beside ``cycling`` for seeds from ``MIX_FROM`` on
    (a single effect turned into it on a stream of its own); every earlier seed, and every later draw that is
    not turned, is the draw it was (the same plant, program, rate, length, kinds, sizes and settings)."""
    def kinds_of(seeds):
        return {s: [e["kind"] for e in effects.draw_card(s).effects] for s in seeds}

    seeds = list(range(effects.MIX_FROM - 30, effects.MIX_FROM + 90))
    new = kinds_of(seeds)
    assert all("memory" not in k for s, k in new.items() if s < effects.MIX_FROM)
    turned = [s for s, k in new.items() if k == ["memory"]]
    assert 2 <= len(turned) <= 20, turned     # 1 in 12 of the single effects (65 % of the draws): about 5 of 90
    before = {s: effects.draw_card(s) for s in seeds}
    monkeypatch.setattr(effects, "_mixed", lambda seed, effect: effect)
    for s in seeds:
        old = effects.draw_card(s)
        if s in turned:
            assert len(old.effects) == 1 and old.effects[0]["kind"] in effects.KINDS
            continue
        b = before[s]
        assert (b.family, b.fs, b.seconds, b.starts, b.sc.plant) == (old.family, old.fs, old.seconds, old.starts,
                                                                    old.sc.plant), s
        assert yaml.safe_dump(b.effects) == yaml.safe_dump(old.effects), s


def test_load_scales_the_level_with_the_transmitted_torque():
    pl, ctl = _joint()
    out = sim.simulate(pl, ctl, _program(), fx=_fx(kL=0.2, L_ref=3.0))
    m = _sliding(out)
    carried = np.abs(out["tau"] - out["F"])[m]       # J a + G at the sample (the kernel uses the last sub-step)
    ratio = out["g_eff"][m] / pl.g(out["w"][m])
    np.testing.assert_allclose(ratio, 1 + 0.2 * carried / 3.0, rtol=0.02)
    assert ratio.max() > 1.1


@pytest.mark.parametrize("kind", ["position", "asymmetry", "gravity2", "cogging", "delay", "drift", "load",
                                  "temperature", "dwell", "cycling", "memory"])
def test_measured_size_lands_near_the_target(kind, tmp_path):
    paths, truth = effects.make_card_logs(7, tmp_path, family="sweeps", effect=kind, minutes=(1.5, 1.5))
    (e,) = truth["effects"]
    assert e["kind"] == kind and 0.03 <= e["size_target"] <= 0.4
    if e["size_plan"] < e["size_target"] - 1e-9:           # stopped by a cap: the plan says so
        assert kind in effects.CAPS or kind == "delay"
    lo, hi = (0.4, 1.6) if kind in ("temperature", "dwell", "load", "memory") else (0.7, 1.3)
    assert lo * e["size_plan"] <= truth["size"] <= hi * e["size_plan"], (truth["size"], e)
    assert len(paths) == (truth["recordings"]) and (len(paths) > 1) == (kind == "drift")


def test_logs_carry_temperature_and_start_times_as_a_user_would_write_them(tmp_path):
    paths, truth = effects.make_card_logs(11, tmp_path, family="work", effect="temperature_logged",
                                          minutes=(1.0, 1.0))
    df = pd.read_csv(paths[0]) if paths[0].suffix == ".csv" else pd.read_parquet(paths[0])
    assert "temp_joint" in df and df["temp_joint"].iloc[-200:].mean() > df["temp_joint"].iloc[:200].mean()
    assert np.allclose(df["temp_joint"] * 10, np.round(df["temp_joint"] * 10))     # 0.1 degC steps
    paths, truth = effects.make_card_logs(11, tmp_path, family="work", effect="drift", minutes=(1.0, 1.0))
    starts = [yaml.safe_load(Path(str(p) + ".meta.yaml").read_text())["meta"]["start_time"] for p in paths]
    assert starts == sorted(starts) and starts == truth["starts"] and starts[-1] - starts[0] >= 3600.0
    paths, _ = effects.make_card_logs(11, tmp_path, family="work", effect="none", minutes=(1.0, 1.0))
    df = pd.read_csv(paths[0]) if paths[0].suffix == ".csv" else pd.read_parquet(paths[0])
    assert "temp_joint" not in df


def test_the_card_draws_are_deterministic_and_cover_every_kind(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, ta = effects.make_card_logs(13, tmp_path / "a", effect="pair", minutes=(0.5, 0.5))
    b, tb = effects.make_card_logs(13, tmp_path / "b", effect="pair", minutes=(0.5, 0.5))
    assert a[0].read_bytes() == b[0].read_bytes() and ta["effects"] == tb["effects"]
    assert len(ta["effects"]) == 2 and all(e["kind"] in effects.IN_LIST for e in ta["effects"])
    drawn = [effects.draw_card(s) for s in range(200)]
    kinds = {e["kind"] for d in drawn for e in d.effects}
    assert kinds == set(effects.KINDS)
    n_clean = sum(1 for d in drawn if not d.effects)
    assert 10 <= n_clean <= 50 and all(d.seconds >= 60 * effects.MINUTES[0] - 1e-6 for d in drawn)


def test_a_level_asymmetry_differs_from_an_offset_only_by_its_hump_or_viscous_part():
    """The card's truth label ``asym_distinct`` (``effects.offset_distinct``): a Coulomb-level asymmetry on a map
    without a hump is an offset and a symmetric map on the sliding data (nothing left); its hump, or the viscous
    part a whole-branch asymmetry scales, is what an offset cannot make; the card then accepts "offset or
    asymmetry" for an asymmetry under 2 % of the friction RMS and nothing else (seed-free, no simulation)."""
    import diagnosis_scorecard as card
    w = np.concatenate([np.linspace(-1.0, -0.02, 400), np.linspace(0.02, 1.0, 400)])
    flat = sim.Plant(J=0.1, Fc=1.0, Fs=1.0, vs=0.05, delta=2.0, sigma2=0.5, sigma0=1e3, sigma1=1.0)
    hump = sim.Plant(J=0.1, Fc=1.0, Fs=1.6, vs=0.05, delta=2.0, sigma2=0.5, sigma0=1e3, sigma1=1.0)

    def distinct(pl, variant, warm=1.0):
        """RMS of what no offset makes of a 0.3 asymmetry, the simulator's level and viscous factors as
        the kernel makes them (``warm``: another effect's level factor, e.g. a warm-up's)."""
        e = {"variant": variant, "coef": 0.3}
        neg = np.where(w < 0, 1.3, 1.0)
        out = {"w": w, "label": np.full(w.size, sim.CODE["other"]), "g_eff": pl.g(w) * neg * warm,
               "mV": neg if variant == "scale" else np.ones(w.size)}
        return float(np.sqrt(np.mean(np.square(effects.offset_distinct(out, pl, 1.0, e)))))

    assert distinct(flat, "coulomb") < 1e-9
    assert 1e-3 < distinct(hump, "coulomb") < distinct(flat, "scale")
    assert distinct(flat, "scale") > 0.02   # 0.3 * 0.5 |w| / 2 less its mean
    # a level that changes in time (a warm-up, a drift) scales a level asymmetry, not an offset
    assert distinct(flat, "coulomb", warm=np.random.default_rng(3).uniform(0.8, 1.2, w.size)) > 0.01
    row = {"truth": {"asym_distinct": 0.004, "effects": [{"kind": "asymmetry"}], "sensors": {"tau_bias": 0.0},
                     "friction_rms": 1.0},
           "diag": {"findings": [], "ambiguous": [["offset", "asymmetry"]], "tested": ["asymmetry", "offset"]}}
    assert card.found_first(row, "asymmetry") and card.found_any(row, "asymmetry")
    row["truth"]["asym_distinct"] = 0.05      # an asymmetry an offset cannot make: the name is required
    assert not card.found_first(row, "asymmetry")
    row["truth"]["asym_distinct"] = 0.004
    row["diag"]["findings"] = [["load", "load_torque", 0.3]]   # a wrong name first stays wrong
    assert not card.found_first(row, "asymmetry")
    row["diag"]["findings"], row["diag"]["ambiguous"] = [], [["offset", "position"]]
    assert not card.found_first(row, "asymmetry")
