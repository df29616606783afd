"""Replay: the compiled kernel against its python twin and hand values, the identified model along a
simulated log (true parameters give the plant's friction back), the closed loop, and the CLI."""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictid.result import FitResult, JointFit, ModelFit, ParamEstimate
from frictid.models import thermal as th
from frictid.models.replay_kernel import replay_friction
from frictid.models.static import canonical_friction, canonical_level, canonical_pair
from frictid.replay import joint_model, position_factor, replay

C_POS, C_NEG = canonical_pair("stribeck_asym", dict(Fc_pos=2.0, Fs_pos=3.0, vs_pos=0.05, delta_pos=1.5,
                                                    sigma2_pos=0.4, Fc_neg=2.5, Fs_neg=3.2, vs_neg=0.08,
                                                    delta_neg=2.0, sigma2_neg=0.3))


def _motion(n=1500, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    w = 0.4 * np.sin(2 * np.pi * 1.3 * t) + 0.05 * np.sin(2 * np.pi * 7 * t) + 0.003 * rng.standard_normal(n)
    return t, w, rng


#: A map whose level is a constant (the kernel compiled without the level's exponentials).
P_POS, P_NEG = canonical_pair("polynomial_asym", dict(c0_pos=4.0, c1_pos=2.0, c2_pos=-0.5, c3_pos=0.3,
                                                      c0_neg=3.5, c1_neg=2.5, c2_neg=0.4, c3_neg=0.2))


@pytest.mark.parametrize("case", ["static", "karnopp", "lugre", "lugre_asym", "thermal4", "thermal6",
                                  "exponential", "thermal_measured", "multipliers", "flat_static",
                                  "flat_thermal6", "flat_exponential_multipliers", "lugre_stick"])
def test_kernel_equals_python_twin(case):
    t, w, rng = _motion()
    n = t.size
    kw = {}
    c_pos, c_neg = (P_POS, P_NEG) if case.startswith("flat") else (C_POS, C_NEG)
    if case == "karnopp":
        kw = dict(u_stick=3 * rng.standard_normal(n), w_stick=0.02)
    elif case == "lugre":
        kw = dict(sigma0=2e3, sigma1=20.0)
    elif case == "lugre_asym":
        kw = dict(sigma0=(5e3, 1e3), sigma1=(30.0, 5.0), z0=1e-4)
    elif case == "lugre_stick":
        kw = dict(sigma0=(5e3, 1e3), sigma1=(30.0, 5.0), u_stick=3 * rng.standard_normal(n), w_stick=0.02,
                  hold=rng.random(n) < 0.5)
    elif case == "thermal4":
        code, theta, dc = th.thermal_code("thermal4", alpha=-0.01, beta=1.0, T0=25.0)
        kw = dict(sigma0=2e3, sigma1=5.0, thermal=dict(code=code, theta=theta, dc_pos=dc, C=20.0, K=1.0, Tenv=25.0))
    elif case == "thermal6":
        code, theta, dc = th.thermal_code("thermal6", T0=25.0, dc=(-0.02, -0.01, 0.002, 0.0))
        kw = dict(thermal=dict(code=code, theta=theta, dc_pos=dc, C=5.0, K=0.5, Tenv=np.linspace(25, 27, n)))
    elif case == "thermal_measured":
        code, theta, dc = th.thermal_code("thermal4", alpha=-0.02, beta=1.0, T0=25.0)
        kw = dict(thermal=dict(code=code, theta=theta, dc_pos=dc, T=25 + np.linspace(0, 15, n)),
                  u_stick=rng.standard_normal(n), w_stick=0.01)
    elif case == "multipliers":
        kw = dict(gmul=1 + 0.1 * np.sin(7 * t), fmul=1 + 0.05 * t, sigma0=3e3, sigma1=10.0)
    elif case == "exponential":
        code, theta, dc = th.thermal_code("exponential", lam=0.02, T0=25.0)
        kw = dict(sigma0=(5e3, 1e3), sigma1=(30.0, 5.0),
                  thermal=dict(code=code, theta=theta, dc_pos=dc, C=5.0, K=0.5, Tenv=25.0, T_init=40.0))
    elif case == "flat_static":
        kw = dict(u_stick=3 * rng.standard_normal(n), w_stick=0.02, gmul=1 + 0.1 * np.sin(7 * t))
    elif case == "flat_thermal6":
        code, theta, dc = th.thermal_code("thermal6", T0=25.0, dc=(-0.02, -0.01, 0.002, 0.001))
        kw = dict(sigma0=(5e3, 2e3), sigma1=(30.0, 10.0), z0=-1e-4,
                  thermal=dict(code=code, theta=theta, dc_pos=dc, C=2.0, K=0.5, Tenv=np.linspace(25, 27, n)))
    elif case == "flat_exponential_multipliers":
        code, theta, dc = th.thermal_code("exponential", lam=0.01, T0=25.0)
        kw = dict(sigma0=4e3, sigma1=20.0, gmul=1 + 0.1 * np.sin(7 * t), fmul=1 + 0.05 * t,
                  thermal=dict(code=code, theta=theta, dc_pos=dc, T=25 + np.linspace(0, 15, n)))
    t = t.copy()
    t[n // 2:] = t[n // 2] + (t[n // 2:] - t[n // 2]) * 0.5   # a change of sample period
    a = replay_friction(t, w, c_pos, c_neg, **kw)
    b = replay_friction(t, w, c_pos, c_neg, reference=True, **kw)
    for x, y in zip(a, b):
        assert np.allclose(x, y, rtol=1e-10, atol=1e-12, equal_nan=True)


def test_static_replay_is_the_map_and_karnopp_holds_at_rest():
    t = np.arange(6) * 0.01
    w = np.array([0.5, -0.3, 0.0, -0.001, -2.0, 0.2])
    F, z, T = replay_friction(t, w, C_POS, C_NEG)
    assert np.allclose(F, canonical_friction(w, C_POS, C_NEG))
    assert np.all(z == 0) and np.all(np.isnan(T))
    u = np.array([0.0, 0.0, 1.2, -9.0, 0.0, 0.0])
    F2, _, _ = replay_friction(t, w, C_POS, C_NEG, u_stick=u, w_stick=0.01)
    assert F2[2] == pytest.approx(1.2)        # sticking: the friction balances the applied torque ...
    assert F2[3] == pytest.approx(-float(canonical_level(0.001, C_NEG)))  # ... up to the level (3.2)
    assert np.allclose(F2[[0, 1, 4, 5]], F[[0, 1, 4, 5]])
    # the friction written over the applied torque it reads gives the same values, in that array
    u2 = u.copy()
    F3, z3, T3 = replay_friction(t, w, C_POS, C_NEG, u_stick=u2, w_stick=0.01, out=u2)
    assert F3 is u2 and np.array_equal(F3, F2)
    # a state that cannot change comes back as one value per sample all the same, and read-only
    assert z3.shape == T3.shape == (6,) and not z3.flags.writeable and np.all(z3 == 0) and np.all(np.isnan(T3))
    with pytest.raises(ValueError, match="out must be"):
        replay_friction(t, w, C_POS, C_NEG, out=np.empty(5))


def test_lugre_replay_at_rest_reads_the_torque_and_resumes_from_it():
    """In the stick zone LuGre's friction reads the applied torque (as the static replay's does); where the
    joint stands the bristles carry that load, so motion resumes from it, not from the last motion's
    state; at a rest's edges (the acceleration filter's half window) they follow the motion."""
    from frictid.models.replay_kernel import standing
    t = np.arange(400) * 0.01
    w = np.where(t < 1.0, 0.3, np.where(t < 2.0, 0.0, -0.3))   # slide one way, rest, slide back
    u = np.where(t < 2.0, -1.0, 0.0)                          # the rest carries -1 (less than the level)
    s0 = 2e3
    hold = standing(w, 0.01, 3)
    rest = (t >= 1.0) & (t < 2.0)
    assert np.array_equal(hold, rest & (t >= 1.03) & (t < 1.97))   # three samples off each edge
    F, z, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=s0, u_stick=u, w_stick=0.01, hold=hold)
    assert np.allclose(F[rest], -1.0) and np.allclose(z[hold], -1.0 / s0)
    # without the stick zone the rest holds the last motion's +level deflection and friction
    F0, z0, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=s0)
    assert z0[np.flatnonzero(rest)[-1]] > 0.0 and F0[np.flatnonzero(rest)[-1]] > 1.0
    # the stick zone alone (no hold) reads the torque but keeps the motion's bristle state
    F1, z1, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=s0, u_stick=u, w_stick=0.01)
    assert np.allclose(F1[rest], -1.0) and np.allclose(z1[rest], z0[rest])
    # sliding back starts from -1 N m: the friction goes to the negative level sooner
    k = np.flatnonzero(t >= 2.0)[0]
    assert F[k] < F1[k] and F[k + 1] < -1.0


