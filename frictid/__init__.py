"""frictid: identify friction in robot joints and drives from measured logs.

``frictid.fit(logs)`` identifies every model the data support and returns a
:class:`~frictid.result.FitResult`; ``frictid.load(path)`` reads a parameter file back.
"""
from __future__ import annotations

__version__ = "0.1.0"

from .api import fit  # noqa: E402
from .result import FitResult  # noqa: E402
from .io.params import read_params as load  # noqa: E402

__all__ = ["__version__", "fit", "load", "FitResult"]
