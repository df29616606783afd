"""Names and signs that tell the truth (issue 19): a Stribeck map keeps Fs >= Fc per branch or says it
cannot, a negative viscous coefficient is never a green badge."""
from __future__ import annotations

import copy

import numpy as np

import frictid
from fit_synth import TRUE, synth_log, truth_derivatives, truth_segments
from frictid.identify.maps import physical_shape
from frictid.result import ModelFit, ParamEstimate

FAST = dict(segmenter=truth_segments, differentiate=truth_derivatives, diagnose=False)


def _fit(true, seed):
    log = synth_log(seed=seed, true=true, excitation=False)
    return frictid.fit(log, models="coulomb_viscous,stribeck,stribeck_asym,polynomial", **FAST)[log.joint]


def test_rising_friction_is_not_called_a_stribeck_drop():
    """Friction that rises from zero speed (Fs below Fc): the stribeck fits say their drop is not
    identifiable, and the choice is a model without a drop."""
    true = copy.deepcopy(TRUE)
    true["stribeck"].update(Fc=2.0, Fs=1.4, vs=0.1)
    jf = _fit(true, seed=21)
    for name, sufs in (("stribeck", ("",)), ("stribeck_asym", ("_pos", "_neg"))):
        for suf in sufs:
            fs, fc = jf.models[name].params["Fs" + suf], jf.models[name].params["Fc" + suf]
            assert fs.value < fc.value
            assert not fs.identifiable and "rises from zero speed" in fs.reason
    assert jf.selected not in ("stribeck", "stribeck_asym")


def test_a_true_drop_stays_identified():
    jf = _fit(TRUE, seed=22)
    st = jf.models["stribeck"].params
    assert st["Fs"].identifiable and st["vs"].identifiable and st["Fs"].value > st["Fc"].value


def test_negative_viscous_is_flagged():
    pe = lambda n, v: ParamEstimate(n, v, 0.1, "N m s/rad")  # noqa: E731
    mf = ModelFit("coulomb_viscous_asym", "coulomb_viscous_asym",
                  {"Fc_pos": pe("Fc_pos", 2.0), "sigma2_pos": pe("sigma2_pos", 0.8),
                   "Fc_neg": pe("Fc_neg", 2.1), "sigma2_neg": pe("sigma2_neg", -0.67)}, {})
    physical_shape(mf)
    assert mf.params["sigma2_pos"].identifiable
    assert not mf.params["sigma2_neg"].identifiable and "negative viscous" in mf.params["sigma2_neg"].reason
    assert not mf.identifiable
    assert np.isclose(mf.params["sigma2_neg"].value, -0.67)  # the number is kept, only the badge goes
