"""The previous move: a competing explanation of a dwell effect built from the move before the current one.

A dwell candidate's variable is the time at rest before a move. On many programs the rests are not
independent of the motion: a point-to-point program waits longer after a long stroke, a duty cycle rests
after its strokes. A level that grows with the previous move (a lubricant film pushed to the ends of a long
stroke, a heated contact) then shows at the start of the next move, fading over its travel, with the
dwell's shape, and the dwell candidate follows it through the rests. Its competitor: the same fade over the
current move's travel, with a free function of the previous move's travel in place of the rest's
logarithm (:func:`previous_columns`); the dwell is refused when the competitor predicts the held-out data
significantly better (:meth:`frictid.diagnose.chain.Chain._not_the_rest`). The residual structure test on
the previous move (:func:`previous_cells`, :mod:`.structure`) states such a level when nothing names it.
"""
from __future__ import annotations

import numpy as np

from ..data import finite
from .binned import PER_BIN, equal_count_bins
from .samples import Samples
from .signals import REST_MIN, _moves, rests


def _cleaned(sg: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The runs of one log's run signs ``sg`` with the short runs taken out, as (first index, sign) per run:
    a rest shorter than :data:`frictid.diagnose.signals.REST_MIN` between two runs of one direction is part
    of the move (a dip of the measured velocity), and a run of motion shorter than that is part of the rest
    around it (a loop hunting at rest, noise across the speed threshold). Worked on the runs (a run that takes
    its neighbour's sign merges with it), not spread over every sample of the log between the two passes."""
    edges = np.flatnonzero(np.concatenate(([True], sg[1:] != sg[:-1])))
    sgr = sg[edges]
    for pass_ in (0, 1):
        ends = np.concatenate((edges[1:], [sg.size]))
        length = t[np.minimum(ends, sg.size - 1)] - t[edges]
        if pass_ == 0:   # dips within a move
            dip = (sgr == 0) & (length < REST_MIN)
            dip[[0, -1]] = False
            dip[1:-1] &= (sgr[:-2] == sgr[2:]) & (sgr[:-2] != 0)
            short = dip
            fill = np.concatenate(([0.0], sgr[:-1]))
        else:            # twitches at rest
            short = (sgr != 0) & (length < REST_MIN)
            fill = np.zeros(sgr.size)
        vals = np.where(short, fill, sgr)
        first = np.concatenate(([True], vals[1:] != vals[:-1]))   # runs that now carry one sign merge
        edges, sgr = edges[first], vals[first]
    return edges, sgr


def previous_travel(S: Samples) -> np.ndarray:
    """Per sliding sample: the travel [q] of the move before the current one (across a rest of any length,
    or at a reversal), NaN where there is none: the first move of a log, and a run that starts after a dip of
    the measured velocity in the same direction (a move cut in two: the dwell's variable is 0 there). Moves
    and rests as :func:`_cleaned` leaves them (cached)."""
    def compute():
        out = np.full(S.n, np.nan)
        for i, lg in enumerate(S.logs):
            sel = S.li == i
            if not sel.any() or lg.q is None:
                continue
            k = S.k[sel]
            sg, st, pv = _moves(S.log_w(i), S.v_min, k)
            edges, sgr = _cleaned(sg, lg.t)
            q = finite(lg.q)
            ends = np.concatenate((edges[1:], [sg.size - 1]))
            travel = np.abs(q[ends] - q[edges])
            # the move before each run: the run before it, or the one before a rest
            j = np.arange(edges.size) - 1
            j = np.where((j >= 0) & (sgr[np.maximum(j, 0)] == 0), j - 1, j)
            prev_travel = np.where((j >= 0) & (sgr != 0), travel[np.maximum(j, 0)], np.nan)
            val = prev_travel[np.searchsorted(edges, k, side="right") - 1]
            # a raw run that starts after a dip in its own direction: not a move's start
            cut = (pv >= 0) & (st > 0)
            cut[cut] &= (sg[st[cut] - 1] == 0) & (pv[cut] >= 1)
            cut[cut] &= (sg[np.maximum(pv[cut] - 1, 0)] == sg[st[cut]]) & (lg.t[st[cut]] - lg.t[pv[cut]] < REST_MIN)
            val[cut] = np.nan
            out[sel] = val
        return out
    return S.cached("previous_travel", compute)


#: Equal-count bins of the previous move's travel over the moves (each bin a free height of the fade): at most
#: this many ...
PREVIOUS_BINS = 8
#: ... and at least this many moves to a bin (a height estimated from a few moves follows their rests, not
#: their previous travel: the free function would carry the dwell's own variable), at least 2 bins.
MOVES_PER_BIN = 25


def _previous_bins(S: Samples) -> np.ndarray:
    """Bin index per sample of :func:`previous_travel` (bins of about equal count of moves, their number from
    the moves: :data:`MOVES_PER_BIN`, :data:`PREVIOUS_BINS`), -1 where there is no previous move (cached)."""
    def compute():
        x = previous_travel(S)
        ok = np.isfinite(x)
        b = np.full(S.n, -1, np.int64)
        if not ok.any():
            return b
        # one value per move: its first sliding sample (the travel since the move started falls, or a log begins)
        _, s = rests(S)
        first = np.concatenate(([True], (np.diff(s) < 0) | (np.diff(S.li) != 0))) & ok
        nb = int(np.clip(np.count_nonzero(first) // MOVES_PER_BIN, 2, PREVIOUS_BINS))
        edges = np.unique(np.quantile(x[first], np.linspace(0, 1, nb + 1)[1:-1]))
        b[ok] = np.searchsorted(edges, x[ok], side="right")
        return b
    return S.cached("previous_bins", compute)


def previous_columns(S: Samples, s_c: float) -> np.ndarray:
    """The competitor's columns (n x bins, level factor): the dwell's fade over the current move's travel
    ``exp(-s / s_c)`` in the bin of the previous move's travel (:func:`_previous_bins`), 0 where there is no
    previous move: a level that grows with the previous move by a free function of its travel, fading as the
    dwell does."""
    b = _previous_bins(S)
    ok = b >= 0
    m = int(b.max()) + 1 if ok.any() else 1
    out = np.zeros((S.n, m))
    _, s = rests(S)
    out[np.flatnonzero(ok), b[ok]] = np.exp(-s[ok] / s_c)
    return out


def previous_cells(S: Samples) -> np.ndarray | None:
    """Cell index per sample for the residual structure test (:mod:`.structure`): the bin of the previous
    move's travel (:func:`_previous_bins`, "no previous move" a bin of its own) by the current move's
    direction (a level that follows the previous move moves the friction torque with the direction of
    motion) by equal-count bins of the travel since the move started (the level shows at a move's start and
    fades over its travel: averaged over the whole move it is diluted); 2..8 travel bins, about
    :data:`frictid.diagnose.binned.PER_BIN` samples a cell. None without positions (cached)."""
    if S.q is None or np.ptp(S.q) <= 0:
        return None

    def compute():
        pb = _previous_bins(S)
        code = (pb + 1) * 2 + (S.w > 0)
        n_code = 2 * (int(pb.max()) + 2)
        nb = int(np.clip(S.n // (PER_BIN * n_code), 2, 8))
        _, s = rests(S)
        return code * nb + equal_count_bins(s, nb)[0]
    return S.cached("previous_cells", compute)
