"""Per-sample variables of the causes outside the friction model's own list, computed on the full logs and
taken at the sliding samples: the rests before each move (``dwell``) and the rate of the measured torque
(``delay``).

- **Dwell** (static friction that grows with the time spent at rest, Dieterich's contact ageing): the
  level factor's variable ``ln(1 + t_rest / t0) exp(-s / s_c)``, with ``t_rest`` the length of the rest
  (slower than the sliding speed ``v_min``) just before the current move (0 after a reversal without a
  rest), ``s`` the travel since the move started, ``t0`` and ``s_c`` chosen on training folds from scales
  of the data (the rests' durations, the moves' lengths).
- **Delay** between the torque and the motion: a torque logged ``d`` seconds ahead of the position and
  velocity leaves ``r = d dtau/dt`` in the friction residual (to first order), so the additive column is the
  measured torque's rate (Savitzky-Golay, quadratic, over :data:`RATE_WINDOW` seconds); its coefficient is
  the delay [s], positive when the torque leads the motion.
"""
from __future__ import annotations

import numpy as np

from ..data import finite
from .samples import Samples

#: Shortest rest [s] that counts (the edge left out at both ends of a run of sliding samples).
REST_MIN = 0.05
#: Window [s] of the Savitzky-Golay rate of the measured torque (at least 7 samples).
RATE_WINDOW = 0.025


def _moves(w: np.ndarray, v_min: float):
    """Per sample of one log: the start index of its run (at rest, or moving one way) and of the run before."""
    sg = np.where(np.abs(w) > v_min, np.sign(w), 0.0)
    n = sg.size
    brk = np.flatnonzero(sg[1:] != sg[:-1]) + 1
    edges = np.concatenate(([0], brk))
    lens = np.diff(np.concatenate((edges, [n])))
    return sg, np.repeat(edges, lens), np.repeat(np.concatenate(([-1], edges[:-1])), lens)


def rests(S: Samples) -> tuple[np.ndarray, np.ndarray]:
    """(t_rest [s], s [q]) at the sliding samples: the length of the rest before the current move (0 after a
    reversal without a rest) and the travel since the move started (cached)."""
    def compute():
        tr, sd = np.zeros(S.n), np.zeros(S.n)
        for i, lg in enumerate(S.logs):
            sel = S.li == i
            if not sel.any() or lg.q is None:
                continue
            sg, start, prev = _moves(S.log_w(i), S.v_min)
            k = S.k[sel]
            st, pv = start[k], prev[k]
            after = (st > 0) & (pv >= 0)
            after[after] &= sg[st[after] - 1] == 0
            tr[sel] = np.where(after, lg.t[st] - lg.t[np.maximum(pv, 0)], 0.0)
            q = finite(lg.q)
            sd[sel] = np.abs(q[k] - q[st])
        return tr, sd
    return S.cached("rests", compute)


def rest_scales(S: Samples) -> tuple[np.ndarray, np.ndarray] | None:
    """The settings tried for the dwell variable: ``t0`` [s] (the shortest and the median rest before a move)
    and ``s_c`` [q] (1 % to 30 % of the median travel of a move, 4 values); None when the moves follow
    fewer than 3 rests of at least two different lengths (nothing to tell a dwell effect by)."""
    tr, sd = rests(S)
    # a rest shorter than the sliding samples' edge at the ends of a run (50 ms, samples.py) is a dip of
    # the measured velocity at a reversal, not a rest
    tr = np.where(tr >= REST_MIN, tr, 0.0)
    lengths = np.unique(np.round(tr[tr > 0], 6))
    if lengths.size < 2 or np.count_nonzero(tr > 0) < 3 or lengths.max() < 2 * lengths.min():
        return None
    travel = float(np.median(sd[tr > 0])) if np.any(tr > 0) else 0.0
    if travel <= 0:
        return None
    t0 = np.unique([float(lengths.min()), float(np.median(lengths))])
    return t0, np.geomspace(0.01, 0.3, 4) * 2 * travel


def dwell_state(S: Samples, t0: float, s_c: float) -> np.ndarray:
    """``ln(1 + t_rest / t0) exp(-s / s_c)`` at the sliding samples (rests shorter than :data:`REST_MIN`: 0)."""
    tr, sd = rests(S)
    tr = np.where(tr >= REST_MIN, tr, 0.0)
    return np.log1p(tr / t0) * np.exp(-sd / s_c)


def _log_rate(S: Samples, i: int) -> np.ndarray:
    """The measured torque's rate [F/s] at every sample of log i (cached)."""
    def compute():
        from scipy.signal import savgol_filter

        lg = S.logs[i]
        dt = S.dt(i)
        win = max(7, int(round(RATE_WINDOW / dt)) | 1)
        tau = finite(lg.tau)
        return savgol_filter(tau, win, 2, deriv=1, delta=dt) if lg.n > win else np.gradient(tau, dt)
    return S.cached(("torque_rate", i), compute)


def torque_rate(S: Samples) -> np.ndarray:
    """The measured torque's rate dtau/dt [F/s] at the sliding samples (cached)."""
    def compute():
        out = np.empty(S.n)
        for i in range(len(S.logs)):
            sel = S.li == i
            if sel.any():
                out[sel] = _log_rate(S, i)[S.k[sel]]
        return out
    return S.cached("torque_rate", compute)


def rate_share(S: Samples) -> float:
    """Share of the torque-rate excitation (sum of (dtau/dt)^2 over the moving samples, faster than 2 % of
    the top speed) that the sliding samples carry: a delay shows where the torque changes fast, and a subset
    that holds little of that change cannot measure it (on a run of plateaus the rate is large only in the
    transitions the sliding samples leave out, and any slow misfit then passes for a delay)."""
    def compute():
        tot = 0.0
        for i in range(len(S.logs)):
            m = np.abs(S.log_w(i)) > 0.02 * S.w0
            tot += float(np.sum(_log_rate(S, i)[m] ** 2))
        return min(1.0, float(np.sum(torque_rate(S) ** 2)) * max(S.decimation, 1) / tot) if tot > 0 else 0.0
    return S.cached("rate_share", compute)
