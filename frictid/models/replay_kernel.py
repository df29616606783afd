"""Replay kernel: the friction an identified model predicts along a *measured* motion.

It evaluates every model the parameter file can hold
(the base static maps, LuGre, the thermal laws and the extensions the diagnosis adds), with one
compiled loop:

- the static map of :mod:`frictid.models.static` (canonical 9-vectors, one per velocity sign), its
  level ``g`` scaled per sample by ``gmul[k]`` and its viscous part ``f`` by ``fmul[k]``. The
  multipliers carry everything that depends on measured quantities only (position, transmitted torque,
  payload, elapsed time), so they are computed once, vectorised, before the loop;
- either the static law ``F = g sgn(w) + f`` (``dynamic = False``) or LuGre
  (``dz/dt = w - sigma0 |w| z / g``, ``F = sigma0 z + sigma1 dz/dt + f``), the bristle state advanced
  exactly for the velocity held at the step's midpoint (as the plant's kernel does);
- a thermal law (code of :data:`frictid.models.thermal.THERMAL_CODES`): the map at joint temperature
  ``T`` is ``c0 s(T) + dc (T - T0)``; ``T`` is either given per sample (a measured joint temperature)
  or follows the heat balance ``C dT/dt = F w - K (T - Tenv)`` driven by the *predicted* friction power,
  stepped exactly with the power held over each sample period.

The temperature is the only state besides ``z`` that the prediction feeds back on, which is why this
runs as a sequential loop (numba, ``cache=True``, the plant kernel's fastmath flags). The map at ``T`` is
evaluated as ``s(T) g0 + dT dc`` instead of rebuilding both canonical vectors every sample, the heat
step's ``exp(-K h / C)`` is reused while the sample period is unchanged, the outputs are allocated by
numpy (huge pages) and maps with a constant level (polynomial, Coulomb-viscous) skip the level's
exponentials: about 45 M samples/s with LuGre and thermal6 (20 M/s with a
Stribeck level), 8x the per-sample rebuild it replaces, equal to it within 1e-14 relative
(``benchmarks/bench_replay.py``). :func:`replay_friction_ref` is an independent plain python/numpy twin
(static.py's vectorised maps, thermal.py's heat step); the tests check that they agree.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, types as nt

from .lugre import _FM, _pair, thermal_factors_nb
from .static import canonical_level, canonical_viscous


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _level(v, cc, o):
    """g0(v) [F] of branch o (0: w >= 0, 9: w < 0) of the packed vectors cc at speed v = |w|.

    cc holds the two canonical vectors concatenated, the velocity scales vs1, vs2 (entries 2 and 5)
    replaced by their reciprocals (see :func:`_pack`)."""
    g = cc[o]
    c1 = cc[o + 1]
    if c1 != 0.0:
        x = v * cc[o + 2]
        d = cc[o + 3]
        if d == 1.0:
            g += c1 * math.exp(-x)
        elif d == 2.0:
            g += c1 * math.exp(-x * x)
        else:
            g += c1 * math.exp(-(x ** d))
    c4 = cc[o + 4]
    if c4 != 0.0:
        g += c4 * (1.0 - math.exp(-v * cc[o + 5]))
    return g


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _clip(x, g):
    """``x`` limited to the level ``[-g, g]`` (the stick zone's friction balances the applied torque up to it)."""
    if x > g:
        return g
    if x < -g:
        return -g
    return x


@njit(cache=True, error_model="numpy", fastmath=_FM)
def _kernel(t, w, gmul, fmul, cc, s0p, s0n, s1p, s1n, z0, dynamic,
            code, theta, dd, C, K, Tenv, T_init, T_in, T_given, u_stick, w_stick, hold, F, z, T, flat):
    """The replay loop, for any canonical map. The map at joint temperature T is ``c0 s(T) + dc (T - T0)``
    (:func:`frictid.models.lugre.thermal_canon_nb`); the level is linear in the amplitudes (a0, a1, a2)
    and the viscous part in (b1, b2, b3), so it is evaluated as ``s g0(|w|) + dT dc_a0`` and
    ``s f0(w) + dT f_dc(w)`` (the plant kernel's algebra): no per-sample rebuild of the two canonical
    vectors. ``exp(-K h / C)`` is recomputed only when the sample period changes. The outputs F, z, T
    are allocated by the caller (numpy maps large arrays on huge pages: a third of the time went into
    page faults when the kernel allocated them); z or T one value long holds a state that cannot change
    (the static law's z = 0, no thermal law's T), and F may be ``u_stick`` itself (each sample's
    ``u_stick`` is read before its F is written). ``flat``: the level is the constant a0 (no Stribeck or
    saturation term; :func:`replay_friction` sets it from the map). One compiled copy for both kinds of map
    (session 25: a copy compiled per literal ``flat``, each behind its own kernel, was a second of a first
    run's compilation; 1 M samples, both builds alternating in one run: 37.9/36.5, 21.4/21.5, 3.8/3.3 and
    17.2/16.7 ns per sample for a Stribeck level with LuGre and thermal6, a flat one with them, a flat static
    map and a Stribeck static map; the same numbers to the last bit)."""
    n = w.shape[0]
    sg = 1 if gmul.shape[0] > 1 else 0  # a multiplier of length 1 holds for every sample
    sf = 1 if fmul.shape[0] > 1 else 0
    sz = 1 if z.shape[0] > 1 else 0  # an output of length 1 (a state that cannot change) is written in place
    sT = 1 if T.shape[0] > 1 else 0
    sh = 1 if hold.shape[0] > 1 else 0
    zk = z0
    Tk = T_init
    T_used = math.nan
    alpha = theta[0]
    beta = theta[1]
    lam = theta[2]
    T0 = theta[3]
    s = 1.0
    dT = 0.0
    thermal = code != 0
    heat = thermal and not T_given
    iK = 1.0 / K
    is0p = 1.0 / s0p
    is0n = 1.0 / s0n
    KC = K / C
    h_last = math.nan
    eK = 0.0
    for k in range(n):
        if T_given:
            Tk = T_in[k]
        if thermal and Tk != T_used:
            s, dT = thermal_factors_nb(code, Tk - T0, alpha, beta, lam)
            T_used = Tk
        wk = w[k]
        v = abs(wk)
        o = 0 if wk >= 0.0 else 9
        g = gmul[k * sg] * (s * (cc[o] if flat else _level(v, cc, o)) + dT * dd[o])
        if g < 1e-300:
            g = 1e-300
        fv = fmul[k * sf] * wk * (s * (cc[o + 6] + cc[o + 7] * v + cc[o + 8] * wk * wk)
                             + dT * (dd[o + 6] + dd[o + 7] * v + dd[o + 8] * wk * wk))
        if dynamic:
            if zk != zk:
                # z0 NaN: the log starts in the steady state of its first sample's motion (sliding: the
                # bristles at g sgn(w) / sigma0; still: unloaded until the stick zone reads the torque)
                zk = 0.0
                if v > w_stick and v > 0.0:
                    zk = g / s0p if wk > 0.0 else -g / s0n
            if zk >= 0.0:
                s0 = s0p
                s1 = s1p
            else:
                s0 = s0n
                s1 = s1n
            if v <= w_stick:
                # the stick zone reads the applied torque, up to the level; where the joint stands (hold)
                # the bristles carry that load, so motion resumes from it, elsewhere they follow the motion
                Fk = _clip(u_stick[k], g)
                if hold[k * sh]:
                    zk = Fk * (is0p if Fk >= 0.0 else is0n)
            else:
                zd = wk - s0 * v / g * zk
                Fk = s0 * zk + s1 * zd + fv
        elif v <= w_stick:
            # Karnopp: sticking, the friction balances the applied torque up to the level
            Fk = _clip(u_stick[k], g)
        elif wk > 0.0:
            Fk = g + fv
        elif wk < 0.0:
            Fk = -g + fv
        else:
            Fk = fv
        F[k] = Fk
        z[k * sz] = zk
        T[k * sT] = Tk
        if k + 1 < n:
            h = t[k + 1] - t[k]
            if dynamic:
                wm = 0.5 * (wk + w[k + 1])
                if wm != 0.0:
                    vm = abs(wm)
                    om = 0 if wm >= 0.0 else 9
                    gm = 0.5 * (gmul[k * sg] + gmul[(k + 1) * sg]) * (
                        s * (cc[om] if flat else _level(vm, cc, om)) + dT * dd[om])
                    if gm < 1e-300:
                        gm = 1e-300
                    # a = sigma0 |wm| / g, z_ss = wm / a = g sgn(wm) / sigma0: one division
                    if zk >= 0.0:
                        s0m = s0p
                        is0m = is0p
                    else:
                        s0m = s0n
                        is0m = is0n
                    zss = gm * is0m
                    if wm < 0.0:
                        zss = -zss
                    zk = zss + (zk - zss) * math.exp(-s0m * vm * h / gm)
            if heat:
                if h != h_last:
                    eK = math.exp(-KC * h)
                    h_last = h
                Tss = Tenv[k] + Fk * wk * iK
                Tk = Tss + (Tk - Tss) * eK
    return F, z, T


_IN = nt.Array(nt.float64, 1, "C", readonly=True)
#: The one signature of :func:`_kernel` (numba types): every input array a read-only
#: view, the outputs writeable (:func:`replay_friction` passes them so).
SIGNATURE = ((_IN,) * 5 + (nt.float64,) * 5 + (nt.boolean, nt.int64, _IN, _IN, nt.float64, nt.float64, _IN,
             nt.float64, _IN, nt.boolean, _IN, nt.float64, nt.Array(nt.boolean, 1, "C", readonly=True))
             + (nt.float64[::1],) * 3 + (nt.boolean,))
#: The kernels with their signature, for :func:`frictid.api.compile_kernels`.
KERNELS = ((_kernel, SIGNATURE),)


def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of the contiguous array ``a`` (no copy)."""
    v = a.view()
    v.flags.writeable = False
    return v


def _pack(c_pos, c_neg):
    """The two canonical vectors concatenated (18), vs1 and vs2 replaced by their reciprocals where used."""
    cc = np.concatenate([c_pos, c_neg]).astype(float)
    for o in (0, 9):
        if cc[o + 1] != 0.0:
            cc[o + 2] = 1.0 / cc[o + 2]
        if cc[o + 4] != 0.0:
            cc[o + 5] = 1.0 / cc[o + 5]
    return cc


def replay_friction_ref(t, w, gmul, fmul, c_pos, c_neg, s0p, s0n, s1p, s1n, z0, dynamic,
                        code, theta, dc_pos, dc_neg, C, K, Tenv, T_init, T_in, T_given, u_stick, w_stick, hold):
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
        if dynamic and zk != zk:  # z0 NaN: the steady state of the first sample's motion
            zk = (g / s0p if wk > 0 else -g / s0n) if abs(wk) > w_stick and wk != 0 else 0.0
        if dynamic and abs(wk) <= w_stick:
            F[k] = float(np.clip(u_stick[k], -g, g))
            if hold[k]:
                zk = F[k] / (s0p if F[k] >= 0 else s0n)
        elif dynamic:
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


def _multiplier(m, n: int) -> np.ndarray:
    """A per-sample multiplier as the kernel takes it: one value (length 1) when it is the same for every
    sample (None: 1), else n contiguous values. A constant then costs no array of the log's length."""
    if m is None:
        return np.ones(1)
    m = np.asarray(m, dtype=float)
    if m.size == 1:
        return np.full(1, float(m.reshape(-1)[0]))
    return np.ascontiguousarray(np.broadcast_to(m, (n,)))


def replay_friction(t, w, c_pos, c_neg=None, *, gmul=None, fmul=None, sigma0=None, sigma1=0.0, z0=0.0,
                    thermal=None, u_stick=None, w_stick=0.0, hold=None, out=None, reference=False):
    """Friction [F] predicted along a measured velocity; returns ``(F, z, T)``.

    t : sample times [s], increasing; w : velocity [q/s] at those times.
    c_pos, c_neg : canonical static vectors (:data:`frictid.models.static.CANON`) for ``w >= 0`` and
    ``w < 0``; c_neg defaults to c_pos.
    gmul, fmul : per-sample multipliers [1] of the level ``g`` and of the viscous part ``f`` (default 1).
    sigma0 : LuGre stiffness [F/q] (number or (z >= 0, z < 0) pair); None gives the static map.
    sigma1 : LuGre damping [F s/q] (number or pair). z0 : initial bristle deflection [q], or ``"steady"``: the
    steady state of the first sample's motion (``g(w) sgn(w) / sigma0`` where the log starts sliding, 0 where
    it starts within the stick zone): a log cut from a longer recording starts with the bristles as the
    motion has already set them, not unloaded.
    thermal : None, or a dict with ``code``, ``theta`` (= [alpha, beta, lam, T0]) and ``dc_pos`` /
    ``dc_neg`` as packed by :func:`frictid.models.thermal.thermal_code`, and either ``T`` (the joint
    temperature per sample [degC], e.g. measured) or ``C`` [J/K], ``K`` [W/K], ``Tenv`` [degC, scalar or
    per sample] and ``T_init`` [degC, default ``Tenv[0]``] for the heat balance.
    u_stick, w_stick : Karnopp's stick zone: where ``|w| <= w_stick`` [q/s] the friction balances the net
    applied torque ``u_stick`` [F] per sample (``tau - J a - G``), clipped to the level; without ``u_stick``
    the sign law holds down to ``w = 0`` (``F = f(0) = 0`` there). With LuGre the bristles follow the
    measured velocity there, except where ``hold`` (bool per sample, default nowhere) says the joint
    stands: there they carry the load the torque puts on them (``z = F / sigma0``), so that motion
    resumes from the rest's load, not from the last motion's state.
    out : a float64 array of n contiguous values to receive the friction (returned as F), e.g. ``u_stick``
    itself when the caller needs it no more: no third array of the log's length.
    reference : run the plain-python twin instead of the compiled loop.

    Returns friction [F], bristle deflection [q] (zeros for the static map) and joint temperature [degC]
    (NaN without a thermal law). The zeros of the static map's z and the NaN of T without a thermal law
    are one value broadcast to n samples (read-only): no array of the log's length each.
    """
    t = np.ascontiguousarray(t, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    if t.ndim != 1 or t.shape != w.shape:
        raise ValueError("t and w must be 1-D arrays of the same length")
    n = w.shape[0]
    c_pos = np.ascontiguousarray(c_pos, dtype=float)
    c_neg = c_pos.copy() if c_neg is None else np.ascontiguousarray(c_neg, dtype=float)
    gmul, fmul = _multiplier(gmul, n), _multiplier(fmul, n)
    dynamic = sigma0 is not None
    s0p, s0n = _pair(sigma0) if dynamic else (1.0, 1.0)
    z0 = math.nan if isinstance(z0, str) and z0 == "steady" else float(z0)
    s1p, s1n = _pair(sigma1)
    # inputs the loop does not read stay one value long (the joint temperature unless given, the ambient
    # without a heat balance, the applied torque without a stick zone): no array of the log's length
    T_in = np.zeros(1)
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
            Tenv = np.zeros(1)
            T_init = float(T_in[0]) if n else 0.0
        else:
            C, K = float(thermal["C"]), float(thermal["K"])
            Tenv = np.ascontiguousarray(np.broadcast_to(np.asarray(thermal["Tenv"], float), (n,)))
            T_init = float(thermal.get("T_init", Tenv[0] if n else 0.0))
    else:
        code, theta = 0, np.zeros(4)
        dc_pos = dc_neg = np.zeros(9)
        C = K = 1.0
        Tenv = np.zeros(1)
        T_init = math.nan
    hold = (np.zeros(1, dtype=np.bool_) if hold is None else
            np.ascontiguousarray(np.broadcast_to(hold, (n,)), dtype=np.bool_))
    if u_stick is None:
        u_stick, w_stick = np.zeros(1), -1.0
    else:
        u_stick = np.ascontiguousarray(np.broadcast_to(u_stick, (n,)), dtype=float)
        w_stick = float(w_stick)
    if out is not None and (not isinstance(out, np.ndarray) or out.dtype != np.float64 or out.shape != (n,)
                            or not out.flags.c_contiguous or not out.flags.writeable):
        raise ValueError("out must be a writeable, contiguous float64 array of the velocity's length")
    if reference:
        gmul, fmul = np.broadcast_to(gmul, (n,)), np.broadcast_to(fmul, (n,))
        T_in, Tenv, u_stick, hold = (np.broadcast_to(x, (n,)) if x.shape[0] == 1 else x
                                     for x in (T_in, Tenv, u_stick, hold))
        F, z, T = replay_friction_ref(t, w, gmul, fmul, c_pos, c_neg, s0p, s0n, s1p, s1n, z0, bool(dynamic),
                                      code, theta, dc_pos, dc_neg, C, K, Tenv, T_init, T_in, T_given, u_stick,
                                      w_stick, hold)
        if out is not None:
            out[:] = F
            F = out
        return F, z, T
    cc = _pack(c_pos, c_neg)
    flat = cc[1] == 0.0 and cc[4] == 0.0 and cc[10] == 0.0 and cc[13] == 0.0
    # a state that cannot change is one value long (the static law's bristle state, the temperature without
    # a thermal law): the replays of a report's diagnosis then allocate 29-58 MB fewer per joint-hour
    z = np.empty(n if dynamic else 1)
    T = np.empty(n if code != 0 else 1)
    # every input as a read-only view (the caller's arrays, broadcasts and fresh ones alike) and every number as a
    # float, an int or a bool: one compiled signature per kernel (:data:`SIGNATURE`), not one per combination of
    # flags a caller's arrays happen to carry (each a second or more of compilation on a first run)
    F, z, T = _kernel(
        *map(_readonly, (t, w, gmul, fmul, cc)), float(s0p), float(s0n), float(s1p), float(s1n), z0, bool(dynamic),
        code, _readonly(theta), _readonly(np.concatenate([dc_pos, dc_neg])), float(C), float(K), _readonly(Tenv),
        float(T_init), _readonly(T_in), bool(T_given), _readonly(u_stick), float(w_stick), _readonly(hold),
        np.empty(n) if out is None else out, z, T, bool(flat))
    if n != 1:
        z = z if z.shape[0] == n else np.broadcast_to(z, (n,))
        T = T if T.shape[0] == n else np.broadcast_to(T, (n,))
    return F, z, T


def standing(w, w_stick: float, window: int) -> np.ndarray:
    """Where a joint stands [bool per sample]: ``|w| <= w_stick`` on every sample within ``window`` samples
    either side (half the derivative filter's window): the samples at the edge of a rest carry the acceleration
    the filter spreads over them, so the torque there does not tell the friction's load."""
    still = np.abs(np.asarray(w, dtype=float)) <= w_stick
    if window <= 0 or still.size == 0:
        return still
    moving = np.concatenate([[0], np.cumsum(~still)])
    lo = np.clip(np.arange(still.size) - window, 0, still.size)
    hi = np.clip(np.arange(still.size) + window + 1, 0, still.size)
    return still & (moving[hi] - moving[lo] == 0)
