"""Step 0 of a joint's fit: its logs made ready (velocity, acceleration, segments) and the data's scales.

:func:`prepare` turns a joint's :class:`~frictid.data.JointLog` objects into :class:`Prep` items (one per
log, with the index of the source it came from) inside a :class:`JointData`, which every later step of
:mod:`frictid.identify` works on. The caller's logs are not changed. Also here: the record of the segments a
log was cut into (:func:`segment_list`, read back by :func:`segments_from_list`), the test for logs that
cannot identify anything (:func:`unidentifiable`) and the segment kinds kept out of the inertia/gravity
regression (:func:`regression_exclude`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from frictid import segments as seg
from frictid.data import SEGMENT_KINDS, JointLog, Segment
from frictid.errors import FrictidInputError
from frictid.result import JointFit
from frictid.segments.detect import K_NOISE, T_MIN

#: Segment kinds whose moving samples enter the inertia/gravity regression.
REGRESSION_EXCLUDE = ("ramp_presliding", "step", "rest")
#: Samples of plateaus / excitation above which duty cycles stay out of the J / gravity regression.
MIN_OTHER_SAMPLES = 2000
#: Moving samples: |w| above this fraction of the 99.5th percentile of |w|.
MIN_SPEED_FRACTION = 0.02


@dataclass
class Prep:
    """One log of a joint, ready for fitting."""

    log: JointLog
    index: int  # source index
    w: np.ndarray
    a: np.ndarray
    segments: list[Segment]
    F: np.ndarray | None = None
    G: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    scales: object = None  # the log's frictid.segments.Scales when the default derivatives measured them
    smoothed: bool = False  # w is the logged velocity smoothed (:func:`logged_velocity_too_noisy`)
    _trig: tuple | None = None

    def trig(self) -> tuple[np.ndarray, np.ndarray]:
        """cos q and sin q, computed once: the friction torque is formed again with every new estimate of
        the gravity terms (:func:`frictid.identify.mechanics.rigid_body` drops them once the estimates are
        final)."""
        if self._trig is None:
            self._trig = (np.cos(self.log.q), np.sin(self.log.q))
        return self._trig


@dataclass
class JointData:
    """A joint being fitted: its result so far, its prepared logs, the scales of its data and the time
    spans of the segments each step used (``segments_used`` of the result, set by the last step).

    w0, F0, a0 : 99.5th percentiles of |w|, |tau - median| and |a| [q/s, F, q/s^2];
    min_speed : moving samples are faster than this [q/s]."""

    jf: JointFit
    preps: list[Prep]
    w0: float
    F0: float
    a0: float
    min_speed: float
    used: dict[str, list] = field(default_factory=dict)

    @property
    def axis(self) -> str:
        return self.jf.axis


#: A log that is one steady run: its first third is the start transient ...
STEADY_START = 1 / 3
#: ... and over the rest the velocity keeps one sign (at most this fraction of samples of the other sign),
STEADY_OPPOSITE = 0.05
#: its 10 batch means stay within this fraction of their mean and the mean is this many standard errors
#: away from zero.
STEADY_SPREAD = 0.25
STEADY_Z = 5.0


def steady_run(log: JointLog, w: np.ndarray) -> list[Segment] | None:
    """Segments of a log that is a single steady run at one velocity (a test bench that logs one file per
    commanded speed): ``other`` for the first third, ``constant_velocity`` for the rest; ``None`` when the
    log is not one (its velocity changes sign or level, or is not clearly away from zero)."""
    n = log.n
    i0 = int(STEADY_START * n)
    ww = np.asarray(w[i0:], dtype=float)
    if ww.size < 20 or not np.all(np.isfinite(ww)):
        return None
    m = float(ww.mean())
    if m == 0.0 or np.mean(np.sign(ww) == -np.sign(m)) > STEADY_OPPOSITE:
        return None
    bm = np.array([b.mean() for b in np.array_split(ww, 10)])
    sd = float(np.std(bm, ddof=1))
    if sd > STEADY_SPREAD * abs(m) or abs(m) < STEADY_Z * sd / math.sqrt(bm.size):
        return None
    t = log.t
    return [Segment("other", 0, i0, float(t[0]), float(t[max(i0 - 1, 0)])),
            Segment("constant_velocity", i0, n, float(t[i0]), float(t[-1]),
                    stats={"w_mean": m})]


def segment_list(source: int, rows: int, segments: list[Segment], scales=None) -> dict:
    """The parameter file's record of one log's segments (``segment_list``; cycle -1 when none), with the
    log's scales (noise levels and derivative windows, :class:`frictid.segments.Scales`) when given."""
    out = {"source": int(source), "rows": int(rows), "kind": [s.kind for s in segments],
           "i0": [int(s.i0) for s in segments], "i1": [int(s.i1) for s in segments],
           "cycle": [-1 if s.cycle is None else int(s.cycle) for s in segments]}
    if scales is not None:
        out["scales"] = scales.to_dict()
    return out


