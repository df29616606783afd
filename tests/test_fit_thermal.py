"""Thermal models: cycle-by-cycle friction, the exact binned heat balance, thermal4 / thermal6 fits."""
from __future__ import annotations

import numpy as np
import pytest

from frictid.identify.thermal import (_power_bins, fit_thermal, heldout, nested_start, predict_coefficients,
                                 prepare, simulate_temperature)
from frictid.models import thermal as mt

C_TRUE = (10.0, 5.0, 1.0, 0.2)
DC_TRUE = (-0.3, -0.1, -0.02, 0.0)


def duty_log(duty=0.5, ncyc=16, fs=10.0, seed=0, C=2000.0, K=2.0, Tenv=20.0, noise=0.2):
    """A joint cycling at several amplitudes; friction by thermal6 with the true heat balance (per sample)."""
    rng = np.random.default_rng(seed)
    Tc = 240.0
    t = np.arange(0, ncyc * Tc, 1 / fs)
    moving = (t % Tc) < duty * Tc
    amp = 0.5 + 1.5 * ((t // 20) % 6) / 5
    w = np.where(moving, amp * np.sin(2 * np.pi * t / 4.0), 0.0)
    n = t.size
    T = np.empty(n)
    F = np.empty(n)
    T[0] = Tenv
    for i in range(n):
        c = mt.thermal6_coefficients(C_TRUE, DC_TRUE, T[i], Tenv)
        v = abs(w[i])
        F[i] = np.sign(w[i]) * (c[0] + c[1] * v + c[2] * v * v + c[3] * v**3)
        if i < n - 1:
            T[i + 1] = mt.heat_step(T[i], F[i] * w[i], Tenv, C, K, 1 / fs)
    cycles = [(int(k * Tc * fs), int((k + 1) * Tc * fs), k) for k in range(ncyc)]
    return t, w, F + rng.normal(0, noise, n), T, cycles


@pytest.fixture(scope="module")
def run_and_truth():
    t, w, F, T, cyc = duty_log()
    run = prepare(t, w, F, cyc, temp_env=np.full(t.size, 20.0), min_speed=0.02)
    return run, (t, w, F, T, cyc)


def test_cycle_friction_and_bins(run_and_truth):
    run, (t, w, F, T, cyc) = run_and_truth
    assert run.n_cycles == 16
    # the first (cold) cycle's polynomial is close to the cold coefficients
    assert run.cycle_c[0][0] == pytest.approx(C_TRUE[0], rel=0.03)
    assert run.bin_h.sum() == pytest.approx(t[-1] - t[0], rel=1e-6)


def test_heat_balance_matches_per_sample_reference(run_and_truth):
    run, (t, w, F, T, cyc) = run_and_truth
    # true law, true C/K: the binned exact integration tracks the per-sample truth
    Tb = simulate_temperature(run, np.array(C_TRUE), 0.0, 1.0, np.array(DC_TRUE), 2000.0, 2.0, 20.0)
    Tc = run.cycle_W @ Tb
    for k in (0, 7, 15):
        i0, i1, _ = cyc[k]
        m = np.abs(w[i0:i1]) > 0.02
        assert Tc[k] == pytest.approx(T[i0:i1][m].mean(), abs=0.05)


def test_thermal6_predicts_friction_and_beats_thermal4(run_and_truth):
    run, (t, w, F, T, cyc) = run_and_truth
    f4 = fit_thermal([run], "thermal4")
    f6 = fit_thermal([run], "thermal6")
    assert f6.rms <= f4.rms
    # time constant: C/K of the truth, corrected by the power's temperature slope (002 eq 31)
    assert 600 < f6.time_constant < 1100
    ww = np.linspace(0.2, 2.0, 20)
    Tm = np.array(f6.cycle_T[0])
    for k in (8, 15):  # after warm-up
        i0, i1, _ = cyc[k]
        m = np.abs(w[i0:i1]) > 0.02
        Ft = mt.thermal6(ww, T[i0:i1][m].mean(), C_TRUE, DC_TRUE, 20.0)
        cp = predict_coefficients(f6, Tm[k])[0]
        Fp = cp[0] + cp[1] * ww + cp[2] * ww**2 + cp[3] * ww**3
        assert np.max(np.abs(Fp - Ft) / np.abs(Ft)) < 0.05
    # K is held: only C/K is identifiable without a joint temperature
    assert f6.fixed["K"] == 1.0 and f6.notes


def test_thermal6_from_thermal4_optimum_fits_at_least_as_well(run_and_truth):
    """thermal4 is nested in thermal6: started at thermal4's optimum (same friction at every temperature),
    thermal6 can only lower the cost, whatever the truth."""
    run, _ = run_and_truth
    f4 = fit_thermal([run], "thermal4")
    st = nested_start(f4)
    assert st["c0"] == pytest.approx(f4.fixed["c0"] * f4.values["beta"])
    assert st["dc1"] == pytest.approx(f4.fixed["c1"] * f4.values["alpha"])
    f6 = fit_thermal([run], "thermal6", start=st)
    assert f6.cost <= f4.cost * (1 + 1e-9)
    # the nested start itself reproduces thermal4's friction at any temperature
    for T in (20.0, 30.0, 45.0):
        c4 = predict_coefficients(f4, T)[0]
        c6 = np.array([st[f"c{i}"] + st[f"dc{i}"] * (T - f4.T0) for i in range(4)])
        assert c6 == pytest.approx(c4, rel=1e-12, abs=1e-12)


def test_compiled_heat_balance_matches_python_twin():
    rng = np.random.default_rng(3)
    n = 300
    h = rng.uniform(0.5, 5.0, n)
    e = rng.normal(0.0, 1.0, n)
    W0 = rng.uniform(0.0, 20.0, n)
    W1 = rng.uniform(-0.5, 0.5, n)
    W1[::7] = 1.0  # K - W1 = 0: the linear branch
    got = mt.heat_balance_bins(h, e, W0, W1, 300.0, 1.0, 0.3)
    want = mt.heat_balance_bins_ref(h, e, W0, W1, 300.0, 1.0, 0.3)
    assert got == pytest.approx(want, rel=1e-10, abs=1e-10)


def test_canonical_at_scales_amplitudes_not_shapes():
    """thermal4 scales the level and viscous amplitudes, never the Stribeck velocities or exponent, as the
    compiled kernels do (frictid.models.lugre.thermal_canon_nb)."""
    from frictid.models.lugre import thermal_canon_nb

    c0 = np.array([10.0, 3.0, 0.05, 1.5, 2.0, 0.4, 0.7, 0.1, 0.01])
    dc9 = np.array([-0.1, 0, 0, 0, 0, 0, -0.02, 0.003, 0.0])
    for law in ("thermal4", "thermal6", "exponential"):
        code, theta, dc = mt.thermal_code(law, alpha=-0.01, beta=1.02, lam=0.005, T0=25.0, dc=dc9[[0, 6, 7, 8]])
        got = mt.canonical_at(c0, 40.0, code, theta, dc)
        out = np.empty(9)
        thermal_canon_nb(c0, dc, code, theta, 40.0, out)
        assert got == pytest.approx(out, rel=1e-12)
        assert got[[2, 3, 5]] == pytest.approx(c0[[2, 3, 5]])


def test_heldout_gain_over_constant_polynomial(run_and_truth):
    run, _ = run_and_truth
    r_t, r_c = heldout([run], "thermal6")
    assert r_t < 0.5 * r_c


def test_too_few_cycles_gives_none():
    t, w, F, T, cyc = duty_log(ncyc=1)
    run = prepare(t, w, F, cyc, temp_env=np.full(t.size, 20.0), min_speed=0.02)
    assert fit_thermal([run], "thermal6") is None


def test_plant_warm_up_predicted_within_5_percent():
    """geared_industrial (thermal6 truth), shortened duty cycles + a multi-sine: after warm-up the fitted
    laws predict the plant's friction within 5 %, thermal6 at least as well as thermal4."""
    import frictid
    from frictid.plant import simulate_recipe
    from frictid.segments import derivatives
    from fit_synth import truth_segments
    from frictid.models import static as sm

    plant = "recipes/plants/geared_industrial.yaml"
    duty = simulate_recipe("recipes/duty_cycle.yaml", plant=plant, seed=0, duration_scale=0.2)
    ms = simulate_recipe("recipes/multisine.yaml", plant=plant, seed=1, duration_scale=0.5)
    res = frictid.fit(duty + ms, models="polynomial_ls,thermal4,thermal6", segmenter=truth_segments,
                      differentiate=derivatives, diagnose=False)
    lg = duty[0]
    jf = res[lg.joint]
    w, _ = derivatives(lg)
    err, err_law = {}, {}
    tp = lg.truth["params"]
    c_true = [tp["static"][f"c{i}"] for i in range(4)]
    dc_true = [tp["thermal"][f"dc{i}"] for i in range(4)]
    for m in ("thermal4", "thermal6"):
        mf = jf.models[m]
        v = mf.values()
        runs = mf.extra["cycle_temperature"]
        cyc = jf.segments_used["duty_cycle"]
        num = den = num_law = den_law = 0.0
        k = 0
        for run in runs:
            for j, T in enumerate(run):
                ta, tb, _ = cyc[k]
                k += 1
                if j < len(run) // 2:
                    continue
                i0, i1 = np.searchsorted(lg.t, [ta, tb])
                mv = np.abs(w[i0:i1]) > 0.1 * np.max(np.abs(w))
                if m == "thermal4":
                    c = np.array([v[f"c{i}"] for i in range(4)]) * (v["alpha"] * (T - v["T0"]) + v["beta"])
                else:
                    c = np.array([v[f"c{i}"] + v[f"dc{i}"] * (T - v["T0"]) for i in range(4)])
                Fp = sm.polynomial(w[i0:i1][mv], *c)
                d = Fp - lg.truth["friction"][i0:i1][mv]
                num += float(d @ d)
                den += float(np.sum(lg.truth["friction"][i0:i1][mv] ** 2))
                # the plant's law at its true temperature (no LuGre transients): the thermal part alone
                Fl = mt.thermal6(w[i0:i1][mv], lg.truth["temp_joint"][i0:i1][mv], c_true, dc_true,
                                 tp["thermal"]["T0"])
                num_law += float((Fp - Fl) @ (Fp - Fl))
                den_law += float(Fl @ Fl)
        err[m] = (num / den) ** 0.5
        err_law[m] = (num_law / den_law) ** 0.5
        assert mf.extra["time_constant"]["value"] > 0
    assert err["thermal6"] < 0.05 and err["thermal4"] < 0.05
    # thermal6 at least as good on the cycles' friction, in and out of sample (002's criterion); against
    # the plant's law both stay within a few tenths of a percent of each other (see docs/fit.md)
    m4, m6 = jf.models["thermal4"].metrics, jf.models["thermal6"].metrics
    assert m6["rms"] <= m4["rms"] and m6["rms_heldout"] <= m4["rms_heldout"]
    assert abs(err_law["thermal6"] - err_law["thermal4"]) < 0.005


def test_temperature_finding_survives_the_diagnosis_check():
    """A warm-up over duty cycles found by the diagnosis is judged on held-out moving samples, duty cycles
    included (the fit's own basis, the plateaus, leaves them out): the thermal model stays selected."""
    import frictid
    from fit_synth import duty_log, synth_log, truth_derivatives, truth_segments

    res = frictid.fit([synth_log(dt=0.01), duty_log()], models="stribeck,stribeck_asym,polynomial",
                      segmenter=truth_segments, differentiate=truth_derivatives)
    jf = res["1"]
    chk = jf.selection["diagnosis_check"]
    assert "thermal" in jf.selected and "kept" not in chk, chk
    assert chk["rms_heldout"] < chk["rms_heldout_fit_choice"]


def test_prepare_matches_plain_per_sample_formulas(run_and_truth):
    """prepare sums the power basis per bin and fills the cycle regressors column by column; the plain
    formulas (a per-sample matrix of all terms, bincount per column, lstsq on the scaled matrix) agree."""
    _, (t, w, F, T, cyc) = run_and_truth
    a = np.gradient(w, t) * np.random.default_rng(3).uniform(0.5, 1.5, t.size)  # not collinear with w
    run = prepare(t, w, F, cyc, temp_env=np.full(t.size, 20.0), min_speed=0.02, a=a)
    nb = run.bin_h.size
    b = np.minimum(((t - t[0]) / ((t[-1] - t[0]) / nb)).astype(int), nb - 1)
    v = np.abs(w)
    P = np.column_stack([v, w * w, v**3, w**4])
    counts = np.maximum(np.bincount(b, minlength=nb), 1)
    ref_P = np.column_stack([np.bincount(b, weights=P[:, i], minlength=nb) for i in range(4)]) / counts[:, None]
    np.testing.assert_allclose(run.bin_P, ref_P, rtol=1e-12, atol=1e-14 * np.abs(ref_P).max())
    for k, (i0, i1, _) in enumerate(cyc):
        m = np.abs(w[i0:i1]) > 0.02
        ww = w[i0:i1][m]
        X = np.column_stack([np.sign(ww), ww, ww * np.abs(ww), ww**3, a[i0:i1][m]])
        d = np.sqrt(np.mean(X * X, axis=0))
        c = np.linalg.lstsq(X / d, F[i0:i1][m], rcond=None)[0] / d
        np.testing.assert_allclose(run.cycle_c[k], c[:4], rtol=1e-9, atol=1e-12)
        G = X.T @ X / m.sum()
        M = G[:4, :4] - np.outer(G[:4, 4], G[4, :4]) / G[4, 4]
        np.testing.assert_allclose(run.cycle_L[k] @ run.cycle_L[k].T, M, rtol=1e-9, atol=1e-12 * np.trace(M))


def test_bin_sums_equal_numpys_bincounts():
    """The heat balance's bins are summed in one compiled pass (:func:`thermal._bin_sums`): the samples, the
    friction power basis (a non-finite speed counted as 0), the ambient and the joint temperatures per bin
    are numpy's bincounts of them to the last bit, and a bin without samples stays 0 (NaN for the joint's)."""
    from frictid.identify.thermal import _bin_sums
    rng = np.random.default_rng(5)
    w = rng.normal(0.0, 2.0, 5000)
    w[[7, 300]] = np.nan, np.inf
    b = np.sort(rng.integers(0, 40, w.size))
    b[b == 13] = 14  # an empty bin
    te, tj = rng.normal(20.0, 3.0, w.size), rng.normal(40.0, 5.0, w.size)
    counts, P, s_te, s_tj = _bin_sums(b, w, te, tj, 41)
    np.testing.assert_array_equal(counts, np.bincount(b, minlength=41).astype(float))
    np.testing.assert_array_equal(P, _power_bins(b, w, 41))
    np.testing.assert_array_equal(s_te, np.bincount(b, weights=te, minlength=41))
    np.testing.assert_array_equal(s_tj, np.bincount(b, weights=tj, minlength=41))
    assert counts[13] == 0 and counts[40] == 0 and np.all(P[13] == 0)
    assert np.isnan(_bin_sums(b, w, te, None, 41)[3]).all()
