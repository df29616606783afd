"""The diagnosis' shortcuts for long logs give the numbers of the plain computations they replace (issue 20,
"a 1-hour 1 kHz log is diagnosed on all its samples in at most 3x the time of the fit"; the speed itself is
measured by ``benchmarks/bench_diagnose_whole.py``): a candidate's grid of settings summed in one pass,
thermal6's columns formed where they are used, the training sets' delay columns computed together (and
equal to their definition), per-group sums by runs, the training sets' predictions on runs, the scored
samples from per-fold extremes."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from frictid.diagnose import signals as sg
from frictid.diagnose.model import Context, Evaluator, Structure, Term
from frictid.diagnose.samples import build_samples
from frictid.models import static as sm

from test_diagnose import TRUE, plateau_log


@pytest.fixture(scope="module")
def S():
    eff = lambda t, q, w, F: F * (1 + 0.1 * np.sin(2 * np.pi * q / 0.9)) * (1 - 0.002 * t) + 0.05
    return build_samples([plateau_log(eff, seed=4, dt=5e-3), plateau_log(eff, seed=5, t0=200.0, dt=5e-3)], 5)


def _current():
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    return Structure("stribeck", cp, (Term("position", "position_periodic", "level_factor", (("period", 0.9),)),
                                      Term("offset", "offset", "additive", ())))


def _grid():
    th = [Term("temperature", "thermal4", "whole_factor", (("source", "heat_balance"), ("tau_c", tc)))
          for tc in (10.0, 25.0, 60.0)]
    pt = [Term("position_torque", "position_torque", "additive", (("period", p),)) for p in (0.31, 0.55)]
    return th + pt


def test_a_grid_summed_in_one_pass_fits_as_setting_by_setting(S):
    st = _current()
    grid = [st.plus(t) for t in _grid()]
    one, plain = Context(S), Context(S)
    one.prefetch(grid)
    calls = []
    one.fold_products = lambda *a, **k: calls.append(a)   # every sum must be there already
    for f in (None, 0, 3):
        idx = np.arange(S.n) if f is None else np.flatnonzero(S.fold != f)
        for s in grid:
            a, b = Evaluator(s, one).fit(idx), Evaluator(s, plain).fit(idx)
            assert a.rms == pytest.approx(b.rms, rel=1e-12)
            for i in b.gamma:
                np.testing.assert_allclose(a.gamma[i], b.gamma[i], rtol=1e-10, atol=1e-14)
            assert all(a.base_pos[k] == pytest.approx(b.base_pos[k], rel=1e-10) for k in b.base_pos)
    assert not calls


def test_thermal6_columns_formed_where_used_equal_the_stored_ones(S):
    t6 = Term("temperature", "thermal6", "thermal6", (("source", "heat_balance"), ("tau_c", 20.0)))
    ctx = Context(S)
    prods = ctx.term_vectors(t6)
    assert all(isinstance(p, tuple) for p in prods)
    X = ctx.term_columns(t6)
    for j, p in enumerate(prods):
        out = np.multiply(p[0], p[1])
        for x in p[2:]:
            out *= x
        np.testing.assert_array_equal(out, X[:, j])
    ext = ctx.extremes(t6, (0,))
    assert ext.ravel().tolist() == [X[:, 0].min(), X[:, 0].max()]
    # a fit and a held-out prediction with the products, against the dense least squares on the samples
    st = Structure("stribeck", _current().shapes, (t6,))
    te = np.flatnonzero(S.fold == 2)
    tr = np.flatnonzero(S.fold != 2)
    a = Evaluator(st, ctx)
    b = Evaluator(st, Context(S, use_normal_equations=False))
    ca, cb = a.fit(tr), b.fit(tr)
    np.testing.assert_allclose(ca.dc, cb.dc, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(a.predict(ca, te), b.predict(cb, te), rtol=1e-7, atol=1e-9)


def test_the_delay_columns_of_several_shifts_at_once_equal_one_at_a_time(S):
    rng = np.random.default_rng(2)
    items = [(0.004, tuple(rng.standard_normal(11))), (0.0065, tuple(rng.standard_normal(11))), (0.01, ())]
    together = sg._delay_columns_at(S, items)
    for it, col in zip(items, together):
        np.testing.assert_array_equal(col, sg._delay_columns_at(S, [it])[0])
    # the training sets' terms, as the proposals ask for them one by one: computed together, the same numbers
    terms = sg._fold_delay_terms(S)
    for shift, beta in terms:
        if shift:
            np.testing.assert_array_equal(sg.delay_column(S, shift, beta), sg._delay_columns_at(S, [(shift, beta)])[0])


def test_position_columns_of_an_encoder_grid_are_the_direct_ones(S):
    # quantised positions (an encoder's steps) take the distinct-position path, continuous ones the direct
    # path: both the numbers of sin and cos of 2 pi q / P at every sample
    for q in (np.round(S.q / 1e-3) * 1e-3, S.q):
        Sq = replace(S, q=q)
        ctx = Context(Sq)
        for P in (0.31, np.pi):
            X = ctx.term_columns(Term("position_torque", "position_torque", "additive", (("period", P),)))
            ph = 2 * np.pi * q / P
            np.testing.assert_array_equal(X[:, 0], np.sin(ph))
            np.testing.assert_array_equal(X[:, 1], np.cos(ph))
        assert (ctx._cache["q2pi"][1] is None) == (np.unique(q).size * 2 > q.size)
        # a periodic level factor's extremes: one row per distinct position, the rows the samples read, so
        # every linear function of the columns reaches the same largest |value| over them
        term = Term("position", "position_periodic", "level_factor", (("period", 0.31),))
        X, E = ctx.term_columns(term), ctx.extremes(term)
        assert E.shape[0] == (np.unique(q).size if ctx._cache["q2pi"][1] is not None else q.size)
        np.testing.assert_array_equal(np.unique(E, axis=0), np.unique(X, axis=0))
        for g in (np.array([0.3, -0.7]), np.array([1e-3, 2.5])):
            assert np.max(np.abs(E @ g)) == np.max(np.abs(X @ g))


def test_group_sums_by_runs_are_the_bincount(S):
    x = np.random.default_rng(3).standard_normal(S.n)
    ref = np.bincount(S.group, weights=x, minlength=S.n_groups)
    assert S.group_sums(x) == pytest.approx(ref, rel=1e-12, abs=1e-12 * np.abs(x).sum())
    assert S.cached("group_runs", lambda: None) is not None   # the fold-ordered samples: one run per group
    # groups that are not runs (the samples shuffled): the bincount itself
    order = np.random.default_rng(4).permutation(S.n)
    Sp = replace(S, group=S.group[order])
    np.testing.assert_array_equal(Sp.group_sums(x), np.bincount(Sp.group, weights=x, minlength=S.n_groups))
    assert Sp.cached("group_runs", lambda: 0) is None


def test_delay_columns_are_the_centred_rate_of_the_interpolated_torque_model(S):
    # the definition, sample by sample: (T(k + h) - T(k - h)) / shift, T linearly interpolated between the
    # samples of the log and held at its ends, h half the shift in samples
    rng = np.random.default_rng(5)
    for shift in (0.004, 0.0065, -0.0123):
        beta = tuple(rng.standard_normal(11))
        col = sg._delay_columns_at(S, [(shift, beta)])[0]
        for i, lg in enumerate(S.logs):
            sel = S.li == i
            T = sg._torque_model(sg._torque_features(S, i, np.arange(lg.n)), beta)
            k = S.k[sel].astype(float)
            h = 0.5 * shift / S.dt(i)
            ref = (np.interp(k + h, np.arange(lg.n), T) - np.interp(k - h, np.arange(lg.n), T)) / shift
            assert col[sel] == pytest.approx(ref, rel=1e-9, abs=1e-9 * np.abs(ref).max())


def test_training_predictions_on_runs_and_the_scored_samples_are_the_plain_ones(S):
    from frictid.diagnose.chain import _on_training, supported

    st = _current()
    ev = Evaluator(st, Context(S))
    for f in range(S.n_folds):
        tr, te = np.flatnonzero(S.fold != f), np.flatnonzero(S.fold == f)
        c = ev.fit(tr)
        np.testing.assert_array_equal(_on_training(ev.predict, c, tr, te), ev.predict(c, tr))
        np.testing.assert_array_equal(_on_training(ev.level, c, tr, te), ev.level(c, tr))
    inside = np.zeros(S.n, bool)   # the definition: held-out speeds within the training folds' of that sign
    for f in range(S.n_folds):
        for sgn in (1.0, -1.0):
            tr_w = S.w[(S.fold != f) & (np.sign(S.w) == sgn)]
            sel = (S.fold == f) & (np.sign(S.w) == sgn)
            if tr_w.size:
                inside[sel] = (S.w[sel] >= tr_w.min()) & (S.w[sel] <= tr_w.max())
    np.testing.assert_array_equal(supported(S), inside)


def test_a_stride_keeps_every_fold_the_logs_values_and_the_training_residual(S, monkeypatch):
    from frictid.diagnose import search

    monkeypatch.setattr(search, "STRIDE_MIN", 1 << 12)
    monkeypatch.setattr(search, "STRIDE_TARGET", 1 << 13)
    st = search.StrideSearch(S)
    assert st.active and st.wants("stribeck") and not st.wants("delay")
    k = int(np.ceil(S.n / (1 << 13)))
    sub = st.sub
    np.testing.assert_array_equal(st.sel, np.arange(0, S.n, k))
    np.testing.assert_array_equal(sub.fold, S.fold[st.sel])
    assert np.all(np.diff(sub.fold) >= 0) and set(sub.fold) == set(range(S.n_folds))   # folds contiguous, all there
    assert sub.dt(0) == S.dt(0) and sub.log_w(1) is S.log_w(1)
    st.sync(Context(S))
    # the dwell's grid and the ripple's periods are the full samples' own, the rests theirs at the stride
    assert sub.cached("rest_scales", lambda: None) is sg.rest_scales(S)
    np.testing.assert_array_equal(sg.rests(sub)[0], sg.rests(S)[0][st.sel])
    for f in (0, 3):
        tr = np.flatnonzero(S.fold != f)
        res = np.random.default_rng(f).standard_normal(tr.size)
        idx, r, lev = st.training(f, tr, res, 2 * res)
        np.testing.assert_array_equal(idx, np.flatnonzero(sub.fold != f))
        full = np.full(S.n, np.nan)
        full[tr] = res
        np.testing.assert_array_equal(r, full[st.sel[idx]])
        np.testing.assert_array_equal(lev, 2 * r)


def test_a_grid_ranked_on_a_stride_chooses_the_setting_of_all_samples(S, monkeypatch):
    # a Stribeck hump the base map lacks: its velocity and exponent ranked on every second or fourth sample
    # of the training folds are those of all of them; the chain's trial judges them on all samples
    from frictid.diagnose import search
    from frictid.diagnose.causes import propose
    from frictid.diagnose.chain import Chain

    cp, _ = sm.canonical_pair("coulomb_viscous", TRUE)
    base = Structure("coulomb_viscous", cp, ())
    monkeypatch.setattr(search, "STRIDE_MIN", 1 << 12)
    for target in (1 << 14, 1 << 13):
        monkeypatch.setattr(search, "STRIDE_TARGET", target)
        ch = Chain(S, base)
        assert ch.stride.active
        tr_full = ch.evaluate("stribeck", 10)
        for f, (tr, te, res, lev, c0) in enumerate(ch.train_info):
            full = propose("stribeck", ch.ctx, ch.st, tr, res, lev, c0)
            assert tr_full.fold_terms[f] == full
        assert tr_full.gain > 0 and np.all(np.isfinite(tr_full.pred_after))


def test_monomial_coefficients_for_all_monomials_at_once_are_the_per_monomial_products():
    """:func:`frictid.diagnose.moments.coefficients` (all monomials at once, its plan kept per layout) gives
    the numbers of the per-monomial products it replaced, exactly, on random layouts and coefficients."""
    from frictid.diagnose import moments as mo

    def plain(monos, amp, gam, free_items, free_gamma):
        col_of_item = {k: n for n, k in enumerate(free_items)}
        col_of_gam = {ij: len(free_items) + n for n, ij in enumerate(free_gamma)}
        c, C = np.zeros(len(monos)), np.zeros((len(monos), len(free_items) + len(free_gamma)))
        for m, x in enumerate(monos):
            vals = [1.0 if j < 0 else float(gam[i][j]) for i, j in zip(x.factors, x.choice)]
            prod_all = float(np.prod(vals)) if vals else 1.0
            c[m] = amp[x.item] * prod_all
            if x.item in col_of_item:
                C[m, col_of_item[x.item]] = prod_all
            for p, (i, j) in enumerate(zip(x.factors, x.choice)):
                if j >= 0 and (i, j) in col_of_gam:
                    others = vals[:p] + vals[p + 1:]
                    C[m, col_of_gam[(i, j)]] = amp[x.item] * (float(np.prod(others)) if others else 1.0)
        return c, C

    rng = np.random.default_rng(7)
    for _ in range(60):
        sizes = [int(s) for s in rng.integers(1, 4, rng.integers(0, 4))]
        n_items = int(rng.integers(1, 7))
        applies = [tuple(i for i in range(len(sizes)) if rng.random() < 0.7) for _ in range(n_items)]
        monos = mo.monomials(n_items, applies, sizes)
        amp = rng.standard_normal(n_items) * 10.0 ** rng.uniform(-3, 3, n_items)
        gam = [rng.standard_normal(s) * 10.0 ** rng.uniform(-4, 1) for s in sizes]
        free_items = [k for k in range(n_items) if rng.random() < 0.8]
        free_gamma = [(i, j) for i, s in enumerate(sizes) for j in range(s) if rng.random() < 0.8]
        for got, want in zip(mo.coefficients(monos, amp, gam, free_items, free_gamma),
                             plain(monos, amp, gam, free_items, free_gamma)):
            assert np.array_equal(got, want)


@pytest.mark.parametrize("side", ["right", "left"])
def test_equal_count_bins_from_one_sort_are_the_quantile_edges_bins(side):
    """The shared binning (one sort of x) gives the bins of the quantile edges found by searchsorted, with
    ties, a constant stretch, a few values and a NaN, on either side of an edge."""
    from frictid.diagnose.binned import equal_count_bins

    rng = np.random.default_rng(7)
    xs = [rng.normal(size=5001), np.round(rng.normal(size=4000), 1), np.r_[np.zeros(3000), rng.random(500)],
          rng.integers(0, 3, 999).astype(float), np.r_[rng.random(300), np.nan], np.arange(7.0)]
    for x in xs:
        for nb in (4, 40, 120):
            edges = np.unique(np.quantile(x, np.linspace(0, 1, nb + 1)[1:-1]))
            b, n = equal_count_bins(x, nb, side)
            assert n == edges.size + 1
            np.testing.assert_array_equal(b, np.searchsorted(edges, x, side=side))


def test_the_spread_of_a_periodic_correction_from_the_distinct_positions_is_the_samples(S):
    # a confound check's spread of a position torque over the samples (Context.spread): from one row per
    # distinct position weighted by its samples when the positions repeat, the same number as the columns'
    for q in (np.round(S.q / 1e-3) * 1e-3, S.q):
        ctx = Context(replace(S, q=q))
        for P, g in ((0.31, np.array([0.3, -0.7])), (np.pi, np.array([1e-3, 2.5]))):
            term = Term("position_torque", "position_torque", "additive", (("period", P),))
            got = ctx.spread(term, g)   # before the columns are formed: the distinct positions' path
            want = float(np.std(ctx.term_columns(term) @ g))
            assert got == pytest.approx(want, rel=1e-12)
            assert ctx.spread(term, np.zeros(3)) == 0.0


@pytest.mark.parametrize("stride", [1, 3])
def test_the_checks_second_sample_set_takes_the_firsts_columns_only_when_build_would_give_them(stride):
    """The fit's check builds one sample set per model on the same logs; the second model's set takes the
    first's velocity, blocks, folds and logs (only its friction gathered) and equals the set built from its
    own targets; with a target that is not finite everywhere it is built again."""
    from types import SimpleNamespace

    from frictid.diagnose import check
    from frictid.identify import samples as smp
    from frictid.data import Segment

    rng = np.random.default_rng(7)
    logs = []
    for n, t0 in ((3000, 0.0), (2000, 40.0)):
        t = t0 + np.arange(n) * 0.01
        w = np.sin(t) + 0.01 * rng.standard_normal(n)
        logs.append(SimpleNamespace(log=SimpleNamespace(t=t, n=n), w=w,
                                    segments=[Segment("duty_cycle", 100, 400, t0 + 1.0, t0 + 4.0)]))
    Y1 = [np.tanh(p.w) + 0.1 * rng.standard_normal(p.w.size) for p in logs]
    Y2 = [y + 0.3 * rng.standard_normal(y.size) for y in Y1]
    kw = dict(exclude=("duty_cycle",), max_samples=(5000 if stride == 1 else 1500))

    def built(Y):
        return smp.build([SimpleNamespace(log=p.log, w=p.w, F=y, segments=p.segments) for p, y in zip(logs, Y)],
                         0.05, 5, **kw)

    S1 = built(Y1)
    assert S1.stride == stride
    folds = [None] + list(range(S1.n_folds))
    for f in folds:   # the first set's velocity bins, which the second takes
        smp._bin_samples(S1, f)
    key = check._SampleKey(S1.order_key(), S1.w, S1.block, S1.fold, S1.log, S1.stride, S1.n_moving, True,
                           tuple((w, f) for w, _, f in S1.by_speed()), S1.velocity_bins_cache())
    S2, ref = check._same_samples(key, Y2), built(Y2)
    assert S2.velocity_bins_cache() is S1.velocity_bins_cache()
    for f in folds:   # its bins (velocity side shared, its friction summed) are those of its own set, to the bit
        assert all(a.tobytes() == b.tobytes() for a, b in zip(smp._bin_samples(S2, f), smp._bin_samples(ref, f))), f
        assert all(a.tobytes() == b.tobytes() for a, b in zip(smp._bin_samples(ref, f), smp.bin_points(
            ref.w[ref.fold != f] if f is not None else ref.w, ref.F[ref.fold != f] if f is not None else ref.F))), f
    for f in ("w", "F", "block", "fold", "log"):
        assert np.array_equal(getattr(S2, f), getattr(ref, f)), f
    assert (S2.stride, S2.n_moving, S2.n_folds) == (ref.stride, ref.n_moving, ref.n_folds)
    assert all(np.array_equal(a, b) for a, b in zip(S2.speed_order(), ref.speed_order()))
    assert all(np.array_equal(a, b) for x, y in zip(S2.by_speed(), ref.by_speed()) for a, b in zip(x, y))
    # a first set with a non-finite target does not share its columns (its masks left those samples out)
    assert check._same_samples(replace(key, finite=False), Y2) is None


def test_quantiles_read_off_a_sorted_array_are_numpys_to_the_bit():
    """:func:`frictid.diagnose.binned.sorted_quantiles` gives ``np.quantile`` of the sorted array bit for bit:
    lengths 1 to 400 and 10^5, ties, integers, a NaN, the bins' quantile grids and random levels."""
    from frictid.diagnose.binned import sorted_quantiles

    rng = np.random.default_rng(11)
    for k in range(600):
        n = int(rng.integers(1, 400)) if k else 100_000
        x = (rng.standard_normal(n) * 10.0 ** rng.integers(-6, 6) if k % 3 else
             rng.integers(0, 7, n).astype(float if k % 2 else np.int64))
        if k % 50 == 7:
            x = np.r_[x.astype(float), np.nan]
        s = np.sort(x)
        for q in (np.linspace(0, 1, int(rng.integers(2, 130)) + 1)[1:-1], np.sort(rng.random(5)), np.array([0.0, 1.0])):
            assert sorted_quantiles(s, q).tobytes() == np.quantile(s, q).tobytes(), (k, n, q.size)


