"""The diagnosis where two explanations meet: a warm-up beside a logged ambient that wanders (issue 20,
session 22; docs/diagnosis.md "Judging a candidate", "Known confusions")."""
from __future__ import annotations

import numpy as np
import pytest

from frictid.diagnose.samples import build_samples, heat_balance_rise
from test_diagnose import GAIN_FOUND, TRUE, _run, fake_fit, plateau_log

#: A small joint: the map of the diagnosis tests at a hundredth of its torque (a friction power of tens of mW).
SMALL = {k: (v * 0.01 if k in ("Fc", "Fs", "sigma2") else v) for k, v in TRUE.items()}


def _ambient(t: np.ndarray) -> np.ndarray:
    """A logged ambient that cycles by a kelvin (a room's air conditioning), in steps of 0.1 K as a drive
    logs it, unrelated to the joint's friction."""
    return 23.0 + np.round(np.sin(2 * np.pi * (t - t[0]) / 50.0), 1)


@pytest.mark.parametrize("seed", [11])
def test_a_warm_up_beside_a_wandering_ambient_is_found(seed):
    """Foreign card seeds 316068 and 316561 (a warm-up of 35 % and 21 % beside a load and an asymmetry, a
    logged ``temp_env`` that wanders by 0.7 K): with the heat balance's conductance at 1 W/K a joint that
    dissipates tens of milliwatts warms by hundredths of a kelvin in the state, and the ambient's wander is
    what the state follows; neither warm-up was named. The conductance is now chosen by the data between
    1 W/K and one that weighs the power a thousand times the ambient's change
    (:meth:`frictid.diagnose.samples.Samples.conductances`): the warm-up (driven by the power alone, its
    rise 20 K at the mean power) is named temperature, with its time constant, and the exported law carries
    the chosen K (C / K the time constant)."""
    tau_c, dt = 40.0, 2e-3
    K_true = None

    def warm(t, q, w, F):
        nonlocal K_true
        P = np.asarray(F) * w
        K_true = float(np.mean(np.abs(P))) / 20.0          # 20 K at the mean power
        x = heat_balance_rise(t, P, np.zeros(t.size), tau_c, K=K_true)
        return F * (1 - 0.01 * x)

    lg = plateau_log(warm, seed=seed, reps=4, alternate=True, noise=1e-4, values=SMALL, dt=dt)
    lg.channels["temp_env"] = _ambient(lg.t)
    S = build_samples([lg], 5)
    K = S.conductances()
    assert len(K) == 2 and K[0] == 1.0 and K[1] < 1e-3
    jf, findings = _run([lg], fake_fit(SMALL))
    causes = [f["cause"] for f in findings]
    assert causes and causes[0] == "temperature", (causes, jf.selection["diagnosis"]["steps"][0]["tested"])
    f = findings[0]
    assert f["gain"] >= GAIN_FOUND
    m = jf.models[f["model"]]
    assert m.params["K"].value == pytest.approx(K[1])
    assert m.params["C"].value / m.params["K"].value == pytest.approx(tau_c, rel=0.4)


def test_a_constant_ambient_offers_the_one_conductance():
    """Without a logged ambient, or with one that does not change, the heat balance keeps its one
    conductance (1 W/K): nothing else to choose, the diagnosis as before."""
    lg = plateau_log(seed=3)
    assert build_samples([lg], 5).conductances() == (1.0,)
    lg.channels = {}
    assert build_samples([lg], 5).conductances() == (1.0,)
