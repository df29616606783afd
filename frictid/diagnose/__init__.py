"""Diagnosis: what the identified model gets wrong, the cause, the extended model and its measured gain.

Public entry: :func:`diagnose_joint`, called by :func:`frictid.fit` for every joint (``--no-diagnose``
skips it). It starts from the base model (the best symmetric velocity-only static map, by the fit's own
choice rule), tests the residual of the current model against every candidate cause on held-out
segments (:mod:`.chain`), extends the model with the best significant cause, and repeats. Each finding
becomes a model under ``models:`` (``stribeck+thermal6+position``), and ``selected`` names the end of the
chain. ``presliding`` is judged on ramp and step segments by the fit's LuGre comparison (leave one ramp
out), since sliding samples say nothing about presliding.

Numbers only (layer 2): arrays in, result objects out. True plant parameters are never read.
See ``docs/diagnosis.md``. The modules:

- :mod:`.joint`: :func:`diagnose_joint`, the chain's findings turned into models;
- :mod:`.check`: :func:`diagnose_fit` (the fit's prepared logs handed over) and :func:`check_diagnosis`
  (the fit's choice kept when the diagnosis' model predicts held-out data worse);
- :mod:`.samples`: the sliding samples and their held-out groups; :mod:`.model`: model structures and
  their least squares; :mod:`.causes`: the candidate causes; :mod:`.chain`: the forward selection;
- :mod:`.evidence`: each finding's sentence; :mod:`.params`: units and standard errors of the entries.
"""
from __future__ import annotations

from ..identify.select import base_model_name
from .causes import CAUSES, EXTENSIONS
from .check import check_diagnosis, diagnose_fit
from .joint import N_FOLDS, diagnose_joint
from .samples import DiagLog

__all__ = ["diagnose_joint", "diagnose_fit", "check_diagnosis", "DiagLog", "CAUSES", "EXTENSIONS",
           "base_model_name", "N_FOLDS"]
