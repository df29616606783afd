"""A torque ripple that follows the position: ``rip_sin sin(2 pi q / P) + rip_cos cos(2 pi q / P)``.

A motor's cogging or a gear's tooth meshing adds a torque that repeats with the position, the same at every
pass whatever the speed and direction (UR10e joint 5: 0.22 N m every 2 pi / 807 rad, eight periods per
motor turn through its 101:1 drive; docs/realdata.md). This module gives the numbers to find its period;
:func:`.reversals.reversal_lugre` decides whether the model keeps it, on the held-out time blocks.

- :func:`period_band`: the periods tried, from the data: from :data:`MIN_STEPS` position steps (the encoder's
  quantisation, else its noise) to :data:`MAX_STROKE` of the median stroke between reversals;
- :func:`best_period`: the period whose sine and cosine explain most of a residual: its periodogram over the
  position (the samples are not evenly spaced in position; their residual is summed in bins of an eighth of
  the shortest period and Fourier-transformed, zero-padded so that a period's phase drifts by at most
  ``1 / OVERSAMPLE`` of a turn between neighbouring periods over the travel covered).

Arrays in, numbers out; truth is never read.
"""
from __future__ import annotations

import numpy as np

#: The shortest period tried: this many position steps.
MIN_STEPS = 20.0
#: The longest: this share of the median stroke between reversals.
MAX_STROKE = 0.5
#: Zero padding of the periodogram: neighbouring frequencies 1 / (OVERSAMPLE x the travel covered) apart.
OVERSAMPLE = 8
#: Position bins per shortest period.
BINS_PER_PERIOD = 8
#: At most this many bins (the shortest periods raised to fit).
MAX_BINS = 1 << 16


def period_band(q: np.ndarray, step: float, stroke: float) -> tuple[tuple[float, float] | None, str]:
    """The shortest and longest period [q] tried on positions ``q`` (the samples used), or None with the
    reason."""
    span = float(np.ptp(q)) if q.size else 0.0
    p_lo, p_hi = MIN_STEPS * step, MAX_STROKE * stroke
    p_lo = max(p_lo, BINS_PER_PERIOD * span / MAX_BINS)
    if not (p_lo > 0 and p_hi > 4.0 * p_lo and span > p_hi):
        return None, (f"the travel ({span:.3g}) and strokes (median {stroke:.3g}) leave no periods between "
                      f"{MIN_STEPS:g} position steps ({p_lo:.3g}) and half a stroke")
    return (p_lo, p_hi), ""


def columns(q: np.ndarray, period: float) -> np.ndarray:
    """The ripple's two columns ``sin(2 pi q / P), cos(2 pi q / P)`` at positions q."""
    x = (2.0 * np.pi / period) * np.asarray(q, dtype=float)
    return np.column_stack([np.sin(x), np.cos(x)])


def best_period(q: np.ndarray, r: np.ndarray, band: tuple[float, float]) -> tuple[float, float, bool]:
    """The period in ``band`` whose sine and cosine explain most of ``r`` (its mean removed), the spacing of
    neighbouring periods there (relative) and whether it lies at the band's end."""
    q = np.asarray(q, dtype=float)
    r = np.asarray(r, dtype=float) - float(np.mean(r))
    p_lo, p_hi = band
    h = p_lo / BINS_PER_PERIOD
    idx = np.floor((q - q.min()) / h).astype(np.int64)
    R = np.bincount(idx, weights=r, minlength=int(idx.max()) + 1)
    n_fft = 1 << int(np.ceil(np.log2(OVERSAMPLE * R.size)))
    X = np.fft.rfft(R, n_fft)
    f = np.fft.rfftfreq(n_fft, d=h)
    sel = np.flatnonzero((f >= 1.0 / p_hi) & (f <= 1.0 / p_lo))
    j = sel[int(np.argmax(np.abs(X[sel])))]
    return 1.0 / float(f[j]), float(f[1] / f[j]), bool(j in (sel[0], sel[-1]))
