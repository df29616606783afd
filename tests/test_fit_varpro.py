"""Variable projection of the static maps (frictid.identify.varpro) against the multi-start it replaced.

The reference below is the fit of sessions 1-12, kept in the tests only: bounded ``least_squares`` on all
parameters from the best three starts of a grid of shape values (linear parameters solved on it) and the
table's start, each screened at 8 evaluations per parameter, the best one run on to 40.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares, lsq_linear

from frictid.identify import static as fs
from frictid.identify import varpro as vp
from frictid.models import static as sm
from frictid.models.params import scaled_table


def _branch(base, w, F, F_se=None, fixed=None):
    smap = sm.STATIC_MAPS[base]
    names = [p.name for p in smap.table]
    fixed = dict(fixed or {})
    F0, w0 = fs._scales(w, F)
    lo, hi, x0, xs = scaled_table(smap.table, F0, w0)
    free = [k for k, nm in enumerate(names) if nm not in fixed]
    pb = fs._Branch(smap, names, fixed, free, w, F, fs._weights(F_se, F0, len(w)), lo[free], hi[free],
                    xs[free], F0, w0)
    return pb, dict(zip(names, x0))


def _reference_multistart(pb, table_start):
    """The session-12 search (static.py at ed678e7): grid starts with the linear parameters solved, the
    best three and the table's start screened, the best run on."""
    base, w = pb.smap.name, pb.w
    v = np.abs(w)
    vmin, vmax = max(v.min(), 1e-9), max(v.max(), max(v.min(), 1e-9) * 10)
    lo = dict(zip([pb.names[k] for k in pb.free], pb.lo_f))
    hi = dict(zip([pb.names[k] for k in pb.free], pb.hi_f))
    if base == "stribeck":
        grids = [{"vs": a, "delta": d} for a in np.geomspace(vmin * 0.5, vmax * 0.7, 8) for d in (1.0, 2.0)]
    else:
        g = np.geomspace(vmin * 0.5, vmax * 0.7, 5)
        grids = [{"ws1": a, "ws2": b} for a in g for b in g]
    starts = []
    for nl in grids:
        nl = {k: float(np.clip(x, lo[k], hi[k])) for k, x in nl.items()}
        full = dict(table_start, **nl)
        pr = vp.Projection(pb)
        A, y, _ = pr.regressors(np.array([nl[pb.names[pb.free[j]]] for j in pr.nl]))
        b = np.linalg.lstsq(A, y, rcond=None)[0]
        full.update({pb.names[pb.free[j]]: bj for j, bj in zip(pr.lin, b)})
        starts.append((float(np.sum((A @ b - y) ** 2)), full))
    starts.sort(key=lambda c: c[0])
    tries = [s for _, s in starts[:3]] + [table_start]
    p = len(pb.free)
    margin = 1e-9 * (pb.hi_f - pb.lo_f)
    budget, screen = 40 * (p + 1), 8 * (p + 1)

    def solve(x0, nfev):
        return least_squares(pb.resid, x0, jac=pb.jac, bounds=(pb.lo_f, pb.hi_f), x_scale=pb.xs_f,
                             method="trf", max_nfev=nfev)
    best = None
    for s in tries:
        x0 = np.clip([s[pb.names[k]] for k in pb.free], pb.lo_f + margin, pb.hi_f - margin)
        res = solve(x0, screen)
        if best is None or res.cost < best.cost:
            best = res
    if best.status == 0:
        res = solve(best.x, budget - screen)
        best = res if res.cost <= best.cost else best
    return best


def _no_worse(new, old, pb, chi2: float = 1e-3):
    """The projected search's best cost no larger than the reference's, up to ``chi2`` of the chi-square
    (``2 delta cost / s^2``, s^2 the reduced chi-square of the reference): in a flat valley both stop where
    the cost no longer changes, and which one stops first is not a difference in fit. The best it found:
    a Stribeck rise it set aside for a drop that fits as well (``new.rival``, :meth:`_Branch._drop_first`)
    counts, the search reached it."""
    cost = new.cost
    if new.rival is not None:
        r = pb.resid(np.array([new.rival[pb.names[k]] for k in pb.free]))
        cost = min(cost, 0.5 * float(r @ r))
    dof = max(pb.w.size - len(pb.free), 1)
    assert 2.0 * (cost - old.cost) / (2.0 * old.cost / dof) <= chi2 + 1e-12 * dof