def segments_from_list(entry: dict, t: np.ndarray) -> list[Segment]:
    """The segments of a ``segment_list`` entry on a log with times ``t`` [s] (the same rows)."""
    return [Segment(str(k), int(a), int(b), float(t[int(a)]), float(t[int(b) - 1]),
                    cycle=None if int(c) < 0 else int(c))
            for k, a, b, c in zip(entry["kind"], entry["i0"], entry["i1"], entry["cycle"])]


def logged_velocity_too_noisy(sc) -> bool:
    """Whether a log's logged velocity is too noisy to use sample by sample: its noise (at least its
    quantisation step over root 12) above the speed that tells a moving sample from a still one
    (:data:`MIN_SPEED_FRACTION` of the motion's speed scale). A drive's backward difference of a coarse
    encoder at a high rate is 0 or one count per sample period (12 bits at 8 kHz: 12 rad/s), so every
    non-zero sample would pass for fast motion and the friction columns would see only +-one count per
    period; the fit then takes the logged velocity smoothed by the velocity window, as segmentation does
    (:func:`frictid.segments.velocity`)."""
    return bool(sc.qd_logged and np.isfinite(sc.sigma_qd) and sc.sigma_qd > MIN_SPEED_FRACTION * sc.w_scale)


def velocity_noise(p: Prep, sc) -> float:
    """The noise [q/s] of a log's velocity as the fit uses it: the scales' ``sigma_w``, or, for a logged
    velocity the fit smoothed (a coarse encoder's backward difference) of a log with positions, at most
    the position's noise through the same window: the smoothed count is the position's derivative over
    the window, whose noise is the position's quantisation, not one count per sample (a 12-bit, 2 kHz log
    moving at 0.5 rad/s read as "no motion" with the count's 0.9 rad/s noise)."""
    if not p.smoothed or p.log.q is None:
        return sc.sigma_w
    from scipy.signal import savgol_coeffs

    c = savgol_coeffs(sc.window_w, 2, deriv=1, delta=sc.dt)
    return min(sc.sigma_w, sc.sigma_q * float(np.sqrt(np.sum(c * c))))


def _prep(lg: JointLog, source: int, segmenter: Callable, differentiate: Callable) -> tuple[Prep, bool]:
    """One log ready for fitting, and whether it is a single steady run (:func:`steady_run`)."""
    scales, smooth = None, False
    if differentiate is seg.derivatives:  # the default: keep the scales it measures (segment_list)
        scales = seg.estimate_scales(lg)
        smooth = logged_velocity_too_noisy(scales)
        w, a = seg.derivatives(lg, scales, smooth_logged=smooth)
    else:
        w, a = differentiate(lg)
    w, a = np.asarray(w, float), np.asarray(a, float)
    # a steady run is judged on the velocity as logged: its mean is the run's, and a coarse one dithers
    # between 0 and one count without changing sign, where the smoothed one overshoots at each count;
    # such a run is one plateau whose mean is all the fit takes, so it keeps the velocity as logged (the
    # real screw drives' 1-rpm counts: smoothed, the diagnosis read the overshoots as a 30 ms delay)
    segs = steady_run(lg, np.asarray(lg.qd, float) if smooth else w)
    if segs is not None and smooth:
        smooth = False
        w, a = (np.asarray(x, float) for x in seg.derivatives(lg, scales))
    steady = segs is not None
    if segs is None:  # the default segmenter takes the scales already measured
        segs = seg.find_segments(lg, scales) if segmenter is seg.find_segments and scales else segmenter(lg)
    return Prep(lg, source, w, a, list(segs), scales=scales, smoothed=smooth), steady


