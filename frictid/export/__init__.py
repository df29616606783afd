"""Export identified models to simulators and controllers: ``frictid export PARAMS --to FORMAT``.

Formats (:data:`FORMATS`): ``mjcf`` (MuJoCo), ``urdf``, ``c`` (a dependency-free C header), ``json`` (the
chosen model with a sampling distribution per parameter). :func:`export` turns a parameter file's models
into the text of one output file and a list of what each joint became; it writes nothing, so a refusal
(no identifiable model, a joint missing from the given model file, a model the format cannot hold) leaves
no file behind. Docs: ``docs/using-the-model.md``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from ..errors import FrictidInputError
from ..io.params import read_params
from ..model import FrictionModel
from .approx import JointFriction, simulator_form
from .cheader import c_header
from .sampling import json_document
from .xmlfiles import mjcf_model, urdf_snippet, write_into_mjcf, write_into_urdf

FORMATS = ("mjcf", "urdf", "c", "json")
#: Rigid-body terms a model may carry: gravity and inertia are not friction, so their identifiability does
#: not decide whether the friction can be exported (the JSON states each with its own distribution).
RIGID = {"J", "Px", "Py", "Mx", "My", "offset"}


@dataclass
class Export:
    """The text of the output file and, for mjcf/urdf, what each joint's model became there."""

    text: str
    models: list[FrictionModel]
    forms: list[JointFriction] = field(default_factory=list)


def chosen_models(params_path, joints=None, model: str | None = None) -> list[FrictionModel]:
    """The selected (or the named) model of each joint of a parameter file, refusing a joint without an
    identifiable one."""
    res = read_params(params_path)
    names = list(res.joints)
    if joints:
        unknown = [j for j in joints if j not in res.joints]
        if unknown:
            raise FrictidInputError(f"{params_path}: no joint {', '.join(unknown)} (joints: {', '.join(names)})")
        names = list(joints)
    out = []
    for j in names:
        jf = res[j]
        name = model or jf.selected
        mf = jf.models.get(name) if name else None
        if mf is None:
            raise FrictidInputError(f"{params_path}: joint {j} has no {'model ' + repr(name) if name else 'selected model'}"
                                    f" to export (models: {', '.join(jf.models) or 'none'}); refit with data "
                                    "that identify one, or name one with --model")
        bad = [p for p, e in mf.params.items() if p not in RIGID and not (e.identifiable or e.fixed)]
        if bad:
            raise FrictidInputError(f"{params_path}: joint {j}, model {name}: {', '.join(bad)} not identifiable; "
                                    "a model with numbers the data do not support is not exported")
        out.append(jf.friction_model(name))
    return out


def export(params_path, fmt: str, *, into=None, joints=None, model: str | None = None,
           temperature: float | None = None) -> Export:
    """The export of a parameter file's chosen models in format ``fmt``; ``into`` a user's MJCF/URDF."""
    if fmt not in FORMATS:
        raise FrictidInputError(f"--to {fmt}: unknown format; choose one of {', '.join(FORMATS)}")
    if into is not None and fmt not in ("mjcf", "urdf"):
        raise FrictidInputError(f"--into: only for mjcf and urdf, not {fmt}")
    models = chosen_models(params_path, joints, model)
    if fmt == "c":
        return Export(c_header(models), models)
    if fmt == "json":
        return Export(json.dumps(json_document(models, str(params_path)), indent=2) + "\n", models)
    forms = [simulator_form(m, order=3 if fmt == "mjcf" else 1, temperature=temperature) for m in models]
    if fmt == "mjcf":
        text = write_into_mjcf(into, forms) if into else mjcf_model(forms, {m.joint: m.axis for m in models})
    else:
        text = write_into_urdf(into, forms) if into else urdf_snippet(forms)
    return Export(text, models, forms)
