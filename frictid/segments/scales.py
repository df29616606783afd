"""The scales of one log, measured from the log itself, and its velocity and acceleration.

Every threshold of the segmentation is a multiple of one of these numbers, so the same code runs on a
0.03 N linear slide and a 300 N m hydraulic joint, at 100 Hz and at 10 kHz, with the velocity logged or not:

- ``dt`` : median sample period [s].
- ``q_step`` : encoder step [rad | m] (the smallest nonzero ``|dq|`` when every ``dq`` is a multiple of
  it; 0 when the position is not quantised).
- ``sigma_q``, ``sigma_qd``, ``sigma_tau`` : white-noise level of position, logged velocity and torque, a
  robust MAD of the fourth difference (a high-pass residual blind to any cubic trend), floored by the
  quantisation noise ``step / sqrt(12)``.
- ``tau_range`` : robust torque range [N m | N] (0.1 to 99.9 percentile).
- ``w_scale``, ``a_scale`` : robust top speed and acceleration of the log (99th percentile of coarse
  differences over ``T_PILOT``).
- ``window_w``, ``window_a`` : the Savitzky-Golay windows [samples] of the velocity and the acceleration,
  the shortest that bring their noise below ``REL_NOISE`` of ``w_scale`` and ``a_scale``, capped at
  ``T_WINDOW_MAX`` seconds.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..data import JointLog
from ..errors import LogFormatError

#: MAD -> standard deviation of a normal distribution.
MAD_TO_SIGMA = 1.482602218505602
#: Variance gain of the fourth difference of white noise: C(8, 4).
DIFF4_GAIN = 70.0
#: Savitzky-Golay polynomial order of the differentiators.
POLYORDER = 2
#: Shortest window [samples] (polyorder + 3).
MIN_WINDOW = 5
#: Longest window [s]: transients of a few tens of ms must survive differentiation.
T_WINDOW_MAX = 0.05
#: The differentiator's noise target, a fraction of the log's speed (acceleration) scale.
REL_NOISE = 2e-3
#: Most differences looked at to find a quantisation step or a global noise level.
QUANTUM_SAMPLES = 1 << 20
#: Noise floor of a noise-free signal, a fraction of its range (keeps every threshold above rounding).
REL_FLOOR = 1e-9
#: Lag of the pilot (coarse) differences that measure the speed and acceleration scales [s].
T_PILOT = 0.05


@dataclass(frozen=True)
class Scales:
    """Scales of one joint log (see the module docstring). Units: [q] = rad or m, [F] = N m or N."""

    n: int
    dt: float
    q_step: float
    sigma_q: float
    sigma_qd: float
    tau_step: float
    sigma_tau: float
    tau_range: float
    w_scale: float
    a_scale: float
    window_w: int
    window_a: int
    sigma_w: float
    sigma_a: float
    qd_logged: bool

    @property
    def fs(self) -> float:
        """Sample rate [Hz]."""
        return 1.0 / self.dt

    def to_dict(self) -> dict:
        return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in asdict(self).items()}


def median_inplace(d: np.ndarray):
    """``np.median(d, axis=-1, overwrite_input=True)`` of a non-empty float array, the same numbers (the
    middle value, or the mean of the two middle ones, NaN where a NaN is present), ``d`` reordered.
    numpy partitions at the two middle places and at the last one (to find a NaN) in one call, which on a
    log's million samples is ten times one partition at the upper middle place followed by the maxima of
    the halves on either side of it."""
    n = d.shape[-1]
    h = n // 2
    d.partition(h, axis=-1)
    mid = d[..., h]
    top = d[..., h:].max(axis=-1)  # NaN wherever a NaN is: partition puts NaNs after every number
    if n % 2 == 0:
        mid = (d[..., :h].max(axis=-1) + mid) / 2.0
    return np.where(np.isnan(top), top, mid) if d.ndim > 1 else (top if np.isnan(top) else mid)


def noise_sigma(x: np.ndarray) -> float:
    """Robust white-noise standard deviation of ``x``: MAD of its fourth difference / sqrt(70)."""
    x = np.asarray(x, dtype=float)
    if x.size < 6:
        return 0.0
    if x.size > QUANTUM_SAMPLES:  # evenly spaced blocks estimate a median to well under 1 %
        nb = 64
        step = QUANTUM_SAMPLES // nb
        starts = np.linspace(0, x.size - step, nb).astype(np.int64)
        d = np.concatenate([np.diff(x[s:s + step], 4) for s in starts])
    else:
        d = np.diff(x, 4)
    return float(MAD_TO_SIGMA * median_inplace(np.abs(d, out=d)) / math.sqrt(DIFF4_GAIN))


def local_noise(x: np.ndarray, block: int, lag: int = 1) -> np.ndarray:
    """Per-sample robust noise standard deviation of ``x`` (noise that changes along the log, e.g. a
    controller switched on): the MAD of the fourth difference in blocks of ``block`` samples, the larger
    of each block's and its neighbours' values (so a boundary is covered from both sides).

    ``lag`` > 1: the fourth difference of samples ``lag`` apart (spanning ``4 lag`` samples), placed at
    its centre, edges repeated: the scatter of ``x`` about any cubic over ``4 lag`` samples, white noise
    as at lag 1 and a jitter correlated over fewer than ``lag`` samples too (a position loop hunting in
    a hold, which the first difference of neighbouring samples does not see)."""
    x = np.asarray(x, dtype=float)
    n = x.size
    block = max(8, int(block))
    lag = max(1, int(lag))
    if n < 2 * block or n <= 4 * lag + 8:
        return np.full(n, noise_sigma(x[::lag]))
    if lag == 1:
        d = np.diff(x, 4)
    else:
        d = np.empty(n)
        m = n - 4 * lag
        c = d[2 * lag:2 * lag + m]
        np.subtract(x[4 * lag:], 4.0 * x[3 * lag:n - lag], out=c)
        c += 6.0 * x[2 * lag:n - 2 * lag]
        c -= 4.0 * x[lag:n - 3 * lag]
        c += x[:m]
        d[:2 * lag] = c[0]
        d[2 * lag + m:] = c[-1]
    np.abs(d, out=d)
    nb = d.size // block
    sig = MAD_TO_SIGMA * median_inplace(d[:nb * block].reshape(nb, block)) / math.sqrt(DIFF4_GAIN)
    if d.size > nb * block:
        sig = np.append(sig, MAD_TO_SIGMA * median_inplace(d[nb * block:]) / math.sqrt(DIFF4_GAIN)
                        if d.size - nb * block >= 8 else sig[-1])
    padded = np.concatenate(([sig[0]], sig, [sig[-1]]))
    sig = np.maximum(np.maximum(padded[:-2], padded[1:-1]), padded[2:])
    # sample i takes block min(i // block, last): whole blocks, then the last value to the end
    out = np.empty(n)
    m = (sig.size - 1) * block
    out[:m].reshape(sig.size - 1, block)[...] = sig[:-1, None]
    out[m:] = sig[-1]
    return out


def quantum(x: np.ndarray) -> float:
    """Quantisation step of ``x``: the smallest nonzero ``|dx|`` if (nearly) every ``|dx|`` is an integer
    multiple of it, else 0 (``x`` is not quantised)."""
    x = np.asarray(x, dtype=float)
    if x.size < 3:
        return 0.0
    if x.size > QUANTUM_SAMPLES:  # evenly spaced blocks are enough to see a grid
        nb = 64
        starts = np.linspace(0, x.size - QUANTUM_SAMPLES // nb, nb).astype(np.int64)
        d = np.abs(np.concatenate([np.diff(x[s:s + QUANTUM_SAMPLES // nb]) for s in starts]))
    else:
        d = np.abs(np.diff(x))
    tol = 1e-9 * max(_abs_max(x), 1e-300)
    nz = d[d > tol]
    if nz.size < 10:
        return 0.0
    step = float(np.min(nz))
    r = nz / step
    r = r[r < 1e6]
    on_grid = np.abs(r - np.round(r)) < 0.05
    return step if on_grid.mean() > 0.95 else 0.0


def _abs_max(x: np.ndarray) -> float:
    """``np.max(np.abs(x))`` without the full-length ``|x|``."""
    return max(float(np.max(x)), -float(np.min(x)))


def _odd(n: float) -> int:
    k = int(math.ceil(n))
    return k if k % 2 == 1 else k + 1


def _sg_noise_gain(window: int, deriv: int, dt: float) -> float:
    """Output standard deviation per unit input white noise of a Savitzky-Golay filter."""
    from scipy.signal import savgol_coeffs  # scipy.signal costs ~0.5 s to import: only when used

    c = savgol_coeffs(window, POLYORDER, deriv=deriv, delta=dt)
    return float(np.sqrt(np.sum(c * c)))


def _choose_window(sigma_in: float, target: float, deriv: int, dt: float, n_max: int) -> int:
    """The shortest odd window whose output noise (input ``sigma_in``, derivative ``deriv``) is below
    ``target``; at most ``n_max``."""
    n_max = max(MIN_WINDOW, n_max if n_max % 2 else n_max - 1)
    if sigma_in <= 0 or not math.isfinite(target) or target <= 0:
        return MIN_WINDOW if sigma_in <= 0 else n_max
    # noise of a polyorder-2 SG derivative falls as N^-(2 deriv + 1)/2: start from that law, then check
    gain5 = _sg_noise_gain(MIN_WINDOW, deriv, dt) * sigma_in
    if gain5 <= target:
        return MIN_WINDOW
    est = MIN_WINDOW * (gain5 / target) ** (2.0 / (2 * deriv + 1))
    w = min(_odd(est), n_max)
    while w < n_max and _sg_noise_gain(w, deriv, dt) * sigma_in > target:
        w = min(_odd(w * 1.2), n_max)
    return w


def log_position(log: JointLog) -> np.ndarray:
    """Position [q]: as logged, or the trapezoidal integral of the logged velocity from 0."""
    if log.q is not None:
        return np.asarray(log.q, dtype=float)
    qd = np.asarray(log.qd, dtype=float)
    q = np.empty_like(qd)
    q[0] = 0.0
    np.cumsum(0.5 * (qd[1:] + qd[:-1]) * np.diff(log.t), out=q[1:])
    return q


#: A logged qd is the position's difference when it equals ``dq / dt`` on this share of the samples ...
R_DIFF_SHARE = 0.99
#: ... within this fraction of one encoder step (or of the position's noise) per sample period.
R_DIFF_TOL = 0.01


def qd_is_difference(log: JointLog) -> bool:
    """True if the logged ``qd`` is the difference of the logged position over one sample period
    (backward or forward; a drive's velocity from its encoder count): then it carries nothing the
    position does not, and its noise is the position's quantisation differenced (a sum over ``k``
    samples telescopes to two readings), not the white noise of ``sigma_qd`` per sample that every
    average of ``qd`` would assume (a 13-bit encoder at 9 kHz: single counts of 7 rad/s, a joint at
    0.3 rad/s "within the noise"). Judged on the samples where the position changes, within
    ``R_DIFF_TOL`` of the position's resolution per period, on ``R_DIFF_SHARE`` of them."""
    if log.q is None or log.qd is None or log.n < 16:
        return False
    return difference_lag(log.q, log.qd, log.t) != 0.0


