"""frictid: identify friction in robot joints and drives from measured logs."""
from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
