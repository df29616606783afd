"""Duty cycles: stretches where the same motion pattern repeats at a constant period (002 section V).

A duty cycle starts when the joint starts moving after a stop; successive cycles start one period later
and repeat the same velocity profile. The search works on onsets of motion, not on samples:

1. *onsets*: starts of motion after a still stretch of at least ``gap_min`` samples;
2. *candidate periods* from an onset: the distances to the next ``LOOKAHEAD`` onsets, and, when the
   onset opens a long stretch of motion without rests (a joint that never stops between cycles), the
   lags where the autocorrelation of that stretch's velocity peaks;
3. *chains*: a chain goes on while the velocity over the next period matches the one before (relative
   RMS difference at most ``R_SHAPE``); the next cycle starts at an onset one period later (within
   ``tol``) or, in continuous motion, exactly one period later. Of the chains of at least ``MIN_CYCLES``
   cycles from an onset (or from an onset within its first period), the one covering the longest time
   wins, then the shortest period; earlier cycles with the same profile are prepended (a run's first
   cycle follows the run's own approach, not a cycle's rest);
4. *whole cycles*: a chain whose cycle repeats the first part of a longer chain's cycle, with a period
   that divides it (a joint moving in every slot of its cycle: nothing marks where a cycle starts), takes
   the longer period.
"""
from __future__ import annotations

import numpy as np

from .runs import fill_short, runs

#: Fewest cycles that make a duty-cycle run.
MIN_CYCLES = 3
#: Largest relative RMS difference between the velocity profiles of two successive cycles.
R_SHAPE = 0.25
#: Most later onsets tried as the start of the next cycle.
LOOKAHEAD = 64
#: Relative tolerance of the period (onset jitter is covered by ``tol`` samples too).
R_PERIOD = 0.005
#: Autocorrelation peaks above this value give candidate periods in continuous motion.
R_AUTOCORR = 0.8
#: Points per cycle compared (the velocity is decimated to this many).
N_PROFILE = 2000


def motion_onsets(moving: np.ndarray, gap_min: int) -> np.ndarray:
    """Onsets (sample indices) of motion after a still stretch of at least ``gap_min`` samples, or at
    the start of the log."""
    s, e = runs(moving)
    if s.size == 0:
        return s
    prev_end = np.concatenate(([0], e[:-1]))
    keep = ((s - prev_end) >= gap_min) | (s == 0)
    return s[keep]


