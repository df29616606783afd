"""frictid: identify friction in robot joints and drives from measured logs.

``frictid.fit(logs)`` identifies every model the data support and returns a
:class:`~frictid.result.FitResult`; ``frictid.load(path, joint=...)`` gives the identified model of a
parameter file as a :class:`~frictid.model.FrictionModel` that evaluates itself
(``.friction(w, T=..., q=...)``); ``frictid.read_params(path)`` / ``frictid.write_params(result, path)``
are the parameter file's one reader and writer.
"""
from __future__ import annotations

from .version import __version__

from .api import fit  # noqa: E402
from .io.params import load_model as load, read_params, write_params  # noqa: E402
from .model import FrictionModel  # noqa: E402
from .result import FitResult  # noqa: E402

__all__ = ["__version__", "fit", "load", "read_params", "write_params", "FitResult", "FrictionModel"]
