"""Simulation of joints with LuGre friction, temperature and hidden effects, driven by recipes.

Public entry: :func:`simulate_recipe`. Plants live in ``recipes/plants/*.yaml``, recipes in
``recipes/*.yaml``; see ``docs/plant.md``.
"""
from __future__ import annotations

from .config import Plant, Recipe, load_plant, load_recipe
from .simulate import simulate_recipe

__all__ = ["simulate_recipe", "load_plant", "load_recipe", "Plant", "Recipe"]