def test_lugre_replay_of_a_log_cut_while_sliding_starts_in_the_steady_state():
    """z0="steady": a log that starts sliding starts with the bristles that motion has set (the map's level
    at once, both signs, compiled loop and twin alike); one that starts at rest starts unloaded; the default
    z0 = 0 starts unloaded anyway (the first sample's friction is its viscous part)."""
    t = np.arange(50) * 0.01
    for sign, c in ((1.0, C_POS), (-1.0, C_NEG)):
        w = np.full(50, 0.3 * sign)
        for ref in (False, True):
            F, z, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=(4e3, 2e3), z0="steady", reference=ref)
            assert np.allclose(F, canonical_friction(w, C_POS, C_NEG), rtol=1e-9)
        F0, _, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=(4e3, 2e3))
        assert abs(F0[0]) < 0.1 * float(canonical_level(0.3, c))
    w = np.concatenate([np.zeros(10), np.full(40, 0.3)])
    F, z, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=4e3, z0="steady", u_stick=np.zeros(50), w_stick=0.01)
    assert np.all(z[:10] == 0.0) and np.all(F[:10] == 0.0)


def test_lugre_replay_reaches_the_map_and_the_heat_balance_its_steady_state():
    n = 20000
    t = np.arange(n) * 1e-3
    w = np.full(n, 0.3)
    F, z, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=1e4, sigma1=30.0)
    assert F[-1] == pytest.approx(float(canonical_friction(0.3, C_POS, C_NEG)), rel=1e-9)
    code, theta, dc = th.thermal_code("thermal4", alpha=0.0, beta=1.0, T0=20.0)
    F, _, T = replay_friction(t, w, C_POS, C_NEG, thermal=dict(code=code, theta=theta, dc_pos=dc, C=2.0, K=0.5,
                                                                Tenv=20.0))
    # C/K = 4 s, 20 s of constant power F w: T -> Tenv + F w / K
    assert T[-1] == pytest.approx(20.0 + F[-1] * 0.3 / 0.5, rel=1e-3)


