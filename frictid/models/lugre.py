"""LuGre dynamic friction (MODELS.md section 3): compiled kernels and their pure-numpy references.

    dz/dt = w - a(w) z,      a(w) = sigma0 |w| / g(w)
    F     = sigma0 z + sigma1 dz/dt + f(w)

``g`` and ``f`` come from the canonical static map of :mod:`frictid.models.static` (one 9-vector for
``w >= 0``, one for ``w < 0``). The bristle equation is stiff (``a`` reaches 1e4-1e6 1/s), so no kernel
here uses an explicit step:

- :func:`lugre_step` (the plant step): one exponential Rosenbrock-Euler step of the coupled
  bristle/velocity system ``(z, w)``. The right-hand side is linearised at the step's start with its
  exact Jacobian (including ``da/dw``), the applied torque held, and the linear system solved exactly
  with the phi-functions of its 2x2 matrix; the position is the exact integral of the velocity.
  Second order, stable for any bristle stiffness, and in fast sliding ``z`` lands on its quasi-steady
  value ``g(w) sgn(w) / sigma0`` (an earlier version froze ``a`` only; that put ``z`` at ``w / a(w0)``
  and cost 10-60 % friction error when the velocity changed within a step).
- the friction along a *given* (measured) velocity is :mod:`frictid.models.replay_kernel`'s, which uses
  the level, viscous and thermal helpers below.

Per-sign stiffness and damping (001 Table 2 gives sigma0 per sign) are selected by the sign of the
bristle deflection ``z``, so that ``sigma0 z`` stays continuous through ``z = 0``.

Each compiled kernel (numba, ``cache=True``) has a plain numpy/python twin (``*_ref``) written
independently; the tests check that they agree.
"""
from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit

#: fastmath flags for the kernels: reassociation and fused multiply-add, but NaN/inf kept IEEE.
_FM = {"contract", "arcp", "afn", "reassoc", "nsz"}

# ---------------------------------------------------------------------------------------------------
# Canonical map pieces, compiled. Must match static._level and static.canonical_viscous.


@njit(cache=True, error_model="numpy", fastmath=_FM)
def level_nb(v, c):
    """g(v) [F] of canonical vector c at speed v = |w| >= 0."""
    out = c[0]
    if c[1] != 0.0:
        x = v / c[2]
        d = c[3]
        if d == 1.0:
            out += c[1] * math.exp(-x)
        elif d == 2.0:
            out += c[1] * math.exp(-x * x)
        else:
            out += c[1] * math.exp(-(x ** d))
    if c[4] != 0.0:
        out += c[4] * (1.0 - math.exp(-v / c[5]))
    return out


@njit(cache=True, error_model="numpy", fastmath=_FM)
def viscous_nb(w, c):
    """f(w) [F] of canonical vector c."""
    return w * (c[6] + c[7] * abs(w) + c[8] * w * w)


@njit(cache=True, error_model="numpy", fastmath=_FM)
def dviscous_nb(w, c):
    """df/dw [F s/q] of canonical vector c."""
    return c[6] + 2.0 * c[7] * abs(w) + 3.0 * c[8] * w * w


@njit(cache=True, error_model="numpy", fastmath=_FM)
def thermal_factors_nb(code, dT, alpha, beta, lam):
    """(s, d) of the canonical rule ``c(T) = c0 s + dc d`` at ``dT = T - T0``: s the scale of the law
    (code 1 thermal4 ``alpha dT + beta``, 3 exponential ``exp(-lam dT)``, else 1) and d the slopes'
    factor (``dT`` for code 2, thermal6; else 0). Shared by the plant, replay and map kernels."""
    if code == 1:
        s = alpha * dT + beta
    elif code == 3:
        s = math.exp(-lam * dT)
    else:
        s = 1.0
    return s, (dT if code == 2 else 0.0)


@njit(cache=True, error_model="numpy", fastmath=_FM)
def thermal_canon_nb(c0, dc, code, theta, T, out):
    """Fill out with the canonical vector at temperature T: ``c0 s(T) + dc (T - T0)``.

    code 0 none, 1 thermal4, 2 thermal6, 3 exponential; theta = [alpha, beta, lam, T0].
    """
    dT = T - theta[3]
    s, _ = thermal_factors_nb(code, dT, theta[0], theta[1], theta[2])
    for i in range(9):
        out[i] = c0[i]
    # shape parameters (vs1, d1, vs2) are not scaled
    out[0] = c0[0] * s
    out[1] = c0[1] * s
    out[4] = c0[4] * s
    out[6] = c0[6] * s
    out[7] = c0[7] * s
    out[8] = c0[8] * s
    if code == 2:
        out[0] += dc[0] * dT
        out[6] += dc[6] * dT
        out[7] += dc[7] * dT
        out[8] += dc[8] * dT


# ---------------------------------------------------------------------------------------------------
# (a) Plant step


