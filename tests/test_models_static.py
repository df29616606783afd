"""Static friction maps: hand values, canonical form, compiled twins, and physics as properties."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from frictid.models import static as sm
from frictid.models.lugre import level_nb, level_slope_nb, viscous_nb

W = np.concatenate([-np.geomspace(1e-4, 5.0, 40), np.geomspace(1e-4, 5.0, 40)])


def test_hand_values():
    # stribeck at w = vs, delta 2: g = Fc + (Fs - Fc) e^-1
    assert sm.stribeck(0.1, Fc=2.0, Fs=3.0, vs=0.1, delta=2.0, sigma2=0.5) == pytest.approx(
        2.0 + np.exp(-1.0) + 0.05)
    assert sm.polynomial(-2.0, 1.0, 0.5, 0.25, 0.125) == pytest.approx(-(1.0 + 1.0 + 1.0 + 1.0))
    assert sm.coulomb_viscous(0.0, 3.0, 1.0) == 0.0
    # 001 Table 1, joint 1, w > 0 at 1 rad/s
    p = dict(alpha0=40.854, alpha1=-32.454, alpha2=-31.233, alpha3=-0.760, alpha4=-0.262, ws1=0.19, ws2=0.17)
    g = 40.854 - 32.454 * np.exp(-1 / 0.19) - 31.233 * (1 - np.exp(-1 / 0.17))
    assert sm.stribeck_2exp(1.0, **p) == pytest.approx(g - 0.760 - 0.262)


@pytest.mark.parametrize("name,params", [
    ("coulomb_viscous", dict(Fc=2.0, sigma2=0.3)),
    ("stribeck", dict(Fc=2.0, Fs=3.0, vs=0.05, delta=1.3, sigma2=0.3)),
    ("stribeck_2exp", dict(alpha0=1.4, alpha1=2.5, alpha2=2.8, alpha3=-0.05, alpha4=0.02, ws1=0.9, ws2=4.1)),
    ("polynomial", dict(c0=45.0, c1=30.0, c2=-4.0, c3=1.5)),
])
def test_canonical_form_equals_named_map(name, params):
    c_pos, c_neg = sm.canonical_pair(name, params)
    assert np.allclose(sm.canonical_friction(W, c_pos, c_neg), sm.evaluate(name, W, params), rtol=1e-12)
    # compiled twins of the level and viscous parts
    for w in W:
        c = c_pos
        assert level_nb(abs(w), c) == pytest.approx(float(sm.canonical_level(w, c)), rel=1e-12)
        assert viscous_nb(w, c) == pytest.approx(float(sm.canonical_viscous(w, c)), rel=1e-12, abs=1e-15)
        g, dg = level_slope_nb(abs(w), c)
        dv = 1e-6 * max(abs(w), 1e-3)
        num = (sm.canonical_level(abs(w) + dv, c) - sm.canonical_level(abs(w) - dv, c)) / (2 * dv)
        assert g == pytest.approx(level_nb(abs(w), c), rel=1e-14)
        assert dg == pytest.approx(float(num), rel=1e-5, abs=1e-8)


def test_asym_branches():
    p = dict(Fc_pos=2.0, sigma2_pos=0.5, Fc_neg=3.0, sigma2_neg=0.1)
    F = sm.evaluate("coulomb_viscous_asym", np.array([1.0, -1.0]), p)
    assert F.tolist() == pytest.approx([2.5, -3.1])


pos = st.floats(1e-3, 1e3)
small = st.floats(1e-4, 10.0)


@settings(max_examples=60, deadline=None)
@given(Fc=pos, ratio=st.floats(1.0, 3.0), vs=small, delta=st.floats(0.3, 5.0), sigma2=st.floats(0, 1e3),
       w=st.floats(1e-6, 1e2))
def test_stribeck_dissipative_and_odd(Fc, ratio, vs, delta, sigma2, w):
    F = sm.stribeck(np.array([w, -w]), Fc, Fc * ratio, vs, delta, sigma2)
    assert F[0] * w > 0
    assert F[1] == pytest.approx(-F[0], rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(c0=pos, c1=st.floats(0, 1e3), c2=st.floats(0, 1e2), c3=st.floats(0, 1e2), w=st.floats(1e-6, 1e2))
def test_polynomial_dissipative_and_odd(c0, c1, c2, c3, w):
    F = sm.polynomial(np.array([w, -w]), c0, c1, c2, c3)
    assert F[0] * w > 0
    assert F[1] == pytest.approx(-F[0], rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(a0=pos, a1=st.floats(-0.9, 3.0), a2=st.floats(-0.9, 3.0), ws1=small, ws2=small,
       a3=st.floats(0, 1e2), a4=st.floats(0, 1e2), w=st.floats(1e-6, 1e2))
def test_2exp_dissipative_and_odd(a0, a1, a2, ws1, ws2, a3, a4, w):
    # physical: every level stays positive (alpha1, alpha2 > -alpha0 / 2 keeps g > 0), viscous >= 0
    F = sm.stribeck_2exp(np.array([w, -w]), a0, a1 * a0 / 2, a2 * a0 / 2, a3, a4, ws1, ws2)
    assert F[0] * w > 0
    assert F[1] == pytest.approx(-F[0], rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(Fc=pos, sigma2=st.floats(0, 1e3), w=st.floats(-1e2, 1e2))
def test_coulomb_viscous_dissipative_and_odd(Fc, sigma2, w):
    F = sm.coulomb_viscous(np.array([w, -w]), Fc, sigma2)
    assert F[0] * w >= 0
    assert F[1] == pytest.approx(-F[0], abs=1e-12)


@pytest.mark.parametrize("name, params", [
    ("coulomb_viscous", dict(Fc=0.5, sigma2=0.2)),
    ("stribeck", dict(Fc=0.5, Fs=0.8, vs=0.1, delta=1.5, sigma2=0.2)),
    ("stribeck_2exp", dict(alpha0=0.5, alpha1=0.3, alpha2=-0.2, alpha3=0.1, alpha4=0.02, ws1=0.1, ws2=0.6)),
    ("polynomial", dict(c0=0.5, c1=0.2, c2=-0.05, c3=0.01)),
])
def test_jacobian_matches_central_differences(name, params):
    """The closed-form Jacobian the optimiser uses agrees with central differences (w = 0 included)."""
    m = sm.STATIC_MAPS[name]
    w = np.concatenate([np.linspace(-2.0, 2.0, 41), [1e-6]])
    J = m.jac(w, **params)
    assert J.shape == (w.size, len(m.names)) and np.all(np.isfinite(J))
    for j, k in enumerate(m.names):
        h = 1e-6 * max(1.0, abs(params[k]))
        up, dn = dict(params), dict(params)
        up[k] += h
        dn[k] -= h
        num = (m.func(w, **up) - m.func(w, **dn)) / (2 * h)
        assert J[:, j] == pytest.approx(num, rel=1e-5, abs=1e-7), k
