"""Plant simulator: physics checks that can fail, labels, configs, determinism, kernel twins."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from frictid.data import SEGMENT_KINDS
from frictid.errors import ConfigError
from frictid.models.static import canonical_friction
from frictid.plant import load_plant, load_recipe, simulate_recipe
from frictid.plant.config import Recipe, Sensors
from frictid.plant.kernel import simulate_joint, simulate_joint_ref
from frictid.plant.reference import simulate_joint_ivp
from frictid.plant.simulate import prepare_joint

ROOT = Path(__file__).resolve().parents[1]
PLANTS = sorted(p.stem for p in (ROOT / "recipes" / "plants").glob("*.yaml"))
RECIPES = sorted(p.stem for p in (ROOT / "recipes").glob("*.yaml"))
# shrink every recipe to a few seconds of simulated time per experiment
SCALE = {"duty_cycle": 0.01, "validation_ptp": 0.02, "multisine": 0.2, "tracking_warm": 0.02}


def quiet(plant):
    """A copy of a plant with ideal sensors (no noise, no quantisation)."""
    p = plant.model_copy(deep=True)
    p.sensors = Sensors(sample_rate=plant.sensors.sample_rate)
    return p


def runs(mask):
    """(start, end) of the runs of True in a boolean array."""
    m = np.concatenate([[False], mask, [False]]).astype(int)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def test_shipped_plants_and_recipes_exist():
    for name in ("direct_drive", "geared_industrial", "hydraulic", "linear_slide"):
        assert name in PLANTS
    for name in ("constant_velocity_sweep", "ramp_presliding", "torque_steps", "duty_cycle",
                 "validation_ptp", "multisine"):
        assert name in RECIPES
        rec, _ = load_recipe(name)
        assert rec.identifies and rec.default_plant


@pytest.mark.parametrize("plant", PLANTS)
@pytest.mark.parametrize("recipe", RECIPES)
def test_every_recipe_runs_on_every_plant(recipe, plant):
    logs = simulate_recipe(recipe, plant=plant, seed=3, duration_scale=SCALE.get(recipe, 0.25))
    pl = load_plant(plant)
    assert [lg.joint for lg in logs] == [j.name for j in pl.joints]
    want = {"constant_velocity_sweep": "constant_velocity", "ramp_presliding": "ramp_presliding",
            "torque_steps": "step", "duty_cycle": "duty_cycle", "validation_ptp": "duty_cycle",
            "multisine": "other", "random_ptp": "other", "tracking_slow": "other", "tracking_lv": "other",
            "tracking_warm": "duty_cycle"}[recipe]
    for lg in logs:
        seg, cyc = lg.truth["segment"], lg.truth["cycle"]
        assert seg.shape == (lg.n,) and cyc.shape == (lg.n,)
        assert set(np.unique(seg)) <= set(SEGMENT_KINDS)
        assert want in set(seg)
        # the index of a repeated piece: duty cycle, presliding ramp, torque step
        assert np.all((cyc >= 0) == np.isin(seg, ["duty_cycle", "ramp_presliding", "step"]))
        if recipe == "random_ptp":
            assert not np.isin(seg, ["ramp_presliding", "step", "constant_velocity", "duty_cycle"]).any()
        assert np.all(np.isfinite(lg.tau)) and np.all(np.isfinite(lg.q)) and np.all(np.isfinite(lg.qd))
        assert np.all(np.diff(lg.t) > 0)
        assert lg.axis == pl.axis and lg.meta["sample_rate"] == pl.sensors.sample_rate
        assert lg.truth["params"]["map"] == pl.joint(lg.joint).friction.map
        assert lg.truth["temp_joint"].shape == (lg.n,)
        for ch in ("q_ref", "qd_ref", "tau_ref"):
            assert lg.channels[ch].shape == (lg.n,)
        if recipe == "duty_cycle":
            assert "temp_env" in lg.channels
            c = cyc[cyc >= 0]
            assert c.max() + 1 == 40 and np.all(np.diff(c) >= 0)


@pytest.mark.parametrize("plant", ["direct_drive", "hydraulic"])
def test_plateaus_give_the_static_map(plant):
    """Mean torque over each labelled plateau equals the true steady-state friction at its mean speed."""
    pl = load_plant(plant)
    lg = simulate_recipe("constant_velocity_sweep", plant=pl, seed=1, duration_scale=0.4)[0]
    P = lg.truth["params"]
    cp, cn = np.array(P["canonical_pos"]), np.array(P["canonical_neg"])
    plateaus = runs(lg.truth["segment"] == "constant_velocity")
    assert len(plateaus) >= 20
    for a, b in plateaus:
        w = lg.qd[a:b].mean()
        F = lg.tau[a:b].mean()          # no gravity on these plants, a ~ 0 on a plateau
        F_ss = float(canonical_friction(w, cp, cn))
        assert F == pytest.approx(F_ss, rel=0.01, abs=3 * pl.sensors.tau_noise / np.sqrt(b - a) + 1e-3)
        # honest labels: the velocity really is constant there
        assert np.std(lg.truth["velocity"][a:b]) < 0.05 * abs(w) + 1e-3 * pl.joints[0].limits.velocity


def test_presliding_slope_is_sigma0():
    """On a slow open-loop ramp below break-away the torque/displacement slope at small load is sigma0."""
    pl = quiet(load_plant("hydraulic"))
    lg = simulate_recipe("ramp_presliding", plant=pl, duration_scale=0.5)[0]
    s0 = pl.joints[0].friction.sigma0
    g = 225.0  # Coulomb level: the lowest level of this map
    n_checked = 0
    for a, b in runs(lg.truth["segment"] == "ramp_presliding"):
        ref = lg.channels["tau_ref"][a:b]
        if abs(ref[-1]) < abs(ref[0]):
            continue                                                 # the ramp-up parts only
        tau, q = lg.tau[a:b], lg.q[a:b]
        tau = tau - tau[0]
        q = q - q[0]
        sel = np.abs(tau) < 0.08 * g
        k = np.polyfit(q[sel], tau[sel], 1)[0]
        assert k == pytest.approx(s0, rel=0.06)
        n_checked += 1
    assert n_checked == 4
    assert np.abs(lg.truth["velocity"]).max() < 5e-3   # never slid


def test_thermal_steady_state_rise_is_power_over_K():
    pl = load_plant("geared_industrial").model_copy(deep=True)
    th = pl.joints[0].thermal
    th.C, th.K = 20.0, 2.5                              # time constant 8 s so the test is short
    rec = Recipe.model_validate(dict(
        name="hot", default_plant="geared_industrial", temp_env=20.0,
        experiments=[dict(kind="constant_velocity", velocities=[0.5], signs="positive", plateau=60.0,
                          relative=True)]))
    pl.joints[0].limits.position = None                 # room for a long plateau
    lg = simulate_recipe(rec, plant=pl)[0]
    a, b = runs(lg.truth["segment"] == "constant_velocity")[0]
    tail = slice(b - 5000, b)
    P = np.mean(lg.truth["friction"][tail] * lg.truth["velocity"][tail])
    rise = lg.truth["temp_joint"][b - 1] - 20.0
    assert rise == pytest.approx(P / 2.5, rel=0.01)
    assert rise > 10.0


def test_geared_warm_up_lowers_friction_by_about_a_third():
    pl = load_plant("geared_industrial")
    j = pl.joints[0]
    th = j.thermal
    P0 = 0.0
    # steady rise at full duty (100 %) from the plant's own thermal numbers, friction power ~ 30 W cold
    c = np.array([j.friction.c0, j.friction.c1, j.friction.c2, j.friction.c3])
    dc = np.array([th.dc0, th.dc1, th.dc2, th.dc3])
    v = 2.5
    F = lambda dT: np.polyval((c + dc * dT)[::-1], v)
    assert 0.25 < 1 - F(25.0) / F(0.0) < 0.42
    assert 5 * 60 <= th.C / th.K <= 20 * 60   # minutes
    del P0


@pytest.mark.parametrize("law", [dict(law="thermal6"), dict(law="thermal4", alpha=-0.008, beta=1.0),
                                 dict(law="exponential", lam=0.012)])
def test_kernel_equals_python_twin_with_every_effect(law):
    pl = load_plant("geared_industrial").model_copy(deep=True)
    data = pl.model_dump()
    data["joints"][0]["thermal"].update(law, C=5.0)   # fast heating so the law matters in 400 samples
    data["joints"][0]["effects"] = [
        dict(kind="position", amplitude=0.1, period=0.3),
        dict(kind="load", coeff=1e-3, payload_coeff=0.01),
        dict(kind="asymmetry", factor=1.2),
        dict(kind="torque_offset", value=0.7),
        dict(kind="drift", per_hour=0.5, per_run=0.05),
    ]
    pl = load_plant(data)
    rec, _ = load_recipe("multisine")
    rec = rec.model_copy(update={"payload": 3.0})
    prog, args, _ = prepare_joint(pl, pl.joints[0], rec, 0, 0.2)
    n = 400
    sl = {k: (v[:n] if isinstance(v, np.ndarray) and v.shape == prog["mode"].shape else v)
          for k, v in args.items()}
    a = simulate_joint(**sl)
    b = simulate_joint_ref(**sl)
    # the twin differentiates the map numerically, so agreement is to ~1e-8, not to round-off
    for x, y in zip(a, b):
        assert np.allclose(x, y, rtol=1e-6, atol=1e-8 * (1 + np.abs(y).max()))
    # only some outputs asked for: the same numbers, the others None (written into a scratch array)
    some = simulate_joint(**sl, outputs=("q", "T"))
    assert [x is None for x in some] == [k not in ("q", "T") for k in ("q", "w", "z", "F", "T", "u", "qm", "qdm")]
    np.testing.assert_array_equal(some[0], a[0])
    np.testing.assert_array_equal(some[4], a[4])
    with pytest.raises(ValueError, match="unknown outputs"):
        simulate_joint(**sl, outputs=("q", "speed"))


def test_inputs_one_value_long_hold_for_every_sample():
    """An input given one value long (a replay's closed loop: mode, no payload, no reset, no noise,
    constant multipliers and ambient) gives the same run as that value repeated for every sample, in the
    kernel and in its twin."""
    pl = quiet(load_plant("geared_industrial"))
    rec, _ = load_recipe("multisine")
    prog, args, _ = prepare_joint(pl, pl.joints[0], rec, 0, 0.2)
    n = 600
    full = {k: (v[:n] if isinstance(v, np.ndarray) and v.shape == prog["mode"].shape else v)
            for k, v in args.items()}
    const = {"mode": full["mode"][:1], "payload": np.full(1, 2.5), "reset_T": np.zeros(1, dtype=np.bool_),
             "gmul": np.full(1, 1.1), "fmul": np.full(1, 0.9), "nq": np.zeros(1), "nqd": np.zeros(1),
             "Tenv": np.full(1, 31.0)}
    short = {**full, **const}
    repeated = {**full, **{k: np.repeat(v, n) for k, v in const.items()}}
    for fn in (simulate_joint, simulate_joint_ref):
        for x, y in zip(fn(**short), fn(**repeated)):
            assert x.shape == (n,)
            np.testing.assert_array_equal(x, y)


def test_kernel_matches_tight_radau_reference():
    pl = quiet(load_plant("direct_drive"))
    rec, _ = load_recipe("multisine")
    prog, args, _ = prepare_joint(pl, pl.joints[0], rec, 0, 0.2)
    q, w, z, F, T, *_ = simulate_joint(**args)
    i0, n = len(q) // 2, 250
    win = {k: (v[i0:i0 + n] if isinstance(v, np.ndarray) and v.shape == q.shape else v)
           for k, v in args.items()}
    win["state0"] = np.array([q[i0], w[i0], z[i0], T[i0]])
    ref = {k: v for k, v in win.items() if k != "nsub"}
    ref["code"] = ref.pop("th_code")
    F_ref = simulate_joint_ivp(**ref, rtol=1e-9)[3]
    F_k = simulate_joint(**win)[3]
    assert np.sqrt(np.mean((F_k - F_ref) ** 2)) / np.sqrt(np.mean(F_ref**2)) < 1e-3


def test_deterministic_for_a_seed():
    a = simulate_recipe("torque_steps", plant="direct_drive", seed=5, duration_scale=0.3)
    b = simulate_recipe("torque_steps", plant="direct_drive", seed=5, duration_scale=0.3)
    c = simulate_recipe("torque_steps", plant="direct_drive", seed=6, duration_scale=0.3)
    for x, y in zip(a, b):
        assert np.array_equal(x.tau, y.tau) and np.array_equal(x.q, y.q)
    assert not np.array_equal(a[0].tau, c[0].tau)
    assert not np.array_equal(a[0].tau, a[1].tau - a[1].tau.mean() + a[0].tau.mean())


def test_effects_show_in_the_data():
    base = load_plant("hydraulic")
    data = base.model_dump()
    data["joints"][0]["effects"] = [dict(kind="asymmetry", factor=1.3), dict(kind="torque_offset", value=20.0)]
    eff = load_plant(data)
    rec = Recipe.model_validate(dict(name="cv", default_plant="hydraulic", experiments=[dict(
        kind="constant_velocity", velocities=[0.5], plateau=1.5)]))
    lb, le = (simulate_recipe(rec, plant=p)[0] for p in (quiet(base), quiet(eff)))

    def plateau_means(lg):
        return [lg.tau[a:b].mean() for a, b in runs(lg.truth["segment"] == "constant_velocity")]

    (bp, bn), (ep, en) = plateau_means(lb), plateau_means(le)
    assert ep == pytest.approx(bp + 20.0, rel=1e-3)
    assert en - 20.0 == pytest.approx(1.3 * bn, rel=1e-3)


def test_delay_and_quantisation():
    pl = load_plant("direct_drive").model_copy(deep=True)
    pl.sensors = Sensors(sample_rate=1000, encoder_counts=76800, delay=3)
    lg = simulate_recipe("multisine", plant=pl, duration_scale=0.1, joints=["j1"])[0]
    step = 2 * np.pi / 76800
    assert np.allclose(np.round(lg.q / step) * step, lg.q, atol=1e-12)
    assert np.allclose(lg.q[3:], np.round(lg.truth["position"][:-3] / step) * step, atol=1e-12)


# ---------------------------------------------------------------------------------------------------
# Bad configs


def _write(tmp_path, rel, data):
    p = tmp_path / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(yaml.safe_dump(data))
    return p


def _plant_data():
    return yaml.safe_load((ROOT / "recipes" / "plants" / "hydraulic.yaml").read_text())


@pytest.mark.parametrize("edit,key,words", [
    (lambda d: d["joints"][0]["friction"].__setitem__("Fs", -1.0), "joints.0.friction.Fs", "must be > 0"),
    (lambda d: d["joints"][0]["friction"].__setitem__("Fz", 1.0), "joints.0.friction.Fz", "unknown key"),
    (lambda d: d["joints"][0].__setitem__("J", 0), "joints.0.J", "must be > 0"),
    (lambda d: d.__setitem__("colour", "red"), "colour", "unknown key"),
    (lambda d: d["sensors"].__setitem__("delay", -2), "sensors.delay", ">= 0"),
    (lambda d: d["joints"][0]["friction"].__setitem__("map", "magic"), "joints.0.friction", "expected one of"),
    (lambda d: d["joints"][0].__setitem__("effects", [dict(kind="position", amplitude=2.0, period=1.0)]),
     "joints.0.effects.0.amplitude", "must be < 1"),
    (lambda d: d["joints"][0].__setitem__("effects", [dict(kind="wobble")]), "joints.0.effects.0",
     "expected one of"),
    (lambda d: d["joints"][0]["thermal"].__setitem__("K", 0.0) if "thermal" in d["joints"][0]
     else d["joints"][0].__setitem__("thermal", dict(K=0.0)), "joints.0.thermal.K", "must be > 0"),
    (lambda d: d["joints"][0]["friction"].__setitem__("sigma2", -500.0), "joints.0.friction",
     "not dissipative"),
])
def test_bad_plant_names_the_key(tmp_path, edit, key, words):
    d = _plant_data()
    edit(d)
    p = _write(tmp_path, "plants/bad.yaml", d)
    with pytest.raises(ConfigError) as ei:
        load_plant(p)
    msg = str(ei.value)
    assert "bad.yaml" in msg and key + ":" in msg and words in msg, msg


@pytest.mark.parametrize("edit,key,words", [
    (lambda d: d["experiments"][0].__setitem__("plateua", 3.0), "experiments.0.plateua", "unknown key"),
    (lambda d: d["experiments"][0].__setitem__("accel", 3.0), "experiments.0.accel", "<= 1"),
    (lambda d: d["experiments"][0]["velocities"].__setitem__("count", 0), "experiments.0.velocities.count",
     ">= 1"),
    (lambda d: d.pop("default_plant"), "default_plant", "required key missing"),
    (lambda d: d["experiments"][0].__setitem__("kind", "dance"), "experiments.0", "expected one of"),
])
def test_bad_recipe_names_the_key(tmp_path, edit, key, words):
    d = yaml.safe_load((ROOT / "recipes" / "constant_velocity_sweep.yaml").read_text())
    edit(d)
    p = _write(tmp_path, "bad_recipe.yaml", d)
    with pytest.raises(ConfigError) as ei:
        simulate_recipe(p)
    msg = str(ei.value)
    assert "bad_recipe.yaml" in msg and key + ":" in msg and words in msg, msg


def test_unreadable_yaml_and_missing_files(tmp_path):
    p = tmp_path / "broken.yaml"
    p.write_text("name: [unclosed\n")
    with pytest.raises(ConfigError, match="broken.yaml.*line"):
        load_plant(p)
    with pytest.raises(ConfigError, match="not found"):
        load_plant(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="recipe file not found"):
        simulate_recipe(tmp_path / "nope_recipe.yaml")


def test_velocity_pi_plateaus():
    rec = Recipe.model_validate(dict(name="vpi", default_plant="geared_industrial", experiments=[dict(
        kind="constant_velocity", velocities=[0.1, 0.4], plateau=1.5, control="velocity_pi")]))
    lg = simulate_recipe(rec, plant=quiet(load_plant("geared_industrial")))[0]
    plateaus = runs(lg.truth["segment"] == "constant_velocity")
    assert len(plateaus) == 4
    for a, b in plateaus:
        w = lg.truth["velocity"][a:b]
        assert np.std(w) < 0.02 * abs(w.mean())


def _truth_runs(lg):
    """(kind, i0, i1) runs of equal (segment, cycle) truth labels."""
    key = np.char.add(np.asarray(lg.truth["segment"]).astype(str), lg.truth["cycle"].astype(str))
    cut = np.flatnonzero(key[1:] != key[:-1]) + 1
    return [(str(lg.truth["segment"][a]), int(a), int(b)) for a, b in zip(np.r_[0, cut], np.r_[cut, lg.n])]


def test_labels_follow_the_segment_conventions():
    """docs/segments.md: one ramp_presliding per monotonic torque ramp, its hold a rest; one step per
    torque jump lasting until the next input (next jump or the controller taking the joint back)."""
    pl = load_plant("hydraulic")
    lg = simulate_recipe("ramp_presliding", plant=pl, duration_scale=0.25)[0]
    ref = lg.channels["tau_ref"]
    ramps = [(a, b) for k, a, b in _truth_runs(lg) if k == "ramp_presliding"]
    assert len(ramps) == 8                                  # 2 peaks x 2 signs x (up, down)
    for a, b in ramps:
        d = np.diff(ref[a - 1:b])
        assert np.all(d > 0) or np.all(d < 0)              # monotonic, and the whole of it
        assert ref[a - 2] == ref[a - 1] and ref[b] == ref[b - 1]
    lg = simulate_recipe("torque_steps", plant=pl)[0]
    ref = lg.channels["tau_ref"]
    steps = [(a, b) for k, a, b in _truth_runs(lg) if k == "step"]
    jumps = np.flatnonzero(np.abs(np.diff(ref)) > 1e-9 * np.ptp(ref)) + 1
    assert len(steps) == 8 and [a for a, _ in steps] == list(jumps[:8])
    assert [b for _, b in steps[:-1]] == list(jumps[1:8])   # each lasts until the next jump
    last = steps[-1][1]                                     # ... the last until the controller
    assert lg.truth["segment"][last] == "rest" and np.all(lg.truth["segment"][last:] == "rest")


def test_rest_lasts_while_the_joint_is_still_and_its_torque_steady():
    """A closed-loop rest before a slow fade-in lasts until the joint moves or its torque changes beyond
    the noise (docs/segments.md, "What a rest is": 5 standard errors of 0.1 s means), not only until its
    reference moves; from there on the torque has changed."""
    from frictid.segments import noise_sigma

    lg = simulate_recipe("multisine", plant="hydraulic", duration_scale=0.3)[0]
    seg, w = lg.truth["segment"], lg.truth["velocity"]
    vmax = load_plant("hydraulic").joints[0].limits.velocity
    first_other = int(np.flatnonzero(seg == "other")[0])
    ref_moves = int(np.flatnonzero(lg.channels["qd_ref"] != 0)[0])
    assert first_other > ref_moves                              # the joint stood while its reference crept
    assert np.all(np.abs(w[:first_other]) < 5e-3 * vmax)
    k = int(round(0.1 / lg.dt))
    se = noise_sigma(lg.tau) * np.sqrt(2.0 / k)                 # standard error of a 0.1 s mean difference
    level = lg.tau[first_other - k:first_other].mean()
    assert abs(lg.tau[first_other - 3 * k:first_other - 2 * k].mean() - level) < 5 * se   # steady before
    assert abs(lg.tau[first_other + k:first_other + 2 * k].mean() - level) > 5 * se       # changed after
    assert seg[-1] == "rest"


def test_duty_cycles_start_with_their_motion():
    """A duty cycle starts at its first moving sample (the joint breaks away after its program starts)
    and the cycles of a run follow each other without a gap."""
    lg = simulate_recipe("duty_cycle", plant="hydraulic", duration_scale=0.01)[0]
    cyc, w = lg.truth["cycle"], lg.truth["velocity"]
    vmax = load_plant("hydraulic").joints[0].limits.velocity
    starts = np.flatnonzero((cyc >= 0) & (np.r_[-1, cyc[:-1]] != cyc))
    assert starts.size == 40
    for s in starts:
        assert np.abs(w[s - 3:s - 1]).max() < 5e-3 * vmax < np.abs(w[s:s + 20]).max()
