"""Issue 20, session 23: the first cause among competing explanations of the same correction, and the
"unexplained" statement on a structure smaller than the torque's noise.

Plateau logs of frictid's own plant (tests/test_diagnose.py) with random noise seeds (test seeds < 1000).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from frictid.diagnose.chain import Chain, paired_t
from frictid.diagnose.model import Structure
from frictid.diagnose.samples import build_samples
from frictid.models import static as sm
from test_diagnose import TRUE, _run, plateau_log


@pytest.mark.parametrize("seed", [231, 232])
def test_an_offset_that_differs_from_its_competitor_by_a_hair_is_not_named(seed):
    """An offset whose competitor (here a per-direction level) makes its correction but for a hair at the
    lowest speeds of one direction, the same in every segment: the offset's part beyond it is significant
    (one-sided t over the held-out groups) but explains under 2 % of what the competitor leaves, so the step
    is left ambiguous, offset or asymmetry (session 23: foreign seed 322035, a Coulomb-level asymmetry named
    ``offset`` first on a hair, 0.9 % of that residual, at t = 5.2). A competitor that is worse by a
    material part is beaten and the offset named. Both fail on the code before (the hair named the offset)."""
    S = build_samples([plateau_log(lambda t, q, w, F: np.asarray(F) + 0.2, seed=seed, noise=0.05)], 5)
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    chain = Chain(S, Structure("stribeck", cp))
    off = chain.evaluate("offset", 2)
    assert off.p < 1e-6 and off.gain > 0.5
    e = S.F - off.pred_after
    rms_e = float(np.sqrt(np.mean(e * e)))
    # a hair: a bump on the slowest samples of the negative direction, 1 % of what the offset leaves
    bump = (S.w < 0) * np.exp(-np.abs(S.w) / (0.2 * np.max(np.abs(S.w))))
    for share, named in ((0.017, False), (0.2, True)):
        d = share * rms_e * bump / float(np.sqrt(np.mean(bump * bump)))
        twin = replace(off, cause="asymmetry", ext="asym_level", pred_after=off.pred_after - d)
        twin.rms_after = float(np.sqrt(np.mean((S.F - twin.pred_after) ** 2)))
        assert not chain.same_correction(off, twin)   # not the same correction: differs by more than rounding
        perp_t, perp_p = paired_t(S.group_sums((S.F - twin.pred_after) * d))
        assert perp_p < 0.005, (share, perp_t)        # and significantly so, in every case
        chain._competitors = lambda best, m, twin=twin: [twin]
        best = chain.choose([off], 2)
        assert best.ext == "offset"
        assert (best.unresolved == []) is named, (share, best.unresolved)


@pytest.mark.parametrize("seed", [233, 234])
def test_a_structure_in_time_under_the_noise_is_stated(seed):
    """A torque ripple in time (a pump, 7.3 s period) of 1.1 times the torque's noise per sample: significant
    on held-out cells of the time and several per cent of the friction RMS, so stated ("unexplained"); the
    3x-noise bar, which the variables carrying the torque's noise keep (the measured torque, its rate, the
    acceleration) and the velocity's map misfit, left it silent before. The same log without the ripple
    states nothing."""
    def ripple(t, q, w, F):
        return np.asarray(F) + 0.15 * np.sin(2 * np.pi * t / 7.3)

    jf, findings = _run([plateau_log(ripple, seed=seed, noise=0.1)])
    d = jf.selection["diagnosis"]
    assert not [f for f in findings if f["gain"] >= 0.05] and not d.get("outside_model"), findings
    time = next(e for e in d["structure"]["tests"] if e["variable"] == "time")
    assert time["significant"] and time["x_noise"] < 3 and time["of_friction_rms"] >= 0.02, time
    assert d["unexplained"] and d["unexplained"][0].startswith("residual varies with time"), d["unexplained"]
    jf, _ = _run([plateau_log(seed=seed, noise=0.1)])
    d = jf.selection["diagnosis"]
    assert d["unexplained"] == [], d["unexplained"]
