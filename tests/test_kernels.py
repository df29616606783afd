"""Compiled fit kernels against their python twins: the step simulation of :mod:`frictid.identify.presliding`
(sigma1's simulation-error fit) and a sigma1 round trip through it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictid.identify import presliding as pre
from frictid.models.static import canonical_level, canonical_pair, canonical_viscous

MAPS = {
    "stribeck_asym": canonical_pair("stribeck_asym", dict(
        Fc_pos=2.0, Fs_pos=3.0, vs_pos=0.05, delta_pos=1.5, sigma2_pos=0.4,
        Fc_neg=2.5, Fs_neg=3.2, vs_neg=0.08, delta_neg=2.0, sigma2_neg=0.3)),
    "polynomial": canonical_pair("polynomial", dict(c0=4.0, c1=2.0, c2=-0.5, c3=0.3)),
}
J, SIGMA0 = 0.05, 2e4


def _torque(n, seed=0):
    """A torque step up past break-away, then down past it the other way (both branches of the map)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    u = np.where(t < 0.3 * t[-1], 5.0, -5.5) + 0.2 * np.sin(40 * t) + 0.05 * rng.standard_normal(n)
    return t, u


@pytest.mark.parametrize("name", list(MAPS))
def test_step_simulation_equals_python_twin(name):
    c_pos, c_neg = MAPS[name]
    t, u = _torque(250)
    s1 = 2 * math.sqrt(SIGMA0 * J)
    q = pre.simulate_step(t, u, 0.01, 0.0, J, SIGMA0, s1, c_pos, c_neg, 1e-5)
    q_ref = pre.simulate_step_ref(t, u, 0.01, 0.0, J, SIGMA0, s1, c_pos, c_neg, 1e-5)
    span = np.ptp(q)
    assert span > 0.01 and np.sign(q[-1] - q[0]) < 0  # it slid both ways
    # the twin takes the slopes of g and f by differences (step 1e-7) and the step by expm
    assert np.max(np.abs(q - q_ref)) < 1e-9 * span
    # scalar callables run the python loop with the compiled step: same numbers
    def level(w):
        return float(canonical_level(w, c_pos if w >= 0 else c_neg))

    def viscous(w):
        return float(canonical_viscous(w, c_pos if w >= 0 else c_neg))
    q_cb = pre.simulate_step(t, u, 0.01, 0.0, J, SIGMA0, s1, level, viscous, 1e-5)
    assert np.max(np.abs(q - q_cb)) < 1e-9 * span


def test_sigma1_round_trip_from_simulated_steps():
    """Steps simulated with a known sigma1 plus position noise give it back within its stated error."""
    c_pos, c_neg = MAPS["stribeck_asym"]
    s1_true = 0.9 * 2 * math.sqrt(SIGMA0 * J)
    rng = np.random.default_rng(4)
    steps = []
    for k in range(4):
        n = 300
        t = np.arange(n) * 1e-3
        amp = (2.0 + 1.0 * k) * (1 if k % 2 == 0 else -1)  # below and above break-away, both signs
        u = np.where(t < 0.15, amp, 0.3 * amp)
        u[0] = 0.0  # the sample before the step: at rest, bristles relaxed (the fit's start state)
        q = pre.simulate_step(t, u, 0.0, 0.0, J, SIGMA0, s1_true, c_pos, c_neg, 0.0)
        steps.append((t, q + 1e-3 * np.ptp(q) * rng.standard_normal(n), u))
    est = pre.fit_sigma1_steps(steps, J, SIGMA0, c_pos, c_neg, 0.4)
    assert est.identifiable and 0 < est.stderr < 0.05 * s1_true
    assert est.value == pytest.approx(s1_true, rel=0.02)
    assert abs(est.value - s1_true) < 5 * est.stderr


def test_ramp_forces_are_the_bristle_path_and_their_derivative():
    """fit_sigma0's compiled pass: sigma0 z along each ramp equals the python bristle path, and its
    analytic derivative in log(sigma0) the central difference of it."""
    rng = np.random.default_rng(5)
    g = np.array([3.0, 2.5])
    ramps = [np.cumsum(rng.uniform(-0.2, 1.0, 300)) * 2e-6, -np.cumsum(rng.uniform(-0.2, 1.0, 200)) * 3e-6]
    F0 = np.array([0.5, -4.0])  # the second start is clipped to 0.999 of its level
    q = np.concatenate(ramps)
    bounds = np.array([0, 300, 500], dtype=np.int64)

    def forces(s0):
        y, dy = np.empty(q.size), np.empty(q.size)
        pre._ramp_forces_nb(q, bounds, F0, g, s0, y, dy)
        return y, dy

    s0 = 8e5
    y, dy = forces(s0)
    for r, (i0, i1) in enumerate(zip(bounds[:-1], bounds[1:])):
        z0 = float(np.clip(F0[r] / s0, -0.999 * g[r] / s0, 0.999 * g[r] / s0))
        assert np.allclose(y[i0:i1], s0 * pre.bristle_path_ref(q[i0:i1], z0, s0, g[r]), rtol=1e-12, atol=1e-12)
    assert np.ptp(y[:300]) > 0.5 * g[0]  # the bristles saturate: the derivative is not a constant factor
    eps = 1e-6
    fd = (forces(s0 * math.exp(eps))[0] - forces(s0 * math.exp(-eps))[0]) / (2 * eps)
    assert np.allclose(dy, fd, rtol=1e-6, atol=1e-8 * np.max(np.abs(fd)))
