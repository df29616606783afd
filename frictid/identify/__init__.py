"""Identification: static maps, inertia and gravity, LuGre, thermal models, model choice.

Numbers only (layer 2): logs and arrays in, result objects (:mod:`frictid.result`) out; no files are
read here and nothing here imports :mod:`frictid.diagnose`. The steps of one joint, in order, are listed
in :mod:`.pipeline` and run by :func:`frictid.api.fit_joint` (``frictid.fit`` at the top level, which
returns a :class:`~frictid.result.FitResult`). The modules:

- :mod:`.prepare`: a joint's logs made ready (derivatives, segments, data scales);
- :mod:`.mechanics`: inertia, gravity and offset (:mod:`.regression`), the friction torque and plateaus;
- :mod:`.maps`: the static maps (:mod:`.static` on plateaus, :mod:`.samples` on moving samples) and the
  choice (:mod:`.select`, which also holds what the diagnosis shares: ``BASE_MODELS``, ``base_model_name``);
- :mod:`.dynamics`: LuGre (:mod:`.presliding`, on :mod:`.smallsq`'s least squares for small problems);
  :mod:`.thermal_fit`: thermal4 / thermal6 (:mod:`.thermal`);
- :mod:`.pipeline`: the model names and the last step.
"""
from __future__ import annotations

from frictid.result import FitResult, JointFit, ModelFit, ParamEstimate

__all__ = ["FitResult", "JointFit", "ModelFit", "ParamEstimate"]