@njit(cache=True, error_model="numpy", fastmath=_FM)
def dlevel_nb(v, c):
    """dg/dv [F s/q] of canonical vector c at speed v >= 0 (0 at v = 0 when the slope is unbounded)."""
    out = 0.0
    if c[1] != 0.0:
        x = v / c[2]
        d = c[3]
        if d == 1.0:
            out -= c[1] / c[2] * math.exp(-x)
        elif d == 2.0:
            out -= c[1] * 2.0 * x / c[2] * math.exp(-x * x)
        elif x > 0.0:
            xd1 = x ** (d - 1.0)
            out -= c[1] * d / c[2] * xd1 * math.exp(-xd1 * x)
    if c[4] != 0.0:
        out += c[4] / c[5] * math.exp(-v / c[5])
    return out


@njit(cache=True, error_model="numpy", fastmath=_FM)
def level_slope_nb(v, c):
    """(g(v), dg/dv) of canonical vector c at speed v >= 0, sharing the exponentials."""
    g = c[0]
    dg = 0.0
    if c[1] != 0.0:
        x = v / c[2]
        d = c[3]
        if d == 1.0:
            e = math.exp(-x)
            g += c[1] * e
            dg -= c[1] / c[2] * e
        elif d == 2.0:
            e = math.exp(-x * x)
            g += c[1] * e
            dg -= c[1] * 2.0 * x / c[2] * e
        elif x > 0.0:
            xd1 = x ** (d - 1.0)
            e = math.exp(-xd1 * x)
            g += c[1] * e
            dg -= c[1] * d / c[2] * xd1 * e
        else:
            g += c[1]
    if c[4] != 0.0:
        e = math.exp(-v / c[5])
        g += c[4] * (1.0 - e)
        dg += c[4] / c[5] * e
    return g, dg


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _phi123(mu):
    """phi1, phi2, phi3 of a complex argument: phi_k(x) = (phi_{k-1}(x) - 1/(k-1)!) / x, phi0 = exp.

    Multiplications by the reciprocal of mu (one real division) rather than three complex divisions
    (three real divisions each): this branch runs whenever the joint rests, its bristles ringing."""
    if abs(mu) < 1e-3:
        m2 = mu * mu
        p1 = 1.0 + mu * 0.5 + m2 * (1.0 / 6.0) + m2 * mu * (1.0 / 24.0) + m2 * m2 * (1.0 / 120.0)
        p2 = 0.5 + mu * (1.0 / 6.0) + m2 * (1.0 / 24.0) + m2 * mu * (1.0 / 120.0) + m2 * m2 * (1.0 / 720.0)
        p3 = (1.0 / 6.0 + mu * (1.0 / 24.0) + m2 * (1.0 / 120.0) + m2 * mu * (1.0 / 720.0)
              + m2 * m2 * (1.0 / 5040.0))
        return p1, p2, p3
    e = cmath.exp(mu)
    d = 1.0 / (mu.real * mu.real + mu.imag * mu.imag)
    imu = complex(mu.real * d, -mu.imag * d)
    p1 = (e - 1.0) * imu
    p2 = (p1 - 1.0) * imu
    p3 = (p2 - 0.5) * imu
    return p1, p2, p3


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _phi12_real(x):
    """phi1, phi2 of a real argument."""
    if abs(x) < 1e-3:
        x2 = x * x
        return (1.0 + x / 2.0 + x2 / 6.0 + x2 * x / 24.0 + x2 * x2 / 120.0,
                0.5 + x / 6.0 + x2 / 24.0 + x2 * x / 120.0 + x2 * x2 / 720.0)
    ix = 1.0 / x
    if x < -40.0:  # exp(x) below round-off: skip it (the fast bristle mode in sliding)
        p1 = -ix
    elif abs(x) > 0.5:  # |e^x - 1| >= 0.39: the subtraction loses under 3 ulp, and exp is ~3x cheaper
        p1 = (math.exp(x) - 1.0) * ix
    else:
        p1 = math.expm1(x) * ix
    return p1, (p1 - 1.0) * ix


