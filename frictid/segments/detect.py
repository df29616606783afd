"""Find the identification experiments in one joint log (MODELS.md section 4).

Every threshold is a multiple of a scale measured on the log (:mod:`.scales`): the noise of each channel
(globally, and locally for the torque, whose noise changes when a controller takes over), the encoder
step, the torque range, the top speed and the sample period. The features are measured at the time scale
``T_MIN`` (the shortest segment; ``h`` samples each side) and ``T_JUMP`` (the longest rise of a torque
step), each compared with its own noise level:

- ``wc`` : mean velocity over ``2h`` samples; *still* where ``|wc| < max(K_NOISE sigma(wc), R_STILL
  w_local)`` (``sigma(wc)`` floored by the encoder resolution, ``w_local`` the top speed within
  ``T_SETTLE``), *moving* where ``|wc| >= K_NOISE sigma(wc)``, *quiet* where still or below ``R_QUIET``
  of the log's top speed; ``still_fine``, ``quiet_fine`` the same tests on the Savitzky-Golay velocity
  (precise edges);
- ``dv`` : velocity change across a sample (mean over the ``h`` samples after minus before); *steady*
  where ``|dv| < max(K_NOISE sigma(dv), R_STEADY |wc|)``;
- ``s`` : torque slope at scale ``h`` (and ``4h`` for slow ramps in noisy torque); jumps of ``tau`` that
  complete within ``T_JUMP``.

Then, in order (each sample gets one kind; earlier kinds win):

1. duty cycles: the same velocity profile, with motion and a rest, repeating at a constant period
   (:mod:`.duty`), one segment per cycle;
2. steps: a torque jump from a still joint under a flat torque, the joint settled again, lasting until
   the next torque event, until the joint moves or until the torque stops being flat (a controller takes
   over); kept in groups that return the torque to where it started (a step and its release);
3. ramps: monotonic torque runs on a still (or steadily creeping) joint, a straight line within the
   noise, changing the torque by ``K_RAMP`` standard errors; kept in groups that start at a hold and
   return to its level at a hold (loading and unloading), one segment per monotonic ramp;
4. constant velocity: steady, moving runs of at least ``T_MIN``, edged where the velocity leaves the
   plateau's band; kept when they form a sweep: plateaus held at their mirror speed nearby or joined
   without a stop, at ``MIN_PLATEAUS`` speeds (a lone steady stretch is a move's cruise phase);
5. rest: still runs of at least ``T_MIN`` where no controller is loading the joint towards break-away;
   everything else is *other*.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..data import JointLog, Segment
from . import stats as _stats
from .duty import duty_cycles
from .runs import (any_in_runs, box_mean, box_slope, chunks, closed_runs, count_prefix, drop_short, fill_short,
                   paint, prefix_sum, runs)
from .scales import Scales, estimate_scales, local_noise, log_position, qd_is_difference, velocity

#: Noise multiple for "clearly nonzero".
K_NOISE = 5.0
#: Shortest segment [s]; also the time scale of the velocity and torque features.
T_MIN = 0.2
#: Longest rise of a torque step [s] (a faster torque change is a step, a slower one a ramp).
T_JUMP = 0.01
#: A joint moving slower than this fraction of the speed of the motion around it (within ``T_SETTLE``)
#: is still (when above the noise): the tail of a move settling.
R_STILL = 0.01
#: A joint moving slower than this fraction of the log's top speed does not slide (presliding, creep):
#: "quiet" for the torque experiments (steps, ramps) and the rests of duty cycles.
R_QUIET = 0.005
#: The longest a loop takes to settle after a move [s].
T_SETTLE = 1.0
#: Fewest plateaus at distinct velocities that make a constant-velocity experiment (a static map).
MIN_PLATEAUS = 3
#: Plateaus looked at on each side for a plateau's mirror speed.
MIRROR_REACH = 3
#: A pause between two plateaus of a sweep longer than this many times the log's median pause between
#: linked plateaus ends the sweep (something else happens in between).
R_PAUSE = 10.0
#: Relative tolerance of a mirror speed (a plateau's mean speed against its mirror's).
R_MIRROR = 0.005
#: Relative velocity tolerance of a constant-velocity plateau.
R_STEADY = 0.02
#: A ramp changes the torque by at least this many standard errors of its fitted change (and by
#: two noise levels).
K_RAMP = 10.0
#: The torque of a hold under a constant (open-loop) torque has ended when it gets noisier: by
#: K_NOISE standard errors and at least this factor ...
R_NOISIER = 1.2
#: ... where the relative standard error of the mean |first difference| of n white-noise samples is
#: R_ABSDIFF / sqrt(n) (sqrt(pi/2 - 1) = 0.755 for independent values, times 1.2 for the correlation of
#: neighbouring differences).
R_ABSDIFF = 0.91
#: A ramp is a straight line: residual standard deviation at most this many torque noise levels ...
R_LINE = 1.5
#: ... and no significant bend larger than this fraction of its torque change.
R_BEND = 0.02
#: A joint under a presliding ramp speeds up by less than this factor over its median speed (creep and
#: the presliding spring speed up a few times; a break-away runs away by orders of magnitude).
R_SLIDE = 10.0
#: The farthest a joint moves under one presliding ramp, bristle deflection and creep together [rad, m]:
#: joints deflect 1e-5..1e-3 rad (1e-6..1e-4 m) before break-away, a creep of 0.6 mrad/s adds a few mrad
#: over a ramp of seconds. A physical bound, not a threshold on the data: it only separates a creeping
#: joint from a sliding one when the log has no sliding motion to compare with (no gross motion).
D_PRESLIDE = (1e-2, 1e-3)
#: A group of ramps returns to its starting torque within this fraction of its largest excursion.
R_RETURN = 0.1

KIND_CODE = {"constant_velocity": 0, "ramp_presliding": 1, "step": 2, "duty_cycle": 3, "rest": 4, "other": 5}
CODE_KIND = {v: k for k, v in KIND_CODE.items()}


@dataclass
class Features:
    """Per-sample features of one log and the noise levels they are compared with."""

    sc: Scales
    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    w: np.ndarray
    h: int
    n_min: int
    still: np.ndarray
    still_fine: np.ndarray
    quiet: np.ndarray
    quiet_fine: np.ndarray
    moving: np.ndarray
    steady: np.ndarray
    s: np.ndarray
    sigma_tau_loc: np.ndarray
    sigma_wc: float
    sigma_dv: float
    resting: np.ndarray | None = None  # still to the sensors over T_MIN: a rest's stillness
    tau_c: np.ndarray | None = None  # prefix_sum(tau): every torque slope (box_slope) works from it
    d_preslide: float = 0.0  # D_PRESLIDE of the log's axis [q]


def _local_top(w: np.ndarray, half: int) -> np.ndarray:
    """The largest ``|w|`` within ``half`` samples each side of every sample [q/s]: the speed of the
    motion around it."""
    from scipy.ndimage import maximum_filter1d  # lazily, as scipy.signal in .scales

    return maximum_filter1d(np.abs(w), 2 * half + 1, mode="nearest")


def _resting(log: JointLog, q: np.ndarray, h: int, sc: Scales, moving: np.ndarray) -> np.ndarray:
    """Per sample: the joint is still to its sensors over ``T_MIN`` (docs/segments.md, "What a rest is"):
    a window of ``2h`` samples (``T_MIN``) holds the sample over each half of which the logged position
    moves by at most ``K_NOISE`` standard errors of a position difference, ``sqrt(2) sigma_q`` (halves: a
    reversal returns to where it was, but moves). ``sigma_q``: the position's noise at the scale of a
    half, :func:`hold_scatter`. Without a logged position: the mean velocity within ``K_NOISE`` of its
    noise (not ``moving``)."""
    n = q.size
    if log.q is None or n <= 2 * h:
        return ~moving
    thr = hold_scatter(q, h, sc)
    thr *= K_NOISE * math.sqrt(2.0)
    # both halves of the window centred on a sample: a reversal returns to where it was, but moves
    ahead = np.empty(n)  # q[min(i + h, n - 1)], by slices
    ahead[:n - h], ahead[n - h:] = q[h:], q[n - 1]
    half = np.abs(ahead - q) <= thr  # |q[i + h] - q[i]|, clipped at the end
    centre = half.copy()
    centre[h:] &= half[:n - h]
    # a sample is still when a still window of T_MIN holds it (the window centred on it reaches h
    # samples into the move before a stop and after a start): c[min(i + h + 1, n)] > c[max(i - h, 0)]
    c = count_prefix(centre)
    hi, lo = np.empty(n, c.dtype), np.empty(n, c.dtype)
    hi[:n - h - 1], hi[n - h - 1:] = c[h + 1:n], c[n]
    lo[:h], lo[h:] = c[0], c[:n - h]
    return hi > lo


def hold_scatter(q: np.ndarray, h: int, sc: Scales) -> np.ndarray:
    """Per sample: the logged position's noise [q] at the scale a rest's stillness reads, a half window of
    ``h`` samples: the largest of its white-noise level ``sigma_q``, the encoder's ``step / sqrt(12)`` and
    the scatter about a cubic over ``h`` samples per block of ``T_MIN`` (:func:`.scales.local_noise` at
    lag ``h / 4``; the larger of a block and its neighbours). The last is a hold's own jitter: a position
    loop that answers its velocity noise hunts a few to tens of encoder steps over ``0.05-0.1 s`` and back,
    which the fourth difference of neighbouring samples does not see; a crawl (a line) or a smooth move
    (a cubic over ``h``) has none, so they stay motion at the encoder's resolution."""
    floor = max(sc.sigma_q, sc.q_step / math.sqrt(12.0))
    lag = max(1, int(round(h / 4)))
    if lag == 1:
        return np.full(q.size, floor)
    return np.maximum(local_noise(q, 2 * h, lag), floor)


