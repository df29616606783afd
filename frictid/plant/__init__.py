"""Simulation of joints with LuGre friction, temperature and hidden effects, driven by recipes.

Public entry: :func:`simulate_recipe`. Plants live in ``recipes/plants/*.yaml``, recipes in
``recipes/*.yaml``; see ``docs/plant.md``.

The names below are imported when first used (PEP 562): ``frictid.plant.kernel``, the compiled loop the
replay's closed loop runs, then loads without the plant and recipe schemas (pydantic) and the recipe
compiler, which the report and the replay do not need (about 0.1 s of the report's serial start).
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__all__ = ["simulate_recipe", "load_plant", "load_recipe", "Plant", "Recipe"]

_WHERE = {"simulate_recipe": ".simulate", "load_plant": ".config", "load_recipe": ".config", "Plant": ".config",
          "Recipe": ".config"}

if TYPE_CHECKING:  # pragma: no cover - for type checkers and editors
    from .config import Plant, Recipe, load_plant, load_recipe
    from .simulate import simulate_recipe


def __getattr__(name: str):
    if name in _WHERE:
        value = getattr(importlib.import_module(_WHERE[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