def _stribeck_points(rng, n, Fc, ratio, vs, delta, sigma2, noise, per_sign=False):
    v = np.geomspace(0.05 * vs, 12 * vs, n)
    w = v if per_sign else np.concatenate([v, -v])
    F = sm.stribeck(w, Fc, Fc * ratio, vs, delta, sigma2)
    return w, F + noise * Fc * rng.standard_normal(w.shape)


# derandomize: CI runs the same examples every time (two optimisers compared; rare degenerate valleys are
# searched for locally with --hypothesis-seed and pinned below with @example)
@settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@example(seed=143, Fc=1.0, ratio=1.125, vs=0.5, delta=1.0, slope=0.0, noise=0.03125, n=7)  # a step
@example(seed=188, Fc=1.0, ratio=1.125, vs=0.25, delta=0.75, slope=0.0, noise=0.046875, n=9)  # singular LM
@example(seed=38, Fc=1.0, ratio=1.0, vs=0.5, delta=1.0, slope=0.0, noise=0.03125, n=7)  # the 0.0505 case
@given(seed=st.integers(0, 999), Fc=st.floats(0.2, 50.0), ratio=st.floats(1.0, 2.5),
       vs=st.floats(0.005, 0.5), delta=st.floats(0.6, 2.5), slope=st.floats(-0.2, 2.0),
       noise=st.floats(0.001, 0.05), n=st.integers(7, 16))
def test_projected_stribeck_reaches_the_multistart_residual(seed, Fc, ratio, vs, delta, slope, noise, n):
    """On random Stribeck curves (slow and fast plateaus, any noise, down to 7 points for 5 parameters),
    the projected fit's cost is never above the old multi-start's by more than 0.1 of a unit of
    chi-square: where there is no drop (Fs = Fc) the shape parameters lie in a flat valley and the two stop
    at different points of it (0.0024 on a case hypothesis found), and on 7 points the Stribeck speed can
    run out to its bound in a valley where the drop's column nearly meets the viscous one (levels that run
    large and cancel), which both searches creep along and leave where the cost stops falling (0.0505 on a
    case hypothesis found: seed 38, no drop, noise 1/32); the joint 68 % region of five parameters spans
    5.9 units. The basins the old search found and the projected one missed (a drop beyond the fastest
    point, a step between two points) are scanned for (:func:`frictid.identify.varpro.shape_grid`): none
    in 900 random curves of this family and 4 x 150 hypothesis examples."""
    rng = np.random.default_rng(seed)
    w, F = _stribeck_points(rng, n, Fc, ratio, vs, delta, slope * Fc / vs / 12, noise, per_sign=True)
    pb, x0 = _branch("stribeck", w, F)
    old = _reference_multistart(pb, x0)
    new = pb.search([x0], cold=True)
    assert new is not None
    _no_worse(new, old, pb, chi2=0.1)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 999), a0=st.floats(0.5, 20.0), a1=st.floats(-1.0, 1.0), a2=st.floats(-1.0, 1.0),
       ws1=st.floats(0.01, 0.3), ws_ratio=st.floats(1.5, 20.0), a3=st.floats(0.0, 5.0),
       noise=st.floats(0.001, 0.03), n=st.integers(10, 18))
