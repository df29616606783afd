"""Static (steady-state) friction maps, MODELS.md section 2.

Every map is written ``F_ss(w) = g(|w|) sgn(w) + f(w)``: a level ``g`` (Coulomb plus Stribeck) that the
LuGre model uses as its bristle limit, and a velocity-growing part ``f`` (viscous and higher orders).
All maps share one canonical form so that compiled kernels (plant, replay) need only one formula::

    g(v) = a0 + a1 exp(-(v/vs1)^d1) + a2 (1 - exp(-v/vs2))          v = |w|
    f(w) = b1 w + b2 w|w| + b3 w^3

:data:`CANON` names the nine canonical numbers. A per-sign ("_asym") model has one canonical vector for
``w > 0`` and one for ``w < 0``; each branch uses the same odd formula with its own numbers.

Convention: in 001 Table 1 the ``w < 0`` branch writes ``alpha4 w^2``; here the odd form ``alpha4 w|w|`` is
used on both branches, so that table's ``alpha4`` for ``w < 0`` enters with its sign flipped.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .params import Param

CANON = ("a0", "a1", "vs1", "d1", "a2", "vs2", "b1", "b2", "b3")
N_CANON = len(CANON)


def _level(v, a0, a1, vs1, d1, a2, vs2):
    """Level g(v) [F] of the canonical form at speed v = |w| >= 0."""
    out = a0 + 0.0 * v
    if a1 != 0.0:
        out = out + a1 * np.exp(-np.power(v / vs1, d1))
    if a2 != 0.0:
        out = out + a2 * (1.0 - np.exp(-v / vs2))
    return out


def canonical_level(w, c):
    """g(|w|) [F] for a canonical vector c (length 9)."""
    return _level(np.abs(w), c[0], c[1], c[2], c[3], c[4], c[5])


def canonical_viscous(w, c):
    """f(w) [F] for a canonical vector c."""
    w = np.asarray(w, dtype=float)
    return c[6] * w + c[7] * w * np.abs(w) + c[8] * w**3


def canonical_friction(w, c_pos, c_neg=None):
    """Steady-state friction F_ss(w) [F] from canonical vectors for w >= 0 and w < 0."""
    w = np.asarray(w, dtype=float)
    c_neg = c_pos if c_neg is None else c_neg
    fp = canonical_level(w, c_pos) * np.sign(w) + canonical_viscous(w, c_pos)
    fn = canonical_level(w, c_neg) * np.sign(w) + canonical_viscous(w, c_neg)
    return np.where(w >= 0, fp, fn)


# ---------------------------------------------------------------------------------------------------
# The named maps. Each is a vectorised function of w [q/s] and named parameters, returning F [F].


def coulomb_viscous(w, Fc, sigma2):
    """Coulomb plus viscous friction ``Fc sgn(w) + sigma2 w``.

    w : joint velocity [rad/s]; Fc : Coulomb level [N m]; sigma2 : viscous coefficient [N m s/rad].
    """
    w = np.asarray(w, dtype=float)
    return Fc * np.sign(w) + sigma2 * w


def stribeck(w, Fc, Fs, vs, delta, sigma2):
    """Stribeck map ``(Fc + (Fs - Fc) exp(-|w/vs|^delta)) sgn(w) + sigma2 w`` (000, 003, 004).

    Fc : Coulomb level [N m]; Fs : static (break-away) level [N m]; vs : Stribeck velocity [rad/s];
    delta : exponent [1] (2 in 000/003); sigma2 : viscous coefficient [N m s/rad].
    """
    w = np.asarray(w, dtype=float)
    g = Fc + (Fs - Fc) * np.exp(-np.power(np.abs(w) / vs, delta))
    return g * np.sign(w) + sigma2 * w


def stribeck_2exp(w, alpha0, alpha1, alpha2, alpha3, alpha4, ws1, ws2):
    """Two-exponential Stribeck map of Bona et al. (001 eq 6-7, 004 eq 3).

    ``g = alpha0 + alpha1 exp(-|w|/ws1) + alpha2 (1 - exp(-|w|/ws2))`` [N m],
    ``F = g sgn(w) + alpha3 w + alpha4 w|w|``; ws1, ws2 [rad/s].
    """
    w = np.asarray(w, dtype=float)
    v = np.abs(w)
    g = alpha0 + alpha1 * np.exp(-v / ws1) + alpha2 * (1.0 - np.exp(-v / ws2))
    return g * np.sign(w) + alpha3 * w + alpha4 * w * v


def polynomial(w, c0, c1, c2, c3):
    """Third-order polynomial ``c0 sgn(w) + c1 w + c2 w|w| + c3 w^3`` (002 eq 1, 003 eq 11). Linear in c."""
    w = np.asarray(w, dtype=float)
    return c0 * np.sign(w) + c1 * w + c2 * w * np.abs(w) + c3 * w**3


# Jacobians: d F / d parameters, one column per parameter in the order of the map's table (closed form;
# the optimiser's finite differences cost one map evaluation per parameter and step).


def coulomb_viscous_jac(w, Fc, sigma2):
    """d coulomb_viscous / d (Fc, sigma2), shape (n, 2)."""
    w = np.asarray(w, dtype=float)
    return np.column_stack([np.sign(w), w])


def stribeck_jac(w, Fc, Fs, vs, delta, sigma2):
    """d stribeck / d (Fc, Fs, vs, delta, sigma2), shape (n, 5)."""
    w = np.asarray(w, dtype=float)
    s = np.sign(w)
    x = np.abs(w) / vs
    u = np.power(x, delta)
    e = np.exp(-u)
    se = s * (Fs - Fc) * e
    with np.errstate(divide="ignore", invalid="ignore"):
        logx = np.where(x > 0, np.log(np.where(x > 0, x, 1.0)), 0.0)
    return np.column_stack([s * (1.0 - e), s * e, se * u * delta / vs, -se * u * logx, w])


def stribeck_2exp_jac(w, alpha0, alpha1, alpha2, alpha3, alpha4, ws1, ws2):
    """d stribeck_2exp / d (alpha0, alpha1, alpha2, alpha3, alpha4, ws1, ws2), shape (n, 7)."""
    w = np.asarray(w, dtype=float)
    s = np.sign(w)
    v = np.abs(w)
    e1 = np.exp(-v / ws1)
    e2 = np.exp(-v / ws2)
    return np.column_stack([s, s * e1, s * (1.0 - e2), w, w * v, s * alpha1 * e1 * v / ws1**2,
                            -s * alpha2 * e2 * v / ws2**2])


def stribeck_2exp_swapped(alpha0, alpha1, alpha2, alpha3, alpha4, ws1, ws2) -> dict:
    """The same two-exponential map with its speeds swapped: ``alpha0 + alpha1 e1 + alpha2 (1 - e2)`` equals
    ``(alpha0 + alpha1 + alpha2) - alpha2 e2 - alpha1 (1 - e1)`` (``e = exp(-|w|/ws)``), the map's other,
    mirror-image optimum; the fit reports the one with ws1 <= ws2 (the Stribeck drop at the lower speed)."""
    return {"alpha0": alpha0 + alpha1 + alpha2, "alpha1": -alpha2, "alpha2": -alpha1, "alpha3": alpha3,
            "alpha4": alpha4, "ws1": ws2, "ws2": ws1}


def polynomial_jac(w, c0, c1, c2, c3):
    """d polynomial / d (c0, c1, c2, c3), shape (n, 4)."""
    w = np.asarray(w, dtype=float)
    return np.column_stack([np.sign(w), w, w * np.abs(w), w**3])


# Separable forms (variable projection): each map is linear in some parameters given the others (its shape).
# ``*_columns(w, **shape)`` returns the regressors of the linear parameters, shape (..., n, L), and their
# derivatives by each shape parameter, shape (..., S, n, L); shape values may be arrays of shape (G, 1) (a
# grid of G shapes) or numbers. The map is ``columns @ linear parameters``.


def stribeck_columns(w, vs, delta):
    """Regressors of (Fc, Fs, sigma2) of :func:`stribeck` and their derivatives by (vs, delta)."""
    w = np.asarray(w, dtype=float)
    s = np.sign(w)
    x = np.abs(w) / vs
    u = np.power(x, delta)
    e = np.exp(-u)
    with np.errstate(divide="ignore", invalid="ignore"):
        logx = np.where(x > 0, np.log(np.where(x > 0, x, 1.0)), 0.0)
    se = s * e
    cols = np.empty(e.shape + (3,))
    cols[..., 0] = s - se
    cols[..., 1] = se
    cols[..., 2] = w
    dcols = np.zeros(e.shape[:-1] + (2,) + e.shape[-1:] + (3,))
    dv = se * u * delta / vs  # s d e / d vs
    dd = -se * u * logx  # s d e / d delta (-s e = -(s e) exactly)
    dcols[..., 0, :, 0], dcols[..., 0, :, 1] = -dv, dv
    dcols[..., 1, :, 0], dcols[..., 1, :, 1] = -dd, dd
    return cols, dcols


def stribeck_2exp_columns(w, ws1, ws2):
    """Regressors of (alpha0 .. alpha4) of :func:`stribeck_2exp` and their derivatives by (ws1, ws2)."""
    w = np.asarray(w, dtype=float)
    s = np.sign(w)
    v = np.abs(w)
    e1 = np.exp(-v / ws1)
    e2 = np.exp(-v / ws2)
    shape = e1.shape if e1.shape == e2.shape else np.broadcast_shapes(e1.shape, e2.shape)
    se1, se2 = s * e1, s * e2
    cols = np.empty(shape + (5,))
    cols[..., 0] = s
    cols[..., 1] = se1
    cols[..., 2] = s - se2
    cols[..., 3] = w
    cols[..., 4] = w * v
    dcols = np.zeros(shape[:-1] + (2,) + shape[-1:] + (5,))
    dcols[..., 0, :, 1] = se1 * v / ws1**2
    dcols[..., 1, :, 2] = -se2 * v / ws2**2  # (-s e2 = -(s e2) exactly)
    return cols, dcols


def coulomb_viscous_columns(w):
    """Regressors of (Fc, sigma2) of :func:`coulomb_viscous` (no shape parameter)."""
    cols = coulomb_viscous_jac(w, 0.0, 0.0)
    return cols, np.zeros((0,) + cols.shape)


def polynomial_columns(w):
    """Regressors of (c0, c1, c2, c3) of :func:`polynomial` (no shape parameter)."""
    cols = polynomial_jac(w, 0.0, 0.0, 0.0, 0.0)
    return cols, np.zeros((0,) + cols.shape)


#: Per map: its linear parameters, its shape parameters (in the order of the columns' derivatives) and its
#: separable form.
SEPARABLE = {"coulomb_viscous": (("Fc", "sigma2"), (), coulomb_viscous_columns),
             "polynomial": (("c0", "c1", "c2", "c3"), (), polynomial_columns),
             "stribeck": (("Fc", "Fs", "sigma2"), ("vs", "delta"), stribeck_columns),
             "stribeck_2exp": (("alpha0", "alpha1", "alpha2", "alpha3", "alpha4"), ("ws1", "ws2"),
                               stribeck_2exp_columns)}


# Canonical conversions: named parameters -> 9-vector.

def _canon_cv(Fc, sigma2):
    return np.array([Fc, 0.0, 1.0, 1.0, 0.0, 1.0, sigma2, 0.0, 0.0])


def _canon_stribeck(Fc, Fs, vs, delta, sigma2):
    return np.array([Fc, Fs - Fc, vs, delta, 0.0, 1.0, sigma2, 0.0, 0.0])


def _canon_2exp(alpha0, alpha1, alpha2, alpha3, alpha4, ws1, ws2):
    return np.array([alpha0, alpha1, ws1, 1.0, alpha2, ws2, alpha3, alpha4, 0.0])


def _canon_poly(c0, c1, c2, c3):
    return np.array([c0, 0.0, 1.0, 1.0, 0.0, 1.0, c1, c2, c3])


@dataclass(frozen=True)
class StaticMap:
    """A named static map: its function, parameter table and canonical conversion."""

    name: str
    func: Callable
    table: tuple[Param, ...]
    to_canonical: Callable
    linear: bool = False  # linear in its parameters (polynomial, coulomb_viscous)
    jac: Callable | None = None  # d func / d parameters (n, p), in the table's order

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.table)

    def __call__(self, w, **params):
        return self.func(w, **params)

    def canonical(self, params: dict) -> np.ndarray:
        return self.to_canonical(**{n: params[n] for n in self.names})


# Dimensions: F force, W velocity, D force/velocity, D2 force/velocity^2, D3 force/velocity^3, 1 none.
STATIC_MAPS: dict[str, StaticMap] = {
    "coulomb_viscous": StaticMap(
        "coulomb_viscous", coulomb_viscous,
        (Param("Fc", "F", 0.0, 10.0, 0.5, 0.1, "Coulomb level"),
         Param("sigma2", "D", -10.0, 10.0, 0.2, 0.1, "viscous coefficient")),
        _canon_cv, linear=True, jac=coulomb_viscous_jac),
    "stribeck": StaticMap(
        "stribeck", stribeck,
        (Param("Fc", "F", 0.0, 10.0, 0.5, 0.1, "Coulomb level"),
         Param("Fs", "F", 0.0, 20.0, 0.7, 0.1, "static (break-away) level"),
         Param("vs", "W", 1e-5, 2.0, 0.05, 0.05, "Stribeck velocity"),
         Param("delta", "1", 0.3, 5.0, 2.0, 1.0, "Stribeck exponent"),
         Param("sigma2", "D", -10.0, 10.0, 0.2, 0.1, "viscous coefficient")),
        _canon_stribeck, jac=stribeck_jac),
    "stribeck_2exp": StaticMap(
        "stribeck_2exp", stribeck_2exp,
        (Param("alpha0", "F", -20.0, 20.0, 0.5, 0.1, "base level"),
         Param("alpha1", "F", -20.0, 20.0, 0.2, 0.1, "Stribeck amplitude"),
         Param("alpha2", "F", -20.0, 20.0, 0.0, 0.1, "second-exponential amplitude"),
         Param("alpha3", "D", -10.0, 10.0, 0.2, 0.1, "viscous coefficient"),
         Param("alpha4", "D2", -10.0, 10.0, 0.0, 0.1, "quadratic coefficient"),
         Param("ws1", "W", 1e-5, 2.0, 0.05, 0.05, "Stribeck velocity"),
         Param("ws2", "W", 1e-5, 2.0, 0.2, 0.05, "second velocity")),
        _canon_2exp, jac=stribeck_2exp_jac),
    "polynomial": StaticMap(
        "polynomial", polynomial,
        (Param("c0", "F", -10.0, 10.0, 0.5, 0.1, "Coulomb term"),
         Param("c1", "D", -20.0, 20.0, 0.2, 0.1, "linear term"),
         Param("c2", "D2", -20.0, 20.0, 0.0, 0.1, "quadratic term"),
         Param("c3", "D3", -20.0, 20.0, 0.0, 0.1, "cubic term")),
        _canon_poly, linear=True, jac=polynomial_jac),
}


def map_names() -> list[str]:
    """Names of the static maps and their per-sign variants."""
    return [n for m in STATIC_MAPS for n in (m, m + "_asym")]


#: The names of a low-speed term ``g + a exp(-(|w|/vs)^delta)`` added to a map that has none (the
#: diagnosis' ``stribeck`` candidate; parameter file ``str_amp``, ``str_amp_neg``), by the sign of its
#: amplitude ``a`` on each velocity branch. A Stribeck term is 003's drop: the friction at rest is above
#: the sliding level (``Fs = Fc + a >= Fc``). A term of negative amplitude is the opposite shape, friction
#: below the sliding level at low speed that rises to it (velocity strengthening at low speed: UR10e joint
#: 1, a = -5.05 N m; the direct-drive sample's plant, whose two-exponential map rises from zero speed).
LOW_SPEED_NAMES = {"drop": "stribeck", "rise": "low_speed_rise", "mixed": "low_speed"}


def low_speed_name(amps) -> str:
    """The name of a low-speed term from its amplitude on each branch it is fitted on (one for a symmetric
    model, ``(w >= 0, w < 0)`` for a per-sign one): ``stribeck`` when none is negative (a drop, ``Fs >= Fc``),
    ``low_speed_rise`` when none is positive and one is negative (a rise to the sliding level, ``Fs < Fc``),
    ``low_speed`` when the branches differ (a drop on one, a rise on the other)."""
    a = [float(x) for x in np.atleast_1d(amps) if np.isfinite(x)]
    if all(x >= 0 for x in a):
        return LOW_SPEED_NAMES["drop"]
    return LOW_SPEED_NAMES["rise" if all(x <= 0 for x in a) else "mixed"]


#: The reason the fit marks a two-exponential map whose level rises from rest with no drop
#: (:func:`frictid.identify.maps.two_exp_drop`; :func:`frictid.identify.select.rises` reads it).
TWO_EXP_RISE = "rises from rest with no Stribeck drop"


def low_speed_shape(c, v, tol: float = 0.0) -> str:
    """The shape of a map's level at low speed on one branch, from its canonical vector ``c`` over the speeds
    ``v`` (>= 0, ascending, the first the lowest): ``drop`` when the level at the lowest speed lies above its
    minimum over ``v`` (a Stribeck drop: friction at rest above a level it falls to), ``rise`` when it does
    not and the level rises above it (friction at rest below the sliding level), ``flat`` otherwise. For the
    single-exponential term this is the sign of its amplitude (``Fs`` against ``Fc``); for the two-exponential
    map, whose amplitudes can cancel (near-equal speeds), it is the curve's, not the first amplitude's sign.
    Differences up to ``tol`` [F] count as none (a dip or a rise the data cannot tell from flat)."""
    g = _level(np.asarray(v, dtype=float), *(float(x) for x in np.asarray(c, dtype=float)[:6]))
    if g[0] - g.min() > tol:
        return "drop"
    return "rise" if g.max() - g[0] > tol else "flat"


def split_asym(name: str) -> tuple[StaticMap, bool]:
    """The base map of a model name and whether it is the per-sign variant."""
    asym = name.endswith("_asym")
    base = name[: -len("_asym")] if asym else name
    if base not in STATIC_MAPS:
        raise KeyError(f"unknown static map {name!r}; known: {', '.join(map_names())}")
    return STATIC_MAPS[base], asym


def canonical_pair(name: str, params: dict) -> tuple[np.ndarray, np.ndarray]:
    """Canonical vectors (w >= 0, w < 0) of a static map given by name and a dict of named parameters.

    A per-sign model takes parameters suffixed ``_pos`` and ``_neg``.
    """
    smap, asym = split_asym(name)
    if not asym:
        c = smap.canonical(params)
        return c, c.copy()
    pos = {n: params[n + "_pos"] for n in smap.names}
    neg = {n: params[n + "_neg"] for n in smap.names}
    return smap.canonical(pos), smap.canonical(neg)


def level(name: str, w, params: dict) -> np.ndarray:
    """The level g(|w|) [F] of the named static map at velocities w, each on its sign's branch (the part of
    the friction that acts against the motion whatever the speed: ``F = g sgn(w) + f(w)``)."""
    return _pair_level(np.asarray(w, dtype=float), *canonical_pair(name, params))


def _pair_level(w: np.ndarray, c_pos: np.ndarray, c_neg: np.ndarray) -> np.ndarray:
    """:func:`level` from the map's packed vectors (:func:`canonical_pair`)."""
    return np.where(w >= 0, canonical_level(w, c_pos), canonical_level(w, c_neg))


