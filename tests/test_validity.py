"""The ranges a joint's data covered (frictid.identify.validity), by hand."""
from __future__ import annotations

import numpy as np

from frictid.identify.validity import TAIL, validity


def test_plateau_speeds_give_the_speed_range_and_logs_the_others():
    v = validity(np.array([-0.9, -0.02, 0.01, 0.5, 0.95]), [np.linspace(-1, 2, 50)], [np.linspace(20, 40, 50)])
    assert v == {"speed": [0.01, 0.95], "position": [-1.0, 2.0], "temperature": [20.0, 40.0]}


def test_samples_drop_their_extreme_tails_and_missing_channels_are_left_out():
    rng = np.random.default_rng(3)
    w = np.concatenate([rng.uniform(0.1, 1.0, 20000), [50.0, -60.0]])  # two reversal spikes
    v = validity(w, [np.zeros(0)], [])
    assert set(v) == {"speed"}
    lo, hi = v["speed"]
    assert 0.1 <= lo < 0.1 + 2 * TAIL and 1.0 - 2 * TAIL < hi <= 1.0


def test_nothing_measured_gives_no_range():
    assert validity(np.zeros(0), [], []) == {}
