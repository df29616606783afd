"""The torque of a joint standing still: the friction it keeps from its last motion.

Where a joint's filtered speed is within its noise band (:meth:`RobotData.moving`), the velocity has no
reliable sign and the joint estimate leaves the samples out: the friction there is not a law of the
velocity. What the velocity cannot say, the history often does. A drive that comes to rest keeps much of
the friction it had while moving (the presliding state is frozen, as in Dahl's and the LuGre model); at a
reversal the friction keeps its sign until the presliding displacement is taken up; and a joint creeping
below the band still slides in its last direction. In each case the torque in the band follows the
direction of the last motion. On the UR10e harmonic run the wrist joints hold 0.5-1.8 N m so, at reversals
and for the seconds they stand.

The level ``fh`` of a joint is the mean of ``s r`` over its standing samples after a motion, where ``r``
is the joint estimate's residual there and ``s`` the sign of the last motion: the best constant predictor
of the friction in the band, whatever mixture of holding, presliding and creeping it is (it is not the
static friction of the joint, which lies anywhere up to the break-away level). Each stop is one
observation (the samples of one stop are not independent), so its standard error is clustered by stop.
It is identified only when the data support it: at least ``MIN_STOPS`` stops, a level above two standard
errors (the torque in the band follows the last motion at all) and not above the Coulomb level by more
than two combined errors (more than the drive's sliding friction would be the controller's holding torque
or a rigid-body model error at that pose, not friction). A joint that never stands has none.
"""
from __future__ import annotations

import numpy as np

from ..result import ParamEstimate

#: Fewer stops after a motion than this cannot show that the hold is a property of the joint.
MIN_STOPS = 3


def last_sign(qd: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """(n, nv): the sign of each joint's velocity at its latest moving sample (0 before its first)."""
    n = qd.shape[0]
    idx = np.where(moving, np.arange(n)[:, None], -1)
    idx = np.maximum.accumulate(idx, axis=0)
    s = np.sign(np.take_along_axis(qd, np.maximum(idx, 0), axis=0))
    return np.where(idx >= 0, s, 0.0)


def stops(standing: np.ndarray) -> list[tuple[int, int]]:
    """The runs [a, b) of True in a boolean vector."""
    e = np.diff(np.r_[0, standing.astype(np.int8), 0])
    return list(zip(np.flatnonzero(e == 1), np.flatnonzero(e == -1)))


def hold_level(r: np.ndarray, s: np.ndarray, standing: np.ndarray, fc: ParamEstimate) -> ParamEstimate:
    """The hold ``fh`` [N m] of one joint from the joint estimate's residual ``r``, the last motion's sign
    ``s`` and the standing mask, at the same samples; identifiable as the module says."""
    runs = stops(standing & (s != 0))
    y = r * s
    nobs = sum(b - a for a, b in runs)
    if not runs:
        return ParamEstimate("fh", 0.0, None, "N m", False, "the joint never stands after a motion")
    h = float(sum(np.sum(y[a:b]) for a, b in runs) / nobs)
    k = len(runs)
    dev = np.array([np.sum(y[a:b] - h) for a, b in runs])
    se = float(np.sqrt(np.sum(dev ** 2) * k / max(k - 1, 1)) / nobs)
    p = ParamEstimate("fh", h, se, "N m")
    if k < MIN_STOPS:
        p.identifiable, p.reason = False, f"{k} stop(s) after a motion, fewer than {MIN_STOPS}"
    elif h <= 2.0 * se:
        p.identifiable = False
        p.reason = (f"the torque standing does not follow the last motion's direction ({h:.3g} +- {se:.2g} N m "
                    f"over {k} stops)")
    elif h > fc.value + 2.0 * np.hypot(se, fc.stderr or 0.0):
        p.identifiable = False
        p.reason = (f"the torque held at rest ({h:.3g} +- {se:.2g} N m) exceeds the Coulomb level "
                    f"({fc.value:.3g} N m): the controller's or the rigid-body model's, not friction")
    return p


def hold_torque(fh: np.ndarray, s: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """(n, nv): the held friction ``fh_j s_j`` where joint j stands, 0 where it moves."""
    return np.where(moving, 0.0, s * fh[None, :])
