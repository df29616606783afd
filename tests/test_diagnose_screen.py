"""The two-stage trials of long logs (:mod:`frictid.diagnose.screen`): a candidate whose trial on the stride
bounds what it would explain on all samples under the bar is not tried on all of them, and the chain's
answer is that of trying every candidate on all samples (issue 20's speed line; the time itself is measured
by ``benchmarks/bench_diagnose_whole.py``)."""
from __future__ import annotations

import numpy as np
import pytest

from frictid.diagnose import chain as ch
from frictid.diagnose import search
from frictid.diagnose.model import Structure
from frictid.diagnose.samples import build_samples
from frictid.models import static as sm

from test_diagnose import TRUE, plateau_log


@pytest.fixture(scope="module")
def S():
    # a position ripple of 10 % of the level: one cause to find, the rest to screen out
    eff = lambda t, q, w, F: F * (1 + 0.1 * np.sin(2 * np.pi * q / 0.9))
    return build_samples([plateau_log(eff, seed=14, dt=5e-3), plateau_log(eff, seed=15, t0=200.0, dt=5e-3)], 5)


def _base():
    cp, _ = sm.canonical_pair("stribeck", TRUE)
    return Structure("stribeck", cp, ())


def _run(S, monkeypatch, screen: bool):
    monkeypatch.setattr(search, "STRIDE_MIN", 1 << 12)
    monkeypatch.setattr(search, "STRIDE_TARGET", 1 << 12)
    if not screen:
        monkeypatch.setattr(ch.Chain, "_screened", lambda self, ext, m: None)
    c = ch.Chain(S, _base())
    assert c.stride.active
    return c, c.run()


def test_a_screened_candidate_could_not_have_passed_and_the_answer_is_unchanged(S, monkeypatch):
    c1, steps1 = _run(S, monkeypatch, True)
    monkeypatch.undo()
    c0, steps0 = _run(S, monkeypatch, False)
    assert [s["chosen"].ext if s["chosen"] else None for s in steps1] == \
           [s["chosen"].ext if s["chosen"] else None for s in steps0]
    assert steps1[0]["chosen"] is not None and steps1[0]["chosen"].cause == "position"
    screened = 0
    for s1, s0 in zip(steps1, steps0):
        full = {r["extension"]: r for r in s0["tested"]}
        assert [r["extension"] for r in s1["tested"]] == [r["extension"] for r in s0["tested"]]
        for r in s1["tested"]:
            r0 = full[r["extension"]]
            if "screened" not in r:   # tried on all samples: the numbers of the chain without the screen
                assert r == r0
                continue
            screened += 1
            sc = r["screened"]
            assert sc["explained_bound"] < sc["explained_min"] and sc["samples"] < S.n and sc["stride"] >= 2
            # what it explains on all samples is within the bound: it could not have passed
            expl = np.sqrt(max(r0["rms_before"] ** 2 - r0["rms_after"] ** 2, 0.0))
            assert expl <= sc["explained_bound"]
    assert screened >= 5
    # the chosen terms and their held-out numbers are those of the chain without the screen
    for s1, s0 in zip(steps1, steps0):
        if s1["chosen"] is not None:
            assert s1["term"] == s0["term"]
            assert s1["chosen"].rms_after == s0["chosen"].rms_after


def test_a_grid_searched_by_the_screen_is_the_one_the_whole_trial_would_search(S, monkeypatch):
    # a candidate ranked on the stride (search.STRIDE_EXTS) tried on all samples after its screen takes the
    # screen's terms (search.StrideSearch.propose): the terms and numbers of searching again
    monkeypatch.setattr(search, "STRIDE_MIN", 1 << 12)
    monkeypatch.setattr(search, "STRIDE_TARGET", 1 << 12)
    cp, _ = sm.canonical_pair("coulomb_viscous", dict(Fc=2.0, sigma2=1.2))
    c = ch.Chain(S, Structure("coulomb_viscous", cp, ()))   # a base without a Stribeck part: stribeck is tried
    exts = [e for e in ch.candidates(S, c.st, c.ctx) if e in search.STRIDE_EXTS]
    assert "stribeck" in exts
    calls = []
    searched = ch.propose
    monkeypatch.setattr(ch, "propose", lambda ext, *a, **k: calls.append(ext) or searched(ext, *a, **k))
    for ext in exts:
        c._screened(ext, 10)   # the screen's trial searches the grid once per fold
        assert calls.count(ext) == S.n_folds
        tr = c.evaluate(ext, 10)
        assert calls.count(ext) == S.n_folds   # not searched again
        c.stride._proposed.clear()
        tr0 = c.evaluate(ext, 10)   # searched again
        assert calls.count(ext) == 2 * S.n_folds
        assert tr.fold_terms == tr0.fold_terms
        assert (tr.rms_after, tr.t) == (tr0.rms_after, tr0.t)


def test_the_stride_s_own_fits_bound_their_share_where_the_residual_is_large(monkeypatch):
    # a level cycling in time (40 %, outside the list) leaves a residual many times the bar: the fits' share
    # with every training group one unit at the residual's whole variance passes the bar alone, the
    # stride's own in-sample to held-out gap (screen.gap_allowance) does not; a candidate it screens could
    # not have passed, and the chain's answer is that of trying every candidate on all samples
    eff = lambda t, q, w, F: F * (1 + 0.4 * np.sin(2 * np.pi * t / 90.0))
    S = build_samples([plateau_log(eff, seed=14, dt=5e-3), plateau_log(eff, seed=15, t0=200.0, dt=5e-3)], 5)
    gaps, by_gap = [], []
    allowance, screened = ch.gap_allowance, ch.Chain._screened
    monkeypatch.setattr(ch, "gap_allowance", lambda *a: gaps.append(allowance(*a)) or gaps[-1])

    def screening(self, ext, m):
        n = len(gaps)
        rec = screened(self, ext, m)
        if rec is not None and len(gaps) > n:   # the old share kept it, the gap's screened it
            by_gap.append(ext)
        return rec
    monkeypatch.setattr(ch.Chain, "_screened", screening)
    c1, steps1 = _run(S, monkeypatch, True)
    assert by_gap
    monkeypatch.undo()
    c0, steps0 = _run(S, monkeypatch, False)
    assert [s["chosen"] and s["chosen"].ext for s in steps1] == [s["chosen"] and s["chosen"].ext for s in steps0]
    for s1, s0 in zip(steps1, steps0):
        full = {r["extension"]: r for r in s0["tested"]}
        for r in s1["tested"]:
            r0 = full[r["extension"]]
            if "screened" not in r:
                assert r == r0
                continue
            sc = r["screened"]
            expl = np.sqrt(max(r0["rms_before"] ** 2 - r0["rms_after"] ** 2, 0.0))
            assert expl <= sc["explained_bound"] < sc["explained_min"]


def test_a_chain_and_its_screen_go_with_their_last_reference(S, monkeypatch):
    # the screen refers to its full chain weakly: no cycle keeps the diagnosis' samples, folds and caches
    # alive after it (on a joint-hour they were 0.83 GB held through the check, until a garbage collection)
    import gc
    import weakref
    monkeypatch.setattr(search, "STRIDE_MIN", 1 << 12)
    monkeypatch.setattr(search, "STRIDE_TARGET", 1 << 12)
    c = ch.Chain(S, _base())
    sub = c._screen_chain()
    assert sub.full.S is S and sub.full.idx_all.size == S.n
    refs = weakref.ref(c), weakref.ref(sub)
    gc.disable()
    try:
        del c, sub
        assert all(r() is None for r in refs)
    finally:
        gc.enable()
