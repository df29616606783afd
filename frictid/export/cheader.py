"""A dependency-free C header with one friction function per joint.

For each joint ``NAME`` (its name made a C identifier):

- ``double NAME_friction(double w, double T)``: the steady-state friction [N m or N] at velocity w
  [rad/s or m/s] and joint temperature T [degC] (read only by a thermal model; pass anything otherwise),
  the formula of :meth:`frictid.FrictionModel.friction` with every extension at its neutral value;
- for a LuGre model, ``double NAME_lugre_force(double z, double w, double T)``, the friction at bristle
  deflection z [rad or m], and ``double NAME_lugre_advance(double z, double w, double h, double T)``, the
  deflection after h seconds at velocity w held: the exact step frictid's replay takes (call it with the
  mean velocity over the step to reproduce the replay sample for sample).

Numbers are written with 17 significant digits, so the header equals the Python model to rounding. Only the
C99 standard library (``math.h``) is used. A model with a position, load or drift term needs inputs these
signatures do not have: :func:`c_header` refuses it (export its base model instead).
"""
from __future__ import annotations

import re

import numpy as np

from ..errors import FrictidInputError
from ..model import FrictionModel
from ..version import __version__

#: Extension terms that need inputs beyond (w, T).
NEEDS_INPUTS = ("position", "load", "drift")

COMMON = r"""
#ifndef FRICTID_COMMON_DEFINED
#define FRICTID_COMMON_DEFINED
/* The canonical map (frictid.models.static): c = {a0, a1, vs1, d1, a2, vs2, b1, b2, b3}.
   g(v) = a0 + a1 exp(-(v/vs1)^d1) + a2 (1 - exp(-v/vs2)),  f(w) = b1 w + b2 w|w| + b3 w^3. */
static double frictid_level(double v, const double *c) {
    double g = c[0];
    if (c[1] != 0.0) {
        double x = v / c[2];
        g += c[1] * (c[3] == 1.0 ? exp(-x) : c[3] == 2.0 ? exp(-x * x) : exp(-pow(x, c[3])));
    }
    if (c[4] != 0.0) g += c[4] * (1.0 - exp(-v / c[5]));
    return g;
}
/* The thermal law at joint temperature T: amplitudes scaled by s, plus dT times the slopes dc.
   code 0 none, 1 thermal4 (s = alpha dT + beta), 2 thermal6 (s = 1), 3 exponential (s = exp(-lam dT));
   theta = {alpha, beta, lam, T0}. */
static void frictid_thermal(int code, const double *theta, double T, double *s, double *dT) {
    *s = 1.0;
    *dT = 0.0;
    if (code == 0) return;
    double d = T - theta[3];
    if (code == 1) *s = theta[0] * d + theta[1];
    else if (code == 3) *s = exp(-theta[2] * d);
    if (code == 2) *dT = d;
}
/* Level g and viscous part f at velocity w, temperature T; g held at 1e-300 or more, as frictid does. */
static void frictid_map(double w, double T, const double *cp, const double *cn, int code, const double *theta,
                        const double *dc, double *g, double *f) {
    double s, dT, v = fabs(w);
    const double *c = w >= 0.0 ? cp : cn;
    frictid_thermal(code, theta, T, &s, &dT);
    *g = s * frictid_level(v, c) + dT * dc[0];
    if (*g < 1e-300) *g = 1e-300;
    *f = w * (s * (c[6] + c[7] * v + c[8] * w * w) + dT * (dc[6] + dc[7] * v + dc[8] * w * w));
}
#endif
"""


def c_name(joint: str) -> str:
    """A C identifier for a joint name: other characters become '_', a leading digit gets 'j'."""
    name = re.sub(r"\W", "_", str(joint), flags=re.ASCII)
    return ("j" + name) if not name or name[0].isdigit() else name


def _array(x) -> str:
    return "{" + ", ".join(repr(float(v)) for v in np.asarray(x, dtype=float)) + "}"


