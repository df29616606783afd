"""Replay kernel: the friction an identified model predicts along a *measured* motion.

This generalises :func:`frictid.models.lugre.lugre_friction` to every model the parameter file can hold
(the base static maps, LuGre, the thermal laws and the extensions the diagnosis adds), with one
compiled loop:

- the static map of :mod:`frictid.models.static` (canonical 9-vectors, one per velocity sign), its
  level ``g`` scaled per sample by ``gmul[k]`` and its viscous part ``f`` by ``fmul[k]``. The
  multipliers carry everything that depends on measured quantities only (position, transmitted torque,
  payload, elapsed time), so they are computed once, vectorised, before the loop;
- either the static law ``F = g sgn(w) + f`` (``dynamic = False``) or LuGre
  (``dz/dt = w - sigma0 |w| z / g``, ``F = sigma0 z + sigma1 dz/dt + f``), the bristle state advanced
  exactly for the velocity held at the step's midpoint, as in :func:`frictid.models.lugre._replay_kernel`;
- a thermal law (code of :data:`frictid.models.thermal.THERMAL_CODES`): the map at joint temperature
  ``T`` is ``c0 s(T) + dc (T - T0)``; ``T`` is either given per sample (a measured joint temperature)
  or follows the heat balance ``C dT/dt = F w - K (T - Tenv)`` driven by the *predicted* friction power,
  stepped exactly with the power held over each sample period.

The temperature is the only state besides ``z`` that the prediction feeds back on, which is why this
runs as a sequential loop (numba, ``cache=True``). :func:`replay_friction_ref` is an independent plain
python/numpy twin (static.py's vectorised maps, thermal.py's heat step); the tests check that they agree.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .lugre import _pair, level_nb, thermal_canon_nb, viscous_nb
from .static import canonical_level, canonical_viscous


@njit(cache=True, error_model="numpy")
def _kernel(t, w, gmul, fmul, c_pos, c_neg, s0p, s0n, s1p, s1n, z0, dynamic,
            code, theta, dc_pos, dc_neg, C, K, Tenv, T_init, T_in, T_given, u_stick, w_stick):
    n = w.shape[0]
    F = np.empty(n)
    z = np.empty(n)
    T = np.empty(n)
    cp = np.empty(9)
    cn = np.empty(9)
    for i in range(9):
        cp[i] = c_pos[i]
        cn[i] = c_neg[i]
    zk = z0
    Tk = T_init
    T_used = math.nan
    thermal = code != 0
    eK = 0.0
    for k in range(n):
        if T_given:
            Tk = T_in[k]
        if thermal and Tk != T_used:
            thermal_canon_nb(c_pos, dc_pos, code, theta, Tk, cp)
            thermal_canon_nb(c_neg, dc_neg, code, theta, Tk, cn)
            T_used = Tk
        wk = w[k]
        c = cp if wk >= 0.0 else cn
        g = gmul[k] * level_nb(abs(wk), c)
        if g < 1e-300:
            g = 1e-300
        fv = fmul[k] * viscous_nb(wk, c)
        if dynamic:
            if zk >= 0.0:
                s0 = s0p
                s1 = s1p
            else:
                s0 = s0n
                s1 = s1n
            zd = wk - s0 * abs(wk) / g * zk
            Fk = s0 * zk + s1 * zd + fv
        elif abs(wk) <= w_stick:
            # Karnopp: sticking, the friction balances the applied torque up to the level
            Fk = u_stick[k]
            if Fk > g:
                Fk = g
            elif Fk < -g:
                Fk = -g
        elif wk > 0.0:
            Fk = g + fv
        elif wk < 0.0:
            Fk = -g + fv
        else:
            Fk = fv
        F[k] = Fk
        z[k] = zk
        T[k] = Tk
        if k + 1 < n:
            h = t[k + 1] - t[k]
            if dynamic:
                wm = 0.5 * (wk + w[k + 1])
                if wm != 0.0:
                    cm = cp if wm >= 0.0 else cn
                    gm = 0.5 * (gmul[k] + gmul[k + 1]) * level_nb(abs(wm), cm)
                    if gm < 1e-300:
                        gm = 1e-300
                    s0m = s0p if zk >= 0.0 else s0n
                    a = s0m * abs(wm) / gm
                    zss = wm / a
                    zk = zss + (zk - zss) * math.exp(-a * h)
            if thermal and not T_given:
                Tss = Tenv[k] + Fk * wk / K
                eK = math.exp(-K * h / C)
                Tk = Tss + (Tk - Tss) * eK
    return F, z, T


def replay_friction_ref(t, w, gmul, fmul, c_pos, c_neg, s0p, s0n, s1p, s1n, z0, dynamic,
                        code, theta, dc_pos, dc_neg, C, K, Tenv, T_init, T_in, T_given, u_stick, w_stick):
    """Plain python/numpy twin of the compiled kernel (slow; for the agreement tests)."""
    from .thermal import heat_step, thermal_scale

    amp = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], dtype=float)  # amplitudes scale, shapes (vs1, d1, vs2) do not

    def canonical_at(c0, T, code, theta, dc9):
        s = float(thermal_scale(T, code, theta[0], theta[1], theta[2], theta[3]))
        return c0 * np.where(amp > 0, s, 1.0) + dc9 * (T - theta[3])

    n = w.shape[0]
    F, z, T = np.empty(n), np.empty(n), np.empty(n)
    zk, Tk = float(z0), float(T_init)
    for k in range(n):
        if T_given:
            Tk = float(T_in[k])
        if code:
            cp = canonical_at(c_pos, Tk, code, theta, dc_pos)
            cn = canonical_at(c_neg, Tk, code, theta, dc_neg)
        else:
            cp, cn = c_pos, c_neg
        wk = float(w[k])
        c = cp if wk >= 0 else cn
        g = max(gmul[k] * float(canonical_level(wk, c)), 1e-300)
        fv = fmul[k] * float(canonical_viscous(wk, c))
        if dynamic:
            s0, s1 = (s0p, s1p) if zk >= 0 else (s0n, s1n)
            F[k] = s0 * zk + s1 * (wk - s0 * abs(wk) / g * zk) + fv
        elif abs(wk) <= w_stick:
            F[k] = float(np.clip(u_stick[k], -g, g))
        else:
            F[k] = g * np.sign(wk) + fv
        z[k], T[k] = zk, Tk
        if k + 1 < n:
            h = t[k + 1] - t[k]
            wm = 0.5 * (wk + float(w[k + 1]))
            if dynamic and wm != 0:
                cm = cp if wm >= 0 else cn
                gm = max(0.5 * (gmul[k] + gmul[k + 1]) * float(canonical_level(wm, cm)), 1e-300)
                s0 = s0p if zk >= 0 else s0n
                zss = wm * gm / (s0 * abs(wm))
                zk = zss + (zk - zss) * math.exp(-s0 * abs(wm) / gm * h)
            if code and not T_given:
                Tk = float(heat_step(Tk, F[k] * wk, Tenv[k], C, K, h))
    return F, z, T


def replay_friction(t, w, c_pos, c_neg=None, *, gmul=None, fmul=None, sigma0=None, sigma1=0.0, z0=0.0,
                    thermal=None, u_stick=None, w_stick=0.0, reference=False):
    """Friction [F] predicted along a measured velocity; returns ``(F, z, T)``.

    t : sample times [s], increasing; w : velocity [q/s] at those times.
    c_pos, c_neg : canonical static vectors (:data:`frictid.models.static.CANON`) for ``w >= 0`` and
    ``w < 0``; c_neg defaults to c_pos.
    gmul, fmul : per-sample multipliers [1] of the level ``g`` and of the viscous part ``f`` (default 1).
    sigma0 : LuGre stiffness [F/q] (number or (z >= 0, z < 0) pair); None gives the static map.
    sigma1 : LuGre damping [F s/q] (number or pair). z0 : initial bristle deflection [q].
    thermal : None, or a dict with ``code``, ``theta`` (= [alpha, beta, lam, T0]) and ``dc_pos`` /
    ``dc_neg`` as packed by :func:`frictid.models.thermal.thermal_code`, and either ``T`` (the joint
    temperature per sample [degC], e.g. measured) or ``C`` [J/K], ``K`` [W/K], ``Tenv`` [degC, scalar or
    per sample] and ``T_init`` [degC, default ``Tenv[0]``] for the heat balance.
    u_stick, w_stick : static map only (Karnopp's stick zone): where ``|w| <= w_stick`` [q/s] the
    friction balances the net applied torque ``u_stick`` [F] per sample (``tau - J a - G``), clipped to
    the level; without ``u_stick`` the sign law holds down to ``w = 0`` (``F = f(0) = 0`` there).
    reference : run the plain-python twin instead of the compiled loop.

    Returns friction [F], bristle deflection [q] (zeros for the static map) and joint temperature [degC]
    (NaN without a thermal law).
    """
    t = np.ascontiguousarray(t, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    if t.ndim != 1 or t.shape != w.shape:
        raise ValueError("t and w must be 1-D arrays of the same length")
    n = w.shape[0]
    c_pos = np.ascontiguousarray(c_pos, dtype=float)
    c_neg = c_pos.copy() if c_neg is None else np.ascontiguousarray(c_neg, dtype=float)
    gmul = np.ones(n) if gmul is None else np.ascontiguousarray(np.broadcast_to(gmul, (n,)), dtype=float)
    fmul = np.ones(n) if fmul is None else np.ascontiguousarray(np.broadcast_to(fmul, (n,)), dtype=float)
    dynamic = sigma0 is not None
    s0p, s0n = _pair(sigma0) if dynamic else (1.0, 1.0)
    s1p, s1n = _pair(sigma1)
    T_in = np.zeros(n)
    T_given = False
    if thermal:
        code = int(thermal["code"])
        theta = np.ascontiguousarray(thermal["theta"], dtype=float)
        dc_pos = np.ascontiguousarray(thermal.get("dc_pos", np.zeros(9)), dtype=float)
        dc_neg = np.ascontiguousarray(thermal.get("dc_neg", dc_pos), dtype=float)
        if thermal.get("T") is not None:
            T_in = np.ascontiguousarray(np.broadcast_to(np.asarray(thermal["T"], float), (n,)))
            T_given = True
            C = K = 1.0
            Tenv = np.zeros(n)
            T_init = float(T_in[0]) if n else 0.0
        else:
            C, K = float(thermal["C"]), float(thermal["K"])
            Tenv = np.ascontiguousarray(np.broadcast_to(np.asarray(thermal["Tenv"], float), (n,)))
            T_init = float(thermal.get("T_init", Tenv[0] if n else 0.0))
    else:
        code, theta = 0, np.zeros(4)
        dc_pos = dc_neg = np.zeros(9)
        C = K = 1.0
        Tenv = np.zeros(n)
        T_init = math.nan
    if u_stick is None:
        u_stick, w_stick = np.zeros(n), -1.0
    else:
        u_stick = np.ascontiguousarray(np.broadcast_to(u_stick, (n,)), dtype=float)
        w_stick = float(w_stick)
    fn = replay_friction_ref if reference else _kernel
    return fn(t, w, gmul, fmul, c_pos, c_neg, s0p, s0n, s1p, s1n, float(z0), bool(dynamic),
              code, theta, dc_pos, dc_neg, C, K, Tenv, T_init, T_in, T_given, u_stick, w_stick)
