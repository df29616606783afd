"""The rigid-body step's warning that the inertia and the gravity trade off (identify/mechanics.py)."""
from __future__ import annotations

import numpy as np

from frictid.identify import regression as rg
from frictid.identify.mechanics import CONFOUND_SHARE, angle_share, confound_warning
from frictid.result import JointFit

NAMES = ("J", "c0", "c1", "c2", "c3", "Px", "Py", "offset")


def _share(q, w, a, names=NAMES, seed=0):
    tau = 1.3 * a + 2 * np.sign(w) + 0.5 * w + 0.3 + np.random.default_rng(seed).normal(0, 0.05, w.size)
    nes = rg.accumulate([(0, w.size // 2), (w.size // 2, w.size)], names, q, w, a, tau, min_speed=0.01)
    fit_ = rg.solve(rg.NormalEquations.total(nes), names)
    return angle_share([(0, k, ne) for k, ne in enumerate(nes)], names, fit_)


def test_an_oscillation_s_acceleration_is_its_angle_a_two_tone_motion_s_is_not():
    t = np.arange(60_000) * 1e-3
    # one tone: a = -w^2 q exactly, all of the acceleration is the angle's
    assert _share(0.8 * np.sin(0.7 * t), 0.56 * np.cos(0.7 * t), -0.392 * np.sin(0.7 * t)) > 0.99
    # two tones (tests/test_fit_regression.py's excitation, which recovers J within 1 %): under half
    q = 0.8 * np.sin(0.7 * t) + 0.5 * np.sin(1.9 * t + 1)
    w = 0.56 * np.cos(0.7 * t) + 0.95 * np.cos(1.9 * t + 1)
    a = -0.392 * np.sin(0.7 * t) - 1.805 * np.sin(1.9 * t + 1)
    s = _share(q, w, a)
    assert 0.3 < s < CONFOUND_SHARE
    # without the gravity columns there is nothing to trade with
    assert _share(q, w, a, names=("J", "c0", "c1", "c2", "c3", "offset")) is None


def test_the_warning_says_how_much_and_what_to_do_only_above_the_share():
    jf = JointFit("5")
    confound_warning(jf, CONFOUND_SHARE - 0.01)
    confound_warning(jf, None)
    assert jf.warnings == []
    confound_warning(jf, 0.82)
    assert len(jf.warnings) == 1 and "82 %" in jf.warnings[0] and "gravity: [0, 0]" in jf.warnings[0]