def test_projected_2exp_reaches_the_multistart_residual(seed, a0, a1, a2, ws1, ws_ratio, a3, noise, n):
    """The same for the seven-parameter two-exponential map (001). Where its two speeds meet, the map has a
    degenerate valley (amplitudes that cancel, running to their bounds) with a nearly flat floor, in which
    the old search stopped at its budget and the projected one where the cost stops falling: there the two
    may differ by a fraction of one unit of chi-square (0.14 at worst on 30 draws of this test's family,
    0.25 on a case hypothesis found, where the old search had stopped at its budget in a basin the scan
    did not refine), statistically nothing: the joint 68 % region of seven parameters spans 8 units. The
    bound is one unit; the Stribeck map's test above holds the projected fit to 0.1."""
    rng = np.random.default_rng(seed)
    ws2 = ws1 * ws_ratio
    w = np.geomspace(0.1 * ws1, 3 * ws2, n)
    F = sm.stribeck_2exp(w, a0, a1 * a0, a2 * a0, a3, 0.0, ws1, ws2)
    F = F + noise * a0 * rng.standard_normal(n)
    pb, x0 = _branch("stribeck_2exp", w, F)
    old = _reference_multistart(pb, x0)
    new = pb.search([x0], cold=True)
    assert new is not None
    _no_worse(new, old, pb, chi2=1.0)


def test_recovers_a_noise_free_stribeck_map_and_its_full_jacobian():
    """A noise-free map is recovered to the optimiser's tolerance, and the Jacobian handed to the error
    estimate is the full problem's (all five parameters), not the reduced one."""
    w = np.concatenate([np.geomspace(0.002, 1.0, 12), -np.geomspace(0.002, 1.0, 12)])
    true = dict(Fc=2.0, Fs=3.1, vs=0.04, delta=1.3, sigma2=0.8)
    bf = fs.fit_branch("stribeck", w, sm.stribeck(w, **true))
    for k, v in true.items():
        assert bf.values[k] == pytest.approx(v, rel=1e-5)
    pb, x0 = _branch("stribeck", w, sm.stribeck(w, **true))
    sol = pb.search([x0], cold=True)
    assert sol.jac.shape == (w.size, 5)
    np.testing.assert_allclose(sol.jac, pb.jac(sol.x))


def test_held_shape_is_a_linear_solve_and_equals_lstsq():
    """With the Stribeck speed and exponent held, the map is linear: the solution is the weighted linear
    least squares one (computed here independently), with no optimiser run."""
    rng = np.random.default_rng(5)
    w = np.concatenate([np.linspace(0.05, 1.0, 9), -np.linspace(0.05, 1.0, 9)])
    F = sm.stribeck(w, 1.0, 1.6, 0.1, 2.0, 0.5) + 0.01 * rng.standard_normal(w.size)
    se = 0.01 * (1 + rng.random(w.size))
    bf = fs.fit_branch("stribeck", w, F, se, fixed={"vs": 0.1, "delta": 2.0})
    wt = fs._weights(se, float(np.max(np.abs(F))), w.size)
    e = np.exp(-(np.abs(w) / 0.1) ** 2)
    X = np.column_stack([np.sign(w) * (1 - e), np.sign(w) * e, w]) * wt[:, None]
    b = np.linalg.lstsq(X, F * wt, rcond=None)[0]
    np.testing.assert_allclose([bf.values["Fc"], bf.values["Fs"], bf.values["sigma2"]], b, rtol=1e-9)
    assert "linear" in bf.message


def test_a_linear_parameter_beyond_its_bound_is_solved_within_it():
    """A Coulomb level the unconstrained solve puts below zero (a friction that rises from nothing) is
    held at its bound by the bounded solve, the same answer as scipy's bounded linear solver, and the
    parameter is reported at its bound."""
    w = np.concatenate([np.linspace(0.1, 1.0, 8), -np.linspace(0.1, 1.0, 8)])
    F = -0.3 * np.sign(w) + 2.0 * w
    bf = fs.fit_branch("coulomb_viscous", w, F)
    assert bf.values["Fc"] == 0.0
    assert "lower bound" in bf.reasons["Fc"]
    ref = lsq_linear(np.column_stack([np.sign(w), w]), F, bounds=([0.0, -np.inf], [np.inf, np.inf]))
    assert bf.values["sigma2"] == pytest.approx(ref.x[1], rel=1e-9)


