"""Identification: static maps, inertia and gravity, LuGre, thermal models, model choice.

The package itself is callable: ``frictid.fit(paths_or_logs, ...)`` is :func:`frictid.fit.pipeline.fit`
(also importable as ``frictid.fit.fit``). The numerics are imported on first use.
"""
from __future__ import annotations

import sys
import types

__all__ = ["fit", "FitResult", "load"]


def fit(paths_or_logs, joint=None, models=None, mapping=None, units=None, **kw):
    """Identify friction models from logs; see :func:`frictid.fit.pipeline.fit`. Returns a FitResult."""
    from .pipeline import fit as _fit
    return _fit(paths_or_logs, joint=joint, models=models, mapping=mapping, units=units, **kw)


def load(path):
    """Read a parameter file (schema 1) into a :class:`~frictid.fit.result.FitResult`."""
    from .result import FitResult as _FR
    return _FR.load(path)


def __getattr__(name):
    if name == "FitResult":
        from .result import FitResult as _FR
        return _FR
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _CallableModule(types.ModuleType):
    """Lets ``frictid.fit(...)`` call the pipeline although ``frictid.fit`` is also this package."""

    def __call__(self, *args, **kwargs):
        return fit(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
