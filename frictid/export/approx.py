"""What a simulator's joint can hold of an identified model: ``F = fl sgn(w) + a w + b w|w| + c w^3``.

MuJoCo's joint has ``frictionloss`` (fl) and, since 3.7, a polynomial ``damping`` ``a b c`` of exactly this
odd form; a URDF joint has ``friction`` and a linear ``damping`` only. Both are symmetric in the velocity
sign, static (no bristle state) and know neither temperature, position, load nor time.

A model of that form (Coulomb-viscous, a polynomial with a non-negative level, symmetric, at one
temperature) is written exactly. Anything else is the least-squares fit of that form to the model's
steady-state friction over the joint's validity range of speeds, both signs alike, with ``fl >= 0`` and
the sign-preserving ``a >= 0``, ``c >= 0`` MuJoCo asks for; the approximation error over that range is
measured and reported, never hidden.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import lsq_linear

from ..model import FrictionModel
from ..models.static import canonical_friction

#: Extension terms a simulator's joint cannot hold, and what is lost with them.
DROPPED_TERMS = {"position": "its position dependence", "load": "its load dependence",
                 "drift": "its drift over time", "lugre": "its bristle (presliding) dynamics",
                 "stribeck": None, "asym": None, "offset": None}
#: Speeds in the error grid: log-spaced from the low end, and evenly spaced up to the top.
N_GRID = 400


@dataclass
class JointFriction:
    """The simulator form of one joint's model: ``F = frictionloss sgn(w) + d1 w + d2 w|w| + d3 w^3``.

    frictionloss [F]; damping (d1, d2, d3) [F s/q, F s^2/q^2, F s^3/q^3]; armature [kg m^2 | kg]: the
    identified inertia. exact: the form equals the model (within rounding). speeds: the validity range of
    |w| the error is measured on [q/s]; max_error, rms_error [F] over both signs there; peak [F]: the
    model's largest |F| there. notes: what the form leaves out, in words.
    """

    joint: str
    model: str
    frictionloss: float
    damping: tuple[float, float, float]
    armature: float
    exact: bool
    speeds: tuple[float, float]
    max_error: float = 0.0
    rms_error: float = 0.0
    peak: float = 0.0
    temperature: float | None = None
    notes: list[str] = field(default_factory=list)

    def friction(self, w) -> np.ndarray:
        """The form's friction [F] at velocities w [q/s]."""
        w = np.asarray(w, dtype=float)
        d1, d2, d3 = self.damping
        return self.frictionloss * np.sign(w) + d1 * w + d2 * w * np.abs(w) + d3 * w**3

    def summary(self, unit: str) -> str:
        """One line: exact, or the approximation error over the validity range."""
        lo, hi = self.speeds
        if self.exact:
            return "exact"
        rel = self.max_error / self.peak if self.peak > 0 else float("nan")
        return (f"approximation: max error {self.max_error:.4g} {unit} ({100 * rel:.1f} % of the model's "
                f"largest friction), RMS {self.rms_error:.4g} {unit}, over speeds {lo:.4g}..{hi:.4g}")


def speed_range(model: FrictionModel) -> tuple[tuple[float, float], list[str]]:
    """The speeds [q/s] the joint's data covered (its validity range), with a note when the file has none."""
    rng = (model.validity or {}).get("speed")
    if rng and rng[1] is not None and float(rng[1]) > 0:
        return (max(float(rng[0] or 0.0), 0.0), float(rng[1])), []
    v_hi = 1.0
    return (0.0, v_hi), [f"the parameter file records no speed range for this joint; the error is measured "
                         f"over 0..{v_hi:g} (refit with this frictid version to record one)"]