def features(log: JointLog, sc: Scales | None = None) -> Features:
    """Compute :class:`Features` (velocity, still/steady masks, torque slope, local torque noise)."""
    sc = sc or estimate_scales(log)
    n, dt = log.n, sc.dt
    n_min = max(10, int(round(T_MIN / dt)))
    h = max(2, n_min // 2)
    w = velocity(log, sc, smooth_logged=True)
    q = log_position(log)
    tau = np.asarray(log.tau, dtype=float)
    if sc.qd_logged:
        wc = box_mean(log.qd, 2 * h + 1)
        sigma_wc = sc.sigma_qd / math.sqrt(2 * h + 1)
        sigma_dv = sc.sigma_qd * math.sqrt(2.0 / h)
    else:  # mean velocity over 2h samples: (q[i+h] - q[i-h]) / (2h dt), shorter near the ends
        wc = np.empty(n)
        if n > 2 * h:
            wc[h:n - h] = (q[2 * h:] - q[:n - 2 * h]) / (2 * h * dt)
        i = np.concatenate((np.arange(0, min(h, n)), np.arange(max(h, n - h), n)))
        lo, hi = np.clip(i - h, 0, n - 1), np.clip(i + h, 0, n - 1)
        wc[i] = (q[hi] - q[lo]) / (np.maximum(hi - lo, 1) * dt)
        sigma_wc = sc.sigma_q * math.sqrt(2.0) / (2 * h * dt)
        sigma_dv = 2.0 * sc.sigma_q / (h * dt)
    sigma_wc = max(sigma_wc, sc.sigma_w / math.sqrt(max(1.0, 2 * h / sc.window_w)))
    # a speed that moves the logged position by less than its resolution over 2h is still to the
    # encoder, however clean a logged qd: the floor of every still test
    sigma_enc = sc.sigma_q * math.sqrt(2.0) / (2 * h * dt) if log.q is not None else sigma_wc
    sigma_wc = max(sigma_wc, sigma_enc)
    sigma_dv = max(sigma_dv, sc.sigma_w * math.sqrt(2.0 / max(1.0, h / sc.window_w)))
    dv = box_slope(w, h, dt)
    dv *= h * dt
    # still: slower than the noise, or than R_STILL of the motion around (a tail after a move), never
    # relative to the log's top speed: a slow plateau next to slow moves is motion
    floor = _local_top(w, max(1, int(round(T_SETTLE / dt))))
    floor *= R_STILL
    # wc and dv serve only the masks: |wc| then the steady band in wc's memory, |dv| in dv's (keeping the
    # two for the whole segmentation was 58 MB of its peak on a joint-hour)
    band = np.abs(wc, out=wc)
    del wc
    moving = band > K_NOISE * sigma_wc
    # <=: a position that never changes (a step log on a coarse encoder: no noise, no motion) is still
    still = band <= np.maximum(floor, K_NOISE * sigma_wc)
    aw = np.abs(w)
    # a rest's stillness: what the sensors resolve over T_MIN, nothing relative to a speed of the log
    resting = _resting(log, q, h, sc, moving)
    still_fine = fill_short(aw <= np.maximum(floor, K_NOISE * max(sc.sigma_w, sigma_enc)), sc.window_w, False)
    # quiet: also below R_STILL of the log's top speed, the scale on which a torque experiment's joint
    # (presliding, creep) does not slide; steps, ramps and duty cycles read it
    top = R_QUIET * sc.w_scale
    quiet = still | (band < top)
    quiet_fine = still_fine | fill_short(aw < top, sc.window_w, False)
    del floor, aw
    band *= R_STEADY
    steady = np.abs(dv, out=dv) < np.maximum(band, K_NOISE * sigma_dv, out=band)
    del band, dv
    tau_c = prefix_sum(tau)
    s = box_slope(tau, h, dt, tau_c)
    floor = max(sc.tau_step / math.sqrt(12.0), 1e-9 * max(sc.tau_range, 1e-300))
    sigma_tau_loc = local_noise(tau, n_min)
    np.maximum(sigma_tau_loc, floor, out=sigma_tau_loc)
    return Features(sc=sc, t=np.asarray(log.t, dtype=float), q=q, tau=tau, w=w, h=h, n_min=n_min,
                    still=still, still_fine=still_fine, quiet=quiet, quiet_fine=quiet_fine, moving=moving, steady=steady, s=s, sigma_tau_loc=sigma_tau_loc,
                    sigma_wc=sigma_wc, sigma_dv=sigma_dv, tau_c=tau_c, resting=resting,
                    d_preslide=D_PRESLIDE[log.axis == "linear"])


# ---------------------------------------------------------------------------------------------------
# Steps


def find_jumps(f: Features) -> np.ndarray:
    """Sample indices of torque jumps: a change completed within ``T_JUMP`` (the change over 4 ``T_JUMP``
    is no larger) that exceeds the trend around it (a quarter of that longer change) by ``K_NOISE``
    standard errors; one index per jump (the steepest sample). Small jumps in noisy torque are looked for
    again at four times that scale."""
    hj = max(1, int(round(T_JUMP / f.sc.dt)))

    def change(k):  # torque change over k samples
        v = _slope(f, k)
        v *= k * f.sc.dt
        return v

    # over hj, 4 hj and 16 hj samples (4 hj is the long change of the fine scale and the short change of
    # the coarse one), two at a time: the three at once were the segmentation's peak
    d1, d4 = change(hj), change(4 * hj)
    fine = _jumps_at(f, hj, d1, d4)
    del d1
    coarse = _new_jumps(_jumps_at(f, 4 * hj, d4, change(16 * hj)), fine, 4 * hj)
    found = np.sort(np.concatenate((fine, coarse)))
    # a slow log (hj of one or two samples) averages too few samples at 4 hj for a jump of a few noise
    # levels: once more at 16 hj, at most the half-width h of the shortest segment (a step's holds last
    # T_MIN, so its flanks still fit in them)
    k3 = min(16 * hj, f.h)
    if k3 > 4 * hj:
        d3 = change(k3)
        slow = _new_jumps(_one_per(_jumps_at(f, k3, d3, change(4 * k3)), d3, k3), found, k3)
        found = np.sort(np.concatenate((found, slow)))
    return found


def _one_per(j: np.ndarray, d: np.ndarray, near: int) -> np.ndarray:
    """Of jumps ``j`` (sorted) closer than ``near`` samples to each other, the one of largest ``|d|``: at
    a long scale one jump lifts ``|d|`` above the threshold over several nearby runs."""
    out: list[int] = []
    for i in (int(v) for v in j):
        if out and i - out[-1] <= near:
            if abs(d[i]) > abs(d[out[-1]]):
                out[-1] = i
        else:
            out.append(i)
    return np.asarray(out, dtype=np.int64)


def _new_jumps(cand: np.ndarray, known: np.ndarray, near: int) -> np.ndarray:
    """The jumps of ``cand`` farther than ``near`` samples from every jump of ``known`` (both sorted)."""
    if not cand.size or not known.size:
        return cand
    k = np.searchsorted(known, cand)
    close = np.zeros(cand.size, dtype=bool)
    for off in (-1, 0):
        idx = np.clip(k + off, 0, known.size - 1)
        close |= np.abs(known[idx] - cand) <= near
    return cand[~close]


def _slope(f: Features, h: int) -> np.ndarray:
    """Torque slope [F/s] at half-width ``h`` samples (:func:`~.runs.box_slope` of ``f.tau``)."""
    return box_slope(f.tau, h, f.sc.dt, f.tau_c)


def _jumps_at(f: Features, hj: int, d1: np.ndarray, d4: np.ndarray) -> np.ndarray:
    """Jumps at scale ``hj``: ``d1``, ``d4`` the torque changes over ``hj`` and ``4 hj`` samples."""
    big = np.empty(d1.size, dtype=bool)
    for c in chunks(d1.size):
        thr = K_NOISE * f.sigma_tau_loc[c]
        thr *= math.sqrt(2.0 / hj)
        u = 0.25 * d4[c]
        np.subtract(d1[c], u, out=u)
        np.greater(np.abs(u, out=u), thr, out=big[c])
    s, e = runs(big)
    if s.size == 0:
        return np.zeros(0, dtype=np.int64)
    peak = _run_peak(d1, s, e)
    inst = np.abs(d1[peak]) >= 0.75 * np.abs(d4[peak])
    return peak[inst]


def _run_peak(x: np.ndarray, s: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Index of the largest ``|x|`` (the first one on a tie) in each run ``[s, e)`` (non-empty, in order),
    looking at the samples of the runs only."""
    n = e - s
    first = np.concatenate(([0], np.cumsum(n)[:-1]))
    idx = np.arange(int(n.sum()), dtype=np.int64) + np.repeat(s - first, n)
    v = np.abs(x[idx])
    top = np.maximum.reduceat(v, first)
    hit = np.flatnonzero(v == np.repeat(top, n))
    return idx[hit[np.searchsorted(hit, first)]]


def _steps(f: Features, code: np.ndarray, jumps: np.ndarray, ramps: list[tuple[int, int, int]], hj: int
           ) -> list[tuple[int, int]]:
    """(start, end) of the steps: a torque jump of ``jumps`` from a still joint, settled (still) again
    within the hold, in groups that return the torque to where it started. The starts of ``ramps`` (the
    ramp candidates) end a hold as a jump does; ``hj``: the longest rise of a jump [samples]."""
    events = np.sort(np.concatenate([jumps, np.array([r[0] for r in ramps], dtype=np.int64)]))
    cands = [seg for seg in (_step(f, int(j), hj, events, code) for j in jumps) if seg is not None]
    return _step_groups(f, cands, hj)


def _step(f: Features, j: int, hj: int, events: np.ndarray, code: np.ndarray) -> tuple[int, int] | None:
    """The step segment of the jump at ``j``: from the jump to the next torque event or to the end of the
    still stretch that follows the transient; None unless the joint is still before the jump and has
    settled within the first half of the segment."""
    n = f.t.size
    i0 = j - hj // 2
    # the smoothed velocity sees the jump's transient half a velocity window early: the joint is judged
    # still before that
    reach = f.sc.window_w // 2
    if i0 - reach < f.h:  # nothing before the jump to judge it by
        return None
    before = f.quiet_fine[i0 - reach - f.h: i0 - reach]
    if before.size == 0 or before.mean() < 0.8:
        return None
    nxt = events[events > j + hj]
    end = int(nxt[0]) - hj // 2 if nxt.size else n
    # the transient is over where the joint is still (fine scale) for at least h samples; the step lasts
    # while it stays still
    rs, re = runs(fill_short(f.quiet_fine[j + hj: end], f.sc.window_w, False))
    long = np.flatnonzero((re - rs) >= min(f.h, end - j - hj))
    if long.size == 0:
        return None
    k = j + hj + int(rs[long[0]])
    i1 = j + hj + int(re[long[0]])
    # open-loop torque: flat before the jump, and the step lasts while it stays flat (a controller that
    # takes over a still joint makes it wander)
    i1 = _flat_end(f, j + hj, i1)
    if i1 - i0 < f.n_min or (k - i0) > 0.5 * (i1 - i0) or np.any(code[i0:i1] >= 0):
        return None
    if not _flat(f, max(0, i0 - f.n_min), i0 - hj):
        return None
    return i0, i1


def _step_groups(f: Features, cands: list[tuple[int, int]], hj: int) -> list[tuple[int, int]]:
    """Steps that belong to groups of contiguous steps bringing the torque back to its level before the
    first one (a step and its release). A lone jump between two holds (a controller switched on or off
    at a still joint) is not an experiment."""
    if not cands:
        return []
    h = max(1, f.h // 2)
    # medians: the h samples before a step's end may hold the start of the next event's rise (a jump
    # found at the long scale is placed at its steepest sample, a controller's rise of several samples)
    before = [float(np.median(f.tau[max(0, a - h): a])) if a > 0 else float(f.tau[0]) for a, _ in cands]
    after = [float(np.median(f.tau[max(a, b - h): b])) for a, b in cands]
    out: list[tuple[int, int]] = []
    k = 0
    while k < len(cands):
        level0 = before[k]
        j = k
        done = k + 1
        while True:
            sig = float(np.median(f.sigma_tau_loc[cands[j][0]:cands[j][1]]))
            # the release returns to the level exactly (open loop): within the noise of the two means,
            # or a small fraction of the first step
            # (a median's standard error is sqrt(pi / 2) that of the mean)
            tol = max(K_NOISE * sig * math.sqrt(math.pi / h), 0.5 * R_RETURN * abs(after[k] - level0))
            if j > k and abs(after[j] - level0) <= tol:
                out.extend(cands[k: j + 1])
                done = j + 1
                break
            # contiguous: apart by at most the jump's rise and the half velocity window by which the
            # smoothed velocity sees the next jump early (the hold's still run ends there, _step)
            if j + 1 >= len(cands) or cands[j + 1][0] - cands[j][1] > 2 * hj + f.sc.window_w // 2:
                break
            j += 1
        k = done
    return out


def _flat_end(f: Features, a: int, b: int) -> int:
    """End of the flat torque that starts at ``a`` (at most ``b``): the first chunk of ``m`` samples whose
    mean leaves the mean of the chunks before it by more than ``K_NOISE`` standard errors, or where the
    torque gets noisier (a controller taking over a still joint: two chunks in a row whose mean absolute
    difference exceeds that of all chunks before them by ``K_NOISE`` standard errors and ``R_NOISIER``)."""
    m = max(f.sc.window_w, f.h // 4, 2)
    nchunk = (b - a) // m
    if nchunk < 3:
        return b
    x = f.tau[a:a + nchunk * m].reshape(nchunk, m).mean(axis=1)
    # each chunk against the mean of the chunks before it (the level so far, known to se / sqrt(k))
    k = np.arange(1, nchunk)
    level = np.cumsum(x)[:-1] / k
    se = float(np.median(f.sigma_tau_loc[a:a + 3 * m])) / math.sqrt(m)
    off = np.concatenate(([False], np.abs(x[1:] - level) > K_NOISE * se * np.sqrt(1.0 + 1.0 / k)
                          + f.sc.tau_step))
    end = b if not off.any() else a + int(np.argmax(off)) * m
    mn = max(m, 128)  # enough differences per chunk for a noise level known to about 8 %
    nn = (b - a) // mn  # over the whole hold: a controller that takes over may also shift the mean
    if nn >= 5:
        rough = np.mean(np.abs(np.diff(f.tau[a:a + nn * mn].reshape(nn, mn), axis=1)), axis=1)
        # from chunk c on (c >= 3) the torque is noisier when the mean roughness of the next (up to 8)
        # chunks exceeds that of all chunks before c by K_NOISE standard errors and by R_NOISIER
        c = np.arange(3, nn)
        cs = np.concatenate(([0.0], np.cumsum(rough)))
        before = cs[c] / c
        na = np.minimum(8, nn - c)
        after = (cs[c + na] - cs[c]) / na
        se = R_ABSDIFF / math.sqrt(mn) * np.sqrt(1.0 / c + 1.0 / na)
        k = np.flatnonzero((after > before * (1.0 + K_NOISE * se)) & (after > R_NOISIER * before))
        if k.size and before[k[0]] > 0:
            # the change is in that window or the chunk before it: where the cumulative sum of
            # |difference| - (halfway between the two levels) is lowest (CUSUM change point)
            c0, c1 = int(c[k[0]]), int(c[k[0]] + na[k[0]])
            mid = 0.5 * (before[k[0]] + after[k[0]])
            lo = a + (c0 - 1) * mn
            d = np.abs(np.diff(f.tau[lo:a + c1 * mn]))
            end = min(end, lo + 1 + int(np.argmin(np.cumsum(d - mid))))
    return end


def _flat(f: Features, a: int, b: int) -> bool:
    """True if the torque over ``[a, b)`` is constant within its noise: the means of chunks of ``m``
    samples stay within ``K_NOISE`` standard errors (plus one torque quantum) of their median."""
    m = max(f.sc.window_w, f.h // 4, 2)
    nchunk = (b - a) // m
    if nchunk < 2:
        return True
    x = f.tau[a:a + nchunk * m].reshape(nchunk, m).mean(axis=1)
    tol = K_NOISE * float(np.median(f.sigma_tau_loc[a:b])) / math.sqrt(m) + f.sc.tau_step
    return bool(np.max(np.abs(x - np.median(x))) <= tol)


def grow(core: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The runs of ``ok`` that contain at least one sample of ``core`` (hysteresis thresholding)."""
    s, e = runs(ok)
    if s.size == 0:
        return np.zeros_like(ok, dtype=bool)
    keep = any_in_runs(core, s, e)  # core outside ok is outside every run
    out = np.zeros_like(ok, dtype=bool)
    paint(out, s[keep], e[keep], True)
    return out


# ---------------------------------------------------------------------------------------------------
# Main


@dataclass
class _Labels:
    """The kind code of every sample of a log (-1 until classified) and the segments found so far."""

    f: Features
    code: np.ndarray
    segs: list[Segment]

    def mark(self, kind: str, i0: int, i1: int, cycle: int | None = None) -> None:
        """Give the samples ``[i0, i1)`` the kind ``kind`` and add their segment."""
        self.code[i0:i1] = KIND_CODE[kind]
        self.segs.append(_segment(self.f, kind, i0, i1, cycle=cycle))


def classify(log: JointLog, scales: Scales | None = None) -> tuple[np.ndarray, list[Segment], Features | None]:
    """Kind code per sample, the segments, and the features (None for a log too short to segment);
    ``scales``: the log's :func:`estimate_scales` when known.

    The kinds are found in the order of the module's description, each among the samples the earlier
    ones left: duty cycles, steps, ramps, constant velocity, rest; what remains is *other*."""
    n = log.n
    if qd_is_difference(log):  # the position says it all, and its quantisation is not white noise in qd
        log, scales = replace(log, qd=None), None
    sc = scales or estimate_scales(log)
    n_min = max(10, int(round(T_MIN / sc.dt)))
    if n < 2 * n_min:
        return np.full(n, KIND_CODE["other"], dtype=np.int8), [], None
    f = features(log, sc)
    lab = _Labels(f, np.full(n, -1, dtype=np.int8), [])
    hj = max(1, int(round(T_JUMP / sc.dt)))
    all_jumps = find_jumps(f)  # torque events: jumps, and runs of one slope sign
    for i0, i1, cyc in _without_experiments(f, find_duty_cycles(f), all_jumps, hj):
        lab.mark("duty_cycle", i0, i1, cycle=cyc)
    jumps = all_jumps[lab.code[all_jumps] < 0]
    ramps = _ramp_list(f, lab.code, jumps)
    for i0, i1 in _steps(f, lab.code, jumps, ramps, hj):
        lab.mark("step", i0, i1)
    ramp_segs, holds = _ramps(f, ramps)
    for i0, i1 in ramp_segs:
        lab.mark("ramp_presliding", i0, i1)
    for i0, i1 in holds:
        lab.mark("rest", i0, i1)
    for i0, i1 in _constant_velocity(f, lab.code, n_min):
        lab.mark("constant_velocity", i0, i1)
    for i0, i1 in zip(*runs(_rest(f, lab.code, _loading(f, jumps, hj), n_min))):
        lab.mark("rest", int(i0), int(i1))
    for i0, i1 in zip(*runs(lab.code < 0)):
        lab.mark("other", int(i0), int(i1))
    lab.segs.sort(key=lambda s: (s.i0, s.i1))
    return lab.code, lab.segs, f


# ---------------------------------------------------------------------------------------------------
# Constant velocity


def _constant_velocity(f: Features, code: np.ndarray, n_min: int) -> list[tuple[int, int]]:
    """(start, end) of the constant-velocity plateaus among the unclassified samples: steady, moving runs
    of one sign and at least ``n_min`` samples, edged where the velocity leaves the plateau's band.

    A plateau identifies the static map only as part of a sweep (:func:`_sweeps`): a steady stretch
    that is neither held at its mirror speed nearby nor joined without a stop to plateaus at other speeds
    is a move's cruise phase (point-to-point motion, a repositioning move), not an experiment."""
    cv = f.steady & f.moving & ~f.still & (code < 0)
    plateaus = []
    # the steady test looks h samples each side, so a plateau of n_min + 2 h shows a steady core of only
    # n_min: cores of h / 2 are grown into their band (short plateaus of 0.25-0.4 s, chained sweeps)
    for i0, i1 in zip(*closed_runs(cv, max(2, f.h // 4), max(2, f.h // 2))):
        got = _plateau(f, int(i0), int(i1), code, n_min)
        if got is None:
            continue
        levels = _levels(f, int(i0), int(i1), code, n_min, got)
        apart = all(abs(u[2] - v[2]) > R_STEADY * (abs(u[2]) + abs(v[2])) for u, v in zip(levels[:-1], levels[1:]))
        for p in (levels if len(levels) >= MIN_PLATEAUS and apart else [got]):
            _add_plateau(f, plateaus, p)
    return [(i0, i1) for i0, i1, _ in _sweeps(f, plateaus, code)]


def _levels(f: Features, i0: int, i1: int, code: np.ndarray, n_min: int, got: tuple[int, int, float] | None
            ) -> list[tuple[int, int, float]]:
    """The plateaus (start, end, velocity) of the steady run ``[i0, i1)`` in time order: ``got`` (the one
    grown around the run's median velocity; None: look for it), then those of what the run holds before
    and after it. A chained sweep whose speed steps are smaller than the steady test's noise over ``h``
    (slow plateaus on a 12-13-bit encoder: 0.1 -> 0.007 rad/s in steps of 30 %) is one steady run
    holding several levels, of which only the median one was kept (foreign sweeps 100346, 100556). The
    caller keeps them only when they are at least ``MIN_PLATEAUS`` (a sweep in itself) and each two
    neighbours' bands (``R_STEADY``) are apart: a cruise phase whose speed drifts a little under gravity
    splits into levels 2 % apart, which would then chain (foreign session 100405)."""
    got = got or _plateau(f, i0, i1, code, n_min)
    if got is None:
        return []
    # what is left of the run on each side (the plateau may have grown beyond it, or lie outside it)
    g0, g1 = max(got[0], i0), min(got[1], i1)
    if g1 <= g0:
        return [got]
    core = max(2, f.h // 2)
    left = _levels(f, i0, g0, code, n_min, None) if g0 - i0 >= core else []
    right = _levels(f, g1, i1, code, n_min, None) if i1 - g1 >= core else []
    # a level grown from what is left stops where this one starts
    left = [(a, min(b, got[0]), v) for a, b, v in left if min(b, got[0]) - a >= n_min]
    right = [(max(a, got[1]), b, v) for a, b, v in right if b - max(a, got[1]) >= n_min]
    return left + [got] + right


def _add_plateau(f: Features, plateaus: list[tuple[int, int, float]], got: tuple[int, int, float]) -> None:
    """Append the plateau ``got`` to ``plateaus`` (time order). Where it overlaps the last one (a sample
    has one kind): two steady cores of one plateau (a gap in the steady mask) grown into the same band are
    one plateau; two levels of a chain that each grew into the other's edge by a sample or two meet where
    the second starts."""
    if plateaus and got[0] < plateaus[-1][1]:
        a, b, v = plateaus.pop()
        if not _apart(_mean_speed(f, a, b), _mean_speed(f, got[0], got[1])):
            b = max(b, got[1])
            got = (a, b, float(np.median(f.w[a:b])))
        elif got[0] - a >= f.n_min:
            plateaus.append((a, got[0], v))
    plateaus.append(got)


def _sweeps(f: Features, plateaus: list[tuple[int, int, float]], code: np.ndarray
            ) -> list[tuple[int, int, float]]:
    """The plateaus (start, end, velocity) that belong to a sweep. A plateau is *linked* when its mirror
    speed is held nearby (:func:`_mirror`, up to ``MIRROR_REACH`` plateaus away, however long the
    repositioning between them: a joint creeping in a dwell is a steady stretch in between) or when the joint runs into or out of it from another plateau
    without stopping (:func:`_chained`: a chained sweep). Linked plateaus no more than ``MIRROR_REACH``
    plateaus apart form a group; a group is a sweep when it holds ``MIN_PLATEAUS`` distinct speeds
    (unsigned). A move's cruise phase is linked only by the chance of a mirror speed, and a few chance
    mirrors side by side at three speeds do not happen."""
    reach = max(1, int(round(T_SETTLE / f.sc.dt)))
    mean_all = [_mean_speed(f, a, b) for a, b, _ in plateaus]
    # still by the rule of the still mask: slower than R_STILL of the motion within T_SETTLE (a settling
    # tail decaying through a few steady stretches is no chained sweep)
    moving = [abs(m[0]) > R_STILL * float(np.max(np.abs(f.w[max(0, a - reach):b + reach])))
              for (a, b, _), m in zip(plateaus, mean_all)]
    plateaus = [p for p, ok in zip(plateaus, moving) if ok]
    mean = [m for m, ok in zip(mean_all, moving) if ok]
    m = len(plateaus)
    chained = [_chained(f, plateaus[k], plateaus[k + 1], mean[k], mean[k + 1], code) for k in range(m - 1)]
    linked = [any(_mirror(mean[k], mean[j]) for j in range(max(0, k - MIRROR_REACH), min(m, k + MIRROR_REACH + 1))
                  if j != k)
              or (k > 0 and chained[k - 1]) or (k < m - 1 and chained[k])
              for k, p in enumerate(plateaus)]
    idx = [k for k in range(m) if linked[k]]
    # a sweep keeps its rhythm: a pause far longer than its usual one (R_PAUSE times the median) between
    # two linked plateaus is another experiment in between (a session's repositioning moves); not between
    # two chained ones: the joint runs from one into the other, nothing happens in between (a chain's
    # plateaus meet, its median pause is a few samples, and the longer speed change between its fastest
    # levels cut it: foreign sweep 101330)
    pauses = [plateaus[b][0] - plateaus[a][1] for a, b in zip(idx[:-1], idx[1:])]
    longest = R_PAUSE * float(np.median(pauses)) if pauses else 0.0
    keep: list[tuple[int, int, float]] = []
    group: list[int] = []
    for k in idx + [m + MIRROR_REACH + 1]:
        if group and (k - group[-1] > MIRROR_REACH or k >= m or (
                plateaus[k][0] - plateaus[group[-1]][1] > longest and not (k == group[-1] + 1 and chained[k - 1]))):
            if _distinct_speeds([abs(plateaus[j][2]) for j in group]) >= MIN_PLATEAUS:
                keep.extend(plateaus[j] for j in group)
            group = []
        group.append(k)
    return keep


def _apart(ma: tuple[float, float], mb: tuple[float, float]) -> bool:
    """True if two plateaus (mean velocity and its standard error, :func:`_mean_speed`) run at clearly
    different speeds: apart by more than the band (``R_STEADY``) and ``K_NOISE`` standard errors of the
    two means."""
    tol = max(R_STEADY * max(abs(ma[0]), abs(mb[0])), K_NOISE * math.hypot(ma[1], mb[1]))
    return abs(ma[0] - mb[0]) > tol


def _chained(f: Features, a: tuple[int, int, float], b: tuple[int, int, float], ma: tuple[float, float],
             mb: tuple[float, float], code: np.ndarray) -> bool:
    """True if the joint runs from plateau ``a`` into plateau ``b`` (start, end, velocity; mean velocity
    and its standard error) without stopping: two clearly different speeds of one sign (:func:`_apart`),
    and never slower than half the slower one in between (a point-to-point move always stops before the
    next one)."""
    va, vb = ma[0], mb[0]
    slower = min(abs(va), abs(vb))
    if va * vb <= 0 or not _apart(ma, mb) or slower <= K_NOISE * max(ma[1], mb[1]):
        return False
    if a[1] >= b[0]:
        return True
    # the velocity in between as the plateaus' own is read on a coarse encoder (averaged over at most a
    # quarter of T_MIN: a stop without a dwell still shows): the staircase of the position's derivative
    # took a slow chain's 10 ms speed change below half the slower level (foreign sweep 101330,
    # 0.0079 rad/s, 17 bits, qd absent)
    k = max(1, f.h // 2)
    lo, hi = max(0, a[1] - k), min(f.t.size, b[0] + k)
    w = _averaged(f, f.w[lo:hi], slower, k)[0]
    gap = w[a[1] - lo:b[0] - lo] * math.copysign(1.0, va)
    return bool(np.all(code[a[1]:b[0]] < 0)) and float(gap.min()) > 0.5 * slower


def _mean_speed(f: Features, a: int, b: int) -> tuple[float, float]:
    """Mean velocity [q/s] of the plateau ``[a, b)`` over its middle half, from the positions at its ends,
    and its standard error (the position noise, at least the encoder's quantisation, at both ends). The
    middle half: a plateau's edges reach into the loop's settling within the plateau's band (``R_STEADY``),
    which moves an end-to-end mean by up to a per cent (foreign sweep draw 100066: mirror speeds 0.0707
    and -0.0712 end to end, 0.07097 and -0.07098 over the middle halves), more than ``R_MIRROR``."""
    quarter = (b - a) // 4
    a, b = a + quarter, b - quarter
    span = max(1, b - 1 - a) * f.sc.dt
    sq = max(f.sc.sigma_q, f.sc.q_step / math.sqrt(12.0))
    mean = float(f.q[b - 1] - f.q[a]) / span
    # and the loop's own speed ripple (a load that changes along the plateau): the spread of the mean
    # speeds over the four quarters of the middle half, as a standard error of their mean
    k = np.linspace(a, b - 1, 5).round().astype(np.int64)
    if f.sc.qd_logged and np.all(np.diff(k) > 0):
        # a logged velocity (a sensor of its own, not the position's difference: classify) resolves the
        # speed where a coarse encoder does not: its mean over each quarter, the noise of a mean of
        # (b - a) / window_w independent smoothed values, and the quarters' spread
        c = np.concatenate(([0.0], np.cumsum(f.w[a:b])))
        parts = np.diff(c[k - a]) / np.diff(k)
        noise = f.sc.sigma_w * math.sqrt(f.sc.window_w / max(1, b - a))
        return float(np.mean(parts)), math.hypot(noise, float(np.std(parts, ddof=1)) / 2.0)
    parts = np.diff(f.q[k]) / np.maximum(np.diff(k), 1) / f.sc.dt
    ripple = float(np.std(parts, ddof=1)) / 2.0 if np.all(np.diff(k) > 0) else 0.0
    return mean, math.hypot(math.sqrt(2.0) * sq / span, ripple)


def _mirror(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """True if two plateaus (mean velocity and its standard error) run at opposite speeds: the mean
    speeds agree within ``R_MIRROR`` or ``K_NOISE`` standard errors (a settled loop holds the mean speed
    of its reference; two unrelated speeds agree that closely by chance about once in a hundred)."""
    if a[0] * b[0] >= 0:
        return False
    tol = max(R_MIRROR * max(abs(a[0]), abs(b[0])), K_NOISE * math.hypot(a[1], b[1]))
    return abs(a[0] + b[0]) <= tol


def _distinct_speeds(w: list[float]) -> int:
    """Number of distinct plateau velocities (signed; equal within ``R_STEADY``)."""
    levels: list[float] = []
    for v in sorted(w):
        if not levels or abs(v - levels[-1]) > R_STEADY * max(abs(v), abs(levels[-1])):
            levels.append(v)
    return len(levels)


def _same_sign(w: np.ndarray) -> bool:
    m = float(np.mean(w))
    return m != 0 and float(np.mean(np.sign(w) == np.sign(m))) > 0.95


def _plateau(f: Features, i0: int, i1: int, code: np.ndarray, n_min: int) -> tuple[int, int, float] | None:
    """(start, end, velocity) of the plateau grown from the steady run ``[i0, i1)``, or None when it is
    too short or changes sign. Edged on the velocity as it is; on a coarse encoder, whose slow plateau
    fails that, on the velocity averaged until it resolves the plateau's band (:func:`_plateau_velocity`),
    each against its own noise level."""
    lo = max(0, i0 - 2 * f.h)
    for w, off, sig in ((f.w[lo:min(f.t.size, i1 + 2 * f.h)], lo, f.sc.sigma_w), _plateau_velocity(f, i0, i1)):
        a, b = _extend_plateau(f, i0, i1, code, w, off, sig)
        if b - a >= n_min and _same_sign(w[a - off:b - off]) and _level(f, w[a - off:b - off], sig):
            a, b = _one_speed(f, a, b, n_min)
            if b - a >= n_min and _in_band(w[a - off:b - off], sig):
                return a, b, float(np.median(w[a - off:b - off]))
    return None


def _in_band(w: np.ndarray, sigma: float) -> bool:
    """True if most samples of the velocity ``w`` [q/s] (noise level ``sigma``) over a candidate plateau
    lie within its band
    (:func:`_extend_plateau`'s): the median distance from the median velocity is within the band. A
    joint in stick-slip under a slow reference (sticking, then slipping at several times the mean speed,
    tens of times a second) has a steady mean over every 0.1 s, a steady position trend, and almost no
    sample near its mean speed (foreign issue-19 sweep 100569: 7 such stretches read as plateaus)."""
    wm = float(np.median(w))
    return float(np.median(np.abs(w - wm))) <= max(K_NOISE * sigma, R_STEADY * abs(wm))


def _one_speed(f: Features, a: int, b: int, n_min: int) -> tuple[int, int]:
    """``[a, b)`` trimmed at its ends until the joint holds one speed over it: the mean speeds of its first
    and last quarters (from the positions: the sample velocity's noise hides a slow change) differ by no
    more than the plateau's band allows (``2 R_STEADY`` of its speed: each end within ``R_STEADY`` of the
    level) or ``K_NOISE`` standard errors (the position noise, at least the encoder's quantisation, at the
    quarters' ends). The end farther from the middle half's speed goes first, an eighth at a time: a loop
    still settling at one end (a slow integrator) keeps its settled part, a joint crawling out of
    stiction while its controller winds up, speeding up steadily a few times over a second and "steady"
    within the noise over every 0.1 s, would have to lose more than half of itself and is no plateau
    (foreign issue-19 sweeps on 17-23-bit encoders at 100-3500 Hz: crawls of 0.004 -> 0.012 rad/s read as
    plateaus, in mirror pairs)."""
    sq = max(f.sc.sigma_q, f.sc.q_step / math.sqrt(12.0))
    keep = max(n_min, (b - a) // 2)
    while True:
        k = np.linspace(a, b - 1, 5).round().astype(np.int64)
        if np.any(np.diff(k) <= 0):
            return a, b
        span = np.diff(k) * f.sc.dt
        v = np.diff(f.q[k]) / span
        se = math.sqrt(2.0) * sq * math.hypot(1.0 / span[0], 1.0 / span[-1])
        level = float(f.q[k[3]] - f.q[k[1]]) / float(span[1] + span[2])
        if K_NOISE * se > abs(level) and not f.sc.qd_logged:
            # the positions cannot tell one speed from a crawl that doubles it: no plateau the log
            # resolves (a 15-bit encoder under a joint creeping out of stiction at 0.001-0.005 rad/s for
            # 0.3 s, five counts: foreign issue-19 sweep 101306)
            return a, a
        if abs(float(v[-1] - v[0])) <= max(2.0 * R_STEADY * abs(level), K_NOISE * se):
            return a, b
        cut = max(1, (b - a) // 8)
        if b - a - cut < keep:  # a speed that changes throughout: no plateau
            return a, a
        if abs(float(v[0]) - level) >= abs(float(v[-1]) - level):
            a += cut
        else:
            b -= cut


def _level(f: Features, w: np.ndarray, sigma: float) -> bool:
    """True if the velocity ``w`` [q/s] (noise level ``sigma``) over a candidate plateau is no hump: the top of a smooth move stays
    within the plateau's band (:func:`_extend_plateau`) for a while too, but both its ends lie below its
    middle. Rejected when the mean velocity over each outer quarter differs from the middle half's in
    the same direction, by more than a quarter of the band and ``K_NOISE`` standard errors. (A plateau
    that settles at one end, or drifts under a changing gravity load, has one end off, not both.)"""
    stride = max(1, w.size // 2000, f.sc.window_w // 2)   # samples about independent after smoothing
    y = w[::stride]
    nq = y.size // 4
    if nq < 2:
        return True
    parts = (y[:nq], y[nq:y.size - nq], y[y.size - nq:])
    m = [float(np.mean(x)) for x in parts]
    d = (m[1] - m[0], m[1] - m[2])
    if d[0] * d[1] <= 0:
        return True
    sd = math.sqrt(sum(float(np.sum((x - mx) ** 2)) for x, mx in zip(parts, m)) / max(1, y.size - 3))
    se = sd * math.sqrt(1.0 / nq + 1.0 / parts[1].size)
    band = max(K_NOISE * sigma, R_STEADY * abs(m[1]))
    bend = min(abs(d[0]), abs(d[1]))
    return not (bend > 0.25 * band and bend > K_NOISE * se)


def _plateau_velocity(f: Features, i0: int, i1: int) -> tuple[np.ndarray, int, float]:
    """The velocity [q/s] around the steady run ``[i0, i1)`` (``2 h`` samples each side), the index of
    its first sample and its noise level [q/s]. On a coarse encoder a slow plateau's derivative is a
    staircase (the position moves one step now and then): it is averaged over ``k`` samples, enough for
    its noise to resolve the plateau's band (``K_NOISE`` noise levels within ``R_STEADY`` of the run's
    speed) and at least the time of two encoder steps, at most ``h``. Its noise is then that of a
    position difference over ``k`` samples (``sqrt(2) sigma_q / (k dt)``, ``sigma_q`` at least the
    quantisation's; a logged velocity keeps its own, :func:`_averaged`): the sample velocity's noise ``sigma_w``,
    against which the band was judged before (2026-11-27, session 19), is some ten times larger, and a
    chain of slow levels 23 % apart on a 17-bit encoder (foreign sweep 101330: 0.017 -> 0.0078 rad/s)
    was one band from which no plateau could be cut."""
    lo, hi = max(0, i0 - 2 * f.h), min(f.t.size, i1 + 2 * f.h)
    speed = abs(float(f.q[i1 - 1] - f.q[i0])) / (max(1, i1 - 1 - i0) * f.sc.dt)
    w, sigma = _averaged(f, f.w[lo:hi], speed, f.h)
    return w, lo, sigma


def _averaged(f: Features, w: np.ndarray, speed: float, k_max: int) -> tuple[np.ndarray, float]:
    """The velocity ``w`` [q/s] of a stretch at about ``speed`` [q/s] on a coarse encoder, box-averaged over
    ``k`` samples (at most ``k_max``): the time of two encoder steps and, without a logged velocity (the
    position's derivative is a staircase), enough that ``K_NOISE`` of its noise lie within ``R_STEADY``
    of the speed; and its noise level [q/s] (:func:`_plateau_velocity`). As it is, with ``sigma_w``,
    when the encoder is fine enough; a logged velocity keeps ``sigma_w`` (its band as before session 19:
    a band from the average's noise made the hydraulic sample sweep's stuck joint, creeping at
    0.0017 rad/s under a reversing torque, a plateau)."""
    sigma, dt = f.sc.sigma_w, f.sc.dt
    if f.sc.q_step > 0 and speed > 0:
        sq = max(f.sc.sigma_q, f.sc.q_step / math.sqrt(12.0))
        k = 2.0 * f.sc.q_step / (speed * dt)
        if not f.sc.qd_logged:  # a logged velocity is no staircase: its band stays that of its samples
            k = max(k, K_NOISE * math.sqrt(2.0) * sq / (R_STEADY * speed * dt))
        k = int(min(k_max, math.ceil(k)))
        if k > f.sc.window_w:
            w = box_mean(w, k)
            if not f.sc.qd_logged:
                sigma = min(sigma, math.sqrt(2.0) * sq / (k * dt))
    return w, sigma


def _extend_plateau(f: Features, i0: int, i1: int, code: np.ndarray, w: np.ndarray, off: int, sigma: float
                    ) -> tuple[int, int]:
    """Grow a steady run into its edges while the velocity ``w`` (from sample ``off`` on, reaching
    ``2 h`` beyond the run) stays within the plateau's band."""
    core = w[i0 - off:i1 - off]
    wm = float(np.median(core))
    tol = max(K_NOISE * sigma, R_STEADY * abs(wm))
    lim = 2 * f.h
    lo = max(off, i0 - lim)
    left = w[lo - off:i0 - off][::-1]
    bad = (np.abs(left - wm) > tol) | (code[lo:i0][::-1] >= 0)
    k = int(np.argmax(bad)) if bad.any() else left.size
    i0n = i0 - k
    hi = min(off + w.size, i1 + lim)
    right = w[i1 - off:hi - off]
    bad = (np.abs(right - wm) > tol) | (code[i1:hi] >= 0)
    k = int(np.argmax(bad)) if bad.any() else right.size
    i1n = i1 + k
    # trim inward while the ends are outside the band (the steady mask is wider than the plateau)
    inner = np.flatnonzero(np.abs(w[i0n - off:i1n - off] - wm) <= tol)
    if inner.size:
        i0n, i1n = i0n + int(inner[0]), i0n + int(inner[-1]) + 1
    return i0n, i1n


# ---------------------------------------------------------------------------------------------------
# Rest


def _fine_width(f: Features) -> int:
    """Half-width [samples] of the fine torque slope that edges a loading; twice it, the longest jolt that
    does not end a rest."""
    return max(f.sc.window_w, f.h // 4)


def _loading(f: Features, jumps: np.ndarray, hj: int) -> np.ndarray:
    """Where the torque on a still joint is not steady (per sample): a controller winding up before a
    move, a transient settling after one. A change that holds a torque jump (one of ``jumps``) and is
    one (:func:`_is_jump`: a slow drift whose start edges short near the threshold holds none) after
    which the joint is not moving (still to the sensors from ``h / 2`` to ``h`` samples after it: a jolt the
    jump gives the joint is over by then) is not a loading: a jump alone does not end a rest (the
    definition, docs/segments.md "What a rest is", as both truths apply it). A torque that settles after
    a stop for longer than a jump is a change (foreign card 100907: a PID's torque rising 7.5 -> 9.6 N m
    over 0.1 s after a stop, excused before because the core of its slope was short)."""
    n, hf = f.t.size, _fine_width(f)
    _, loading = _torque_changing(f, hf)
    ls, le = runs(loading)
    moving_c = count_prefix(~f.resting)
    h2 = f.h // 2
    moves_after = moving_c[np.minimum(le + f.h, n)] - moving_c[np.minimum(le + h2, n)] > 0
    # only a change no longer than a jump seen through the wide mean can be one
    js = np.sort(jumps)
    has_jump = np.searchsorted(js, le) > np.searchsorted(js, ls)
    cand = np.flatnonzero((le - ls <= 2 * hf + hj) & has_jump & ~moves_after)
    relax = [k for k in cand.tolist() if _is_jump(f, int(ls[k]), int(le[k]), hj)]
    if relax:
        paint(loading, ls[relax], le[relax], False)
    return loading


def _is_jump(f: Features, a: int, b: int, hj: int) -> bool:
    """True if the torque change edged at ``[a, b)`` is a jump: edged again on means over ``h / 2`` samples
    (the truths' scale, docs/segments.md "What a rest is"; the edges' own mean, over two fine windows, can
    be as long as the change, and hid a 30 ms settling), from the first such mean that leaves the level of
    the ``h`` samples before it to the last that differs from the level of the ``h`` after it by
    ``K_NOISE`` standard errors, it lasts no longer than that mean and ``hj`` samples."""
    n, h, tc = f.t.size, f.h, f.tau_c if f.tau_c is not None else prefix_sum(f.tau)
    hq = max(1, h // 4)
    lo0, hi1 = max(a - h, 0), min(b + h, n)
    if a - lo0 < 1 or hi1 - b < 1:
        return False
    before, after = (tc[a] - tc[lo0]) / (a - lo0), (tc[hi1] - tc[b]) / (hi1 - b)
    i = np.arange(a, b)
    lo, hi = np.maximum(i - hq, 0), np.minimum(i + hq, n)
    m = (tc[hi] - tc[lo]) / (hi - lo)
    thr = K_NOISE * float(f.sigma_tau_loc[a]) * math.sqrt(1.0 / h + 0.5 / hq)
    off = np.flatnonzero(np.abs(m - before) > thr)
    if off.size == 0:
        return True
    last = np.flatnonzero(np.abs(m - after) > thr)
    return (int(last[-1]) if last.size else int(off[0])) - int(off[0]) + 1 <= 2 * hq + hj


def _torque_changing(f: Features, hf: int) -> tuple[np.ndarray, np.ndarray]:
    """Two masks: ``core``, where the torque slope at the feature scale exceeds ``K_NOISE`` standard
    errors under the local torque noise (the torque is not steady, whatever the log's torque range); and
    each run of it edged where the torque itself changes: from the first sample whose mean over ``2 hf``
    samples leaves the mean of the ``h`` samples before the run, to the last one that differs from the
    mean of the ``h`` after it, by ``K_NOISE`` standard errors of the two means (the feature window sees
    a change ``h`` samples early; a slow trend is changing all along). Runs less than ``h`` apart are one
    change (the slope passes through zero where a move's torque turns, e.g. a stop and its settling)."""
    n, sc, h = f.t.size, f.sc, f.h
    core = np.empty(n, dtype=bool)
    for c in chunks(n):  # chunk by chunk: no full-length thresholds or |slopes|
        thr = f.sigma_tau_loc[c] * math.sqrt(2.0 / h)  # K_NOISE sig_s, the noise of f.s
        thr /= h * sc.dt
        thr *= K_NOISE
        np.greater(np.abs(f.s[c]), thr, out=core[c])
    changing = np.zeros(n, dtype=bool)
    cs, ce = runs(fill_short(core, h, False))  # one change through a sign flip of its slope
    tc = f.tau_c if f.tau_c is not None else prefix_sum(f.tau)
    for a, b in zip(cs.tolist(), ce.tolist()):
        before = (tc[a] - tc[max(a - h, 0)]) / max(a - max(a - h, 0), 1)
        after = (tc[min(b + h, n)] - tc[b]) / max(min(b + h, n) - b, 1)
        i = np.arange(a, b)
        lo, hi = np.maximum(i - hf, 0), np.minimum(i + hf, n)
        m = (tc[hi] - tc[lo]) / (hi - lo)
        thr = K_NOISE * float(f.sigma_tau_loc[a]) * math.sqrt(1.0 / h + 0.5 / hf)
        off = np.flatnonzero(np.abs(m - before) > thr)
        if off.size:
            a0 = int(off[0])
            off = np.flatnonzero(np.abs(m[a0:] - after) > thr)
            changing[a + a0:a + a0 + (int(off[-1]) + 1 if off.size else 0)] = True
    return core, changing


def _rest(f: Features, code: np.ndarray, loading: np.ndarray, n_min: int) -> np.ndarray:
    """Where the joint rests (per sample), among the unclassified samples: runs still to the sensors
    (``Features.resting``) outside every torque change (``loading``: the edged changes themselves, no
    speck removed) of at least ``n_min`` samples, of which at least ``n_min`` less a velocity window are
    unclassified. A torque jump alone does not end a rest (:func:`_loading`), nor does the jolt it gives
    the joint: a gap shorter than two fine windows over which the joint moves no farther than a
    presliding deflection (``D_PRESLIDE``: the bristles take up the new torque, the joint does not
    slide). A move does, however short (until 2026-11-27, session 19, every gap shorter than two fine
    windows was filled: a linear axis moving 2.8 mm in 30 ms at 150 Hz between two holds was one rest,
    foreign card 101347)."""
    free = code < 0
    calm = ~loading
    # still to the sensors over T_MIN (the logged position's displacement, not a speed of the log): one
    # statistic for the rest and its edges, the one the definition reads
    rest = _fill_jolts(f, f.resting & calm, 2 * _fine_width(f))
    # at least T_MIN still and steady, judged before a neighbour takes its edge: a segment's edge is
    # known to within its smoothing window (a plateau's edge runs half a velocity window into the stop)
    rest = drop_short(rest, n_min) & free
    return drop_short(rest, max(1, n_min - f.sc.window_w))


def _fill_jolts(f: Features, rest: np.ndarray, longest: int) -> np.ndarray:
    """``rest`` with its gaps shorter than ``longest`` samples filled where the logged position, from the
    sample before the gap to the one after it, spans no more than ``D_PRESLIDE`` (a jolt, not a move)."""
    s, e = runs(~rest)
    inner = (s > 0) & (e < rest.size) & (e - s < longest)
    s, e = s[inner], e[inner]
    if s.size == 0:
        return rest
    # the samples [a - 1, b + 1) of every gap, one after the other (no loop over gaps)
    n = e - s + 2
    first = np.concatenate(([0], np.cumsum(n)[:-1]))
    idx = np.arange(int(n.sum()), dtype=np.int64) + np.repeat(s - 1 - first, n)
    span = np.maximum.reduceat(f.q[idx], first) - np.minimum.reduceat(f.q[idx], first)
    jolt = span <= f.d_preslide
    out = rest.copy()
    paint(out, s[jolt], e[jolt], True)
    return out


# ---------------------------------------------------------------------------------------------------
# Ramps


def _ramp_candidates(f: Features, code: np.ndarray, scale: int) -> np.ndarray:
    """(start, end, sign) rows of monotonic torque runs at half-width ``scale`` samples, outside already
    classified samples; edges where the slope falls to half the run's median (the corners of a ramp)."""
    out = []
    dt = f.sc.dt
    s = f.s if scale == f.h else _slope(f, scale)
    # sign * s > thr, both signs in one pass chunk by chunk (no full-length thresholds)
    up, down = np.empty(s.size, dtype=bool), np.empty(s.size, dtype=bool)
    for c in chunks(s.size):
        thr = 2.0 * f.sigma_tau_loc[c]
        thr *= math.sqrt(2.0 / scale)
        thr /= scale * dt
        np.greater(s[c], thr, out=up[c])
        np.less(s[c], np.negative(thr, out=thr), out=down[c])
    free = code < 0
    for sign, m in ((1, up), (-1, down)):
        m &= free
        for s0, e0 in zip(*closed_runs(m, scale, f.n_min)):
            seg = sign * s[s0:e0]
            half = 0.5 * float(np.median(seg))
            # the longest stretch at or above half the typical slope (the corners of the ramp), short
            # dips closed: noise next to a ramp must not drag its edges out
            a, b = closed_runs(seg >= half, max(1, scale // 4))
            if a.size == 0:
                continue
            k = int(np.argmax(b - a))
            out.append((int(s0 + a[k]), int(s0 + b[k]), sign))
    if not out:
        return np.zeros((0, 3), dtype=np.int64)
    return np.array(sorted(out), dtype=np.int64)


def _ramp_ok(f: Features, i0: int, i1: int, sign: int, tau_b: np.ndarray, code: np.ndarray) -> bool:
    """A torque run is a presliding ramp candidate: long enough, a large enough torque change, a straight
    line within the noise (an open-loop ramp, not a controller wandering) and no sliding."""
    if i1 - i0 < f.n_min or np.any(code[i0:i1] >= 0):
        return False
    dtau = tau_b[i1 - 1] - tau_b[i0]
    sigma = float(np.median(f.sigma_tau_loc[i0:i1]))
    # the torque change must stand out: K_RAMP standard errors of a line fitted through n samples
    if sign * dtau < max(K_RAMP * sigma * math.sqrt(12.0 / (i1 - i0)), 2.0 * sigma):
        return False
    if not _straight(f.t[i0:i1], f.tau[i0:i1], sigma, abs(dtau)):
        return False
    return _no_break_away(f, i0, i1)


def _no_break_away(f: Features, i0: int, i1: int) -> bool:
    """The joint does not break away over ``[i0, i1)``: it is quiet or steadily creeping throughout, or
    its speed never grows beyond ``R_SLIDE`` times its median there (presliding and creep speed up
    smoothly as the load grows, by at most a few times; a joint breaking away under an open-loop ramp
    runs away by orders of magnitude), and it moves no farther than a presliding displacement can
    (``D_PRESLIDE``). The displacement bound holds first, for a steady joint too: a slow cruise at a
    constant speed is steady, and a torque ripple on it (cogging, a position-dependent load) is no
    presliding ramp (the issue-19 ptp logs: 16 "ramps" of 7 mm each on one 0.016 m/s move)."""
    if abs(float(f.q[i1 - 1] - f.q[i0])) > f.d_preslide:  # beyond any bristle deflection: sliding
        return False
    if np.mean(f.steady[i0:i1] | f.quiet[i0:i1]) >= 0.98:
        return True
    aw = np.abs(f.w[i0:i1])
    return bool(np.max(aw) <= R_SLIDE * max(float(np.median(aw)), K_NOISE * f.sigma_wc))


def _ramp_list(f: Features, code: np.ndarray, jumps: np.ndarray) -> list[tuple[int, int, int]]:
    """Qualified ramp candidates at the feature scale, plus those found only at four times that scale
    (slow ramps in noisy torque), without the runs that contain a torque jump."""
    hq = max(1, f.h // 2)
    tau_b = box_mean(f.tau, hq)
    cands = []
    for scale in (f.h, 4 * f.h):
        cand = _ramp_candidates(f, code, scale)
        if cand.size and jumps.size:
            k = np.searchsorted(jumps, cand[:, 0])
            has_jump = (k < jumps.size) & (jumps[np.minimum(k, jumps.size - 1)] < cand[:, 1])
            cand = cand[~has_jump]
        for i0, i1, sign in cand:
            if _ramp_ok(f, int(i0), int(i1), int(sign), tau_b, code):
                cands.append((abs(float(tau_b[i1 - 1] - tau_b[i0])), scale, int(i0), int(i1), int(sign)))
    # overlapping candidates: the one with the largest torque change (a whole ramp, not a fragment)
    cands.sort(key=lambda c: (-c[0], c[1]))
    chosen: list[tuple[int, int, int]] = []
    for _, _, i0, i1, sign in cands:
        if not any(min(i1, b) > max(i0, a) for a, b, _ in chosen):
            chosen.append((i0, i1, sign))
    return sorted(chosen)


def _straight(t: np.ndarray, y: np.ndarray, sigma: float, dtau: float) -> bool:
    """True if ``y(t)`` is a straight line within its noise ``sigma``: the residual of a line fit is at most
    ``R_LINE`` sigma, and a quadratic term is either insignificant (``K_NOISE`` standard errors) or bends
    the line by less than ``R_BEND`` of the torque change ``dtau``."""
    x = t - t.mean()
    x2 = x * x - float(np.mean(x * x))
    A = np.column_stack([x2, x, np.ones_like(x)])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    lin = np.polyfit(x, y, 1)
    r_lin = y - np.polyval(lin, x)
    if float(np.std(r_lin)) > R_LINE * sigma:
        return False
    r = y - A @ coef
    s2 = float(np.dot(r, r)) / max(1, y.size - 3)
    se = math.sqrt(s2 / max(float(np.dot(x2, x2)), 1e-300))
    bend = abs(coef[0]) * float(np.max(np.abs(x2)))
    return not (abs(coef[0]) > K_NOISE * se and bend > R_BEND * dtau)


def _ramps(f: Features, ok: list[tuple[int, int, int]]) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """The ramps that belong to groups that load and unload the joint: the group starts at a hold (a
    still joint under a flat torque) and its connected ramps bring the torque back to that hold's level
    at a hold. A controller unwinding its integrator on a stuck joint after a move makes a one-way ramp
    between two different levels. Returns the ramps and the holds between the ramps of a group (the
    joint under a constant load below break-away: a rest, even if it creeps)."""
    out: list[tuple[int, int]] = []
    holds: list[tuple[int, int]] = []
    gap = f.sc.window_w + f.h // 4
    n = f.t.size
    k = 0
    while k < len(ok):
        s0 = ok[k][0]
        level0 = _hold_level(f, max(0, s0 - gap - f.n_min), max(0, s0 - gap))
        done = k + 1
        if level0 is not None:
            peak = 0.0
            j = k
            while True:
                i0, i1, _ = ok[j]
                seg = f.tau[i0:i1]
                peak = max(peak, float(np.max(np.abs(seg - level0))))
                level = _hold_level(f, min(n, i1 + gap), min(n, i1 + gap + f.n_min))
                sig = float(np.median(f.sigma_tau_loc[i0:i1]))
                both = len({sg for _, _, sg in ok[k: j + 1]}) == 2
                if both and level is not None and _within_bristles(f, s0, i1) and abs(level - level0) <= max(
                        K_NOISE * sig / math.sqrt(f.n_min), R_RETURN * peak) and _holds_slow(
                        f, ok[k:j + 1], (max(0, s0 - gap - f.n_min), max(0, s0 - gap)),
                        (min(n, i1 + gap), min(n, i1 + gap + f.n_min)),
                        *((b, a) for (_, b, _), (a, _, _) in zip(ok[k:j], ok[k + 1:j + 1]) if a - b >= f.n_min)):
                    out.extend((a, b) for a, b, _ in ok[k: j + 1])
                    holds.extend((b, a) for (_, b, _), (a, _, _) in zip(ok[k:j], ok[k + 1:j + 1]) if a - b >= f.n_min)
                    done = j + 1
                    break
                if j + 1 >= len(ok) or not _connected(f, ok[j], ok[j + 1]):
                    break
                j += 1
        k = done
    return out, holds


def _within_bristles(f: Features, i0: int, i1: int) -> bool:
    """A group of ramps (loading and unloading) moves the joint no farther than a presliding displacement
    (``D_PRESLIDE``) in all: a joint sliding steadily under a torque ripple (cogging, a position-dependent
    load on a slow move) passes each ramp's own test on a rotary joint, but not the group's."""
    return float(np.ptp(f.q[i0:i1])) <= f.d_preslide


def _holds_slow(f: Features, ramps: list[tuple[int, int, int]], *holds: tuple[int, int]) -> bool:
    """The holds around a group of ramps are no faster (median speed) than the joint at its fastest under
    the ramps: a creeping joint creeps on, but a plateau on each side of a stuck joint whose controller
    winds up (or of a move) is no loading and unloading. Between two ramps only a hold of at least
    ``T_MIN`` is one (as for the rests): the corner of a ramp that turns without a hold is the ramps'
    fastest point, and its 50 ms were 0.04 % faster than the ramps' straight parts (foreign card 101041:
    0 of 12 ramps)."""
    speed = max(max(float(np.max(np.abs(f.w[a:b]))) for a, b, _ in ramps), K_NOISE * f.sigma_wc)
    return all(float(np.median(np.abs(f.w[a:b]))) <= speed for a, b in holds if b > a)


def _hold_level(f: Features, a: int, b: int) -> float | None:
    """Torque level over ``[a, b)`` if the joint holds there (quiet, creeping steadily or not breaking
    away) under a flat torque, else None."""
    if b - a < max(2, f.n_min // 2) or not _flat(f, a, b):
        return None
    if (f.quiet[a:b] | f.steady[a:b]).mean() <= 0.8 and not _no_break_away(f, a, b):
        return None
    return float(np.mean(f.tau[a:b]))


def _connected(f: Features, r0: tuple[int, int, int], r1: tuple[int, int, int]) -> bool:
    """Two ramps (start, end, sign) belong to one chain when the joint does not slide (break away) between
    them: it is quiet or steady, or does not break away by itself (:func:`_no_break_away`), or moves no
    farther than a presliding displacement and never faster than ``R_SLIDE`` times its median speed under
    the two ramps (the bristles relaxing at a hold after a ramp: fast at first, then still)."""
    e0, s1 = r0[1], r1[0]
    if s1 <= e0:
        return True
    gap = slice(e0, s1)
    if bool(np.all(f.steady[gap] | f.quiet[gap])) or _no_break_away(f, e0, s1):
        return True
    if abs(float(np.ptp(f.q[gap]))) > f.d_preslide:
        return False
    under = max(float(np.median(np.abs(f.w[a:b]))) for a, b, _ in (r0, r1))
    return float(np.max(np.abs(f.w[gap]))) <= R_SLIDE * max(under, K_NOISE * f.sigma_wc)


# ---------------------------------------------------------------------------------------------------
# Duty cycles


def find_duty_cycles(f: Features) -> list[tuple[int, int, int]]:
    """(start, end, cycle index) of each duty cycle (see :mod:`.duty`)."""
    gap_min = max(3, f.sc.window_w // 2)
    tol = max(2 * f.sc.window_w, int(round(2 * T_JUMP / f.sc.dt)))
    # motion as the log's own scales see it (noise, R_QUIET of the top speed): a duty cycle's rests and
    # moves are judged against the whole log, not against the motion around them
    rest = fill_short(np.abs(f.w) < max(K_NOISE * f.sc.sigma_w, R_QUIET * f.sc.w_scale), f.sc.window_w, False)
    cycles = duty_cycles(f.w, ~rest, gap_min, f.n_min, tol, f.sc.sigma_w)
    # a cycle's motion moves the logged position (by more than an encoder step and the position noise):
    # presliding seen in a logged qd, with an encoder that never changes its count, is no duty cycle
    floor = max(f.sc.q_step, K_NOISE * f.sc.sigma_q)
    return [(a, b, c) for a, b, c in cycles if float(np.ptp(f.q[a:b])) > floor]


def _without_experiments(f: Features, cycles: list[tuple[int, int, int]], jumps: np.ndarray, hj: int
                         ) -> list[tuple[int, int, int]]:
    """The duty cycles that contain no experiment of another kind: no torque step group and no
    presliding ramp group, each found on the whole log as if no duty cycle had claimed its samples. In a
    log without sliding, a presliding deflection under repeated ramps or steps (0.02-0.3 mrad, foreign
    card 100677 and 100777) is the joint's fastest motion and repeats as motion and rest; the duty
    cycles, found first, took the experiments' samples. Only a cycle that moves the joint no farther
    than a presliding displacement (``D_PRESLIDE``, the experiments' own bound) can be made of them, so
    only such cycles are checked (the search costs a third of a duty-cycle log's segmentation)."""
    small = [float(np.ptp(f.q[a:b])) <= f.d_preslide for a, b, _ in cycles]
    if not any(small):
        return cycles
    free = np.full(f.t.size, -1, dtype=np.int8)
    ramps = _ramp_list(f, free, jumps)
    exps = _steps(f, free, jumps, ramps, hj) + _ramps(f, ramps)[0]
    if not exps:
        return cycles
    inside = np.zeros(f.t.size + 1, dtype=np.int64)
    for a, b in exps:
        inside[a] += 1
        inside[b] -= 1
    held = count_prefix(np.cumsum(inside[:-1]) > 0)
    return [(a, b, c) for (a, b, c), sm in zip(cycles, small) if not sm or held[b] - held[a] == 0]


def _segment(f: Features, kind: str, i0: int, i1: int, cycle: int | None = None) -> Segment:
    return Segment(kind=kind, i0=int(i0), i1=int(i1), t_start=float(f.t[i0]), t_end=float(f.t[i1 - 1]),
                   cycle=cycle, stats=_stats.segment_stats(f, kind, int(i0), int(i1), cycle))
