"""The candidates' trials on long logs: shortcuts that give the numbers of the plain computations they
replace (issue 20's speed line; the speed itself is measured by ``benchmarks/bench_diagnose_whole.py``): a
screen's delay columns formed together on the stride, the position torque's periodogram bins kept per
training set."""
from __future__ import annotations

import numpy as np
import pytest

from frictid.diagnose import signals as sg
from frictid.diagnose.model import Context, Structure
from frictid.models import static as sm

from frictid.diagnose.samples import build_samples

from test_diagnose import TRUE, plateau_log


@pytest.fixture(scope="module")
def S():
    # two plateau logs at 200 Hz with a position ripple, a drift and an offset (the samples of
    # tests/test_diagnose_speed.py, other seeds)
    eff = lambda t, q, w, F: F * (1 + 0.1 * np.sin(2 * np.pi * q / 0.9)) * (1 - 0.002 * t) + 0.05
    return build_samples([plateau_log(eff, seed=6, dt=5e-3), plateau_log(eff, seed=7, t0=200.0, dt=5e-3)], 5)


def test_a_screen_s_delay_columns_are_formed_together_and_are_the_whole_logs_at_the_stride(S, monkeypatch):
    """The screen's delay terms are the whole logs' (one per training set): on the stride their five columns
    come from one pass (:func:`frictid.diagnose.signals.share_delay_terms`), each equal to the whole logs'
    column at the stride's samples."""
    from frictid.diagnose import search
    from frictid.diagnose.chain import Chain

    monkeypatch.setattr(search, "STRIDE_MIN", 1 << 12)
    monkeypatch.setattr(search, "STRIDE_TARGET", 1 << 13)
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    ch = Chain(S, Structure("stribeck", cp, ()))
    sub = ch._screen_chain()
    calls = []
    real = sg._delay_columns_at
    monkeypatch.setattr(sg, "_delay_columns_at", lambda S_, items: calls.append((S_, len(items))) or real(S_, items))
    tr = sub.evaluate("delay", 10)
    assert tr is not None
    on_stride = [n for s, n in calls if s is sub.S]
    shifts = [t.settings["shift"] for t in tr.fold_terms]
    assert on_stride == [sum(1 for x in set(shifts) if x)]   # one pass, every training set's column
    for t in tr.fold_terms:
        if t.settings["shift"]:
            col = sg.delay_column(sub.S, t.settings["shift"], t.settings["beta"])
            np.testing.assert_array_equal(col, sg.delay_column(S, t.settings["shift"], t.settings["beta"])[ch.stride.sel])


@pytest.mark.parametrize("fold", [None, 0, 2, 4, "gather"])
def test_the_position_torque_s_periodogram_bins_are_best_period_s_own(S, fold):
    """The bins kept for a training set (read off every sample's bins where the lowest position and the range
    are all samples') are those best_period forms from the positions, and its period the same; also for a
    training set that lacks the lowest or the highest position (its bins then start elsewhere)."""
    from frictid.diagnose.causes import _period_range, best_period

    pr = _period_range(S)
    assert pr is not None
    ctx = Context(S)
    lo, hi = int(np.argmin(S.q)), int(np.argmax(S.q))
    for f_out in ((S.fold[lo], S.fold[hi]) if fold == 2 else (fold,)):
        if f_out == "gather":
            idx = np.flatnonzero(np.arange(S.n) % 3 != 0)
        else:
            idx = np.arange(S.n) if f_out is None else np.flatnonzero(S.fold != f_out)
        resid = np.random.default_rng(7).standard_normal(idx.size) + 0.3 * np.sin(2 * np.pi * S.q[idx] / 0.9)
        for _ in range(2):   # kept, then read again
            q0, rng, j2, B2 = ctx.position_bins(idx, pr[0])
            q = S.q[idx]
            h2 = pr[0] / 32.0
            assert q0 == float(q.min()) and rng == float(np.ptp(q))
            np.testing.assert_array_equal(j2, np.minimum(((q - q0) / h2).astype(np.int64), int(rng / h2)))
            np.testing.assert_array_equal(B2, np.bincount(j2, weights=np.ones(idx.size), minlength=int(rng / h2) + 1))
        assert best_period(None, resid, None, pr, bins=(q0, rng, j2, B2)) == best_period(q, resid, np.ones(idx.size), pr)


