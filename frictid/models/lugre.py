"""LuGre dynamic friction (MODELS.md section 3): compiled kernels and their pure-numpy references.

    dz/dt = w - a(w) z,      a(w) = sigma0 |w| / g(w)
    F     = sigma0 z + sigma1 dz/dt + f(w)

``g`` and ``f`` come from the canonical static map of :mod:`frictid.models.static` (one 9-vector for
``w >= 0``, one for ``w < 0``). The bristle equation is stiff (``a`` reaches 1e4-1e6 1/s), so no kernel
here uses an explicit step:

- :func:`lugre_step` (the plant step). Over one step the coupled bristle/velocity system
  ``(z, w)`` is linearised at the step's start (``a`` frozen, ``f`` linearised, applied torque held) and
  the resulting 2x2 linear ODE is solved *exactly* with its matrix exponential; the position is the
  exact integral of the velocity. This is stable for any stiffness and exact at steady sliding (the
  equilibrium of the frozen system is ``F = F_ss(w)``). Only the freezing of ``a`` and ``f'`` over the
  step is approximate.
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

import math

import numpy as np
from numba import njit

from .static import canonical_level, canonical_viscous

# ---------------------------------------------------------------------------------------------------
# Canonical map pieces, compiled. Must match static._level and static.canonical_viscous.


@njit(cache=True)
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


@njit(cache=True)
def viscous_nb(w, c):
    """f(w) [F] of canonical vector c."""
    return w * (c[6] + c[7] * abs(w) + c[8] * w * w)


@njit(cache=True)
def dviscous_nb(w, c):
    """df/dw [F s/q] of canonical vector c."""
    return c[6] + 2.0 * c[7] * abs(w) + 3.0 * c[8] * w * w


@njit(cache=True)
def thermal_canon_nb(c0, dc, code, theta, T, out):
    """Fill out with the canonical vector at temperature T: ``c0 s(T) + dc (T - T0)``.

    code 0 none, 1 thermal4, 2 thermal6, 3 exponential; theta = [alpha, beta, lam, T0].
    """
    dT = T - theta[3]
    if code == 1:
        s = theta[0] * dT + theta[1]
    elif code == 3:
        s = math.exp(-theta[2] * dT)
    else:
        s = 1.0
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


@njit(cache=True)
def lugre_step(q, w, z, u, h, J, sigma0, sigma1, g, f, fp):
    """One exact step of the linearised joint-with-LuGre system; returns ``(q1, w1, z1)``.

    q [q], w [q/s], z [q] : state at the step's start. u [F] : applied torque minus gravity, held over
    the step. h [s] : step. J [F s^2/q] : inertia. sigma0 [F/q], sigma1 [F s/q] : bristle stiffness and
    damping. g [F] : level g(|w|) at the start (> 0). f [F], fp [F s/q] : viscous part f(w) and its slope.

    Frozen system: ``z' = w - a z``, ``J w' = u - sigma0 z - sigma1 (w - a z) - f - fp (w' - w)``.
    """
    a = sigma0 * abs(w) / g
    A11 = -a
    A12 = 1.0
    A21 = -(sigma0 - sigma1 * a) / J
    A22 = -(sigma1 + fp) / J
    det = (sigma0 + a * fp) / J
    # equilibrium of the frozen system: z* = (u - f + fp w) / (sigma0 + a fp), w* = a z*
    zs = (u - f + fp * w) / (sigma0 + a * fp)
    ws = a * zs
    y1 = z - zs
    y2 = w - ws
    # E = exp(hA) = e^{hs} [C I + S (A - s I)]
    s = 0.5 * (A11 + A22)
    D = s * s - det
    if D > 0.0:
        r = math.sqrt(D)
        hr = h * r
        if hr < 1e-4:
            ehs = math.exp(h * s)
            C = ehs * (1.0 + 0.5 * hr * hr)
            S = ehs * h * (1.0 + hr * hr / 6.0)
        else:
            e1 = math.exp(h * (s + r))
            e2 = math.exp(h * (s - r))
            C = 0.5 * (e1 + e2)
            S = (e1 - e2) / (2.0 * r)
    else:
        r = math.sqrt(-D)
        hr = h * r
        ehs = math.exp(h * s)
        if hr < 1e-4:
            C = ehs * (1.0 - 0.5 * hr * hr)
            S = ehs * h * (1.0 - hr * hr / 6.0)
        else:
            C = ehs * math.cos(hr)
            S = ehs * math.sin(hr) / r
    E11 = C + S * (A11 - s)
    E12 = S * A12
    E21 = S * A21
    E22 = C + S * (A22 - s)
    z1 = zs + E11 * y1 + E12 * y2
    w1 = ws + E21 * y1 + E22 * y2
    # position: q1 = q + h w* + [A^{-1} (E - I) y]_w ;  A^{-1} = [[A22, -A12], [-A21, A11]] / det
    v1 = (E11 - 1.0) * y1 + E12 * y2
    v2 = E21 * y1 + (E22 - 1.0) * y2
    q1 = q + h * ws + (-A21 * v1 + A11 * v2) / det
    return q1, w1, z1


def lugre_step_ref(q, w, z, u, h, J, sigma0, sigma1, g, f, fp):
    """Pure-numpy twin of :func:`lugre_step`: the same frozen affine system, solved with scipy's expm.

    The state (z, w, q, 1) obeys x' = M x with a 4x4 M; x(h) = expm(h M) x(0).
    """
    from scipy.linalg import expm

    a = sigma0 * abs(w) / g
    M = np.zeros((4, 4))
    M[0, 0], M[0, 1] = -a, 1.0
    M[1, 0] = -(sigma0 - sigma1 * a) / J
    M[1, 1] = -(sigma1 + fp) / J
    M[1, 3] = (u - f + fp * w) / J
    M[2, 1] = 1.0
    x1 = expm(h * M) @ np.array([z, w, q, 1.0])
    return float(x1[2]), float(x1[1]), float(x1[0])


def lugre_rhs(z, w, u, J, sigma0, sigma1, g, f):
    """Unfrozen right-hand side ``(dz/dt, dw/dt)`` for given g(w), f(w) [used by reference solvers]."""
    zd = w - sigma0 * abs(w) / g * z
    F = sigma0 * z + sigma1 * zd + f
    return zd, (u - F) / J


# ---------------------------------------------------------------------------------------------------
# (b) Replay: friction along a given velocity


@njit(cache=True)
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
