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
- :func:`lugre_friction` (the replay kernel): the friction predicted along a *given* (measured) velocity
  array. Over a step the velocity is held at the midpoint value, so ``dz/dt = w - a z`` is linear and
  ``z_new = z_ss + (z - z_ss) exp(-a h)``. Optionally a joint temperature is carried along, driven by the
  predicted friction power ``F w`` through the heat balance of :mod:`frictid.models.thermal`.

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

from .static import canonical_level, canonical_viscous

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


# ---------------------------------------------------------------------------------------------------
# (b) Replay: friction along a given velocity


@njit(cache=True, error_model="numpy", fastmath=_FM)
def _replay_kernel(t, w, c_pos, c_neg, s0p, s0n, s1p, s1n, z0,
                   code, theta, dc_pos, dc_neg, C, K, Tenv, T_init):
    n = w.shape[0]
    F = np.empty(n)
    z = np.empty(n)
    T = np.empty(n)
    cp = np.empty(9)
    cn = np.empty(9)
    zk = z0
    Tk = T_init
    thermal = code != 0
    if not thermal:
        for i in range(9):
            cp[i] = c_pos[i]
            cn[i] = c_neg[i]
    for k in range(n):
        if thermal:
            thermal_canon_nb(c_pos, dc_pos, code, theta, Tk, cp)
            thermal_canon_nb(c_neg, dc_neg, code, theta, Tk, cn)
        wk = w[k]
        if zk >= 0.0:
            s0 = s0p
            s1 = s1p
        else:
            s0 = s0n
            s1 = s1n
        c = cp if wk >= 0.0 else cn
        g = level_nb(abs(wk), c)
        zd = wk - s0 * abs(wk) / g * zk
        Fk = s0 * zk + s1 * zd + viscous_nb(wk, c)
        F[k] = Fk
        z[k] = zk
        T[k] = Tk
        if k + 1 < n:
            h = t[k + 1] - t[k]
            wm = 0.5 * (wk + w[k + 1])
            cm = cp if wm >= 0.0 else cn
            if wm != 0.0:
                a = s0 * abs(wm) / level_nb(abs(wm), cm)
                zss = wm / a
                zk = zss + (zk - zss) * math.exp(-a * h)
            if thermal:
                Tss = Tenv[k] + Fk * wk / K
                Tk = Tss + (Tk - Tss) * math.exp(-K * h / C)
    return F, z, T


def _replay_ref(t, w, c_pos, c_neg, s0p, s0n, s1p, s1n, z0,
                code, theta, dc_pos, dc_neg, C, K, Tenv, T_init):
    """Pure python/numpy twin of the replay kernel (uses static.py's vectorised map functions)."""
    from .thermal import canonical_at, heat_step

    n = w.shape[0]
    F, z, T = np.empty(n), np.empty(n), np.empty(n)
    zk, Tk = float(z0), float(T_init)
    for k in range(n):
        if code:
            cp = canonical_at(c_pos, Tk, code, theta, dc_pos)
            cn = canonical_at(c_neg, Tk, code, theta, dc_neg)
        else:
            cp, cn = c_pos, c_neg
        s0, s1 = (s0p, s1p) if zk >= 0 else (s0n, s1n)
        wk = float(w[k])
        c = cp if wk >= 0 else cn
        g = float(canonical_level(wk, c))
        zd = wk - s0 * abs(wk) / g * zk
        F[k] = s0 * zk + s1 * zd + float(canonical_viscous(wk, c))
        z[k], T[k] = zk, Tk
        if k + 1 < n:
            h = t[k + 1] - t[k]
            wm = 0.5 * (wk + w[k + 1])
            if wm != 0:
                cm = cp if wm >= 0 else cn
                a = s0 * abs(wm) / float(canonical_level(wm, cm))
                zk = wm / a + (zk - wm / a) * np.exp(-a * h)
            if code:
                Tk = float(heat_step(Tk, F[k] * wk, Tenv[k], C, K, h))
    return F, z, T


def _pair(x):
    if np.ndim(x) == 0:
        return float(x), float(x)
    a, b = x
    return float(a), float(b)


def lugre_friction(t, w, c_pos, c_neg=None, sigma0=1e4, sigma1=0.0, z0=0.0, thermal=None,
                   reference=False):
    """Friction predicted by LuGre along a measured velocity.

    t : sample times [s] (increasing); w : velocity [q/s] at those times.
    c_pos, c_neg : canonical static vectors for w >= 0 and w < 0 (c_neg defaults to c_pos).
    sigma0 : stiffness [F/q], a number or (pos, neg) pair selected by the sign of z.
    sigma1 : damping [F s/q], number or (pos, neg) pair.
    z0 : initial bristle deflection [q].
    thermal : None, or a dict with keys ``code, theta, dc_pos, dc_neg`` (see
    :func:`frictid.models.thermal.thermal_code`), ``C`` [J/K], ``K`` [W/K], ``Tenv`` [degC, scalar or
    per sample] and ``T_init`` [degC, default Tenv[0]]; the joint temperature then follows the heat
    balance driven by the predicted friction power.
    reference : use the pure-numpy twin instead of the compiled kernel (slow; for tests).

    Returns ``(F, z, T)``: friction [F], bristle state [q], joint temperature [degC] (NaN without thermal).
    """
    t = np.ascontiguousarray(t, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    if t.shape != w.shape or t.ndim != 1:
        raise ValueError("t and w must be 1-D arrays of the same length")
    c_pos = np.ascontiguousarray(c_pos, dtype=float)
    c_neg = c_pos.copy() if c_neg is None else np.ascontiguousarray(c_neg, dtype=float)
    s0p, s0n = _pair(sigma0)
    s1p, s1n = _pair(sigma1)
    if thermal:
        code = int(thermal["code"])
        theta = np.asarray(thermal["theta"], dtype=float)
        dc_pos = np.asarray(thermal.get("dc_pos", np.zeros(9)), dtype=float)
        dc_neg = np.asarray(thermal.get("dc_neg", dc_pos), dtype=float)
        C, K = float(thermal["C"]), float(thermal["K"])
        Tenv = np.ascontiguousarray(np.broadcast_to(np.asarray(thermal["Tenv"], float), w.shape))
        T_init = float(thermal.get("T_init", Tenv[0] if w.size else 0.0))
    else:
        code, theta = 0, np.zeros(4)
        dc_pos = dc_neg = np.zeros(9)
        C = K = 1.0
        Tenv = np.zeros(w.shape)
        T_init = np.nan
    fn = _replay_ref if reference else _replay_kernel
    F, z, T = fn(t, w, c_pos, c_neg, s0p, s0n, s1p, s1n, float(z0),
                 code, theta, dc_pos, dc_neg, C, K, Tenv, T_init)
    return F, z, T