@pytest.mark.parametrize("shift", [-40, 0, 3, 40])
def test_the_delay_search_s_sums_at_whole_shifts_are_those_of_the_shifted_torque(S, shift):
    """The delay search reads the torque at whole shifts by one clipped gather (the ends of a log held):
    per fold the sums X'y and y'y of the interpolated shifted torque (:func:`signals.shifted_torque`)."""
    from frictid.data import finite

    dt = S.dt(0)
    XtX, XtY, yty = sg._delay_sums(S, shift * dt)
    want_y, want_yy = np.zeros_like(XtY), np.zeros_like(yty)
    for i, (km, fk) in enumerate(sg._moving_rows(S)):
        lg = S.logs[i]
        tau = finite(lg.tau)
        X = sg._delay_columns(S, i, km)
        y = lg.F[km] - tau[km] + sg.shifted_torque(tau, km.astype(float), float(shift))
        for g in range(S.n_folds):
            m = fk == g
            want_y[g] += X[m].T @ y[m]
            want_yy[g] += y[m] @ y[m]
    np.testing.assert_allclose(XtY, want_y, rtol=1e-10, atol=1e-12 * np.abs(want_y).max())
    np.testing.assert_allclose(yty, want_yy, rtol=1e-12)


@pytest.fixture(scope="module")
def S_encoder():
    # the plateau logs' positions read by an encoder of 2e-3 rad: fewer distinct positions than half the samples
    eff = lambda t, q, w, F: F * (1 + 0.1 * np.sin(2 * np.pi * q / 0.9)) + 0.05
    logs = [plateau_log(eff, seed=8, dt=5e-3), plateau_log(eff, seed=9, t0=200.0, dt=5e-3)]
    for lg in logs:
        lg.q = np.round(lg.q / 2e-3) * 2e-3
    return build_samples(logs, 5)


def test_the_position_torque_s_columns_read_from_the_positions_table_give_the_same_numbers(S_encoder):
    """A position torque's columns (sin and cos of a period; the smooth form 1, d, d^2) are read from a table of
    the distinct positions where they are used (:class:`frictid.diagnose.gathered.Gathered`), never formed over
    every sample: its values, each fold's sums of products with the current model's columns, the fits from
    them, the held-out predictions and the columns' extremes are those of the whole columns (a context
    without the tables)."""
    from frictid.diagnose.gathered import Gathered
    from frictid.diagnose.model import Evaluator, Term

    S = S_encoder
    assert 2 * np.unique(S.q).size <= S.n
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    st = Structure("stribeck", cp, ())
    q0, qs = float(0.5 * (S.q.max() + S.q.min())), float(0.5 * np.ptp(S.q))
    terms = [Term("position_torque", "position_torque", "additive", (("period", 0.9),)),
             Term("position_torque", "position_torque", "additive", (("period", 0.0), ("q0", q0), ("qs", qs)))]
    table, whole = Context(S), Context(S)
    whole.TABLE_EXTS = ()
    for term in terms:
        vec = table.term_vectors(term)
        assert all(isinstance(v, Gathered) for v in vec)
        cols = whole.term_columns(term)
        assert not any(k[0] == "term" for k in table._cache)   # no column over every sample
        for j, v in enumerate(vec):
            np.testing.assert_array_equal(v.at(), cols[:, j])
        for j in range(cols.shape[1]):
            np.testing.assert_array_equal(table.extremes(term, (j,)), whole.extremes(term, (j,)))
        for ctx in (table, whole):
            ctx.prefetch([st.plus(term)])
        for f in (None, 0, 3):
            tr = np.arange(S.n) if f is None else np.flatnonzero(S.fold != f)
            te = np.flatnonzero(S.fold == (0 if f is None else f))
            ca, cb = Evaluator(st.plus(term), table).fit(tr), Evaluator(st.plus(term), whole).fit(tr)
            assert ca.rms == cb.rms and all(np.array_equal(ca.gamma[i], cb.gamma[i]) for i in cb.gamma)
            np.testing.assert_array_equal(Evaluator(st.plus(term), table).predict(ca, te),
                                          Evaluator(st.plus(term), whole).predict(cb, te))
        items = [(k, v) for k, v, _ in Evaluator(st.plus(term), table)._linear_items()[0]]
        ref = [(k, v) for k, v, _ in Evaluator(st.plus(term), whole)._linear_items()[0]]
        np.testing.assert_array_equal(table.fold_products([v for _, v in items]),
                                      whole.fold_products([v for _, v in ref]))


