"""Issue 20, session 25: a torque late by a fraction of a sample period, judged against its mirror image.

Plateau logs of frictid's own plant (tests/test_diagnose.py) with random noise seeds (test seeds < 1000).
A shift under half a period was called unresolved (``chain.DELAY_MIN_SAMPLES``) and, rounded to whole
samples, explained nothing on the moving samples: foreign card seeds 340000 and 340544 (delays of 0.45 and
0.44 of a period at 131 and 190 Hz, 27 % and 11 % of the friction RMS) were missed. A torque interpolated
between two samples averages their noise; its mirror image about the velocity's own lag averages it alike.
"""
from __future__ import annotations

import numpy as np
import pytest

from frictid.diagnose.chain import ALPHA, Chain, _unresolved_delay, delay_moving
from frictid.diagnose.model import Structure
from frictid.diagnose.samples import build_samples
from frictid.models import static as sm
from test_diagnose import TRUE, plateau_log

DT = 2e-3
FLAT = dict(TRUE, Fs=TRUE["Fc"])   # no hump: the delay's velocity-only map carries the friction


def _trial(seed: int, lag: float):
    """A plateau log whose logged torque is ``lag`` sample periods late (negative: early), a quadratic drag
    on a Coulomb + viscous map, and the chain's delay trial on it."""
    rng = np.random.default_rng(seed)
    frac = lag * rng.uniform(0.8, 1.0)

    def effect(t, q, w, F):
        drag = np.asarray(F) + 0.8 * w * np.abs(w)
        return np.interp(t - frac * DT, t, drag) if frac else drag

    lg = plateau_log(effect, seed=seed, reps=5, dt=DT, noise=0.002, values=FLAT)
    # the position by the trapezoid rule: the velocity is then no one-sided difference of it (no lag of its own)
    lg.q = np.concatenate([[0.0], np.cumsum(0.5 * (lg.w[1:] + lg.w[:-1]) * DT)])
    S = build_samples([lg], 5)
    cp, _ = sm.canonical_pair("stribeck", FLAT)
    chain = Chain(S, Structure("stribeck", cp))
    return S, chain, chain.evaluate("delay", 2)


@pytest.mark.parametrize("seed", [261, 262])
def test_a_torque_late_by_a_fraction_of_a_period_is_resolved_against_its_mirror(seed):
    """0.3-0.4 of a period late: resolved (the code before: "the log's rate does not resolve it") and
    significant on every moving sample, against its mirror image (on these slow moves it explains under the
    2 % of the friction RMS a term must: not named); the same log without the delay, or with the torque early
    by as much (a held command's timing), stays unresolved."""
    S, chain, tr = _trial(seed, 0.4)
    shifts = [float(t.settings["shift"]) for t in tr.fold_terms]
    assert all(-0.5 * DT < x < -0.2 * DT for x in shifts), shifts
    assert _unresolved_delay(S, tr) is None
    mv = delay_moving(S, tr)
    assert "mirror" in mv and mv["p"] < ALPHA and mv["mirror"] > mv["rms_after"]
    assert chain.significant(tr, 2)
    for lag in (0.0, -0.4):
        S, chain, tr = _trial(seed, lag)
        assert _unresolved_delay(S, tr) is not None, lag
        assert not chain.significant(tr, 2), lag
