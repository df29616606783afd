"""Per-kind statistics of a segment (units of the log: [q] rad or m, [F] N m or N, s).

constant_velocity : ``w_mean``, ``w_std`` [q/s], ``tau_mean``, ``tau_std`` [F].
ramp_presliding : ``tau_slope`` [F/s] (least squares), ``tau_start``, ``tau_end``, ``tau_peak`` [F] (largest
    |tau|, signed), ``displacement`` [q] (q at the end minus q at the start), ``stiffness`` [F/q] (least-squares
    slope of tau against q: the sigma0 estimate of MODELS.md section 4).
step : ``step_size`` [F] (torque after minus before), ``tau_before``, ``tau_after`` [F], ``displacement`` [q]
    (settled position minus position before), ``settling`` [s] (time from the step until q stays within
    ``max(5 % of |displacement|, 3 sigma_q, one encoder step)`` of its final value), ``overshoot`` [1].
duty_cycle : ``period`` [s], ``moving_fraction`` [1], ``w_rms`` [q/s], ``tau_rms`` [F], ``power`` [F q/s]
    (mean of tau w) (the cycle index is the row's ``cycle``).
rest : ``q_mean`` [q], ``tau_mean``, ``tau_std`` [F].
other : ``w_mean`` [q/s], ``tau_mean`` [F].
"""
from __future__ import annotations

import math

import numpy as np

#: Statistic columns in table order.
STAT_COLUMNS = (
    "w_mean", "w_std", "tau_mean", "tau_std",
    "tau_slope", "tau_start", "tau_end", "tau_peak", "displacement", "stiffness",
    "step_size", "tau_before", "tau_after", "settling", "overshoot",
    "period", "moving_fraction", "w_rms", "tau_rms", "power",
    "q_mean",
)


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    x = x - x.mean()
    den = float(np.dot(x, x))
    return float(np.dot(x, y - y.mean()) / den) if den > 0 else math.nan


def segment_stats(f, kind: str, i0: int, i1: int, cycle: int | None = None) -> dict[str, float]:
    """Statistics of samples ``[i0, i1)`` of the features ``f`` (a :class:`~.detect.Features`)."""
    t, q, tau, w = f.t[i0:i1], f.q[i0:i1], f.tau[i0:i1], f.w[i0:i1]
    if kind == "constant_velocity":
        return {"w_mean": float(w.mean()), "w_std": float(w.std()), "tau_mean": float(tau.mean()),
                "tau_std": float(tau.std())}
    if kind == "ramp_presliding":
        k = int(np.argmax(np.abs(tau)))
        hq = max(1, min(f.h // 2, (i1 - i0) // 4))
        return {"tau_slope": _slope(t, tau), "tau_start": float(tau[:hq].mean()),
                "tau_end": float(tau[-hq:].mean()), "tau_peak": float(tau[k]),
                "displacement": float(q[-hq:].mean() - q[:hq].mean()), "stiffness": _slope(q, tau)}
    if kind == "step":
        return _step_stats(f, i0, i1)
    if kind == "duty_cycle":
        moving = ~f.quiet[i0:i1]
        return {"period": float(f.t[i1 - 1] - f.t[i0] + f.sc.dt), "moving_fraction": float(moving.mean()),
                "w_rms": float(np.sqrt(np.mean(w * w))), "tau_rms": float(np.sqrt(np.mean(tau * tau))),
                "power": float(np.mean(tau * w))}
    if kind == "rest":
        return {"q_mean": float(q.mean()), "tau_mean": float(tau.mean()), "tau_std": float(tau.std())}
    return {"w_mean": float(w.mean()), "tau_mean": float(tau.mean())}


def _step_stats(f, i0: int, i1: int) -> dict[str, float]:
    h = max(1, min(f.h // 2, (i1 - i0) // 4))
    lo = max(0, i0 - h)
    tau_before = float(f.tau[lo:i0].mean()) if i0 > lo else float(f.tau[i0])
    q_before = float(f.q[lo:i0].mean()) if i0 > lo else float(f.q[i0])
    tau_after = float(f.tau[i1 - h:i1].mean())
    q_final = float(f.q[i1 - h:i1].mean())
    disp = q_final - q_before
    band = max(0.05 * abs(disp), 3.0 * f.sc.sigma_q, f.sc.q_step)
    qs = f.q[i0:i1]
    out = np.flatnonzero(np.abs(qs - q_final) > band)
    settling = float(f.t[i0 + out[-1] + 1] - f.t[i0]) if out.size and out[-1] + 1 < qs.size else (
        0.0 if out.size == 0 else math.nan)
    peak = float(np.max((qs - q_before) * np.sign(disp))) if disp != 0 else 0.0
    overshoot = (peak / abs(disp) - 1.0) if disp != 0 else math.nan
    return {"step_size": tau_after - tau_before, "tau_before": tau_before, "tau_after": tau_after,
            "displacement": disp, "settling": settling, "overshoot": max(overshoot, 0.0)
            if math.isfinite(overshoot) else math.nan}
