"""Identification: static maps, inertia and gravity, LuGre, thermal models, model choice.

The entry is :func:`frictid.identify.pipeline.fit` (``frictid.fit`` at the top level); its result is a
:class:`~frictid.result.FitResult`.
"""
from __future__ import annotations

from .pipeline import fit
from frictid.result import FitResult, JointFit, ModelFit, ParamEstimate

__all__ = ["fit", "FitResult", "JointFit", "ModelFit", "ParamEstimate"]
