"""A per-sign map is taken only when the plateaus show a friction that differs between the signs beyond what
the rigid-body terms subtracted from the torque make of them (issue 19, foreign fit card class W4); the
acceleration column's noise is taken out of the inertia's normal equations (class W3, errors in
variables)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import frictid
from frictid.identify import select as sel
from frictid.identify import validity
from frictid.identify.static import fit_static
from frictid.models import static as sm

import fit_synth as fs


def _points(seed: int, asym: float):
    """Plateau points of a Stribeck joint (the negative branch's viscous slope ``1 + asym`` times the
    positive one's) that carry a gravity error along the positions the two signs ran through (the
    positive plateaus further from the start than the negative ones), and that error's shift columns."""
    rng = np.random.default_rng(seed)
    Fc = float(rng.uniform(0.5, 5.0))
    true = dict(Fc=Fc, Fs=Fc * rng.uniform(1.2, 1.5), vs=rng.uniform(0.04, 0.1), delta=rng.uniform(1.0, 2.0),
                sigma2=Fc * rng.uniform(0.1, 0.4))
    v = np.geomspace(0.04, 0.75, 11)
    w = np.concatenate([v, -v])
    F = sm.stribeck(w, **true)
    F[w < 0] -= asym * true["sigma2"] * v
    q = np.where(w > 0, 0.4, 0.32) * np.abs(w)          # where each plateau ran [rad]
    se = np.full(w.size, 4e-5 * Fc)
    Px_err, Px_se = -0.3 * Fc, 0.35 * Fc                 # gravity fitted where there is none, not identifiable
    F = F - Px_err * (np.cos(q) - 1.0) + rng.normal(0.0, 1.0, w.size) * se
    shifts = [Px_se * np.cos(q), Px_se * np.ones_like(q)]
    return w, F, se, shifts


def _maps(w, F, se, shifts):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {n: fit_static(n, w, F, se, shifts=shifts) for n in ("stribeck", "stribeck_asym")}


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_a_sign_difference_the_gravity_error_makes_is_not_a_per_sign_map(seed):
    """The per-sign map fits these points far better than the symmetric one (its held-out error is the
    smaller) but the difference between the signs is the gravity error's pattern: the per-sign map is
    marked and the choice takes the symmetric map."""
    w, F, se, shifts = _points(seed, 0.0)
    models = _maps(w, F, se, shifts)
    a, s = models["stribeck_asym"], models["stribeck"]
    assert a.metrics["rms"] < 0.7 * s.metrics["rms"]      # what the plain comparison sees
    validity.per_sign_supported(a, s, (w, F, se), shifts)
    assert "per_sign_not_supported" in a.extra, a.metrics.get("per_sign_p")
    for m in models.values():
        m.metrics["rms_heldout"] = m.metrics["rms"]
    assert sel.choose(models)[0] == "stribeck"


@pytest.mark.parametrize("seed", [11, 12])
def test_a_real_sign_difference_in_the_slope_keeps_the_per_sign_map(seed):
    """The same points with the negative branch's viscous slope 60 % steeper: the per-sign map stays."""
    w, F, se, shifts = _points(seed, 0.6)
    models = _maps(w, F, se, shifts)
    validity.per_sign_supported(models["stribeck_asym"], models["stribeck"], (w, F, se), shifts)
    assert "per_sign_not_supported" not in models["stribeck_asym"].extra
    assert models["stribeck_asym"].metrics["per_sign_p"] < validity.SPLIT_P


def test_the_acceleration_noise_of_a_coarse_encoder_does_not_pull_the_inertia_down():
    """A 12-bit encoder logged at 120 Hz without a velocity column: the acceleration's noise is a large
    share of its variance on the moving samples, and plain least squares gave J 55 % low (the bandwidth
    check then made it not identifiable). With the noise taken out of X^T X J is identifiable and its two
    errors cover the truth."""
    rng = np.random.default_rng(3)
    true = dict(fs.TRUE, J=float(rng.uniform(0.3, 1.5)), Px=0.0, Py=0.0)
    log = fs.synth_log(dt=1 / 120, noise=0.02, seed=3, true=true)
    step = 2 * np.pi / 4096
    log.q = np.floor(log.q / step + rng.uniform()) * step
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        J = next(iter(frictid.fit([log], models="coulomb_viscous", diagnose=False).joints.values())).inertia
    assert J.identifiable, J.reason
    assert abs(J.value - true["J"]) <= 2 * J.stderr
    assert abs(J.value / true["J"] - 1) < 0.1