def test_kept_bins_are_found_for_the_same_values_only(S):
    """A variable binned again (formed anew, equal value by value) takes its kept bins; one that differs only
    inside, or starts with a NaN, is binned anew."""
    from frictid.diagnose.binned import _bins, _bins_of

    nb = 40
    x = np.asarray(S.w, dtype=float) * 1.0
    b0 = _bins_of(S, x, nb)
    assert _bins_of(S, x.copy(), nb) is b0
    y = x.copy()
    y[y.size // 2] += 10.0 * np.ptp(x)   # the same ends, another middle
    by = _bins_of(S, y, nb)
    assert by is not b0 and np.array_equal(by, _bins(y, nb))
    z = x.copy()
    z[0] = np.nan
    assert _bins_of(S, z, nb) is not b0 and _bins_of(S, z, nb) is not by


def test_the_time_since_the_last_rest_from_the_runs_ends_is_the_running_maximums():
    """:func:`frictid.diagnose.structure.since_rest` finds each sample's last sample at rest among the ends of
    the runs of rest; on random logs (rests at the start, at the end, none, everywhere; several logs; any
    samples kept) the times are those of the running maximum over the whole log it replaced."""
    from types import SimpleNamespace

    from frictid.diagnose.structure import since_rest

    def running_max(S):
        out = np.empty(S.n)
        for i, lg in enumerate(S.logs):
            sel = S.li == i
            last = np.where(np.abs(S.log_w(i)) <= S.v_min, np.arange(lg.n), 0)
            np.maximum.accumulate(last, out=last)
            out[sel] = lg.t[S.k[sel]] - lg.t[last[S.k[sel]]]
        return out

    rng = np.random.default_rng(20)
    for trial in range(200):
        logs, ks, li = [], [], []
        for i in range(int(rng.integers(1, 4))):
            n = int(rng.integers(1, 60))
            w = np.where(rng.random(n) < rng.random(), 0.0, rng.normal(size=n))
            w[:int(rng.integers(0, 3))] = 0.0 if trial % 3 else 1.0
            if trial % 7 == 0:
                w[:] = 1.0
            logs.append(SimpleNamespace(w=w, t=np.cumsum(rng.random(n)), n=n))
            k = np.sort(rng.choice(n, size=int(rng.integers(0, n + 1)), replace=False))
            ks.append(k)
            li.append(np.full(k.size, i))
        k = np.concatenate(ks)
        S = SimpleNamespace(n=k.size, logs=logs, li=np.concatenate(li), k=k, v_min=0.3,
                            cached=lambda key, fn: fn())
        S.log_w = lambda i, S=S: S.logs[i].w
        assert np.array_equal(since_rest(S), running_max(S)), trial


def test_the_runs_starts_at_some_samples_are_those_spread_over_the_log():
    """``signals._moves`` looks each sample's run start and the run before up among the runs' starts: on random
    velocities (rests, reversals, a constant sign, one sample) they are the starts spread over every sample."""
    rng = np.random.default_rng(21)
    for trial in range(200):
        n = int(rng.integers(1, 80))
        w = np.where(rng.random(n) < 0.4, 0.0, rng.normal(size=n))
        if trial % 9 == 0:
            w[:] = -1.0
        sign = np.where(np.abs(w) > 0.3, np.sign(w), 0.0)
        edges = np.concatenate(([0], np.flatnonzero(sign[1:] != sign[:-1]) + 1))
        lens = np.diff(np.concatenate((edges, [n])))
        start, prev = np.repeat(edges, lens), np.repeat(np.concatenate(([-1], edges[:-1])), lens)
        k = np.sort(rng.choice(n, size=int(rng.integers(0, n + 1)), replace=False))
        s2, st, pv = sg._moves(w, 0.3, k)
        assert np.array_equal(s2, sign) and np.array_equal(st, start[k]) and np.array_equal(pv, prev[k]), trial
        assert st.dtype == start.dtype and pv.dtype == prev.dtype


def test_the_speed_bands_shares_from_one_count_over_cells_are_the_band_by_band_ones(S):
    """``chain._band_shares`` sums each (speed band, group) cell in one ``bincount``: the shares, their errors
    and the bands' speeds are those of the band-by-band sums it replaced, to the bit (twice: the second from the
    cached bands)."""
    from frictid.diagnose.binned import equal_count_bins
    from frictid.diagnose.chain import SPEED_BANDS, _band_shares

    def by_band(rw, dw):
        speed = np.abs(S.w)
        band, nb = equal_count_bins(speed, SPEED_BANDS)
        out = []
        for k in range(nb):
            sel = band == k
            s = np.bincount(S.group[sel], weights=(rw * dw)[sel], minlength=S.n_groups)
            d = np.bincount(S.group[sel], weights=(dw * dw)[sel], minlength=S.n_groups)
            if d.sum() <= 0:
                continue
            beta = float(s.sum() / d.sum())
            out.append((beta, float(np.sqrt(np.sum((s - beta * d) ** 2)) / d.sum()),
                        float(speed[sel].min()), float(speed[sel].max())))
        return out

    rng = np.random.default_rng(22)
    for _ in range(2):
        rw, dw = rng.standard_normal(S.n), rng.standard_normal(S.n)
        assert _band_shares(S, rw, dw) == by_band(rw, dw)
    dw[np.abs(S.w) < np.median(np.abs(S.w))] = 0.0   # slow bands without a correction: left out alike
    assert _band_shares(S, rw, dw) == by_band(rw, dw)


def test_samples_gathered_in_fold_order_are_their_logs_values(S):
    """``build_samples`` gathers each log's arrays once, in the folds' order: every per-sample array of the
    two-log fixture is its log's value at the sample's (log, index), the folds are contiguous, and within a
    fold the samples keep their order in time (log by log, index by index)."""
    from frictid.diagnose.samples import PER_SAMPLE

    assert np.all(np.diff(S.fold) >= 0) and np.unique(S.li).size == 2
    for name, full in (("w", "w"), ("a", "a"), ("tau", "tau"), ("F", "F"), ("G", "G"), ("q", "q"), ("t", "t")):
        ref = np.empty(S.n)
        for i, lg in enumerate(S.logs):
            ref[S.li == i] = np.asarray(getattr(lg, full), float)[S.k[S.li == i]]
        assert np.array_equal(getattr(S, name), ref, equal_nan=True), name
    for f in range(S.n_folds):
        key = S.li[S.fold == f].astype(np.int64) * (1 << 40) + S.k[S.fold == f]
        assert np.all(np.diff(key) > 0)
    assert all(getattr(S, n) is None or getattr(S, n).shape == (S.n,) for n in PER_SAMPLE)


def test_the_cleaned_runs_are_those_of_the_cleaned_signs_spread_over_the_log():
    """``previous._cleaned`` works on the runs: on random run signs and times (dips within moves, twitches at
    rest, one run, one sample) its runs' first indices and signs are those of the per-sample signs the two
    passes spread over the log before."""
    from frictid.diagnose.previous import _cleaned
    from frictid.diagnose.signals import REST_MIN

    def per_sample(sg, t):
        out = sg.copy()
        for pass_ in (0, 1):
            edges = np.flatnonzero(np.concatenate(([True], out[1:] != out[:-1])))
            ends = np.concatenate((edges[1:], [out.size]))
            length = t[np.minimum(ends, out.size - 1)] - t[edges]
            sgr = out[edges]
            if pass_ == 0:
                dip = (sgr == 0) & (length < REST_MIN)
                dip[[0, -1]] = False
                dip[1:-1] &= (sgr[:-2] == sgr[2:]) & (sgr[:-2] != 0)
                short, fill = dip, np.concatenate(([0.0], sgr[:-1]))
            else:
                short, fill = (sgr != 0) & (length < REST_MIN), np.zeros(sgr.size)
            out = np.repeat(np.where(short, fill, sgr), ends - edges)
        return out

    rng = np.random.default_rng(23)
    for trial in range(300):
        n = int(rng.integers(1, 120))
        sg = rng.choice([-1.0, 0.0, 1.0], size=n, p=rng.dirichlet(np.ones(3)))
        sg = np.repeat(sg, rng.integers(1, 6, n))[:n]
        t = np.cumsum(rng.random(n) * 0.04)
        cl = per_sample(sg, t)
        edges, sgr = _cleaned(sg, t)
        assert np.array_equal(edges, np.flatnonzero(np.concatenate(([True], cl[1:] != cl[:-1])))), trial
        assert np.array_equal(sgr, cl[edges]), trial

