"""Settings ranked on a stride of the training samples (long logs): a candidate's grid of nonlinear settings
(the Stribeck velocities and exponents, the dwell's rest scale and fading travel, the thermal time constants
and the temperature's source) is ranked by fits on every ``k``-th sliding sample of the training folds;
then the chosen settings (each fold's, in one pass: :meth:`frictid.diagnose.chain.Chain.evaluate`) are
summed on all of them, so every held-out fit, prediction and gain is still on all sliding samples.

Why. A grid's settings are summed in one pass (:meth:`frictid.diagnose.model.Context.prefetch`), but each
setting's columns are formed over all samples and enter the pass's products, and the dwell's and the
thermal terms' refinements take a second pass; on a one-hour log (1.16 M sliding samples) that was about
1.5 s of the 3.6 s of candidates' trials. Ranking a grid needs far fewer samples than judging the chosen
setting: the stride keeps about :data:`STRIDE_TARGET` samples, spread over every group of every training
fold (the samples are in folds and in time within a fold, so every ``k``-th sample keeps about ``1/k`` of
each group's). A log with at most :data:`STRIDE_MIN` sliding samples is searched on all of them, as before
(every test and sample log). Not on the stride: the position torque (its periods include each training
set's periodogram peak, a continuous estimate; ranked on the stride it cost more, the peak estimated
twice), the position ripple and the delay (one estimated setting per training set, no grid).

What it may change: where two settings of a grid nearly tie on the training folds, the stride may rank them
the other way; the held-out judgement of the chosen one is unchanged (docs/diagnosis.md, "Whole logs").
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .model import Context
from .samples import PER_SAMPLE, Samples

#: Candidates whose grid of settings is ranked on the stride.
STRIDE_EXTS = ("stribeck", "dwell", "thermal4", "thermal6")
#: Logs with more sliding samples than this are searched on a stride ...
STRIDE_MIN = 1 << 18
#: ... of about this many samples.
STRIDE_TARGET = 1 << 17


def stride_samples(S: Samples, k: int) -> tuple[Samples, np.ndarray]:
    """Every ``k``-th sample of S (in S's order: fold by fold, in time within a fold) as a :class:`Samples`,
    and their indices in S; the per-log values (sample periods, velocities, heat inputs) are S's."""
    sel = np.arange(0, S.n, k)
    sub = replace(S, **{name: (None if getattr(S, name) is None else getattr(S, name)[sel]) for name in PER_SAMPLE})
    for key, val in S._memo.items():
        if isinstance(key, tuple) and key[0] in ("dt", "log_w", "log_a", "power", "heat_input"):
            sub._memo[key] = val
    return sub, sel


class StrideSearch:
    """The stride of one chain's samples (None-like when the log is short: :attr:`active` False) and its
    own column cache, and each fold's training set and residual on it."""

    def __init__(self, S: Samples):
        self.active = S.n > STRIDE_MIN
        if not self.active:
            return
        k = int(np.ceil(S.n / STRIDE_TARGET))
        self.S = S
        self.sub, self.sel = stride_samples(S, k)
        self.ctx = Context(self.sub)
        self.train = [np.flatnonzero(self.sub.fold != f) for f in range(S.n_folds)]
        #: the last grid search per (candidate, fold): its structure and its term (:meth:`propose`)
        self._proposed: dict = {}

    def propose(self, ext: str, f: int, st, make):
        """Fold f's term of a candidate whose settings are ranked on the stride (:data:`STRIDE_EXTS`), from
        ``make()`` once per structure ``st``: the screen's trial of a long log (:mod:`.screen`, a chain on
        the stride's samples) and the whole chain's trial search the same grid on the same training samples
        of the stride with the same sums (these candidates' searches fit the structure with each setting and
        read neither the residual nor the current coefficients), so a candidate tried on all samples after
        its screen takes the screen's terms instead of searching again (the same terms)."""
        got = self._proposed.get((ext, f))
        if got is not None and got[0] is st:
            return got[1]
        term = make()
        self._proposed[(ext, f)] = (st, term)
        return term

    def wants(self, ext: str) -> bool:
        return self.active and ext in STRIDE_EXTS

    def sync(self, ctx: Context) -> None:
        """Before a proposal: the full samples' rests and their scales (the dwell's grid must be theirs), and
        the current model's columns that cost a pass over the logs (thermal states, term columns: a delay's,
        a thermal term's) taken from the full samples' cache at the stride's samples."""
        from .signals import rest_scales, rests

        S, sub = self.S, self.sub
        self.ctx.full = (ctx, self.sel)
        if "rests" not in sub._memo and S.q is not None:
            tr, sd = rests(S)
            sub._memo["rests"] = (tr[self.sel], sd[self.sel])
            sub._memo["rest_scales"] = rest_scales(S)
        for key, val in ctx._cache.items():
            if (isinstance(key, tuple) and key and key[0] in ("thermal", "term") and key not in self.ctx._cache
                    and isinstance(val, np.ndarray) and val.shape[:1] == (S.n,)):
                self.ctx._cache[key] = val[self.sel]

    def training(self, f: int | None, tr: np.ndarray, res: np.ndarray, lev: np.ndarray) -> tuple:
        """Fold f's training set on the stride (None: all of the stride's samples) and the current model's
        residual and level there (``res`` and ``lev`` on the full training set ``tr``)."""
        idx = self.train[f] if f is not None else np.arange(self.sub.n)
        at = np.searchsorted(tr, self.sel[idx])
        return idx, res[at], lev[at]