def check_model(model: FrictionModel) -> None:
    """Refuse a model the header's (w, T) signatures cannot evaluate."""
    extra = [t for t in model.terms() if t in NEEDS_INPUTS]
    if extra:
        raise FrictidInputError(
            f"joint {model.joint}, model {model.name}: the C header's functions take velocity and temperature "
            f"only, and this model has a {', '.join(extra)} term; export a model without it with --model")


def joint_code(model: FrictionModel) -> str:
    """The constants and functions of one joint."""
    check_model(model)
    n = c_name(model.joint)
    law = model.thermal_law()
    code, theta, dc = (0, np.zeros(4), np.zeros(9)) if law is None else (law["code"], law["theta"], law["dc_pos"])
    offset = float(model.ext.get("tau_offset", 0.0))
    words = model.formula()["words"]
    lines = [f"/* joint {model.joint}: model {model.name} ({words}). */",
             f"static const double {n}_cpos[9] = {_array(model.c_pos)};",
             f"static const double {n}_cneg[9] = {_array(model.c_neg)};",
             f"static const double {n}_theta[4] = {_array(theta)};",
             f"static const double {n}_dc[9] = {_array(dc)};",
             f"static const int {n}_code = {int(code)};",
             f"static const double {n}_offset = {offset!r};",
             f"static inline double {n}_friction(double w, double T) {{",
             "    double g, f;",
             f"    frictid_map(w, T, {n}_cpos, {n}_cneg, {n}_code, {n}_theta, {n}_dc, &g, &f);",
             f"    return (w > 0.0 ? g + f : w < 0.0 ? -g + f : f) + {n}_offset;",
             "}"]
    if model.sigma0 is not None:
        lines += _lugre_code(n, model)
    return "\n".join(lines)


def _lugre_code(n: str, model: FrictionModel) -> list[str]:
    (s0p, s0n), (s1p, s1n) = model.sigma0, model.sigma1
    return [f"static const double {n}_sigma0[2] = {_array([s0p, s0n])};  /* z >= 0, z < 0 */",
            f"static const double {n}_sigma1[2] = {_array([s1p, s1n])};",
            f"static inline double {n}_lugre_force(double z, double w, double T) {{",
            "    double g, f;",
            "    int k = z >= 0.0 ? 0 : 1;",
            f"    frictid_map(w, T, {n}_cpos, {n}_cneg, {n}_code, {n}_theta, {n}_dc, &g, &f);",
            f"    return {n}_sigma0[k] * z + {n}_sigma1[k] * (w - {n}_sigma0[k] * fabs(w) / g * z) + f"
            f" + {n}_offset;",
            "}",
            f"static inline double {n}_lugre_advance(double z, double w, double h, double T) {{",
            "    double g, f;",
            "    if (w == 0.0) return z;",
            "    int k = z >= 0.0 ? 0 : 1;",
            f"    frictid_map(w, T, {n}_cpos, {n}_cneg, {n}_code, {n}_theta, {n}_dc, &g, &f);",
            f"    double zss = (w > 0.0 ? g : -g) / {n}_sigma0[k];",
            f"    return zss + (z - zss) * exp(-{n}_sigma0[k] * fabs(w) * h / g);",
            "}"]


def c_header(models: list[FrictionModel], guard: str = "FRICTID_FRICTION_H") -> str:
    """The header text for the joints' models."""
    codes = [joint_code(m) for m in models]  # refuses before anything is written
    names = [c_name(m.joint) for m in models]
    if len(set(names)) != len(names):
        raise FrictidInputError("joint names " + ", ".join(m.joint for m in models) + " give the same C "
                                "identifier twice; rename the joints in the parameter file")
    head = (f"/* Friction models identified by frictid {__version__}. Generated: edit the parameter file and "
            "export again.\n   Units: w [rad/s or m/s], T [degC], friction [N m or N], z [rad or m]. */\n"
            f"#ifndef {guard}\n#define {guard}\n#include <math.h>\n")
    return head + COMMON + "\n" + "\n\n".join(codes) + f"\n\n#endif /* {guard} */\n"