def evaluate(name: str, w, params: dict, formula: bool = False) -> np.ndarray:
    """Steady-state friction [F] of the named static map (symmetric or ``_asym``) at velocities w, as the
    model a parameter file describes runs it (:class:`frictid.model.FrictionModel`, the replay kernel): a
    level g below zero is held at zero (a friction level cannot push the motion), so a map whose formula's
    level crosses zero is scored as the function the file runs, not as its formula. ``formula``: the
    formula as written (a curve through friction points that no file runs: the rigid-body step's map)."""
    smap, asym = split_asym(name)
    w = np.asarray(w, dtype=float)
    if not asym:
        F = smap.func(w, **{n: params[n] for n in smap.names})
    else:
        fp = smap.func(w, **{n: params[n + "_pos"] for n in smap.names})
        fn = smap.func(w, **{n: params[n + "_neg"] for n in smap.names})
        F = np.where(w >= 0, fp, fn)
    if formula:
        return F
    c_pos, c_neg = canonical_pair(name, params)
    if all(c[0] + min(c[1], 0.0) + min(c[4], 0.0) >= 0.0 for c in (c_pos, c_neg)):
        return F  # a level that cannot go below zero at any speed (its lower bound): nothing to hold
    g = _pair_level(w, c_pos, c_neg)
    below = g < 0
    if np.any(below):  # elsewhere the formula is left as it is (bit for bit)
        F = np.where(below, F - g * np.sign(w), F)
    return F


def param_table(name: str) -> tuple[Param, ...]:
    """Parameter table of a static map, per-sign variants with suffixed names."""
    smap, asym = split_asym(name)
    if not asym:
        return smap.table
    return tuple(
        Param(p.name + suffix, p.dim, p.lower, p.upper, p.start, p.scale, p.doc + side)
        for suffix, side in (("_pos", " (w > 0)"), ("_neg", " (w < 0)"))
        for p in smap.table
    )