def _pe(name, v, unit=""):
    return ParamEstimate(name, float(v), None, unit, True)


def true_result(log, name="true", extensions=None) -> FitResult:
    """A parameter file holding the plant's true model of a log's joint (tests only read the truth)."""
    tp = log.truth["params"]
    params = {k: _pe(k, v) for k, v in tp["static"].items()}
    params["sigma0"] = _pe("sigma0", tp["sigma0"])
    params["sigma1"] = _pe("sigma1", tp["sigma1"])
    if tp["sigma0_neg"] != tp["sigma0"]:
        params["sigma0_neg"] = _pe("sigma0_neg", tp["sigma0_neg"])
        params["sigma1_neg"] = _pe("sigma1_neg", tp["sigma1_neg"])
    for k, v in (extensions or {}).items():
        params[k] = _pe(k, v)
    g = tp["gravity"]
    jf = JointFit(joint=log.joint, axis=tp["axis"], units=dict(log.units), inertia=_pe("J", tp["J"]),
                  gravity={"Px": _pe("Px", g["Px"]), "Py": _pe("Py", g["Py"])}, offset=_pe("offset", g["offset"]),
                  models={name: ModelFit(name, tp["map"], params)}, selected=name)
    return FitResult(joints={log.joint: jf})


@pytest.fixture(scope="module")
def sweep():
    from frictid.plant import simulate_recipe
    return simulate_recipe("recipes/constant_velocity_sweep.yaml", plant="recipes/plants/hydraulic.yaml",
                           seed=3, duration_scale=0.15)[0]


def test_true_model_gives_back_the_plants_friction(sweep):
    lg = sweep
    res = true_result(lg)
    r = replay(lg, joint_model(res[lg.joint]))
    F_true = lg.truth["friction"]
    mv = np.abs(lg.truth["velocity"]) > 0.02
    scale = np.sqrt(np.mean(F_true[mv] ** 2))
    err = np.sqrt(np.mean((r.F_model - F_true)[mv] ** 2))
    assert err < 0.02 * scale
    # torque residual on sliding samples: noise plus the error of the estimated acceleration
    noise = lg.truth["params"]["sensors"]["tau_noise"]
    assert np.sqrt(np.mean(r.residual[mv] ** 2)) < 3 * noise + 0.02 * scale
    assert r.tau_model.shape == lg.tau.shape and np.all(np.isfinite(r.tau_model))


