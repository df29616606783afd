"""Duty cycles: stretches where the same motion pattern repeats at a constant period (002 section V).

A duty cycle starts when the joint starts moving after a stop; successive cycles start one period later
and repeat the same velocity profile. The search works on onsets of motion, not on samples:

1. *onsets*: starts of motion after a still stretch of at least ``gap_min`` samples;
2. *candidate periods* from an onset: the distances to the next ``LOOKAHEAD`` onsets, and, when the
   onset opens a long stretch of motion without rests (a joint that never stops between cycles), the
   lags where the autocorrelation of that stretch's velocity peaks;
3. *chains*: a chain goes on while the velocity over the next period matches the one before (relative
   RMS difference at most ``R_SHAPE``) and its RMS that of the chain's first cycle within a factor
   ``1 + R_SHAPE`` (the same motion repeats, where a sweep's cycles drift, each a little faster); the next cycle starts at an onset one period later (within
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
from numba import njit, types as nt

from .runs import count_prefix, fill_short, paint, runs

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
#: Autocorrelation peaks of the whole log's velocity above this value are tried as periods everywhere.
R_AUTOCORR_LOG = 0.3
#: Points per cycle compared (the velocity is decimated to this many).
N_PROFILE = 2000
#: A stop: the joint stays within this share of its cycle's travel (``detect.R_STILL`` for speeds).
R_STOP = 0.01


def motion_onsets(moving: np.ndarray, gap_min: int) -> tuple[np.ndarray, np.ndarray]:
    """Onsets (sample indices) of motion after a still stretch of at least ``gap_min`` samples, and the
    length of that still stretch. The first motion is an onset however few still samples precede it:
    the stretch before it is cut by the start of the record (a cycle searched on its own starts where a
    chain put it, a sample or two before its motion), so its length is unknown, not short."""
    s, e = runs(moving)
    if s.size == 0:
        return s, s
    prev_end = np.concatenate(([0], e[:-1]))
    gap = s - prev_end
    keep = gap >= gap_min
    keep[0] = True
    return s[keep], gap[keep]


class _Signal:
    """The velocity, with cumulative counts of resting samples (inside still stretches of at least
    ``rest_min`` samples) and of moving samples."""

    def __init__(self, w: np.ndarray, moving: np.ndarray, rest_min: int):
        self.w = w
        self.size = w.size
        s, e = runs(~moving)
        long = (e - s) >= rest_min
        resting = np.zeros(w.size, dtype=bool)
        paint(resting, s[long], e[long], True)
        self.rests = count_prefix(resting)
        self.moves = count_prefix(moving)
        self.x = np.cumsum(w)  # position in units of the velocity times a sample period

    def stop_before(self, o: int, c: int) -> int:
        """Samples before ``o`` (back to ``c`` at most) over which the joint stays within ``R_STOP`` of
        the travel of ``[c, o)`` from where it is at ``o``: a stop is read by how far the joint goes,
        whatever small jerks it makes on the spot."""
        x = self.x[c:o + 1]
        if x.size < 2:
            return 0
        far = np.flatnonzero(np.abs(x[:-1] - x[-1]) > R_STOP * float(np.ptp(x)))
        return int(x.size - 1 - (far[-1] + 1 if far.size else 0))

    def rest_and_motion(self, a: int, b: int) -> bool:
        """The window ``[a, b)`` holds part of a rest and some motion."""
        a, b = max(a, 0), min(b, self.size)
        return bool(self.rests[b] - self.rests[a] > 0 and self.moves[b] - self.moves[a] > 0)


def _difference(sig: _Signal, a: int, b: int, P: int) -> float:
    """Relative RMS difference of the velocity over ``[a, a+P)`` and ``[b, b+P)``; inf if a window is
    outside the log or does not hold both motion and part of a rest (duty cycles alternate motion and
    rest; a plateau or a smooth excitation repeats too, but never rests)."""
    return _difference_nb(sig.w, sig.rests, sig.moves, a, b, P)


# The chain search below is the inner loop of the duty-cycle detection (thousands of candidate chains
# per log): compiled, with the python twins ``_chain_nb.py_func`` etc. for reading and testing.

@njit(cache=True)
def _difference_nb(w, rests, moves, a, b, P):  # pragma: no cover - compiled
    """:func:`_difference` on the arrays of a :class:`_Signal`."""
    n = w.size
    if a < 0 or b < 0 or max(a, b) + P > n:
        return np.inf
    for s in (a, b):
        e = min(s + P, n)
        if rests[e] - rests[s] <= 0 or moves[e] - moves[s] <= 0:
            return np.inf
    return _rel_rms(w, a, b, P, max(1, P // N_PROFILE))


@njit(cache=True)
def _rel_rms(w, a, b, P, stride):  # pragma: no cover - compiled
    """RMS of ``w[a:a+P:stride] - w[b:b+P:stride]`` over the larger RMS of the two; inf when both are 0.
    One pass, no temporaries."""
    sxx = syy = sdd = 0.0
    for k in range(0, P, stride):
        x = w[a + k]
        y = w[b + k]
        sxx += x * x
        syy += y * y
        sdd += (x - y) * (x - y)
    scale = max(sxx, syy)
    if scale <= 0.0:
        return np.inf
    return np.sqrt(sdd / scale)


@njit(cache=True)
def _rms_ratio(w, a, b, P):  # pragma: no cover - compiled
    """Ratio (at least 1) of the RMS velocities over ``[a, a+P)`` and ``[b, b+P)``; inf when one is 0."""
    stride = max(1, P // N_PROFILE)
    sxx = syy = 0.0
    for k in range(0, P, stride):
        sxx += w[a + k] * w[a + k]
        syy += w[b + k] * w[b + k]
    if sxx <= 0.0 or syy <= 0.0:
        return np.inf
    return np.sqrt(max(sxx, syy) / min(sxx, syy))


def _similar(w: _Signal, a: int, b: int, P: int) -> bool:
    """Velocity over ``[a, a+P)`` and ``[b, b+P)`` agree within ``R_SHAPE`` (relative RMS)."""
    return _difference(w, a, b, P) <= R_SHAPE


@njit(cache=True)
def _next_start_nb(onsets, w, rests, moves, prev, target, P, tol, virtual):  # pragma: no cover
    """Start of the cycle after the one at ``prev``: the onset within ``tol`` of ``target`` or, when
    ``virtual``, ``target`` itself, whichever repeats the previous cycle best (the target on a tie);
    -1 if none does."""
    best, best_d = -1, np.inf
    if virtual:
        best, best_d = target, _difference_nb(w, rests, moves, prev, target, P)
    j = 0  # the first onset at or after target - tol (np.searchsorted by bisection)
    hi = onsets.size
    while j < hi:
        mid = (j + hi) >> 1
        if onsets[mid] < target - tol:
            j = mid + 1
        else:
            hi = mid
    if j < onsets.size and abs(onsets[j] - target) <= tol and onsets[j] > prev:
        d = _difference_nb(w, rests, moves, prev, onsets[j], P)
        if best < 0 or d < best_d:
            best, best_d = onsets[j], d
    if best < 0 or not best_d <= R_SHAPE:
        return -1
    return best


@njit(cache=True)
def _chain_nb(onsets, w, rests, moves, start, P, tol, virtual):  # pragma: no cover - compiled
    """Cycle starts of the chain from ``start`` with period ``P`` samples (see :func:`_chain`). The starts
    are kept in an array that doubles when full (a list compiled numba's reflected-list code, and
    ``np.searchsorted`` its generic comparison code: half a second of a first run's compilation)."""
    chain = np.empty(16, dtype=np.int64)
    chain[0] = start
    m = 1
    period = float(P)
    while True:
        nxt = _next_start_nb(onsets, w, rests, moves, chain[m - 1], int(np.rint(chain[m - 1] + period)), P, tol,
                             virtual)
        # a duty cycle repeats the same motion: every cycle moves as fast as the chain's first one (a
        # sweep's cycles drift, each a little faster than the one before)
        if nxt < 0 or _rms_ratio(w, chain[0], nxt, P) > 1.0 + R_SHAPE:
            out = np.empty(m, dtype=np.int64)
            for i in range(m):
                out[i] = chain[i]
            return out
        if m == chain.size:
            grown = np.empty(2 * m, dtype=np.int64)
            for i in range(m):
                grown[i] = chain[i]
            chain = grown
        chain[m] = nxt
        m += 1
        period = (chain[m - 1] - chain[0]) / (m - 1)


def _chain(onsets: np.ndarray, w: _Signal, start: int, P: int, tol: int, virtual: bool) -> list[int]:
    """Cycle starts of the chain from ``start`` with period ``P`` samples: the next cycle starts at the
    onset within ``tol`` of one (mean) period later or, when ``virtual``, exactly there, whichever repeats
    the previous cycle better (relative RMS difference at most ``R_SHAPE``)."""
    return [int(v) for v in _chain_nb(onsets, w.w, w.rests, w.moves, int(start), int(P), int(tol), bool(virtual))]


def _extend_back(onsets: np.ndarray, w: _Signal, chain: list[int], P: int, tol: int, floor: int
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
        diffs = [_difference(w, c, out[0], P) if _rms_ratio(w.w, c, chain[0], P) <= 1.0 + R_SHAPE else np.inf
                 for c in cands]
        k = int(np.argmin(diffs))
        if diffs[k] > R_SHAPE:
            return out
        out.insert(0, cands[k])


def _autocorr_periods(w: np.ndarray, a: int, b: int, p_min: int, level: float = R_AUTOCORR,
                      most: int = 8) -> list[int]:
    """Lags [samples] of the autocorrelation peaks (above ``level``, the ``most`` highest) of the
    velocity over ``[a, b)``, at most ``(b - a) / MIN_CYCLES`` long. The velocity is averaged in bins so
    that at most 2^16 points are transformed."""
    L = b - a
    stride = max(1, L // 65536)
    m = L // stride
    if m < 8:
        return []
    x = w[a:a + m * stride].reshape(m, stride).mean(axis=1)
    nfft = 1 << int(np.ceil(np.log2(2 * m)))
    spec = np.fft.rfft(x, nfft)
    ac = np.fft.irfft(spec * np.conj(spec), nfft)[:m]
    xx = x * x
    tail = np.cumsum(xx[::-1])[::-1]          # energy of x[k:]
    head = np.cumsum(xx)[::-1]                # energy of x[:m-k]
    r = ac / np.sqrt(np.maximum(tail * head, 1e-300))
    lo = max(2, p_min // stride)
    hi = m // MIN_CYCLES
    if hi <= lo + 2:
        return []
    seg = r[lo:hi]
    peak = np.flatnonzero((seg[1:-1] > seg[:-2]) & (seg[1:-1] >= seg[2:]) & (seg[1:-1] >= level)) + 1
    if peak.size > most:
        peak = peak[np.argsort(seg[peak])[::-1][:most]]
    return [int(v) for v in np.sort((peak + lo) * stride)]


def _best_chain(onsets: np.ndarray, w: _Signal, i: int, tol_min: int, extra: list[int], p_min: int):
    """(cover, starts, period) of the best chain from onset ``i``, or None: of the candidate periods (the
    ``extra`` ones, then the distances to the next :data:`LOOKAHEAD` onsets), each not within its
    tolerance of one tried before, the chain of at least :data:`MIN_CYCLES` cycles that covers the most
    (the shorter period where two cover the same within twice its tolerance). The loop is compiled
    (:func:`_best_chain_nb`: hundreds of onsets a log, dozens of periods each)."""
    start = int(onsets[i])
    ahead = [int(onsets[j] - start) for j in range(i + 1, min(onsets.size, i + 1 + LOOKAHEAD))]
    cands = np.array(list(extra) + ahead, dtype=np.int64)
    cover, P, ch = _best_chain_nb(onsets, w.w, w.rests, w.moves, start, cands, int(p_min), int(tol_min))
    return None if P < 0 else (int(cover), [int(v) for v in ch], int(P))


@njit(cache=True)
def _best_chain_nb(onsets, w, rests, moves, start, cands, p_min, tol_min):  # pragma: no cover - compiled
    """:func:`_best_chain`'s loop: (cover, period, chain starts), the period -1 when no chain is found."""
    tried = np.empty(cands.size, dtype=np.int64)  # sorted, the first nt
    nt = 0
    best_cover, best_P, best_ch = 0, -1, np.empty(0, dtype=np.int64)
    for P in cands:
        if P < p_min or start + MIN_CYCLES * P > w.size + tol_min:
            continue
        tol = max(tol_min, int(R_PERIOD * P))
        j = 0  # the first period tried at or above P - tol (np.searchsorted by bisection)
        hi = nt
        while j < hi:
            mid = (j + hi) >> 1
            if tried[mid] < P - tol:
                j = mid + 1
            else:
                hi = mid
        if j < nt and tried[j] <= P + tol:  # a period within tol was tried already
            continue
        k = nt
        while k > 0 and tried[k - 1] > P:
            tried[k] = tried[k - 1]
            k -= 1
        tried[k] = P
        nt += 1
        ch = _chain_nb(onsets, w, rests, moves, start, P, tol, True)
        if ch.size < MIN_CYCLES:
            continue
        cover = ch[-1] + P - start
        if best_P < 0 or cover > best_cover + 2 * tol or (cover >= best_cover - 2 * tol and P < best_P):
            best_cover, best_P, best_ch = cover, P, ch
    return best_cover, best_P, best_ch


#: The kernel with its signature (numba types), for :func:`frictid.api.compile_kernels`.
KERNELS = ((_best_chain_nb, (nt.int64[::1], nt.float64[::1], nt.int32[::1], nt.int32[::1], nt.int64, nt.int64[::1],
                             nt.int64, nt.int64)),)


def _settle(onsets: np.ndarray, w: _Signal, ch: list[int], P: int, tol_min: int, p_min: int) -> tuple[list[int], int]:
    """Fundamental period and phase of a chain. Period: the shortest P / m that chains as far from the
    second cycle on (the first may hold the run's approach). Phase: of the onsets within the first
    period from which the next period repeats about as well as it does from the best such onset, the
    one that follows the cycle's rest (:func:`_after_longest_rest`), the earliest of equals (the run
    starts where the repetition starts)."""
    if len(ch) < 2:
        return ch, P
    end = ch[-1] + P
    anchor = ch[1]
    for m in range(6, 1, -1):
        q = int(round(P / m))
        if q < p_min:
            continue
        tol = max(tol_min, int(R_PERIOD * q))
        sub = _chain(onsets, w, anchor, q, tol, True)
        if sub[-1] + q >= end - tol and len(sub) >= MIN_CYCLES:
            P = q
            break
    lo = int(np.searchsorted(onsets, ch[0]))
    hi = int(np.searchsorted(onsets, ch[0] + P))
    cands = [int(c) for c in onsets[lo:hi]] or [ch[0]]
    diffs = np.array([_difference(w, c, c + P, P) for c in cands])
    if np.all(~np.isfinite(diffs)):
        return ch, P
    best = float(np.nanmin(diffs))
    ok = np.flatnonzero(diffs <= max(2.0 * best, best + 0.05))
    tol = max(tol_min, int(R_PERIOD * P))
    start = cands[int(ok[_after_longest_rest(onsets, w, [cands[k] for k in ok], P, tol)])]
    out = _chain(onsets, w, start, P, tol, True)
    if len(out) < MIN_CYCLES:
        return ch, P
    return out, P


def _after_longest_rest(onsets: np.ndarray, w: _Signal, cands: list[int], P: int, tol: int) -> int:
    """Index into ``cands`` (onsets within a chain's first period) of the one where a cycle starts: a duty
    cycle is motion, then rest, so it starts where the motion starts after the cycle's longest stop. The
    stop is read one period later (the first cycle may follow the run's own approach and its dwell):
    before the onset within ``tol`` of ``c + P`` (0 where no onset is there), as far back as the joint
    stays where that motion starts (:meth:`_Signal.stop_before`), not the contiguous still samples: a
    loop hunting in stick-slip blips of a fraction of a mrad splits a rest into stops shorter than the
    cycle's dwell (foreign card 100821). The earliest of the candidates whose stop is within ``2 tol``
    of the longest (a cycle with two equal stops: the run starts where the repetition starts)."""
    rest = np.zeros(len(cands), dtype=np.int64)
    for k, c in enumerate(cands):
        j = int(np.searchsorted(onsets, c + P - tol))
        if j < onsets.size and abs(int(onsets[j]) - (c + P)) <= tol:
            rest[k] = w.stop_before(int(onsets[j]), c)
    return int(np.flatnonzero(rest >= rest.max() - 2 * tol)[0])


def find_chains(w: np.ndarray, moving: np.ndarray, gap_min: int, rest_min: int, tol_min: int
                ) -> list[tuple[np.ndarray, int]]:
    """Duty-cycle chains: (cycle start samples, period in samples).

    w : velocity. moving : motion mask. gap_min : shortest stop that marks an onset [samples].
    rest_min : shortest rest that separates two stretches of motion [samples]. tol_min : onset jitter.

    A duty cycle contains no experiment of another kind: a chain whose cycle holds a run of shorter
    duty cycles and motion outside it (:func:`_session`: a session of experiments, a sweep, a duty-cycle
    run, a sweep, repeated once per payload) is no duty cycle; its cycles are searched one by one.
    """
    out: list[tuple[np.ndarray, int]] = []
    for starts, P in _search_chains(w, moving, gap_min, rest_min, tol_min):
        inner = _session(w, moving, starts, P, (gap_min, rest_min, tol_min))
        out.extend([(starts, P)] if inner is None else inner)
    return out


def _session(w: np.ndarray, moving: np.ndarray, starts: np.ndarray, P: int, args: tuple[int, int, int]
             ) -> list[tuple[np.ndarray, int]] | None:
    """The duty-cycle runs inside the cycles of the chain (``starts``, period ``P``) when its cycle is a
    session of experiments, else None. A session: one of its cycles (the second: the first may hold the
    run's approach) holds a run of at least ``MIN_CYCLES`` shorter cycles, and the joint moves outside
    that run for at least ``rest_min`` samples (``T_MIN``; a cycle that is all its shorter repetitions
    is one duty cycle with several moves, :func:`_whole_cycles`)."""
    n = w.size
    probe = int(starts[1])
    if not _holds_other_motion(w[probe:min(n, probe + P)], moving[probe:min(n, probe + P)], args):
        return None
    ends = np.concatenate((starts[1:], [starts[-1] + P]))
    out = []
    for s, e in zip(starts.tolist(), np.minimum(ends, n).tolist()):
        out += [(st + s, p) for st, p in find_chains(w[s:e], moving[s:e], *args)]
    return out


def _holds_other_motion(w: np.ndarray, moving: np.ndarray, args: tuple[int, int, int]) -> bool:
    """The stretch holds a duty-cycle run and at least ``rest_min`` moving samples outside it. The run
    reaches over the periods (or the part of one left at the stretch's ends) next to it whose velocity
    repeats its end cycles (within ``R_SHAPE``, rest or not: a joint moving in every slot of its cycle
    has no rest in the last slot, and the run of slots stops one short of the cycle)."""
    inner = find_chains(w, moving, *args)
    if not inner:
        return False
    n = w.size
    covered = np.zeros(n, dtype=bool)
    for st, p in inner:
        a, b = int(st[0]), int(st[-1]) + p
        stride = max(1, p // N_PROFILE)
        while b < n and _rel_rms(w, b - p, b, min(p, n - b), stride) <= R_SHAPE:  # the end: part of a period
            b += min(p, n - b)
        while a > 0 and _rel_rms(w, a - min(p, a), a + p - min(p, a), min(p, a), stride) <= R_SHAPE:
            a -= min(p, a)
        covered[a:min(b, n)] = True
    return int(np.count_nonzero(moving & ~covered)) >= args[1]


def _search_chains(w: np.ndarray, moving: np.ndarray, gap_min: int, rest_min: int, tol_min: int
                   ) -> list[tuple[np.ndarray, int]]:
    """The chains of :func:`find_chains` before the session test."""
    n = w.size
    onsets, gaps = motion_onsets(moving, gap_min)
    if onsets.size == 0:
        return []
    onsets = onsets.astype(np.int64)
    # periods that repeat somewhere in the log, and stretches of motion without a rest (their starts
    # may open cycles that never stop)
    common = _autocorr_periods(w, 0, n, 2 * gap_min, R_AUTOCORR_LOG, 16)
    raw = w
    w = _Signal(raw, moving, rest_min)  # noqa: PLW2901 - the chain functions take the signal object
    bs, be = runs(fill_short(moving, rest_min, False))
    block_end = {int(s): int(e) for s, e in zip(bs, be)}
    claimed = -1
    acf: dict[tuple[int, int], list[int]] = {}
    chains: list[tuple[np.ndarray, int]] = []
    i = 0
    while i < onsets.size:
        if onsets[i] < claimed:
            i += 1
            continue
        best, bi = None, i
        k = i
        while k < onsets.size and (k == i or (best is not None and onsets[k] < onsets[i] + best[2])):
            if k > i and gaps[k] < rest_min:  # later starts: only after a rest
                k += 1
                continue
            extra = list(common)
            e = block_end.get(int(onsets[k]))
            if e is not None and e - onsets[k] >= MIN_CYCLES * 2 * gap_min:
                key = (int(onsets[k]), e)
                if key not in acf:  # an onset is tried again from each earlier onset within a period
                    acf[key] = _autocorr_periods(raw, key[0], e, 2 * gap_min)
                extra += acf[key]
            cand = _best_chain(onsets, w, k, tol_min, extra, 2 * rest_min)
            if cand is not None and (best is None or cand[0] > best[0] + 2 * tol_min):
                best, bi = cand, k
            k += 1
        if best is None:
            i += 1
            continue
        _, ch, P = best
        ch, P = _settle(onsets, w, ch, P, tol_min, 2 * gap_min)
        ch = _extend_back(onsets, w, ch, P, max(tol_min, int(R_PERIOD * P)), claimed)
        starts = np.asarray(ch, dtype=np.int64)
        period = int(round((starts[-1] - starts[0]) / (starts.size - 1)))
        chains.append((starts, period))
        claimed = int(starts[-1] + period)
        i = max(bi, int(np.searchsorted(onsets, claimed)))
    return _whole_cycles(chains, w)


def _whole_cycles(chains: list[tuple[np.ndarray, int]], w: _Signal) -> list[tuple[np.ndarray, int]]:
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


def motion_start(w: np.ndarray, onsets: np.ndarray, sigma_w: float, reach: int) -> np.ndarray:
    """Where the motion detected at each onset really starts: back from the onset (at most ``reach``
    samples) to the last sample whose velocity is within one noise level ``sigma_w`` of zero or of the
    other sign (the motion mask needs several noise levels: on a slow start it trips late)."""
    out = np.asarray(onsets, dtype=np.int64).copy()
    for k, o in enumerate(out):
        if o <= 0 or o >= w.size:
            continue
        a = max(0, int(o) - reach)
        back = w[a:o] * np.sign(w[o])
        quiet = np.flatnonzero(back <= sigma_w)
        out[k] = a + int(quiet[-1]) + 1 if quiet.size else a
    return out


def duty_cycles(w: np.ndarray, moving: np.ndarray, gap_min: int, rest_min: int, tol_min: int,
                sigma_w: float = 0.0) -> list[tuple[int, int, int]]:
    """(start, end, cycle index) of every duty cycle; indices count on across the log's chains. A cycle
    starts where its motion starts (:func:`motion_start` with the velocity noise ``sigma_w``), ends where
    the next one of its chain starts, the last one a period after its start."""
    out = []
    k = 0
    n = w.size
    for starts, P in find_chains(w, moving, gap_min, rest_min, tol_min):
        starts = np.maximum.accumulate(motion_start(w, starts, sigma_w, rest_min))
        ends = np.concatenate((starts[1:], [starts[-1] + P]))
        for s, e in zip(starts, ends):
            out.append((int(s), int(min(n, e)), k))
            k += 1
    return out
