"""Right-sized errors of the Stribeck map's level and slope where the plateaus measure them but do not span
the drop (identify/validity.py, ``_level_spread`` and ``akaike_weight``; issue 19, item 15 of docs/scorecards.md).

The drop-free map's change to Fc and sigma2 entered their errors whole; on the foreign fit card that made
Fc's error 60-175x its own on sweeps whose drop lies below the plateaus (median |value - truth| / stderr
0.23 against an honest 0.67). It now enters weighted by the drop-free map's Akaike weight: a line the data
reject adds nothing. Here: random Stribeck joints (seeds < 1000; the cards use >= 100000) measured on ten
plateau speeds from 1.5 vs up, so the drop's tail is seen and the drop is not spanned; the errors are
calibrated (median |z| near the honest 0.67, the truth within 2.5 errors of nearly every value). The old
rule gave median |z| of a few hundredths.
"""
from __future__ import annotations

import math
import statistics

import numpy as np

from frictid.identify.static import fit_static
from frictid.identify.validity import akaike_weight, drop_spanned
from frictid.models.static import stribeck


def _z(seed: int) -> tuple[float, float, bool, float]:
    rng = np.random.default_rng(seed)
    Fc = math.exp(rng.uniform(math.log(0.1), math.log(100.0)))
    Fs, vs = Fc * rng.uniform(1.2, 1.6), math.exp(rng.uniform(math.log(0.02), math.log(0.1)))
    delta, s2 = rng.uniform(1.0, 2.5), Fc * rng.uniform(0.1, 1.0)
    v = np.geomspace(1.5 * vs, 2.0, 10)
    w = np.concatenate([v, -v])
    noise = 0.002 * Fc
    F = stribeck(w, Fc, Fs, vs, delta, s2) + rng.normal(0, noise, w.size)
    se = np.full(w.size, noise)
    st, cv = fit_static("stribeck", w, F, se), fit_static("coulomb_viscous", w, F, se)
    drop_spanned(st, w, cv, points=(w, F, se))
    p = st.params
    return ((p["Fc"].value - Fc) / p["Fc"].stderr, (p["sigma2"].value - s2) / p["sigma2"].stderr,
            p["Fs"].identifiable, akaike_weight(cv, st))


def test_the_level_and_slope_errors_of_an_unspanned_drop_are_calibrated():
    runs = [_z(seed) for seed in range(21, 33)]
    assert not any(r[2] for r in runs)  # the drop is never spanned: the rule applies to every draw
    assert all(r[3] < 1e-6 for r in runs)  # the data reject the drop-free line
    z = [abs(r[0]) for r in runs] + [abs(r[1]) for r in runs]
    assert 0.35 < statistics.median(z) < 1.3
    assert sum(x <= 2.5 for x in z) >= 0.85 * len(z)