def _assert_reduced_gradient(pr, theta: np.ndarray, rel_step: float) -> None:
    """J_red^T r at theta equals the reduced cost's gradient by central differences (steps rel_step x theta)."""
    grad = pr.jac(theta).T @ pr.resid(theta)
    cost = lambda t: 0.5 * float(np.sum(pr.resid(t) ** 2))  # noqa: E731
    h = rel_step * theta
    num = [(cost(theta + h * e) - cost(theta - h * e)) / (2 * h[i]) for i, e in enumerate(np.eye(theta.size))]
    np.testing.assert_allclose(grad, num, rtol=1e-4)


def test_kaufman_jacobian_is_the_reduced_cost_gradient():
    """J_red^T r is the gradient of the reduced cost (the projection drops nothing of it), checked against
    central differences."""
    rng = np.random.default_rng(11)
    w, F = _stribeck_points(rng, 10, 1.0, 1.7, 0.05, 1.5, 0.3, 0.02)
    pb, _ = _branch("stribeck", w, F)
    pr = vp.Projection(pb)
    _assert_reduced_gradient(pr, np.array([0.07, 1.2]), 1e-6)


def test_reduced_gradient_with_a_level_at_its_bound():
    """Where a linear parameter is held at its bound by the bounded solve (a drop beyond the fastest point,
    its level at the upper bound), its column is not projected off the shape columns: J_red^T r is still
    the reduced cost's gradient. bvls returns such a level a rounding error inside its bound; counting it
    free there turned the exponent's gradient round (+7.3 for -13.2) and stalled the refinement."""
    rng = np.random.default_rng(80)
    w, F = _stribeck_points(rng, 11, 23.392802250038102, 1.415987509347475, 0.19759465364793424,
                            1.3213597388162992, 0.04163098011582006 * 23.392802250038102 / 0.19759465364793424 / 12,
                            0.04533557434382976, per_sign=True)
    pb, _ = _branch("stribeck", w, F)
    pr = vp.Projection(pb)
    theta = np.array([3.820495014215447, 1.3096669624047137])  # where the refinement stalled
    b, _, _ = pr._eval(theta)
    assert b[0] == pb.hi_f[pr.lin[0]]  # Fc at its upper bound
    _assert_reduced_gradient(pr, theta, 1e-7)


def test_warm_start_stays_in_its_basin():
    """A warm start (held-out refits) is refined from where it is, without the scan: a start near the
    optimum of the full data returns it."""
    rng = np.random.default_rng(3)
    w, F = _stribeck_points(rng, 12, 1.0, 1.5, 0.05, 2.0, 0.2, 0.01)
    cold = fs.fit_branch("stribeck", w, F)
    warm = fs.fit_branch("stribeck", w, F, start=dict(cold.values))
    for k, v in cold.values.items():
        assert warm.values[k] == pytest.approx(v, rel=1e-6, abs=1e-9)
    assert math.isclose(warm.cost, cold.cost, rel_tol=1e-9)


def test_levenberg_marquardt_reaches_interior_and_bound_minima():
    """The refinement's own Levenberg-Marquardt: Rosenbrock's valley (residuals 10 (y - x^2), 1 - x) to its
    minimum (1, 1) from (-1.2, 1); with an upper bound of 0.5 on x, to the bound's constrained minimum
    (0.5, 0.25), held there with the gradient pointing out of the box; within its budget or reporting it."""
    def resid(p):
        return np.array([10.0 * (p[1] - p[0] ** 2), 1.0 - p[0]])

    def jac(p):
        return np.array([[-20.0 * p[0], 10.0], [-1.0, 0.0]])
    inf = np.full(2, np.inf)
    x, status, _ = vp.levenberg_marquardt(resid, jac, np.array([-1.2, 1.0]), -inf, inf, np.ones(2), 200)
    np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-6)
    assert status > 0
    x, status, _ = vp.levenberg_marquardt(resid, jac, np.array([-1.2, 1.0]), -inf, np.array([0.5, np.inf]),
                                          np.ones(2), 200)
    np.testing.assert_allclose(x, [0.5, 0.25], atol=1e-6)
    x, status, msg = vp.levenberg_marquardt(resid, jac, np.array([-1.2, 1.0]), -inf, inf, np.ones(2), 3)
    assert status == 0 and "budget" in msg