def test_the_moving_samples_fold_order_is_sorted_once_and_gives_the_same_blocks(S):
    """Every pass over a log's moving samples (the delay search's shifts, its judgement, the lag's) reads them
    fold by fold: the order is kept while the rows live (:func:`signals._fold_order`), sorted once, and the
    blocks are those of a stable sort by fold."""
    km, fk = sg._moving_rows(S)[0]
    assert km.size > 100 and np.unique(fk).size > 1
    first = sg._fold_order(km, fk)
    assert sg._fold_order(km, fk) is first   # kept, not sorted again
    order = np.argsort(fk, kind="stable")
    blocks = list(sg._fold_blocks(km, fk, 64))
    want = []
    for g in np.unique(fk):
        ks = km[order][fk[order] == g]
        want += [(int(g), ks[b:b + 64]) for b in range(0, ks.size, 64)]
    assert [g for g, _ in blocks] == [g for g, _ in want]
    for (_, a), (_, b) in zip(blocks, want):
        np.testing.assert_array_equal(a, b)
    other = fk.copy()   # another array of the same folds: its own entry
    assert sg._fold_order(km, other) is not first


def test_a_vector_in_both_lists_of_a_bordered_sum_is_formed_once_with_the_same_sums(S_encoder):
    """The sums of a system's rows against some of them (a bordered system's new columns: the same vectors,
    gathers from a table among them) copy each shared vector's row within a block instead of forming it
    again: the same sums as with distinct copies of those vectors (the same products, one call per block)."""
    from frictid.diagnose.gathered import Gathered
    from frictid.diagnose.model import Evaluator, Term

    S = S_encoder
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    term = Term("position_torque", "position_torque", "additive", (("period", 0.7),))
    ctx = Context(S)
    vecs = [v for _, v, _ in Evaluator(Structure("stribeck", cp, ()).plus(term), ctx)._linear_items()[0]]
    assert any(isinstance(v, Gathered) for v in vecs)
    others = vecs[-3:]
    apart = [Gathered(v.table, v.index) if isinstance(v, Gathered) else v.copy() for v in others]
    np.testing.assert_array_equal(ctx.fold_products(vecs, others), ctx.fold_products(vecs, apart))


