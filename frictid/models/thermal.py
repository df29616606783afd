"""Temperature dependence of friction and the joint heat balance, MODELS.md section 5 (002).

Three laws map a joint temperature ``T`` [degC] onto the static friction map given at the reference
temperature ``T0`` [degC] (the cold start, ``T0 = Tenv``):

- ``thermal4`` (002 eq 16-20): every coefficient scales together,
  ``F(w, T) = F0(w) [alpha (T - T0) + beta]``.
- ``thermal6`` (002 eq 24-31): each polynomial coefficient has its own slope,
  ``c_i(T) = c_i0 + c_i' (T - T0)``, i = 0..3. In the canonical form of :mod:`frictid.models.static`
  these are the entries ``a0`` (c0), ``b1`` (c1), ``b2`` (c2) and ``b3`` (c3).
- ``exponential``: ``F(w, T) = F0(w) exp(-lam (T - T0))``.

All three are written as one canonical rule, used by the compiled kernels::

    c(T) = c0 * s(T) + dc * (T - T0)

with ``s = alpha (T - T0) + beta`` (thermal4), ``s = exp(-lam (T - T0))`` (exponential) or ``s = 1``
(thermal6, with ``dc`` the slopes; none, with ``dc = 0``). :func:`thermal_code` packs a law into the
integer code and numbers the kernels take.

The heat balance (002 eq 12-15) is ``C dT/dt = P - K (T - Tenv)`` with ``P = F w`` the friction power
[W]; for ``P`` and ``Tenv`` held over a step of length ``h`` it has the exact solution of
:func:`heat_step`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .static import CANON, N_CANON

#: Kernel codes of the thermal laws.
THERMAL_CODES = {"none": 0, "thermal4": 1, "thermal6": 2, "exponential": 3}

#: Canonical entries that thermal6's slopes c0'..c3' act on (a0, b1, b2, b3).
THERMAL6_SLOTS = (CANON.index("a0"), CANON.index("b1"), CANON.index("b2"), CANON.index("b3"))


def thermal4(F0, T, alpha, beta, T0):
    """Four-parameter law (002 eq 20): ``F0 [alpha (T - T0) + beta]``.

    F0 : friction at the reference temperature [N m | N]; T : joint temperature [degC];
    alpha : temperature slope [1/K]; beta : scale at T0 [1] (near 1); T0 : reference temperature [degC].
    Returns friction [N m | N].
    """
    return np.asarray(F0, dtype=float) * (alpha * (np.asarray(T, dtype=float) - T0) + beta)


def thermal6_coefficients(c, dc, T, T0):
    """Six-parameter law (002 eq 25-26): ``c_i(T) = c_i0 + c_i' (T - T0)``.

    c : (c0, c1, c2, c3) at T0 [N m, N m s/rad, N m s^2/rad^2, N m s^3/rad^3]; dc : their slopes per kelvin
    [same units / K]; T : joint temperature [degC] (scalar); T0 : reference temperature [degC].
    Returns the four coefficients at T.
    """
    return np.asarray(c, dtype=float) + np.asarray(dc, dtype=float) * (float(T) - T0)


def thermal6(w, T, c, dc, T0):
    """Friction of the six-parameter law (002 eq 26) at velocity w [rad/s] and temperature T [degC].

    T may be an array of the same shape as w (one temperature per sample). Returns [N m | N].
    """
    w = np.asarray(w, dtype=float)
    dT = np.asarray(T, dtype=float) - T0
    k = [c[i] + dc[i] * dT for i in range(4)]
    v = np.abs(w)
    return np.sign(w) * (k[0] + k[1] * v + k[2] * v**2 + k[3] * v**3)


def exponential(F0, T, lam, T0):
    """Exponential law: ``F0 exp(-lam (T - T0))``; lam [1/K] > 0 makes friction fall as T rises."""
    return np.asarray(F0, dtype=float) * np.exp(-lam * (np.asarray(T, dtype=float) - T0))


def thermal_scale(T, code, alpha=0.0, beta=1.0, lam=0.0, T0=0.0):
    """The scale s(T) [1] of the canonical rule ``c(T) = c0 s(T) + dc (T - T0)`` for a law code."""
    T = np.asarray(T, dtype=float)
    if code == 1:
        return alpha * (T - T0) + beta
    if code == 3:
        return np.exp(-lam * (T - T0))
    return np.ones_like(T)


def thermal_code(law: str | None, alpha=0.0, beta=1.0, lam=0.0, T0=25.0, dc=None):
    """Pack a thermal law for the kernels.

    Returns ``(code, theta, dc9)``: the integer code of :data:`THERMAL_CODES`, ``theta = [alpha, beta,
    lam, T0]`` and the 9-vector of canonical slopes ``dc9`` [canonical units / K] (thermal6 only; ``dc``
    gives c0'..c3').
    """
    law = "none" if law is None else law
    if law not in THERMAL_CODES:
        raise KeyError(f"unknown thermal law {law!r}; known: {', '.join(THERMAL_CODES)}")
    dc9 = np.zeros(N_CANON)
    if law == "thermal6" and dc is not None:
        for slot, v in zip(THERMAL6_SLOTS, dc):
            dc9[slot] = v
    theta = np.array([alpha, beta, lam, T0], dtype=float)
    return THERMAL_CODES[law], theta, dc9


#: Canonical entries a thermal law scales: the amplitudes (a0, a1, a2, b1, b2, b3), not the shapes
#: (vs1, d1, vs2), as in the compiled kernels (:func:`frictid.models.lugre.thermal_canon_nb`).
AMPLITUDE_SLOTS = tuple(CANON.index(k) for k in ("a0", "a1", "a2", "b1", "b2", "b3"))
_AMPLITUDE = np.isin(np.arange(N_CANON), AMPLITUDE_SLOTS)


def canonical_at(c0, T, code, theta, dc9):
    """The canonical 9-vector at temperature T [degC]: amplitudes ``c0 s(T) + dc9 (T - T0)``; the shape
    entries (Stribeck velocities and exponent) are those of c0 at every temperature."""
    alpha, beta, lam, T0 = theta
    s = float(thermal_scale(T, code, alpha, beta, lam, T0))
    c0 = np.asarray(c0, dtype=float)
    return np.where(_AMPLITUDE, c0 * s, c0) + np.asarray(dc9, dtype=float) * (float(T) - T0)


def heat_step(T, P, Tenv, C, K, h):
    """Exact step of ``C dT/dt = P - K (T - Tenv)`` over h [s] with P [W] and Tenv [degC] held.

    T : joint temperature at the start [degC]; C : heat capacity [J/K]; K : heat transfer [W/K].
    Returns T at the end of the step [degC]. The steady state is ``Tenv + P / K``; the time constant C/K.
    """
    T_ss = Tenv + P / K
    return T_ss + (T - T_ss) * np.exp(-K * h / C)


def heat_balance(P, t, Tenv, C, K, T_init=None):
    """Temperature [degC] along times t [s] for a friction power P [W] per sample (held between samples).

    Tenv : ambient temperature [degC], scalar or per sample. T_init : start temperature (default Tenv[0]).
    """
    P = np.asarray(P, dtype=float)
    t = np.asarray(t, dtype=float)
    Tenv = np.broadcast_to(np.asarray(Tenv, dtype=float), P.shape)
    T = np.empty_like(P)
    T[0] = Tenv[0] if T_init is None else T_init
    for k in range(P.size - 1):
        T[k + 1] = heat_step(T[k], P[k], Tenv[k], C, K, t[k + 1] - t[k])
    return T


def steady_temperature_rise(P, K):
    """Steady-state rise T - Tenv [K] for a constant friction power P [W] and heat transfer K [W/K]."""
    return P / K


@njit(cache=True)
def heat_balance_bins(h, e, W0, W1, C, K, x0):  # pragma: no cover - compiled; twin: heat_balance_bins_ref
    """Mean temperature rise per bin [K] of ``C dx/dt = W0 + W1 x - K (x - e)`` with x = T - T0, the
    power affine in x and W0, W1, e (ambient rise over T0) held over each bin of length h [s].

    Exact per bin: relaxation towards ``x_inf = (W0 + K e) / (K - W1)`` at rate ``(K - W1) / C``; the
    bin mean is the integral of that exponential. x0 : rise at the start of the first bin.
    """
    nb = h.shape[0]
    Tm = np.empty(nb)
    x = x0
    for k in range(nb):
        a = K - W1[k]
        rh = a / C * h[k]
        if abs(rh) < 1e-9:
            drift = (W0[k] + K * e[k] - a * x) / C
            Tm[k] = x + 0.5 * drift * h[k]
            x = x + drift * h[k]
        else:
            x_inf = (W0[k] + K * e[k]) / a
            ex = math.exp(-rh) if rh > -700.0 else math.inf
            Tm[k] = x_inf + (x - x_inf) * (-math.expm1(-rh)) / rh
            x = x_inf + (x - x_inf) * ex
    return Tm


#: Plain python twin of :func:`heat_balance_bins` (the same source, interpreted; for the agreement test).
heat_balance_bins_ref = heat_balance_bins.py_func
