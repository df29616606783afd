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


def _sweeps(seed=3):
    """Sweeps only (no excitation part), 364 Hz, no gravity: the foreign card's sweeps family in small."""
    import fit_synth as fs

    true = dict(J=0.5, Px=0.0, Py=0.0, offset=0.05, stribeck=dict(Fc=3.5, Fs=5.6, vs=0.04, delta=1.0, sigma2=4.5))
    v = np.geomspace(0.02, 1.0, 8)
    return fs.synth_log(speeds=np.concatenate([v, -v]), dt=1 / 364, hold=3.0, move=0.6, noise=0.016, seed=seed,
                        true=true, excitation=False), true


def test_a_stage_two_that_no_longer_determines_the_inertia_leaves_stage_one_s_terms(monkeypatch):
    """The foreign sweeps with cogging (seeds 309207, 309227): stage 2's plateau map did not hold between the
    plateaus, its J came out -19 +- 144 and its gravity and offset of hundreds of N m were trusted. Here the
    plateau map is made wrong between the plateaus (exact at none of the transitions' speeds) the same way:
    stage 1's J, gravity and offset stand, J is not identifiable with the reason, and the fit says so."""
    import frictid
    from frictid.identify import mechanics

    log, true = _sweeps()
    res = frictid.fit(log, diagnose=False)
    jf = next(iter(res.joints.values()))
    assert jf.inertia.identifiable and abs(jf.inertia.value / true["J"] - 1) < 0.05
    assert not any("stage 1's" in w for w in jf.warnings)

    real = mechanics._stage2_map

    def wrong_between(plat, odd=False):
        out = real(plat, odd)
        if out is None:
            return None
        name, friction, v_low = out
        return name, (lambda w: friction(w) + 30.0 * np.sin(40.0 * w)), v_low

    monkeypatch.setattr(mechanics, "_stage2_map", lambda plat, odd=False: None)
    stage1 = next(iter(frictid.fit(log, diagnose=False).joints.values()))
    monkeypatch.setattr(mechanics, "_stage2_map", wrong_between)
    jf = next(iter(frictid.fit(log, diagnose=False).joints.values()))
    assert not jf.inertia.identifiable and "plateau map" in jf.inertia.reason
    assert any("stage 1's" in w for w in jf.warnings)
    # stage 1's values and errors (stage 2's here: J -0.28 +- 2.9, offset 0.06 +- 3.8)
    for mine, one in [(jf.inertia, stage1.inertia), (jf.offset, stage1.offset),
                      *((jf.gravity[n], stage1.gravity[n]) for n in ("Px", "Py"))]:
        assert mine.value == one.value and mine.stderr == one.stderr
    assert abs(jf.inertia.value / true["J"] - 1) < 0.1
    assert abs(jf.offset.value - true["offset"]) < 3 * jf.offset.stderr