def prepare(jlogs: list[JointLog], sources: list[int], segmenter: Callable, differentiate: Callable
            ) -> JointData:
    """A joint's logs ready for fitting: derivatives and segments of each log (``sources[i]`` is the index
    of log i's source in the fit's ``sources``), the segment counts and ``segment_list`` of the result,
    and the scales of the data. segmenter(log) -> segments, differentiate(log) -> (w, a)."""
    axis = jlogs[0].axis
    jf = JointFit(joint=str(jlogs[0].joint), axis=axis, units=dict(jlogs[0].units))
    if any(lg.axis != axis for lg in jlogs):
        raise FrictidInputError(f"joint {jf.joint}: logs disagree on the axis (rotary / linear)")
    preps: list[Prep] = []
    n_steady = 0
    for lg, source in zip(jlogs, sources):
        p, steady = _prep(lg, source, segmenter, differentiate)
        preps.append(p)
        n_steady += steady
        jf.warnings.extend(lg.warnings)
    if n_steady:
        jf.warnings.append(f"{n_steady} of {len(jlogs)} logs are single steady runs at one velocity: the last "
                           f"{1 - STEADY_START:.0%} of each is one constant-velocity plateau")
    jf.segments = {k: 0 for k in SEGMENT_KINDS}
    for p in preps:
        for s in p.segments:
            jf.segments[s.kind] = jf.segments.get(s.kind, 0) + 1
    jf.segment_list = [segment_list(p.index, p.log.n, p.segments, p.scales) for p in preps]
    w0 = _abs_percentile([p.w for p in preps])
    F0 = _abs_percentile([p.log.tau for p in preps], centre=True)
    a0 = _abs_percentile([p.a for p in preps])
    F0 = F0 if F0 > 0 else 1.0
    if w0 <= 0:
        jf.warnings.append("no motion in the logs: nothing that depends on velocity can be identified")
    return JointData(jf, preps, w0, F0, a0, MIN_SPEED_FRACTION * w0)


def _abs_percentile(arrays: list[np.ndarray], centre: bool = False) -> float:
    """The 99.5th percentile of ``|x|`` over the finite values of ``arrays`` (of ``|x - median(x)|`` when
    ``centre``); 0 when there are none. One copy of the values, worked on in place and freed on return:
    the three concatenations of every finite velocity, torque and acceleration sample that the fit kept to
    its end were 87 MB of a joint-hour's 280 MB baseline."""
    x = np.concatenate([v[np.isfinite(v)] for v in arrays])
    if not x.size:
        return 0.0
    if centre:
        x -= np.median(x, overwrite_input=True)  # an order statistic: the same value after the partition
    return float(np.percentile(np.abs(x, out=x), 99.5, overwrite_input=True))


def unidentifiable(preps: list[Prep]) -> str | None:
    """Why no friction parameter can be identified from a joint's logs, or None. Judged against each log's
    own scales (:func:`frictid.segments.estimate_scales`): no motion (fewer than a shortest segment's worth
    of samples, ``T_MIN``, faster than ``K_NOISE`` velocity noise levels) or a flat torque signal (its
    0.1-99.9 percentile range within one quantisation step: a dead, disconnected or saturated sensor)."""
    moving = need = 0
    flat = True
    for p in preps:
        sc = p.scales or seg.estimate_scales(p.log)
        moving += int(np.sum(np.abs(p.w) > K_NOISE * velocity_noise(p, sc)))
        need = max(need, int(round(T_MIN / sc.dt)))
        flat &= sc.tau_range <= sc.tau_step
    if moving < need:
        return (f"no motion: only {moving} samples move faster than {K_NOISE:g} velocity noise levels "
                f"(a shortest segment is {need}); nothing that depends on velocity can be identified")
    if flat:
        return ("flat torque signal: the torque does not change by more than one quantisation step while "
                "the joint moves (a dead, disconnected or saturated sensor?); no friction can be identified")
    return None


def regression_exclude(preps: list[Prep]) -> tuple[str, ...]:
    """Segment kinds kept out of the inertia/gravity regression. Duty cycles are kept out when other
    moving segments (plateaus, excitation) provide at least :data:`MIN_OTHER_SAMPLES` samples: friction
    changes with temperature during duty cycles (002 section IV) and a constant-friction regression over
    them biases J and gravity."""
    other = sum(s.n for p in preps for s in p.segments
                if s.kind not in REGRESSION_EXCLUDE and s.kind != "duty_cycle")
    has_duty = any(s.kind == "duty_cycle" for p in preps for s in p.segments)
    return REGRESSION_EXCLUDE + (("duty_cycle",) if has_duty and other >= MIN_OTHER_SAMPLES else ())