def test_a_drop_that_fits_as_well_as_a_rise_is_reported_with_the_rise_noted():
    """No drop (Fs = Fc) and noise of 1/32 on 7 points (the 0.0505 case above): the best valley is a rise
    (Fs below Fc), and a drop fits within DELTA_CHI2 of it. The fit reports the drop (the Stribeck map is
    003's drop), keeps the rise as its rival and notes it, and its levels and slope carry their change to the
    rise in their errors (here the drop is also within its errors of none, so its shape is held by
    static._shapeless). Competing
    explanation, a rise the data show clearly, stays a rise:
    tests/test_fit_shape.py::test_rising_friction_is_not_called_a_stribeck_drop."""
    rng = np.random.default_rng(38)
    w, F = _stribeck_points(rng, 7, 1.0, 1.0, 0.5, 1.0, 0.0, 0.03125, per_sign=True)
    pb, x0 = _branch("stribeck", w, F)
    sol = pb.search([x0], cold=True)
    x = dict(zip(pb.names, pb.full(sol.x)))
    assert x["Fs"] >= x["Fc"] and sol.rival is not None and sol.rival["Fs"] < sol.rival["Fc"]
    r = pb.resid(np.array([sol.rival[pb.names[k]] for k in pb.free]))
    dof = w.size - len(pb.free)
    assert 0.0 < 2.0 * (sol.cost - 0.5 * float(r @ r)) / (float(r @ r) / dof) <= fs.DELTA_CHI2
    bf = fs.fit_branch("stribeck", w, F)
    assert bf.rival is not None and bf.values["Fs"] >= bf.values["Fc"]
    assert f"Fs {bf.rival['Fs']:.4g} below Fc" in fs._rival_note(bf.rival, "")
    se = dict(bf.stderr)
    fs._rival_spread(bf, bf.rival)  # the levels and slope carry their change to the rise, the shape does not
    for nm in fs.SHARED_WITH_A_RISE:
        assert np.isclose(bf.stderr[nm], np.hypot(se[nm], bf.rival[nm] - bf.values[nm]))
    assert bf.stderr["vs"] == se["vs"]
    mf = fs.fit_static("stribeck", w, F, delta="free")
    for nm in ("vs", "delta"):
        pe = mf.params[nm]
        assert pe.fixed and not pe.identifiable and "held where the fit put it" in pe.reason
    assert mf.params["Fs"].value >= mf.params["Fc"].value


def test_an_exponent_whose_profile_reaches_its_bound_is_held_at_two():
    """delta "auto" is free only when the data pin it: a sharp drop (delta 5, the table's bound) on 12 speeds
    per sign comes out at 4.96 with an error under 100 % (identifiable by the Jacobian), but with delta held
    at its bound 5 the fit is within DELTA_CHI2 of chi-square, so no interval of exponents closes: held at 2
    with the reason. Competing explanation, an exponent the data do pin (delta 2 on 10 speeds, 1 % noise):
    it stays free and is not 2 exactly."""
    w, F = _stribeck_points(np.random.default_rng(0), 12, 1.0, 1.5, 0.2, 5.0, 0.3, 0.002)
    free = fs.fit_branch("stribeck", w, F)
    assert "delta" not in free.reasons and free.values["delta"] < 5.0
    mf = fs.fit_static("stribeck", w, F)
    assert mf.params["delta"].fixed and mf.params["delta"].value == 2.0
    assert any("do not pin it" in n and "at its bound 5" in n for n in mf.notes)
    w, F = _stribeck_points(np.random.default_rng(3), 10, 1.0, 1.5, 0.2, 2.0, 0.3, 0.01)
    mf = fs.fit_static("stribeck", w, F)
    d = mf.params["delta"]
    assert not d.fixed and d.identifiable and d.value != 2.0 and abs(d.value - 2.0) < 3 * d.stderr
    assert not any("do not pin it" in n for n in mf.notes)


