"""The rigid terms refitted with the bristles from the stops and reversals (identify/reversals.py), and a
torque ripple that follows the position (identify/ripple.py), on a simulated UR-like wrist joint (100 Hz,
2.4 N m Coulomb level, bristles of 0.4 mrad, J 0.45 kg m^2) that oscillates: its acceleration follows its
angle, so the inertia and a free gravity trade off."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

WRIST = {
    "name": "wrist", "description": "UR-like wrist joint (tests)", "robot": "wrist_like", "source": "tests",
    "axis": "rotary", "substeps": 1,
    "sensors": {"sample_rate": 100, "encoder_counts": 62832, "tau_noise": 0.15, "qd_noise": 0.001, "delay": 0},
    "joints": [{"name": "j1", "J": 0.45, "gravity": {"Px": 0.0, "Py": 0.0, "offset": 0.0},
                "friction": {"map": "stribeck", "Fc": 2.4, "Fs": 2.9, "vs": 0.06, "delta": 2.0, "sigma2": 3.0,
                             "sigma0": 6000.0, "sigma1": 20.0},
                "limits": {"velocity": 0.7, "acceleration": 4.0, "torque": 30.0, "position": [-2.0, 2.0]},
                "control": {"bandwidth_hz": 10.0, "damping": 1.0, "integral": 0.2}, "effects": []}]}


def _sine_log(tmp_path, seed: int, gravity=(0.0, 0.0), ripple=None):
    """A one-tone multi-sine (a = -w^2 (q - qc)) on the wrist; ``ripple`` (amplitude, period, phase): a
    cogging torque the drive delivers on top (its velocity loop holds the motion)."""
    from frictid.plant import simulate_recipe
    rec = yaml.safe_load(open("recipes/multisine.yaml"))
    rec["experiments"][0]["harmonics"] = 1
    (tmp_path / "sine.yaml").write_text(yaml.safe_dump(rec))
    plant = yaml.safe_load(yaml.safe_dump(WRIST))
    plant["joints"][0]["gravity"].update(Px=gravity[0], Py=gravity[1])
    (tmp_path / "wrist.yaml").write_text(yaml.safe_dump(plant))
    (lg, *_) = simulate_recipe(str(tmp_path / "sine.yaml"), plant=str(tmp_path / "wrist.yaml"), seed=seed,
                               duration_scale=0.5)
    if ripple:
        amp, period, phase = ripple
        lg.tau = lg.tau + amp * np.sin(2 * math.pi * lg.q / period + phase)
    lg.meta["position_absolute"] = True  # the plant's position has one zero in every recording
    return lg


def _sine_fit(tmp_path, seed: int, gravity=(0.0, 0.0), ripple=None):
    """:func:`_sine_log` fitted with LuGre from the reversals."""
    import frictid
    lg = _sine_log(tmp_path, seed, gravity, ripple)
    return frictid.fit([lg], models="polynomial,lugre")[lg.joint]


@pytest.mark.parametrize("seed", [2, 5])
def test_a_gravity_the_oscillation_cannot_tell_from_none_is_held_at_zero(tmp_path, seed):
    """Without gravity the free Px, Py predict the held-out blocks no better than none and are held at 0,
    with the reason; J is then the plant's within 7 % (with them free: 9 % and 11 % high on these seeds,
    the trade moving J)."""
    jf = _sine_fit(tmp_path, seed)
    assert jf.selected.endswith("lugre")
    p = jf.models["lugre"].params
    assert p["Px"].fixed and p["Px"].value == 0.0 and p["Py"].fixed and "no better than none" in p["Px"].reason
    assert abs(p["J"].value - 0.45) < 0.07 * 0.45
    assert any("gravity held at 0" in n for n in jf.models["lugre"].notes)
    fm = jf.friction_model()
    assert fm.Px == 0.0 and fm.Py == 0.0
    # no ripple in this plant, none kept (the period searched on each fold's training blocks)
    assert "rip_period" not in p and any("no position ripple" in n for n in jf.models["lugre"].notes)


def test_a_gravity_the_joint_has_is_kept(tmp_path):
    """With 0.67 N m of gravity (a quarter of the Coulomb level) the gravity terms beat none and stay
    free, near the plant's."""
    jf = _sine_fit(tmp_path, 2, gravity=(0.6, -0.3))
    p = jf.models["lugre"].params
    assert not p["Px"].fixed and abs(p["Px"].value - 0.6) < 0.1 and abs(p["Py"].value + 0.3) < 0.1
    assert not any("gravity held at 0" in n for n in jf.models["lugre"].notes)


def test_a_torque_ripple_that_follows_the_position_is_found_and_predicts():
    """A cogging ripple of 0.25 N m every 2 pi / 800 rad (a tenth of the Coulomb level, under the 0.15 N m
    noise per sample): its period and amplitude are found from the first log, and the model replays a second
    recording (another seed) better with it than without."""
    import tempfile
    from pathlib import Path

    from frictid.replay import replay
    P = 2 * math.pi / 800
    with tempfile.TemporaryDirectory() as d:
        import frictid
        lg = _sine_log(Path(d), 3, ripple=(0.25, P, 0.7))
        jf = frictid.fit([lg], models="polynomial,lugre")[lg.joint]
        other = _sine_log(Path(d), 4, ripple=(0.25, P, 0.7))
    p = jf.models["lugre"].params
    assert jf.selected.endswith("lugre") and abs(p["rip_period"].value - P) < 0.002 * P
    assert abs(math.hypot(p["rip_sin"].value, p["rip_cos"].value) - 0.25) < 0.05
    m = jf.friction_model()
    flat = jf.friction_model()
    flat.ext = {k: v for k, v in flat.ext.items() if not k.startswith("rip_")}
    moving = np.abs(other.qd) > 0.02
    err = [float(np.sqrt(np.mean(replay(other, x).residual[moving] ** 2))) for x in (m, flat)]
    assert err[0] < err[1] - 0.02
    assert "rip_sin sin(2 pi q / rip_period)" in m.formula()["torque"]
    # positions not declared absolute (an incremental encoder's zero moves between recordings): not tried
    lg.meta.pop("position_absolute")
    jf = frictid.fit([lg], models="polynomial,lugre")[lg.joint]
    assert "rip_period" not in jf.models["lugre"].params
    assert any("no position ripple: not tried" in n for n in jf.models["lugre"].notes)
