"""Segmentation: find the identification experiments in a joint log (MODELS.md section 4).

``find_segments(log)`` returns one :class:`~frictid.data.Segment` per constant-velocity plateau, monotonic
presliding torque ramp, torque step, duty cycle, rest and other stretch, in time order.
``derivatives(log)`` gives the Savitzky-Golay velocity and acceleration that the fit also uses.
Every threshold derives from the log's own scales (:func:`estimate_scales`); the algorithm and the
thresholds are described in ``docs/segments.md``. numpy/scipy only; the plant's truth labels are never read.
"""
from __future__ import annotations

import numpy as np

from ..data import JointLog, Segment
from .detect import CODE_KIND, KIND_CODE, classify, features
from .scales import Scales, derivatives, estimate_scales, log_position, noise_sigma, quantum, velocity
from .stats import STAT_COLUMNS

__all__ = ["find_segments", "segment_labels", "derivatives", "velocity", "estimate_scales", "Scales", "STAT_COLUMNS",
           "noise_sigma", "quantum", "log_position", "features", "KIND_CODE", "CODE_KIND"]


def find_segments(log: JointLog, scales: Scales | None = None) -> list[Segment]:
    """The segments of one joint log, in time order (empty for a log too short to hold one). ``scales``:
    the log's :func:`estimate_scales` when the caller has measured them.

    Raises :class:`~frictid.errors.LogFormatError` for non-finite samples or non-increasing time.
    """
    return classify(log, scales)[1]


def segment_labels(log: JointLog) -> np.ndarray:
    """The kind of every sample (array of strings, same length as the log)."""
    code = classify(log)[0]
    kinds = np.array([CODE_KIND[i] for i in range(len(CODE_KIND))], dtype=object)
    return kinds[code].astype(str)
