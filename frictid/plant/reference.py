"""A slow, tight reference for the plant kernel: the unfrozen nonlinear ODE solved by scipy's Radau.

Same controller and sensor logic as :func:`frictid.plant.kernel.simulate_joint_ref`, but each sample
interval is integrated by ``solve_ivp(method="Radau", rtol=1e-10)`` on the full state
``(q, w, z, T)`` with the exact LuGre right-hand side (no frozen ``a``, temperature inside the ODE).
Used by the benchmark and the accuracy test to measure the kernel's discretisation error.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from ..models.static import canonical_level, canonical_viscous
from ..models.thermal import canonical_at
from .kernel import (P_C, P_GOFF, P_HAMP, P_HPER, P_HPH, P_J, P_K, P_LOAD, P_PAMP, P_PAY, P_PPER, P_PPH, P_PX,
                     P_PY, P_QRES, P_S0N, P_S0P, P_S1N, P_S1P, command_ref)


def _friction(q, w, z, T, u, k, p, c_pos, c_neg, dc_pos, dc_neg, code, theta, gmul, fmul):
    c = c_pos if w >= 0 else c_neg
    dc = dc_pos if w >= 0 else dc_neg
    if code:
        c = canonical_at(c, T, code, theta, dc)
    gm = gmul[k] * (1 + p[P_LOAD] * abs(u))
    if p[P_PAMP]:
        gm *= 1 + p[P_PAMP] * math.sin(2 * math.pi / p[P_PPER] * q + p[P_PPH])
    g = gm * float(canonical_level(w, c))
    f = fmul[k] * float(canonical_viscous(w, c))
    s0, s1 = (p[P_S0P], p[P_S1P]) if z >= 0 else (p[P_S0N], p[P_S1N])
    zd = w - s0 * abs(w) / g * z
    return s0 * z + s1 * zd + f, zd


def simulate_joint_ivp(h, mode, q_ref, qd_ref, tau_ff, Tenv, payload, reset_T, gmul, fmul, nq, nqd, p,
                       c_pos, c_neg, dc_pos, dc_neg, code, theta, state0, rtol=1e-10, atol=None):
    """Reference closed loop over len(mode) samples. Returns (q, w, z, F, T, u) at the samples."""
    n = len(mode)
    out = {k: np.empty(n) for k in ("q", "w", "z", "F", "T", "u")}
    x = np.array(state0, dtype=float)
    integ, prev = 0.0, -1
    if atol is None:
        atol = np.array([1e-13, 1e-12, 1e-14, 1e-9])
    for k in range(n):
        q, w, z, T = x
        if reset_T[k]:
            x[3] = T = Tenv[k]
        qm = q + nq[k]
        if p[P_QRES] > 0:
            qm = math.floor(qm / p[P_QRES] + 0.5) * p[P_QRES]
        qdm = w + nqd[k]
        if mode[k] != prev:
            integ, prev = 0.0, mode[k]
        u, integ = command_ref(mode[k], integ, q_ref[k] - qm, qd_ref[k] - qdm, tau_ff[k], p, h)
        F, _ = _friction(q, w, z, T, u, k, p, c_pos, c_neg, dc_pos, dc_neg, code, theta, gmul, fmul)
        for key, val in (("q", q), ("w", w), ("z", z), ("T", T), ("u", u), ("F", F)):
            out[key][k] = val

        def rhs(_t, s, u=u, k=k):
            q_, w_, z_, T_ = s
            F_, zd = _friction(q_, w_, z_, T_, u, k, p, c_pos, c_neg, dc_pos, dc_neg, code, theta,
                               gmul, fmul)
            G = (p[P_GOFF] + p[P_PX] * math.cos(q_) + p[P_PY] * math.sin(q_)
                 + payload[k] * p[P_PAY] * math.cos(q_))
            if p[P_HAMP]:
                G += p[P_HAMP] * math.sin(2 * math.pi / p[P_HPER] * q_ + p[P_HPH])
            return [w_, (u - G - F_) / p[P_J], zd, (F_ * w_ - p[P_K] * (T_ - Tenv[k])) / p[P_C]]

        sol = solve_ivp(rhs, (0.0, h), x, method="Radau", rtol=rtol, atol=atol)
        x = sol.y[:, -1].copy()
    return tuple(out[k] for k in ("q", "w", "z", "F", "T", "u"))