def test_extension_multipliers_enter_the_prediction(sweep):
    lg = sweep
    base = replay(lg, joint_model(true_result(lg)[lg.joint]))
    ext = {"pos_amp": 0.1, "pos_period": 0.5, "pos_phase": 0.3, "tau_offset": 4.0}
    res = true_result(lg, "true+position+offset", ext)
    mf = res[lg.joint].models["true+position+offset"]
    mf.extra = {"extensions": ["position_periodic", "offset"]}
    for k in ("sigma0", "sigma1"):  # the static map: the formula holds sample by sample
        mf.params.pop(k)
    r = replay(lg, joint_model(res[lg.joint]))
    mv = np.abs(lg.truth["velocity"]) > 0.1
    # steady sliding: F = g(w) m(q) sgn w + f(w) + offset, with the plant's own map g, f
    tp = lg.truth["params"]
    cp, cn = np.array(tp["canonical_pos"]), np.array(tp["canonical_neg"])
    w = r.w[mv]
    from frictid.models.static import canonical_level, canonical_viscous
    c = np.where(w[:, None] >= 0, cp, cn)
    g = np.array([canonical_level(x, ci) for x, ci in zip(w, c)])
    f = np.array([canonical_viscous(x, ci) for x, ci in zip(w, c)])
    expect = g * position_factor(lg.q[mv], ext) * np.sign(w) + f + 4.0
    steady = np.abs(base.F_model[mv] - canonical_friction(w, cp, cn)) < 0.01 * np.abs(base.F_model[mv])
    assert steady.mean() > 0.5
    assert np.allclose(r.F_model[mv], expect, rtol=1e-12, atol=1e-9)


def test_closed_loop_with_the_true_model_follows_the_log(sweep):
    from frictid.replay import closed_loop, controller_from_meta
    lg = sweep
    gains = controller_from_meta(lg.meta)
    assert gains is not None, "the plant writes its controller into the log metadata"
    q_model, qd_model, notes = closed_loop(lg, joint_model(true_result(lg)[lg.joint]), gains)
    assert q_model.shape == lg.q.shape
    err = np.sqrt(np.mean((q_model - lg.q) ** 2))
    assert err < 0.01 * np.ptp(lg.q)


def test_cli_replay_writes_one_row_per_input_row(sweep, tmp_path, cli):
    import pyarrow.parquet as pq

    from frictid.io.logs import write_logs
    from frictid.io.params import write_params

    src = tmp_path / "run.parquet"
    write_logs([sweep], str(src))
    par = tmp_path / "p.yaml"
    write_params(true_result(sweep), str(par))
    out = tmp_path / "rep.parquet"
    r = cli("simulate", "--params", par, "--replay", src, "-o", out)
    assert r.code == 0, r
    tab = pq.read_table(out)
    inp = pq.read_table(src)
    assert tab.num_rows == inp.num_rows
    assert set(inp.column_names) <= set(tab.column_names)
    for c in ("tau_model", "residual", "F_model", "q_model"):
        assert c in tab.column_names, c
    res = np.asarray(tab["residual"])
    assert np.allclose(res, np.asarray(tab["tau"]) - np.asarray(tab["tau_model"]))
    # CSV output keeps the input columns too
    r = cli("simulate", "--params", par, "--replay", src, "-o", tmp_path / "rep.csv")
    assert r.code == 0, r
    head = (tmp_path / "rep.csv").read_text().splitlines()[0]
    assert head.startswith('"t","joint","q"') and '"residual"' in head
    # the recipe form still works and the two forms do not mix
    r = cli("simulate", "recipes/constant_velocity_sweep.yaml", "--params", par, "--replay", src, "-o",
            tmp_path / "x.csv")
    assert r.code == 2 and not (tmp_path / "x.csv").exists()


def test_cli_replay_errors_are_exit_2_without_output(sweep, tmp_path, cli):
    from frictid.io.logs import write_logs
    from frictid.io.params import write_params

    src = tmp_path / "run.csv"
    write_logs([sweep], str(src))
    par = tmp_path / "p.yaml"
    res = true_result(sweep)
    res.joints["other"] = res.joints.pop(sweep.joint)
    res.joints["other"].joint = "other"
    write_params(res, str(par))
    out = tmp_path / "o.csv"
    for args, words in [(("--params", par), "--replay"),
                        (("--params", par, "--replay", src), "not in the parameter file"),
                        (("--params", tmp_path / "missing.yaml", "--replay", src), "not found"),
                        (("--params", par, "--replay", src, "--model", "nope"), "")]:
        r = cli("simulate", *args, "-o", out)
        assert r.code == 2, (args, r)
        assert words in r.err
        assert not out.exists()