def difference_lag(q, qd, t) -> float:
    """The lag [sample periods] of a velocity ``qd`` that is the difference of the position ``q`` over one
    sample period (:func:`qd_is_difference`'s test): 0.5 for a backward difference (``qd[i] = (q[i] -
    q[i-1]) / dt``, the velocity at the middle of the period before the sample), -0.5 for a forward one,
    0 when ``qd`` is neither (measured, filtered, or a bad log)."""
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    t = np.asarray(t, dtype=float)
    m = min(q.shape[0], QUANTUM_SAMPLES)
    if m < 16:
        return 0.0
    dq, dt = np.diff(q[:m]), np.diff(t[:m])
    if not (np.all(dt > 0) and np.all(np.isfinite(dq)) and np.all(np.isfinite(qd[:m]))):
        return 0.0  # a bad log: estimate_scales refuses it
    moved = dq != 0
    if moved.sum() < 10:
        return 0.0
    res = max(quantum(q[:m]), noise_sigma(q[:m]), REL_FLOOR * max(_abs_max(q[:m]), 1e-300))
    d = dq / dt
    tol = R_DIFF_TOL * res / dt
    for lo, hi, lag in ((1, m, 0.5), (0, m - 1, -0.5)):  # backward: qd[i] = (q[i] - q[i-1]) / dt; forward
        if np.mean(np.abs(qd[lo:hi] - d)[moved] <= tol[moved]) >= R_DIFF_SHARE:
            return lag
    return 0.0


