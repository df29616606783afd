"""The fast helpers of the segmentation against the plain numpy they replace, bit for bit: the compiled
prefix sum, the shared-prefix moving slope, run painting and counting, closed runs, the per-run peak, and
the one-partition median and percentile."""
from __future__ import annotations


import numpy as np
import pytest

import frictid.segments.runs as runs_module
from frictid.segments.detect import _run_peak
from frictid.segments.runs import (any_in_runs, box_slope, closed_runs, count_prefix, drop_short, fill_short,
                                   paint, prefix_sum, prefix_sum_ref, runs)


def _masks(seed: int, count: int = 300):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        n = int(rng.integers(0, 400))
        yield rng, rng.random(n) < rng.random()


def test_compiled_prefix_sum_equals_numpy():
    rng = np.random.default_rng(0)
    for n in (1, 2, 7, 1000, 200_000):
        x = rng.normal(50.0, 20.0, n) * 10 ** rng.uniform(-6, 6)
        np.testing.assert_array_equal(prefix_sum(x), prefix_sum_ref(x))
    strided = rng.normal(size=(500, 3))[:, 1]  # not contiguous
    np.testing.assert_array_equal(prefix_sum(strided), prefix_sum_ref(strided))
    assert prefix_sum(np.zeros(0)).tolist() == [0.0]


def test_box_slope_from_a_shared_prefix_sum():
    rng = np.random.default_rng(1)
    for n in (1, 2, 3, 10, 11, 401, 5000):
        x = np.cumsum(rng.normal(size=n))
        c = prefix_sum(x)
        for h in (1, 2, 5, 50, 200):
            np.testing.assert_array_equal(box_slope(x, h, 1e-3, c), box_slope(x, h, 1e-3))
    # a straight line has its slope everywhere after the first sample (the ends use the shorter windows)
    t = np.arange(1000) * 1e-3
    np.testing.assert_allclose(box_slope(3.0 * t + 1.0, 20, 1e-3)[1:], 3.0, rtol=1e-9)


@pytest.mark.parametrize("few", [0, 10**9], ids=["vectorised", "slice-per-run"])
def test_paint_few_and_many_runs(monkeypatch, few):
    monkeypatch.setattr(runs_module, "FEW_RUNS", few)
    monkeypatch.setattr(runs_module, "SAMPLES_PER_RUN", 10**9)
    for rng, m in _masks(2):
        s, e = runs(m)
        sel = rng.random(s.size) < 0.5
        want = m.copy()
        for a, b in zip(s[sel], e[sel]):
            want[a:b] = False
        got = m.copy()
        paint(got, s[sel], e[sel], False)
        np.testing.assert_array_equal(got, want)
    got = np.zeros(10, dtype=bool)
    paint(got, [0, 2, 1], [3, 4, 2], True)  # overlapping runs
    assert got[:4].all() and not got[4:].any()


def test_run_counts_and_closed_runs():
    for rng, m in _masks(3):
        c = count_prefix(m)
        assert c[0] == 0 and np.array_equal(np.diff(c), m.astype(int))
        ok = rng.random(m.size) < 0.7
        s, e = runs(ok)
        want = np.array([m[a:b].any() for a, b in zip(s, e)], dtype=bool)
        np.testing.assert_array_equal(any_in_runs(m, s, e), want)
        gap, least = int(rng.integers(0, 20)), int(rng.integers(0, 20))
        for got, ref in ((closed_runs(m, gap, least), runs(drop_short(fill_short(m, gap, False), least))),
                         (closed_runs(m, gap), runs(fill_short(m, gap, False)))):
            np.testing.assert_array_equal(got[0], ref[0])
            np.testing.assert_array_equal(got[1], ref[1])


def test_run_peak_is_the_first_largest_sample_of_each_run():
    rng = np.random.default_rng(4)
    x = np.round(rng.normal(size=5000), 1)  # ties, also between signs
    s, e = runs(rng.random(x.size) < 0.6)
    want = [a + int(np.argmax(np.abs(x[a:b]))) for a, b in zip(s, e)]
    assert _run_peak(x, s, e).tolist() == want


def test_box_slope_in_chunks_equals_the_whole_array(monkeypatch):
    """The interior of box_slope, computed chunk by chunk, equals the whole-array formula bit for bit."""
    rng = np.random.default_rng(2)
    x = np.cumsum(rng.normal(size=20_000))
    c = prefix_sum(x)
    n = x.size
    monkeypatch.setattr(runs_module, "CHUNK", 1000)
    for h in (1, 7, 125, 126, 999, 4000):
        sums = c[h:] - c[:n + 1 - h]
        mid = (sums[h:] - sums[:n + 1 - 2 * h]) / (h * h * 1e-3)
        np.testing.assert_array_equal(box_slope(x, h, 1e-3, c)[h:n - h + 1], mid)


def test_chunks_cover_the_range_in_order():
    for n, size in ((0, 4), (1, 4), (8, 4), (9, 4), (10, 3)):
        got = [i for k in runs_module.chunks(n, size) for i in range(n)[k]]
        assert got == list(range(n))
        assert all(k.stop - k.start <= size for k in runs_module.chunks(n, size))


def test_one_partition_median_equals_numpy():
    from frictid.segments.scales import median_inplace
    rng = np.random.default_rng(5)
    for t in range(600):
        rows, n = int(rng.integers(1, 5)), int(rng.integers(1, 50))
        x = rng.standard_normal((rows, n)) if t % 2 else rng.integers(0, 4, (rows, n)).astype(float)
        if t % 5 == 0:
            x[rng.random(x.shape) < 0.1] = np.nan
        if t % 7 == 0:
            x[rng.random(x.shape) < 0.2] = -np.inf if t % 3 else np.inf
        for arr in (x, x[0]):
            ref, got = np.median(arr.copy(), axis=-1), median_inplace(arr.copy())
            assert np.shape(got) == np.shape(ref)
            assert np.array_equal(got, ref, equal_nan=True)
    big = np.abs(rng.standard_normal(100_001))
    for arr in (big, big[:-1], big[:-1].reshape(-1, 100)):
        assert np.array_equal(median_inplace(arr.copy()), np.median(arr, axis=-1))