def _difference(w: np.ndarray, a: int, b: int, P: int) -> float:
    """Relative RMS difference of the velocity over ``[a, a+P)`` and ``[b, b+P)`` (inf if outside)."""
    stride = max(1, P // N_PROFILE)
    if a < 0 or b < 0 or max(a, b) + P > w.size:
        return np.inf
    x, y = w[a:a + P:stride], w[b:b + P:stride]
    scale = max(float(np.sqrt(np.mean(x * x))), float(np.sqrt(np.mean(y * y))))
    if scale <= 0:
        return np.inf
    return float(np.sqrt(np.mean((x - y) ** 2))) / scale


def _similar(w: np.ndarray, a: int, b: int, P: int) -> bool:
    """Velocity over ``[a, a+P)`` and ``[b, b+P)`` agree within ``R_SHAPE`` (relative RMS)."""
    return _difference(w, a, b, P) <= R_SHAPE


def _next_start(onsets: np.ndarray, w: np.ndarray, prev: int, target: int, P: int, tol: int,
                virtual: bool) -> int | None:
    """Start of the cycle after the one at ``prev``: the onset within ``tol`` of ``target`` or, when
    ``virtual``, ``target`` itself, whichever repeats the previous cycle best; None if none does."""
    cands = [target] if virtual else []
    j = int(np.searchsorted(onsets, target - tol))
    if j < onsets.size and abs(int(onsets[j]) - target) <= tol and int(onsets[j]) > prev:
        cands.append(int(onsets[j]))
    if not cands:
        return None
    diffs = [_difference(w, prev, c, P) for c in cands]
    k = int(np.argmin(diffs))
    return cands[k] if diffs[k] <= R_SHAPE else None


def _chain(onsets: np.ndarray, w: np.ndarray, start: int, P: int, tol: int, virtual: bool) -> list[int]:
    """Cycle starts of the chain from ``start`` with period ``P`` samples."""
    chain = [start]
    period = float(P)
    while True:
        nxt = _next_start(onsets, w, chain[-1], int(round(chain[-1] + period)), P, tol, virtual)
        if nxt is None:
            return chain
        chain.append(nxt)
        period = (chain[-1] - chain[0]) / (len(chain) - 1)


def _extend_back(onsets: np.ndarray, w: np.ndarray, chain: list[int], P: int, tol: int, floor: int
                 ) -> list[int]:
    """Prepend earlier cycles with the same profile: at an onset one period back, or exactly one period
    back when the joint was already moving (the run's first cycle follows its approach move)."""
    out = list(chain)
    while True:
        target = out[0] - P
        if target - tol < max(0, floor):
            return out
        cands = [target]
        j = int(np.searchsorted(onsets, target - tol))
        if j < onsets.size and abs(int(onsets[j]) - target) <= tol and int(onsets[j]) < out[0]:
            cands.append(int(onsets[j]))
        diffs = [_difference(w, c, out[0], P) for c in cands]
        k = int(np.argmin(diffs))
        if diffs[k] > R_SHAPE:
            return out
        out.insert(0, cands[k])


def _autocorr_periods(w: np.ndarray, a: int, b: int, p_min: int) -> list[int]:
    """Lags [samples] of the autocorrelation peaks (above ``R_AUTOCORR``) of the velocity over
    ``[a, b)``, at most ``(b - a) / MIN_CYCLES`` long."""
    L = b - a
    stride = max(1, L // 65536)
    x = w[a:b:stride]
    m = x.size
    if m < 8:
        return []
    nfft = 1 << int(np.ceil(np.log2(2 * m)))
    spec = np.fft.rfft(x, nfft)
    ac = np.fft.irfft(spec * np.conj(spec), nfft)[:m]
    overlap = np.arange(m, 0, -1, dtype=float)
    e = np.cumsum((x * x)[::-1])[::-1]  # energy of the tail x[k:]
    e_head = np.cumsum(x * x)[::-1]     # energy of x[:m-k]
    norm = np.sqrt(np.maximum(e * e_head, 1e-300))
    r = ac / norm
    lo = max(2, p_min // stride)
    hi = m // MIN_CYCLES
    if hi <= lo + 2:
        return []
    seg = r[lo:hi]
    peak = (seg[1:-1] > seg[:-2]) & (seg[1:-1] >= seg[2:]) & (seg[1:-1] >= R_AUTOCORR)
    lags = (np.flatnonzero(peak) + 1 + lo) * stride
    del overlap
    return [int(v) for v in lags[:8]]


def _best_chain(onsets: np.ndarray, w: np.ndarray, i: int, tol_min: int, extra: list[int]):
    """(cover, starts, period) of the best chain from onset ``i``, or None."""
    n = w.size
    start = int(onsets[i])
    # continuous-motion periods first: a chain allowed to continue without onsets covers the same
    # cycles as one that needs them, and more
    cands = [(p, True) for p in extra]
    cands += [(int(onsets[j] - start), False) for j in range(i + 1, min(onsets.size, i + 1 + LOOKAHEAD))]
    best = None
    tried: list[int] = []
    for P, virtual in cands:
        if P <= 0 or start + MIN_CYCLES * P > n + tol_min:
            continue
        tol = max(tol_min, int(R_PERIOD * P))
        if any(abs(P - p) <= tol for p in tried):
            continue
        tried.append(P)
        ch = _chain(onsets, w, start, P, tol, virtual)
        if len(ch) < MIN_CYCLES:
            continue
        cover = ch[-1] + P - start
        if best is None or cover > best[0] + 2 * tol or (cover >= best[0] - 2 * tol and P < best[2]):
            best = (cover, ch, P)
    return best


def find_chains(w: np.ndarray, moving: np.ndarray, gap_min: int, rest_min: int, tol_min: int
                ) -> list[tuple[np.ndarray, int]]:
    """Duty-cycle chains: (cycle start samples, period in samples).

    w : velocity. moving : motion mask. gap_min : shortest stop that marks an onset [samples].
    rest_min : shortest rest that separates two stretches of motion [samples]. tol_min : onset jitter.
    """
    n = w.size
    onsets = motion_onsets(moving, gap_min)
    if onsets.size == 0:
        return []
    # stretches of motion without a rest: their starts may open cycles that never stop
    bs, be = runs(fill_short(moving, rest_min, False))
    block_end = {int(s): int(e) for s, e in zip(bs, be)}
    claimed = -1
    chains: list[tuple[np.ndarray, int]] = []
    i = 0
    while i < onsets.size:
        if onsets[i] < claimed:
            i += 1
            continue
        best, bi = None, i
        k = i
        while k < onsets.size and (k == i or (best is not None and onsets[k] < onsets[i] + best[2])):
            extra = []
            e = block_end.get(int(onsets[k]))
            if e is not None and e - onsets[k] >= MIN_CYCLES * 2 * gap_min:
                extra = _autocorr_periods(w, int(onsets[k]), e, 2 * gap_min)
            cand = _best_chain(onsets, w, k, tol_min, extra)
            if cand is not None and (best is None or cand[0] > best[0] + 2 * tol_min):
                best, bi = cand, k
            k += 1
        if best is None:
            i += 1
            continue
        _, ch, P = best
        ch = _extend_back(onsets, w, ch, P, max(tol_min, int(R_PERIOD * P)), claimed)
        starts = np.asarray(ch, dtype=np.int64)
        period = int(round((starts[-1] - starts[0]) / (starts.size - 1)))
        chains.append((starts, period))
        claimed = int(starts[-1] + period)
        i = max(bi, int(np.searchsorted(onsets, claimed)))
    return _whole_cycles(chains, w)


def _whole_cycles(chains: list[tuple[np.ndarray, int]], w: np.ndarray) -> list[tuple[np.ndarray, int]]:
    """A chain of period P whose cycle repeats the first P of another chain's period Q = m P (the joint
    moves in every slot of a Q cycle, so nothing marks the cycle start) takes the period Q."""
    out = []
    for starts, P in chains:
        best_q = None
        for other, Q in chains:
            m = round(Q / P)
            if m < 2 or abs(Q - m * P) > max(2.0, R_PERIOD * Q):
                continue
            if not _similar(w, int(starts[0]), int(other[0]), P):
                continue
            best_q = Q if best_q is None else max(best_q, Q)
        if best_q is not None:
            m = int(round(best_q / P))
            if starts[::m].size >= MIN_CYCLES:
                out.append((starts[::m], int(best_q)))
                continue
        out.append((starts, P))
    return out


def duty_cycles(w: np.ndarray, moving: np.ndarray, gap_min: int, rest_min: int, tol_min: int
                ) -> list[tuple[int, int, int]]:
    """(start, end, cycle index) of every duty cycle; indices count on across the log's chains. A cycle
    ends where the next one of its chain starts, the last one a period after its start."""
    out = []
    k = 0
    n = w.size
    for starts, P in find_chains(w, moving, gap_min, rest_min, tol_min):
        ends = np.concatenate((starts[1:], [starts[-1] + P]))
        for s, e in zip(starts, ends):
            out.append((int(s), int(min(n, e)), k))
            k += 1
    return out