def test_bvls_is_scipys_bvls_step_for_step():
    """Two implementations agreeing: varpro.bvls against scipy's lsq_linear(method="bvls") on random
    bounded problems of the maps' sizes (2-5 columns, 7-40 points, bounds that cut the unbounded solution),
    from the same unbounded start: the same active set and the same solution to rounding (bvls runs on a
    Fortran-ordered copy of A, scipy on A as given: the products' last bits may differ)."""
    rng = np.random.default_rng(7)
    cut = 0
    for _ in range(200):
        n, p = int(rng.integers(7, 41)), int(rng.integers(2, 6))
        A = rng.standard_normal((n, p)) * rng.uniform(0.1, 10, p)
        y = rng.standard_normal(n)
        x_lsq = np.linalg.lstsq(A, y, rcond=-1)[0]
        lo = x_lsq - rng.uniform(-0.5, 1.0, p) * np.abs(x_lsq)
        hi = np.maximum(lo + 1e-3, x_lsq + rng.uniform(-0.5, 1.0, p) * np.abs(x_lsq))
        ref = lsq_linear(A, y, bounds=(lo, hi), method="bvls")
        x, on_bound = vp.bvls(A, y, x_lsq, lo, hi)
        cut += int(np.any((x_lsq < lo) | (x_lsq > hi)))
        np.testing.assert_allclose(x, ref.x, rtol=1e-12, atol=1e-14 * np.abs(ref.x).max())
        np.testing.assert_array_equal(on_bound, ref.active_mask)
    assert cut > 100


@pytest.mark.parametrize("base", ["stribeck", "stribeck_2exp"])
def test_compiled_projection_is_numpys_to_the_last_bit(base):
    """The compiled evaluation of the reduced problem (varpro._project_nb: SVD, linear parameters, bounded
    solve, residual, Kaufman's Jacobian) against the same on numpy's calls (Projection._eval_numpy), at
    random shapes of random curves, some levels held, many solutions at a bound: equal to the last bit."""
    rng = np.random.default_rng(5 if base == "stribeck" else 6)
    names = [p.name for p in sm.STATIC_MAPS[base].table]
    shapes, held_ok = sm.SEPARABLE[base][1], sm.SEPARABLE[base][0]
    bounded = 0
    for k in range(60):
        n = int(rng.integers(7, 30))
        w = np.sort(rng.uniform(0.05, 3.0, n)) * rng.choice([-1.0, 1.0], n)
        F = np.sign(w) * (1 + 0.5 * np.exp(-np.abs(w) / 0.3)) + 0.2 * w + 0.05 * rng.standard_normal(n)
        fixed = {held_ok[int(rng.integers(len(held_ok)))]: 0.1} if k % 3 == 0 else {}
        if base == "stribeck" and k % 4 == 1:
            fixed["delta"] = 2.0
        pb, _ = _branch(base, w, F, F_se=0.01 + 0.05 * rng.random(n), fixed=fixed)
        pr = vp.Projection(pb)
        for _ in range(5):
            theta = np.exp(rng.uniform(np.log(pb.lo_f[pr.nl]), np.log(pb.hi_f[pr.nl])))
            A, y, dA = pr.regressors(theta)
            got = pr._projected(A, y, dA)
            want = pr._eval_numpy(A, y, dA)
            assert got is not None
            for g, e in zip(got, want):
                assert g.shape == e.shape and g.tobytes() == e.tobytes()
            bounded += int(any(b in (lo, hi) for b, lo, hi in zip(want[0], pr.lo, pr.hi)))
        assert all(nm in names for nm in fixed) and all(s in names for s in shapes)
    assert bounded > 20
