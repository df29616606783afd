"""The small data objects every layer passes around: one joint's log, and a segment of it.

These hold numpy arrays only (no pandas), so the numerics layers (segments, fit, diagnose) stay free of
file formats. :mod:`frictid.io` builds them from files.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Segment kinds, in the order tables list them.
SEGMENT_KINDS = ("constant_velocity", "ramp_presliding", "step", "duty_cycle", "rest", "other")

#: Optional numeric channels of the joint-log format (besides t, q, qd, tau).
OPTIONAL_CHANNELS = ("q_ref", "qd_ref", "tau_ref", "temp_env", "temp_joint", "payload")

#: Columns the plant writes as truth labels. Only tests and scorecards may read them.
TRUTH_COLUMNS = ("segment", "cycle")


@dataclass
class JointLog:
    """One joint's samples, in SI units (rad or m, rad/s or m/s, N m or N, degC, kg).

    t : time [s], strictly increasing. q : position [rad | m] or None for a velocity-only log.
    qd : velocity as logged [rad/s | m/s] or None (then differentiated from q). tau : actuator torque
    on the joint side [N m | N]. channels : optional columns (q_ref, qd_ref, tau_ref, temp_env,
    temp_joint, payload, and any other numeric column). axis : "rotary" or "linear".
    meta : metadata (inertia, gravity, robot, joint names, sample rate, ...).
    truth : the plant's labels (``segment``, ``cycle``) and true parameters; never read by the code that
    segments, fits or diagnoses, only by tests and scorecards.
    """

    joint: str
    t: np.ndarray
    tau: np.ndarray
    q: np.ndarray | None = None
    qd: np.ndarray | None = None
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    axis: str = "rotary"
    meta: dict = field(default_factory=dict)
    source: str = ""
    truth: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    @property
    def dt(self) -> float:
        """Median sample period [s]."""
        return float(np.median(np.diff(self.t))) if self.n > 1 else float("nan")

    @property
    def units(self) -> dict[str, str]:
        """Units of q, qd and tau for this axis."""
        if self.axis == "linear":
            return {"q": "m", "qd": "m/s", "tau": "N"}
        return {"q": "rad", "qd": "rad/s", "tau": "N m"}


@dataclass
class Segment:
    """A stretch of one joint's log that identifies something.

    kind : one of :data:`SEGMENT_KINDS`. i0, i1 : sample indices, i1 exclusive. t_start, t_end [s].
    cycle : duty-cycle index, or None. stats : per-kind statistics (means, spreads, slopes, ...).
    """

    kind: str
    i0: int
    i1: int
    t_start: float
    t_end: float
    cycle: int | None = None
    stats: dict[str, float] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.i1 - self.i0


def log_warnings(logs) -> list[str]:
    """The read-time warnings of joint logs (dropped rows, jittery sample period), each naming its file."""
    out = []
    for lg in logs:
        for w in lg.warnings:
            src = lg.source or "<log>"
            out.append(w if w.startswith(src) else f"{src}: {w}")
    return out


def finite(x) -> np.ndarray:
    """x as float64 with NaN and infinities replaced by numbers (``np.nan_to_num``), copied only when it
    holds any: the check is much cheaper than the copy of a whole log."""
    x = np.asarray(x, dtype=float)
    return x if np.isfinite(x).all() else np.nan_to_num(x)
