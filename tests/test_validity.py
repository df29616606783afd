"""The ranges a joint's data covered (frictid.identify.validity), by hand."""
from __future__ import annotations

import numpy as np
import pytest

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


def test_the_fit_records_the_ranges_and_the_model_warns_outside_them(tmp_path):
    """The hydraulic sample sweeps 0.01..0.95 rad/s on its plateaus (sample_logs/README.md)."""
    import warnings

    import frictid
    from frictid.io.params import write_params
    from frictid.model import ValidityWarning

    from conftest import ROOT

    res = frictid.fit(str(ROOT / "sample_logs" / "hydraulic_sweep.csv"), diagnose=False)
    lo, hi = res["j1"].validity["speed"]
    assert 0.008 < lo < 0.012 and 0.9 < hi < 1.0
    assert "position" in res["j1"].validity and "temperature" not in res["j1"].validity
    write_params(res, tmp_path / "p.yaml")
    m = frictid.load(tmp_path / "p.yaml")
    assert m.validity == res["j1"].validity
    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)
        m.friction(np.linspace(-hi, hi, 11))
    with pytest.warns(ValidityWarning, match="speed"):
        m.friction([2 * hi])