def _check(log: JointLog) -> np.ndarray:
    """The sample periods ``diff(t)`` [s], after checking the log."""
    problems = []
    if log.q is None and log.qd is None:
        problems.append("neither position 'q' nor velocity 'qd' is present; one is required")
    for name in ("t", "tau", "q", "qd"):
        v = getattr(log, name)
        if v is not None and not np.all(np.isfinite(v)):
            problems.append(f"column {name!r} holds missing or infinite values; read logs with "
                            "frictid.io.logs.read_logs, which drops or refuses them")
    dts = np.diff(np.asarray(log.t, dtype=float))
    if log.n >= 2 and np.any(dts <= 0):
        problems.append("column 't': time must increase strictly")
    if problems:
        raise LogFormatError(log.source or f"joint {log.joint}", problems)
    return dts


def estimate_scales(log: JointLog) -> Scales:
    """Measure the noise levels, encoder step, torque range, speed scales and derivative windows of
    ``log``. Raises :class:`LogFormatError` on non-finite values or non-increasing time."""
    dts = _check(log)
    n = log.n
    dt = float(np.median(dts)) if n > 1 else 1.0  # log.dt, from the periods already at hand
    del dts
    tau = np.asarray(log.tau, dtype=float)
    q = log_position(log)
    lag = max(1, min(n // 4, int(round(T_PILOT / dt))))
    n_max = max(MIN_WINDOW, min(_odd(T_WINDOW_MAX / dt), n // 2 if (n // 2) % 2 else n // 2 - 1))

    if n:
        lo, hi = np.percentile(tau, [0.1, 99.9])
    else:
        lo = hi = 0.0
    tau_range = float(hi - lo)
    q_range = float(np.ptp(q)) if n else 0.0
    q_step = quantum(q) if log.q is not None else 0.0
    sigma_q = max(noise_sigma(q), q_step / math.sqrt(12.0), REL_FLOOR * max(q_range, _abs_max(q)))
    tau_step = quantum(tau)
    sigma_tau = max(noise_sigma(tau), tau_step / math.sqrt(12.0), REL_FLOOR * max(tau_range, 1e-300))

    if n > 2 * lag:
        w_pilot = (q[2 * lag:] - q[:-2 * lag]) / (2 * lag * dt)
        w_scale = float(np.percentile(np.abs(w_pilot, out=w_pilot), 99, overwrite_input=True))
        a_pilot = (q[2 * lag:] - 2 * q[lag:-lag] + q[:-2 * lag]) / (lag * dt) ** 2
        a_scale = float(np.percentile(np.abs(a_pilot, out=a_pilot), 99, overwrite_input=True))
        del w_pilot, a_pilot
    else:
        w_scale = a_scale = 0.0

    if log.qd is not None:
        qd = np.asarray(log.qd, dtype=float)
        qd_step = quantum(qd)
        sigma_qd = max(noise_sigma(qd), qd_step / math.sqrt(12.0), REL_FLOOR * max(float(np.ptp(qd)), 1e-300))
        window_w = _choose_window(sigma_qd, REL_NOISE * w_scale, 0, dt, n_max)
        window_a = _choose_window(sigma_qd, REL_NOISE * a_scale, 1, dt, n_max)
        sigma_w = sigma_qd * _sg_noise_gain(window_w, 0, dt)
        sigma_a = sigma_qd * _sg_noise_gain(window_a, 1, dt)
    else:
        sigma_qd = float("nan")
        window_w = _choose_window(sigma_q, REL_NOISE * w_scale, 1, dt, n_max)
        window_a = _choose_window(sigma_q, REL_NOISE * a_scale, 2, dt, n_max)
        sigma_w = sigma_q * _sg_noise_gain(window_w, 1, dt)
        sigma_a = sigma_q * _sg_noise_gain(window_a, 2, dt)
    return Scales(n=n, dt=float(dt), q_step=q_step, sigma_q=sigma_q, sigma_qd=sigma_qd, tau_step=tau_step,
                  sigma_tau=sigma_tau, tau_range=tau_range, w_scale=w_scale, a_scale=a_scale,
                  window_w=window_w, window_a=window_a, sigma_w=float(sigma_w), sigma_a=float(sigma_a),
                  qd_logged=log.qd is not None)


def velocity(log: JointLog, scales: Scales | None = None, smooth_logged: bool = False) -> np.ndarray:
    """Velocity [q/s] of ``log``: the logged ``qd`` as is (smoothed by the velocity window if
    ``smooth_logged``), else the Savitzky-Golay first derivative of ``q`` (window ``scales.window_w``,
    polyorder 2, ``mode="interp"``)."""
    from scipy.signal import savgol_filter  # lazily: see _sg_noise_gain

    sc = scales or estimate_scales(log)
    if log.n < MIN_WINDOW:
        return np.asarray(log.qd, dtype=float).copy() if log.qd is not None else np.gradient(log.q, log.t)
    if log.qd is not None:
        qd = np.asarray(log.qd, dtype=float)
        return savgol_filter(qd, sc.window_w, POLYORDER) if smooth_logged else qd.copy()
    return savgol_filter(np.asarray(log.q, dtype=float), sc.window_w, POLYORDER, deriv=1, delta=sc.dt)


def derivatives(log: JointLog, scales: Scales | None = None, smooth_logged: bool = False
                ) -> tuple[np.ndarray, np.ndarray]:
    """Velocity [q/s] and acceleration [q/s^2] of ``log``, one value per sample.

    Velocity: as :func:`velocity`. Acceleration: the Savitzky-Golay first derivative of ``qd`` when logged,
    else the second derivative of ``q``. Windows and polynomial order as in :func:`estimate_scales`
    (``scales.window_w``, ``scales.window_a``; polyorder 2, ``mode="interp"``).
    """
    from scipy.signal import savgol_filter  # lazily: see _sg_noise_gain

    sc = scales or estimate_scales(log)
    w = velocity(log, sc, smooth_logged)
    if log.n < MIN_WINDOW:
        return w, np.gradient(w, log.t) if log.n > 1 else np.zeros_like(w)
    if log.qd is not None:
        a = savgol_filter(np.asarray(log.qd, dtype=float), sc.window_a, POLYORDER, deriv=1, delta=sc.dt)
    else:
        a = savgol_filter(np.asarray(log.q, dtype=float), sc.window_a, POLYORDER, deriv=2, delta=sc.dt)
    return w, a
