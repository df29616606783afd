"""The identification steps of one joint, in the order :func:`frictid.api.fit_joint` runs them.

After :func:`.prepare.prepare` (velocity and acceleration by Savitzky-Golay, segments):

1. rigid body (:func:`.mechanics.rigid_body`): inertia, gravity and torque offset with the polynomial
   friction by chunked least squares on the moving samples (002 eq 4-11), unless the log metadata gives
   them (:mod:`.regression`); then the friction torque ``F = tau - J a - G(q) - offset`` and one averaged
   point per constant-velocity plateau (:func:`.static.plateau_points`);
2. static maps (:func:`.maps.static_maps`): every static map and its per-sign variant on the plateau
   points (:mod:`.static`), each with a held-out error by segment folds; the polynomial also from step 1
   (``polynomial_ls``);
3. choose (:func:`.maps.choose_base`): the base model by held-out error and AIC (:mod:`.select`);
4. dynamics (:func:`.dynamics.fit_lugre`): LuGre on top of the chosen map: sigma0 from ramps, sigma1 from
   steps or the critical-damping rule (:mod:`.presliding`); LuGre replaces its map as the chosen model only
   when its dynamic parameters are identifiable and it predicts held-out presliding segments better than
   the map alone;
5. thermal (:func:`.thermal_fit.fit_thermal_models`): thermal4 / thermal6 from duty cycles with
   ``temp_env`` (:mod:`.thermal`), reported with their held-out gain over a temperature-blind polynomial;
   they never enter the choice (the diagnosis does);
6. after the diagnosis (:mod:`frictid.diagnose`), :func:`finish`.

This module holds the model names (:func:`parse_models`), the path for logs that cannot identify anything
(:func:`nothing_identifiable`) and :func:`finish`. Arrays in, result objects out: no files are read here
and true plant parameters (``JointLog.truth``) are never read.
"""
from __future__ import annotations

import numpy as np

from frictid.errors import FrictidInputError

from . import thermal as th
from .mechanics import Regressors, mechanics_not_identified, set_mechanics
from .prepare import JointData, segments_from_list  # noqa: F401 (frictid.report.content reads it here)
from .select import BASE_MODELS

#: Every model name `fit` knows.
ALL_MODELS = BASE_MODELS + ("lugre",) + th.THERMAL_MODELS
#: Parameters that set a static map's level at low speed: with one velocity sign only they carry the
#: torque offset, which the data cannot separate from them.
LEVEL_PARAMS = ("Fc", "Fs", "c0", "alpha0", "alpha1", "alpha2")


def parse_models(models) -> list[str]:
    """Model names from a list or a comma-separated string; ``None`` or ``all`` means every model."""
    if models is None:
        return list(ALL_MODELS)
    if isinstance(models, str):
        models = [m.strip() for m in models.split(",") if m.strip()]
    out = []
    for m in models:
        if m == "all":
            out.extend(ALL_MODELS)
        elif m in ALL_MODELS:
            out.append(m)
        else:
            raise FrictidInputError(f"--models: unknown model {m!r}; known: {', '.join(ALL_MODELS)}")
    return list(dict.fromkeys(out))


def thermal_names(wanted: list[str]) -> list[str]:
    """The thermal models among the wanted models."""
    return [m for m in wanted if m in th.THERMAL_MODELS]


def nothing_identifiable(jd: JointData, regs: Regressors, wanted: list[str], poor: str) -> None:
    """The result of a joint whose logs cannot pin any friction number down
    (:func:`.prepare.unidentifiable` says why): the metadata's mechanics only, every model not identified."""
    jf = jd.jf
    set_mechanics(jd, None, regs, poor, "")
    mechanics_not_identified(jf)
    jf.not_identified += [{"what": m, "reason": poor} for m in wanted]
    jf.warnings.append(poor)
    jf.selection = {"rule": "none: the data cannot identify any model", "reason": poor}


def finish(jd: JointData) -> None:
    """The last step: level parameters that carry an unknown offset marked, the segments used recorded,
    and a warning when no model could be chosen."""
    jf = jd.jf
    level_with_offset(jd)
    jf.segments_used = jd.used
    if jf.selected is None:
        jf.warnings.append("no model could be chosen: " + str(jf.selection.get("reason", "")))


def level_with_offset(jd: JointData) -> None:
    """With motion in one direction only and the offset neither identified nor given in the metadata, the
    Coulomb level of every map is the level plus an unknown offset: mark those parameters not identifiable."""
    jf = jd.jf
    if jf.offset is None or jf.offset.identifiable or jf.offset.source == "log metadata":
        return
    w = np.concatenate([p.w[np.isfinite(p.w)] for p in jd.preps])
    w = w[np.abs(w) > jd.min_speed]
    if w.size == 0 or ((w > 0).any() and (w < 0).any()):
        return
    why = ("not separable from the torque offset (motion in one direction only): the value is the level plus "
           "an unknown offset")
    for mname, mf in jf.models.items():
        for n, pe in mf.params.items():
            base = n[:-4] if n.endswith(("_pos", "_neg")) else n
            if base in LEVEL_PARAMS and pe.identifiable and not pe.fixed:
                pe.identifiable, pe.reason = False, why
                jf.not_identified.append({"what": f"{mname}.{n}", "reason": why})
