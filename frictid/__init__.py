"""frictid: identify friction in robot joints and drives from measured logs."""
from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]


def __getattr__(name):  # lazy: frictid.fit(...) without importing the numerics at package import
    if name == "fit":
        import importlib
        return importlib.import_module("frictid.fit")
    raise AttributeError(f"module 'frictid' has no attribute {name!r}")
