"""A static map's level must stay a friction inside the speeds it was fitted on (issue 19).

The model a parameter file describes (:class:`frictid.model.FrictionModel`, the replay kernel) holds a
level ``g`` below zero at zero; a fit whose formula's level crosses zero is not the function the file
runs, so the choice must not take it, and every score is computed with the model as the file runs it."""
from __future__ import annotations

import numpy as np

import frictid
from fit_synth import TRUE, synth_log, truth_derivatives, truth_segments
from frictid.model import FrictionModel
from frictid.models import static as sm
from frictid.models.replay_kernel import replay_friction

#: A two-exponential map whose level is 3 N m at rest and crosses zero near 0.5 rad/s (-1.0 at 2 rad/s):
#: the friction torque itself stays positive (the viscous terms), so a fit follows it closely.
CROSSING = dict(alpha0=2.0, alpha1=1.0, alpha2=-3.0, alpha3=3.0, alpha4=1.0, ws1=0.03, ws2=0.3)


def test_evaluate_runs_the_map_as_the_file_does():
    w = np.concatenate([-np.geomspace(2.0, 0.01, 40), np.geomspace(0.01, 2.0, 40)])
    c, _ = sm.canonical_pair("stribeck_2exp", CROSSING)
    run, _, _ = replay_friction(np.arange(w.size, dtype=float), w, c, c)
    g = sm.level("stribeck_2exp", w, CROSSING)
    assert g.min() < -0.9  # the case: the formula's level goes well below zero
    np.testing.assert_allclose(sm.evaluate("stribeck_2exp", w, CROSSING), run, atol=1e-12)
    formula = sm.evaluate("stribeck_2exp", w, CROSSING, formula=True)
    np.testing.assert_allclose(formula, sm.stribeck_2exp(w, **CROSSING))
    assert np.abs(formula - run).max() > 0.9


def test_a_map_whose_level_crosses_zero_is_not_chosen():
    log = synth_log(seed=7, excitation=False)
    w = log.truth["w"]
    log.tau = log.tau - sm.stribeck(w, **TRUE["stribeck"]) + sm.stribeck_2exp(w, **CROSSING)
    jf = frictid.fit(log, models="coulomb_viscous,stribeck,stribeck_2exp,polynomial", segmenter=truth_segments,
                     differentiate=truth_derivatives, diagnose=False)[log.joint]
    two = jf.models["stribeck_2exp"]
    assert not two.identifiable and two.metrics.get("rms_heldout") is None
    assert "below zero inside the fitted speeds" in (two.params["alpha2"].reason or "")
    assert jf.selected != "stribeck_2exp"
    # the chosen model is the function the file runs: at the fitted speeds its formula and the file's model agree
    lo, hi = jf.validity["speed"]
    v = np.geomspace(lo, hi, 50)
    v = np.concatenate([-v, v])
    mf = jf.models[jf.selected]
    formula = sm.evaluate(mf.map, v, mf.values(), formula=True)
    np.testing.assert_allclose(FrictionModel.from_joint(jf, jf.selected).steady_state(v) - formula, 0.0,
                               atol=1e-9 * np.abs(formula).max())
