"""Diagnosis on frictid's plants: the matrix over hidden causes, plants, log sizes and sensor noise
(``@pytest.mark.slow``). Each case simulates a session with ``tests/diag_synth.py``, runs the whole
``frictid fit`` with its diagnosis and requires the hidden cause named first with a held-out gain of at
least ``GAIN_FOUND_PLANT`` (``GAIN_FOUND_NOISY`` at three times the plant's noise), and no finding above
``GAIN_NULL`` with nothing hidden (thresholds in ``tests/test_diagnose.py``). Its own file, so that the
test workers (one file each, ``--dist loadfile``) can run it beside the rest of the diagnosis tests."""
from __future__ import annotations

import pytest

import diag_synth as ds
from test_diagnose import GAIN_FOUND_NOISY, GAIN_FOUND_PLANT, GAIN_NULL


#: (cause, plant, size, noise) cases of the matrix; strength 0.15 (about 15 % of the friction RMS).
MATRIX = [
    ("temperature", "hydraulic", "small", 1.0), ("temperature", "geared_industrial", "large", 3.0),
    ("position", "hydraulic", "small", 3.0), ("position", "linear_slide", "large", 1.0),
    ("load", "geared_industrial", "small", 1.0), ("load", "geared_industrial", "large", 3.0),
    ("asymmetry", "geared_industrial", "small", 1.0), ("asymmetry", "hydraulic", "large", 3.0),
    ("asymmetry", "linear_slide", "small", 1.0),
    ("offset", "linear_slide", "small", 3.0), ("offset", "hydraulic", "large", 1.0),
    ("drift", "geared_industrial", "small", 1.0), ("drift", "linear_slide", "large", 3.0),
]


@pytest.mark.slow
@pytest.mark.parametrize("cause,plant,size,noise", MATRIX)
def test_hidden_effect_is_found(cause, plant, size, noise):
    """The hidden cause named first; or, for an offset or a per-direction level, the honest answer where the
    data cannot tell them apart (a base without a Stribeck part: the same correction of the sliding samples,
    ``diagnose.chain.COMPETITORS``): a step ambiguous between exactly those two, and no cause named."""
    jf, es, logs = ds.run_case(plant, cause, 0.15, size, seed=7, noise=noise, with_effect_size=True)
    top, gain = ds.top_cause(jf)
    assert es > 0.08, f"the injected effect is {100 * es:.0f} % of the friction RMS"
    amb = (jf.selection.get("diagnosis") or {}).get("ambiguous") or []
    if cause in ("offset", "asymmetry") and top != cause and amb:
        assert sorted(amb[0]["causes"]) == ["asymmetry", "offset"] and top == "none", (amb, jf.diagnosis)
        gain = amb[0]["heldout_gain"]
    else:
        assert top == cause, (top, jf.diagnosis)
    assert gain >= (GAIN_FOUND_PLANT if noise <= 1.0 else GAIN_FOUND_NOISY)


@pytest.mark.slow
@pytest.mark.parametrize("plant,size,noise", [("hydraulic", "small", 1.0), ("geared_industrial", "small", 3.0),
                                              ("linear_slide", "large", 1.0), ("hydraulic", "large", 3.0)])
def test_nothing_hidden_gives_no_finding(plant, size, noise):
    jf, _, _ = ds.run_case(plant, "none", 0.0, size, seed=11, noise=noise)
    assert not [f for f in jf.diagnosis if f["gain"] > GAIN_NULL], jf.diagnosis