def test_the_delay_search_s_gravity_columns_are_kept_between_passes_with_the_same_sums(S, monkeypatch):
    """cos q and sin q of a log's moving samples are formed once in fold order (:func:`signals._fold_trig`),
    kept while the rows live, and read by every pass of the delay search: the sums X'X, X'y and y'y of its
    shifts are those of the columns computed per block (bit for bit)."""
    assert S.axis_rotary
    km, fk = sg._moving_rows(S)[0]
    trig = sg._fold_trig(S, 0, km, fk)
    assert trig is not None and sg._fold_trig(S, 0, km, fk) is trig
    ks = sg._fold_order(km, fk)[0]
    np.testing.assert_array_equal(sg._delay_columns(S, 0, ks, trig), sg._delay_columns(S, 0, ks))
    dt = S.dt(0)
    shifts = [0.0, 3 * dt, -7 * dt, 2.5 * dt]
    fresh = [build_samples(S.logs, 5) for _ in range(2)]
    kept = [sg._delay_sums(fresh[0], s) for s in shifts]
    monkeypatch.setattr(sg, "_fold_trig", lambda *a: None)
    per_block = [sg._delay_sums(fresh[1], s) for s in shifts]
    for a, b in zip(kept, per_block):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_the_heat_input_without_a_logged_ambient_is_that_of_a_zero_column(S):
    """Without ``temp_env`` the ambient's change is zero: the heat balance's input is ``P / K`` plus a scalar
    zero in place, not a column of zeros of every sample, with the same numbers bit for bit (-0 made +0 as by
    the column) and so the same thermal state."""
    from frictid.diagnose.samples import _heat_input

    P = np.array([1.5, -0.0, 0.0, -2.25, 1e-300, -3.0])
    for K in (1.0, 0.37):
        u, x0 = _heat_input(P, None, K)
        v, y0 = _heat_input(P, np.zeros(P.size), K)
        assert u.tobytes() == v.tobytes() and x0 == y0 == 0.0 and not np.signbit(u[1])
    import copy

    lg = copy.copy(S.logs[0])
    lg.channels = {k: v for k, v in lg.channels.items() if k != "temp_env"}
    T = build_samples([lg], 5)
    u, x0 = T._heat_input(0)
    v, y0 = _heat_input(T.power(0), T._dTenv(0))
    assert u.tobytes() == v.tobytes() and x0 == y0


def test_the_heat_input_with_a_logged_ambient_is_summed_in_place_with_the_same_numbers():
    """``dTenv + P / K`` formed in the quotient's array: the same sum bit for bit."""
    from frictid.diagnose.samples import _heat_input

    rng = np.random.default_rng(3)
    P, dT = rng.standard_normal(1000) * 10.0 ** rng.integers(-8, 8, 1000), rng.standard_normal(1000)
    P[::9] = -0.0
    for K in (1.0, 0.37, 3e4):
        u, x0 = _heat_input(P, dT, K)
        assert u.tobytes() == (dT + P / K).tobytes() and x0 == dT[0]


def test_the_ambient_s_spread_from_its_extremes_is_that_of_the_column():
    """:meth:`Samples._ambient_spread` reads a finite ambient's extremes: the spread of ``finite(Tenv - T0)``
    bit for bit, as before (and that column where Tenv holds NaN)."""
    from frictid.data import finite
    from frictid.diagnose.samples import Samples

    rng = np.random.default_rng(5)
    for T0, Tenv in ((25.0, 25.0 + np.cumsum(rng.standard_normal(5000)) * 1e-3),
                     (23.1, rng.uniform(-40.0, 90.0, 777)), (0.1, np.array([0.3, np.nan, -0.2]))):
        S = Samples.__new__(Samples)
        S.T0, S.logs = T0, [type("L", (), {"channels": {"temp_env": Tenv}, "n": Tenv.size})()]
        assert S._ambient_spread(0) == float(np.ptp(finite(Tenv - T0)))


def test_the_within_cell_line_in_the_speed_is_formed_once_with_the_same_numbers(S):
    """What :func:`chain._within` takes out of a candidate's residual and correction depends on the cells and
    the velocity only: formed once while they live (:func:`chain._cell_line`), with the numbers of the
    formula written out."""
    from frictid.diagnose import chain

    cell = chain.speed_cells(S)
    rng = np.random.default_rng(11)
    first = chain._cell_line(cell, S.w)
    assert chain._cell_line(cell, S.w) is first
    for x in (S.F, rng.standard_normal(S.n)):
        cnt = np.maximum(np.bincount(cell), 1)
        xc = x - (np.bincount(cell, weights=x) / cnt)[cell]
        wc = S.w - (np.bincount(cell, weights=S.w) / cnt)[cell]
        sww = np.bincount(cell, weights=wc * wc)
        want = xc - (np.bincount(cell, weights=wc * xc) / np.where(sww > 0, sww, np.inf))[cell] * wc
        assert chain._within(cell, x, S.w).tobytes() == want.tobytes()
    assert chain._cell_line(cell, S.w.copy()) is not first   # another velocity: its own