def grid(lo: float, hi: float) -> np.ndarray:
    """Speeds (> 0) over [lo, hi]: log-spaced near the low end (where a Stribeck drop lives), even above."""
    start = lo if lo > 0 else hi * 1e-3
    return np.unique(np.concatenate([np.geomspace(start, hi, N_GRID // 2), np.linspace(start, hi, N_GRID // 2)]))


def dropped_notes(model: FrictionModel) -> list[str]:
    """What the simulator form leaves out of the model, one sentence each."""
    notes = [f"{DROPPED_TERMS[t]} is left out" for t in model.terms() if DROPPED_TERMS.get(t)]
    if model.ext.get("tau_offset"):
        notes.append(f"its torque offset {model.ext['tau_offset']:.4g} is not friction and is left out "
                     "(apply it as a bias torque)")
    if model.ext.get("rip_period"):
        notes.append(f"its torque ripple that follows the position (period {model.ext['rip_period']:.4g}) is not "
                     "friction and is left out, as the gravity is")
    return notes


def simulator_form(model: FrictionModel, *, order: int = 3, temperature: float | None = None) -> JointFriction:
    """The model in the form ``fl sgn(w) + d1 w [+ d2 w|w| + d3 w^3]`` (order 3: MuJoCo; 1: URDF).

    temperature [degC]: where a thermal model is evaluated (default its reference temperature T0).
    """
    T = temperature if temperature is not None else (model.thermal or {}).get("T0")
    c_pos, c_neg = model.canonical_at(T) if model.thermal else (model.c_pos, model.c_neg)
    (lo, hi), notes = speed_range(model)
    notes = notes + dropped_notes(model)
    if model.thermal:
        notes.append(f"the {model.thermal['law']} law is evaluated at {T:.4g} degC")
    out = JointFriction(joint=model.joint, model=model.name, frictionloss=0.0, damping=(0.0, 0.0, 0.0),
                        armature=float(model.J or 0.0), exact=False, speeds=(lo, hi), temperature=T, notes=notes)
    v = grid(lo, hi)
    w = np.concatenate([-v[::-1], v])
    F = canonical_friction(w, c_pos, c_neg)
    exact = _exact_form(c_pos, c_neg, order)
    if exact is not None:
        out.frictionloss, out.damping, out.exact = exact[0], exact[1], True
    else:
        out.frictionloss, out.damping = _least_squares(w, F, order)
    err = out.friction(w) - F
    out.max_error, out.rms_error = float(np.max(np.abs(err))), float(np.sqrt(np.mean(err**2)))
    out.peak = float(np.max(np.abs(F)))
    return out


def _exact_form(c_pos, c_neg, order: int):
    """(fl, damping) when the canonical map is already ``a0 sgn(w) + b1 w + b2 w|w| + b3 w^3`` on both
    signs with a0 >= 0 (and b2 = b3 = 0 for order 1); else None."""
    if not np.array_equal(c_pos, c_neg) or c_pos[1] != 0.0 or c_pos[4] != 0.0 or c_pos[0] < 0.0:
        return None
    if not _dissipative(c_pos[6], c_pos[7], c_pos[8]):
        return None
    if order < 3 and (c_pos[7] != 0.0 or c_pos[8] != 0.0):
        return None
    return float(c_pos[0]), (float(c_pos[6]), float(c_pos[7]), float(c_pos[8]))


def _dissipative(d1, d2, d3) -> bool:
    """MuJoCo's sign-preservation condition on a damping polynomial: ``d1, d3 >= 0`` and, where
    ``d2 < 0``, ``d2^2 <= 4 d1 d3`` (the damping force never pushes the joint along)."""
    return d1 >= 0.0 and d3 >= 0.0 and (d2 >= 0.0 or d2 * d2 <= 4.0 * d1 * d3)


def _least_squares(w, F, order: int) -> tuple[float, tuple[float, float, float]]:
    """Least-squares ``fl sgn(w) + d1 w (+ d2 w|w| + d3 w^3)`` to F on the grid w with fl >= 0 and a
    dissipative damping polynomial (:func:`_dissipative`; d2 >= 0 when the free fit breaks it)."""
    cols = [np.sign(w), w] + ([w * np.abs(w), w**3] if order >= 3 else [])
    A = np.column_stack(cols)
    scale = np.maximum(np.max(np.abs(A), axis=0), 1e-300)  # columns of like size: a well-posed solve
    upper = np.full(A.shape[1], np.inf)
    for d2_low in (-np.inf, 0.0):
        lower = np.array([0.0, 0.0, d2_low, 0.0][:A.shape[1]])
        x = lsq_linear(A / scale, F, bounds=(lower, upper), method="bvls").x / scale
        d = (float(x[1]), float(x[2]) if order >= 3 else 0.0, float(x[3]) if order >= 3 else 0.0)
        if _dissipative(*d):
            break
    return float(x[0]), d
