"""The Stribeck drop's errors no smaller than the delete-a-pair jackknife over the plateau points
(identify/static.py, ``_pair_jackknife`` and ``mirrored_groups``; issue 19, item 17 of docs/scorecards.md).

A sweep runs each speed both ways; what biases a plateau's mean beyond its batch-means error (a settling,
the loop after the move, the program around it) depends on the speed, not the sign, so a mirrored pair of
points shares it. The Jacobian's error takes each point's batch-means error as its whole error: on the
foreign fit card Fs was outside two errors on 10 of 52 draws (median |value - truth| / stderr 0.94 against
an honest 0.67). Here: random Stribeck joints (seeds < 1000; the cards use >= 100000) on 14 speeds from
0.15 vs to 2 rad/s each way, every pair sharing an error of the size of the points' own; with the
jackknife Fs and vs are calibrated, without it (the old errors) their median |z| is 1.2.
"""
from __future__ import annotations

import math
import statistics

import numpy as np

from frictid.identify.static import fit_static, mirrored_groups
from frictid.models.static import stribeck


def _z(seed: int, shared: float) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    Fc = math.exp(rng.uniform(math.log(0.1), math.log(100.0)))
    Fs, vs = Fc * rng.uniform(1.1, 1.6), math.exp(rng.uniform(math.log(0.02), math.log(0.3)))
    delta, s2 = rng.uniform(0.6, 2.5), Fc * rng.uniform(0.05, 1.0)
    v = np.geomspace(0.15 * vs, 2.0, 14)
    w = np.concatenate([v, -v])
    se = 0.002 * Fc * np.exp(rng.uniform(-0.7, 0.7, w.size))
    pair = rng.normal(0.0, 1.0, v.size) * 0.002 * Fc * shared  # one error per speed, both signs alike
    F = stribeck(w, Fc, Fs, vs, delta, s2) + rng.normal(0.0, se) + np.concatenate([pair, -pair])
    p = fit_static("stribeck", w, F, se, jackknife=True).params
    return {k: abs(p[k].value - t) / p[k].stderr for k, t in (("Fs", Fs), ("vs", vs))
            if p[k].identifiable and p[k].stderr}


def _summary(shared: float) -> dict[str, tuple[float, float]]:
    runs = [_z(seed, shared) for seed in range(31, 71)]
    out = {}
    for k in ("Fs", "vs"):
        z = [r[k] for r in runs if k in r]
        assert len(z) >= 36
        out[k] = (sum(x <= 2.0 for x in z) / len(z), statistics.median(z))
    return out


def test_a_pair_shared_error_is_in_the_drops_errors():
    for k, (cover, med) in _summary(1.0).items():  # the Jacobian's errors alone: median 1.18 / 1.24
        assert cover >= 0.9, (k, cover)
        assert 0.4 < med < 1.0, (k, med)


def test_independent_points_keep_errors_near_their_size():
    for k, (cover, med) in _summary(0.0).items():  # no shared error: the jackknife adds little
        assert cover >= 0.9, (k, cover)
        assert med > 0.4, (k, med)


def test_mirrored_groups_pair_each_speed_with_its_mirror():
    w = np.array([0.1, -0.1, 0.2, -0.205, 0.4, -0.5, 1.0])
    groups = [sorted(g.tolist()) for g in mirrored_groups(w)]
    assert groups == [[0, 1], [2, 3], [4], [6], [5]]  # -0.5 is 25 % from 0.4: no mirror
    assert [g.tolist() for g in mirrored_groups(np.array([0.1, 0.2]))] == [[0], [1]]