@njit(cache=True, error_model="numpy", fastmath=_FM)
def lugre_step(q, w, z, u, h, J, sigma0, sigma1, g, dg, f, fp):
    """One exponential Rosenbrock-Euler step of the joint with LuGre friction; returns ``(q1, w1, z1)``.

    q [q], w [q/s], z [q] : state at the step's start. u [F] : applied torque minus gravity, held over
    the step. h [s] : step. J [F s^2/q] : inertia. sigma0 [F/q], sigma1 [F s/q] : bristle stiffness and
    damping. g [F], dg [F s/q] : level g(|w|) (> 0) and its slope dg/d|w| at the start.
    f [F], fp [F s/q] : viscous part f(w) and its slope.

    The right-hand side of ``x = (z, w)`` is linearised at the start with its exact Jacobian
    (``dz'/dz = -a``, ``dz'/dw = 1 - a'(w) z``, ``a = sigma0 |w| / g``) and the linear system is solved
    exactly: ``x1 = x0 + h phi1(hA) r0``, ``q1 = q0 + h w0 + h^2 [phi2(hA) r0]_w``. Second order, and
    stable for any stiffness (in fast sliding z lands on its quasi-steady value ``g sgn(w)/sigma0``).
    """
    q1, w1, z1, _ = lugre_core(q, w, z, u, h, 1.0 / J, sigma0, sigma1, g, dg, f, fp)
    return q1, w1, z1


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def lugre_core(q, w, z, u, h, iJ, sigma0, sigma1, g, dg, f, fp):
    """:func:`lugre_step` with the inverse inertia iJ [q/(F s^2)]; returns ``(q1, w1, z1, F0)`` with F0
    [F] the friction at the step's start (one reciprocal of g, of 2r and of the phi arguments instead of
    repeated divisions: divisions dominate the step's latency)."""
    aw = abs(w)
    ig = 1.0 / g
    a = sigma0 * aw * ig
    if w != 0.0:
        da = sigma0 * (g - aw * dg) * (ig * ig)
        if w < 0.0:
            da = -da
    else:
        da = 0.0
    zd0 = w - a * z
    F0 = sigma0 * z + sigma1 * zd0 + f
    r1 = zd0
    r2 = (u - F0) * iJ
    # Jacobian of (z', w')
    A11 = -a
    A12 = 1.0 - da * z
    A21 = -(sigma0 - sigma1 * a) * iJ
    A22 = -(sigma1 * A12 + fp) * iJ
    # M = hA = s I + N with N^2 = D I; f(M) = al I + be N
    s = 0.5 * h * (A11 + A22)
    N11 = h * A11 - s
    N22 = h * A22 - s
    N12 = h * A12
    N21 = h * A21
    D = N11 * N11 + N12 * N21
    if abs(D) < 1e-14 * max(1.0, s * s):
        p1, p2, p3 = _phi123(complex(s, 0.0))
        # f'(s): phi1' = phi1 - phi2, phi2' = phi2 - 2 phi3
        al1, be1 = p1.real, (p1 - p2).real
        al2, be2 = p2.real, (p2 - 2.0 * p3).real
    elif D > 0.0:
        r = math.sqrt(D)
        a1, a2 = _phi12_real(s + r)
        b1, b2 = _phi12_real(s - r)
        i2r = 0.5 / r
        al1, be1 = 0.5 * (a1 + b1), (a1 - b1) * i2r
        al2, be2 = 0.5 * (a2 + b2), (a2 - b2) * i2r
    else:
        r = math.sqrt(-D)
        a1, a2, _ = _phi123(complex(s, r))
        ir = 1.0 / r
        al1, be1 = a1.real, a1.imag * ir
        al2, be2 = a2.real, a2.imag * ir
    # phi1(M) r0 and phi2(M) r0
    v1 = al1 * r1 + be1 * (N11 * r1 + N12 * r2)
    v2 = al1 * r2 + be1 * (N21 * r1 + N22 * r2)
    u2 = al2 * r2 + be2 * (N21 * r1 + N22 * r2)
    return q + h * w + h * h * u2, w + h * v2, z + h * v1, F0


def lugre_step_ref(q, w, z, u, h, J, sigma0, sigma1, g, dg, f, fp):
    """Pure-numpy twin of :func:`lugre_step`: the same linearised affine system, solved with scipy's expm.

    The state (z, w, q, 1) obeys x' = M x with a 4x4 M; x(h) = expm(h M) x(0).
    """
    from scipy.linalg import expm

    a = sigma0 * abs(w) / g
    da = np.sign(w) * sigma0 * (g - abs(w) * dg) / g**2
    zd0 = w - a * z
    F0 = sigma0 * z + sigma1 * zd0 + f
    Jac = np.array([[-a, 1.0 - da * z],
                    [-(sigma0 - sigma1 * a) / J, -(sigma1 * (1.0 - da * z) + fp) / J]])
    r0 = np.array([zd0, (u - F0) / J])
    x0 = np.array([z, w])
    M = np.zeros((4, 4))
    M[:2, :2] = Jac
    M[:2, 3] = r0 - Jac @ x0          # x' = Jac (x - x0) + r0
    M[2, 1] = 1.0                     # q' = w
    x1 = expm(h * M) @ np.array([z, w, q, 1.0])
    return float(x1[2]), float(x1[1]), float(x1[0])


def lugre_rhs(z, w, u, J, sigma0, sigma1, g, f):
    """Unfrozen right-hand side ``(dz/dt, dw/dt)`` for given g(w), f(w) [used by reference solvers]."""
    zd = w - sigma0 * abs(w) / g * z
    F = sigma0 * z + sigma1 * zd + f
    return zd, (u - F) / J


def _pair(x):
    if np.ndim(x) == 0:
        return float(x), float(x)
    a, b = x
    return float(a), float(b)

