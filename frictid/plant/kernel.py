"""The compiled simulation loop: one joint, controller at the sample rate, LuGre friction, heat balance.

Per sample k (period h, ZOH torque):

1. sensors: ``qm = quantise(q + nq[k])``, ``qdm = w + nqd[k]`` (what the drive measures);
2. controller: open-loop torque (mode 0), PID on position (mode 1) or PI on velocity (mode 2), plus the
   feedforward ``tau_ff[k]``, saturated at ``tau_max`` with conditional-integration anti-windup;
3. ``nsub`` substeps of :func:`frictid.models.lugre.lugre_step` with gravity at the substep midpoint;
4. heat balance, exact first-order step driven by the friction power ``F w`` at the sample.

Friction: canonical map at temperature T (thermal law), level ``g`` scaled by ``gmul[k]`` (drift,
payload, dwell), by ``1 + amp sin(2 pi q / period + phase)`` (position effect) and by ``1 + load |u|``
(load effect); viscous part ``f`` scaled by ``fmul[k]`` (drift). Gravity ``G(q)`` includes a
``position_torque`` effect's ``amplitude sin(2 pi q / period + phase)``.

Why numba: the loop is inherently sequential (each step needs the previous state and the controller
closes the loop every sample), so numpy cannot vectorise it; compiled, one hour at 1 kHz runs in well
under a second. :func:`simulate_joint_ref` is the same loop in plain python for the agreement tests.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..models.lugre import lugre_core, lugre_step_ref
from ..models.static import canonical_level, canonical_viscous
from ..models.lugre import _FM, thermal_factors_nb

# Indices into the parameter vector p.
P_J, P_S0P, P_S0N, P_S1P, P_S1N = 0, 1, 2, 3, 4
P_PX, P_PY, P_GOFF, P_PAY = 5, 6, 7, 8
P_TMAX, P_KP, P_KD, P_KI, P_KV, P_KVI = 9, 10, 11, 12, 13, 14
P_PAMP, P_PPER, P_PPH, P_LOAD = 15, 16, 17, 18
P_C, P_K, P_QRES = 19, 20, 21
P_HAMP, P_HPER, P_HPH = 22, 23, 24
N_P = 25

MODE_TORQUE, MODE_PID, MODE_VEL = 0, 1, 2


@njit(cache=True, error_model="numpy", fastmath=_FM)
def _branch(c, dc):
    """The map's coefficients of one velocity sign as tuples (values, not arrays: no reference
    counting where the loop passes them on): canonical vector c with the velocity scales vs1, vs2
    (entries 2 and 5) replaced by their reciprocals, and the thermal6 slopes of (a0, b1, b2, b3)."""
    return ((c[0], c[1], 1.0 / c[2], c[3], c[4], 1.0 / c[5], c[6], c[7], c[8]),
            (dc[0], dc[6], dc[7], dc[8]))


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _map_at(w, cp, cn, dp, dn, s_th, dT):
    """The canonical map at velocity w (branch cp, dp for w >= 0, cn, dn for w < 0) and temperature.

    cp, cn, dp, dn : tuples from :func:`_branch`. The map at joint temperature T is
    ``c0 s(T) + dc (T - T0)`` (:func:`frictid.models.lugre.thermal_canon_nb`); since the level is linear
    in the amplitudes (a0, a1, a2) and the viscous part in (b1, b2, b3), it is evaluated as
    ``s g0(v) + dT dc_a0`` and ``s f0(w) + dT f_dc(w)``: no per-sample copy of the vectors.
    s_th = s(T); dT = T - T0 for thermal6 (0 otherwise). Returns (g, dg/d|w|, f, df/dw).
    """
    if w >= 0.0:
        c = cp
        dc = dp
    else:
        c = cn
        dc = dn
    v = abs(w)
    g = c[0]
    dg = 0.0
    c1 = c[1]
    if c1 != 0.0:
        ivs = c[2]
        x = v * ivs
        d = c[3]
        if d == 1.0:
            e = math.exp(-x)
            g += c1 * e
            dg -= c1 * ivs * e
        elif d == 2.0:
            e = math.exp(-x * x)
            g += c1 * e
            dg -= c1 * 2.0 * x * ivs * e
        elif x > 0.0:
            xd1 = math.sqrt(x) if d == 1.5 else x ** (d - 1.0)
            e = math.exp(-xd1 * x)
            g += c1 * e
            dg -= c1 * d * ivs * xd1 * e
        else:
            g += c1
    c4 = c[4]
    if c4 != 0.0:
        ivs2 = c[5]
        e = math.exp(-v * ivs2)
        g += c4 * (1.0 - e)
        dg += c4 * ivs2 * e
    b1 = c[6]
    b2 = c[7]
    b3 = c[8]
    f = w * (b1 + b2 * v + b3 * w * w)
    fp = b1 + 2.0 * b2 * v + 3.0 * b3 * w * w
    g *= s_th
    dg *= s_th
    f *= s_th
    fp *= s_th
    if dT != 0.0:
        g += dc[0] * dT
        d1 = dc[1]
        d2 = dc[2]
        d3 = dc[3]
        f += dT * w * (d1 + d2 * v + d3 * w * w)
        fp += dT * (d1 + 2.0 * d2 * v + 3.0 * d3 * w * w)
    return g, dg, f, fp


#: Pieces a step is cut into when the velocity changes sign within it.
REFINE = 8


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _step_map(q, w, z, u, hs, g0, dg0, f0, fp0, lmul, fm, amp, sin_end, G, iJ, s0p, s0n, s1p, s1n):
    """One plant step of length hs with the applied torque u held, given the map (g0, dg0, f0, fp0) at
    (|w|, T) before the level and viscous multipliers, the position effect's sine at the step's
    predicted end position and the gravity torque G at its midpoint position. Returns (q, w, z, F) with
    F the friction at the step's start."""
    gm = lmul
    if amp != 0.0:
        # the level along the step is taken at the predicted end position, so that z, which settles
        # within the step in sliding, lands on g(q1)/sigma0 rather than lagging a step behind
        gm *= 1.0 + amp * sin_end
    if z >= 0.0:
        s0 = s0p
        s1 = s1p
    else:
        s0 = s0n
        s1 = s1n
    return lugre_core(q, w, z, u - G, hs, iJ, s0, s1, gm * g0, gm * dg0, fm * f0, fm * fp0)


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _gravity(qm, pay, goff, px, py, parm, harm):
    """Gravity and offset torque [F] at position qm [q] with payload pay [kg], plus the position torque
    ``harm = (amplitude, 2 pi / period, phase)`` (a ``position_torque`` effect)."""
    G = goff
    if px != 0.0 or py != 0.0 or (pay != 0.0 and parm != 0.0):
        cq = math.cos(qm)
        G += px * cq + py * math.sin(qm) + pay * parm * cq
    if harm[0] != 0.0:
        G += harm[0] * math.sin(harm[1] * qm + harm[2])
    return G


#: Largest angle change [rad] over which a cos/sin pair is rotated rather than recomputed.
ROTATE_MAX = 0.04
#: cos/sin are recomputed exactly every this many samples (bounds the round-off of the rotations).
RESYNC = 1024


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _rotate(qm, qg, cg, sg, exact):
    """(cos qm, sin qm) from (cos qg, sin qg) by the rotation through d = qm - qg (Taylor to d^7,
    error below d^8/40320 < 1e-15 for |d| < ROTATE_MAX), or exactly when asked or when |d| is larger.
    A 1 kHz step moves a joint by a few mrad (and the position effect's phase by a few hundredths), so
    this replaces a sin/cos pair on the loop's critical path with a few multiply-adds."""
    d = qm - qg
    if exact or abs(d) > ROTATE_MAX:
        return math.cos(qm), math.sin(qm)
    d2 = d * d
    cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)))
    sd = d * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0))))
    return cg * cd - sg * sd, sg * cd + cg * sd


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _step(q, w, z, u, hs, cp, cn, dp, dn, s_th, dT, lmul, fm, amp, kper, ph, pay,
          iJ, s0p, s0n, s1p, s1n, goff, px, py, parm, harm):
    """:func:`_step_map` with the map looked up from w and gravity computed; returns (q, w, z)."""
    g0, dg0, f0, fp0 = _map_at(w, cp, cn, dp, dn, s_th, dT)
    G = _gravity(q + 0.5 * hs * w, pay, goff, px, py, parm, harm)
    sin_end = math.sin(kper * (q + hs * w) + ph) if amp != 0.0 else 0.0
    q1, w1, z1, _ = _step_map(q, w, z, u, hs, g0, dg0, f0, fp0, lmul, fm, amp, sin_end, G,
                              iJ, s0p, s0n, s1p, s1n)
    return q1, w1, z1


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _needs_refine(w, w1, z, z1, s0, hs, ig, per_sign):
    """Whether a step from (w, z) to (w1, z1) must be redone in pieces.

    ``ah = s0 max|w| h / g`` is how far the bristles move in one step relative to their deflection
    limit; ``s0 |z| / g`` how loaded they are (ig = 1/g). Refine on a velocity reversal with loaded
    bristles (``ah s0|z|/g > 1e-3``), on a bristle sign change with per-sign stiffness, and on a velocity
    change of more than 10 % with ``ah > 0.05`` (the steep part of a Stribeck curve).
    """
    wm = max(abs(w), abs(w1))
    ah = wm * s0 * hs * ig
    if w1 * w < 0.0 and ah * s0 * abs(z) * ig > 1e-3:
        return True
    if z1 * z < 0.0 and per_sign and ah > 1e-2:
        return True
    return abs(w1 - w) > 0.1 * wm and ah > 0.05


@njit(cache=True, error_model="numpy", fastmath=_FM)
def _refined(q, w, z, u, hs, cp, cn, dp, dn, s_th, dT, lmul, fm, amp, kper, ph, pay,
             iJ, s0p, s0n, s1p, s1n, goff, px, py, parm, harm):
    """The step hs cut into REFINE pieces; a piece in which the velocity changes sign is cut again."""
    hr = hs / REFINE
    for _ in range(REFINE):
        q1, w1, z1 = _step(q, w, z, u, hr, cp, cn, dp, dn, s_th, dT, lmul, fm, amp, kper, ph, pay,
                           iJ, s0p, s0n, s1p, s1n, goff, px, py, parm, harm)
        if w1 * w < 0.0:
            q1, w1, z1 = q, w, z
            for _ in range(REFINE):
                q1, w1, z1 = _step(q1, w1, z1, u, hr / REFINE, cp, cn, dp, dn, s_th, dT, lmul, fm, amp,
                                   kper, ph, pay, iJ, s0p, s0n, s1p, s1n, goff, px, py, parm, harm)
        q, w, z = q1, w1, z1
    return q, w, z


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _observer(w, e, zh, h, gain, ocp, ocn, odp, odn, s0p, s0n, s1p, s1n):
    """The LuGre friction observer of Canudas de Wit et al. (1995; seed 000 eq. 17) at one controller step:
    ``dz/dt = w - sigma0 |w| z / g(w) - gain e``, ``F = sigma0 z + sigma1 dz/dt + f(w)``, with the measured
    velocity w and the tracking error e = q - q_ref. Returns (the friction estimate, z after the step h,
    integrated exactly: the equation is linear in z over the step)."""
    g, _, f, _ = _map_at(w, ocp, ocn, odp, odn, 1.0, 0.0)
    s0 = s0p if w >= 0.0 else s0n
    s1 = s1p if w >= 0.0 else s1n
    a = w - gain * e
    b = s0 * abs(w) / g if g > 0.0 else 0.0
    F = s0 * zh + s1 * (a - b * zh) + f
    if b * h > 1e-12:
        zs = a / b
        return F, zs + (zh - zs) * math.exp(-b * h)
    return F, zh + a * h


@njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _measured_map(w, wf, h, band, ocp, ocn, odp, odn):
    """A static friction map as feed-forward from the measured velocity w, low-passed to the loop's
    bandwidth ``band`` [rad/s] (first order, exact over the step: wf its state): ``g(wf) sgn(wf) + f(wf)``.
    Returns (the feed-forward, wf after the step)."""
    wf = w + (wf - w) * math.exp(-band * h)
    g, _, f, _ = _map_at(wf, ocp, ocn, odp, odn, 1.0, 0.0)
    if wf > 0.0:
        return g + f, wf
    if wf < 0.0:
        return f - g, wf
    return f, wf


#: The outputs of :func:`simulate_joint`, in order.
OUTPUTS = ("q", "w", "z", "F", "T", "u", "qm", "qdm")


def simulate_joint(h, nsub, mode, q_ref, qd_ref, tau_ff, Tenv, payload, reset_T, gmul, fmul,
                   nq, nqd, p, c_pos, c_neg, dc_pos, dc_neg, th_code, theta, state0, outputs=OUTPUTS,
                   observer=None):
    """Run the closed loop over n samples. Returns (q, w, z, F, T, u, qm, qdm), each of length n;
    ``outputs`` names those wanted, the others are None (the loop writes them into one scratch array:
    a caller that needs the position alone touches two arrays of n doubles instead of eight).

    h [s] sample period; nsub substeps; mode (int) per sample; q_ref [q], qd_ref [q/s], tau_ff [F];
    Tenv [degC]; payload [kg]; reset_T (bool) resets T to Tenv; gmul, fmul [1] level/viscous multipliers;
    nq [q], nqd [q/s] sensor noise; p parameters (see P_* indices); c_pos, c_neg canonical static vectors;
    dc_pos, dc_neg thermal6 slopes; th_code, theta thermal law; state0 = (q, w, z, T).

    observer : None, or (gain, sigma0 (pos, neg), sigma1 (pos, neg), c_pos, c_neg) of an identified LuGre model:
    its friction observer (:func:`_observer`) adds its estimate to the torque wherever the loop is closed;
    with both sigma0 zero, the map's steady state at the measured velocity low-passed to ``gain`` [rad/s]
    (:func:`_measured_map`: a static map fed forward from the measured velocity) instead.

    mode, Tenv, payload, reset_T, gmul, fmul, nq and nqd may be one value long, a constant for every
    sample (a replay's closed loop: no array of the log's length for what does not change); q_ref sets n.

    The outputs are allocated here, by numpy, and filled by the compiled loop :func:`_closed_loop`:
    numpy asks the kernel for transparent huge pages for large arrays, so the first touch of the
    8 n doubles of a one-hour run costs ~4,000 page faults (the unaligned ends of each array) instead
    of 56,000, one per 4 KiB page with numba's own allocator: those were a fifth of its CPU time.
    """
    n = q_ref.shape[0]
    unknown = set(outputs) - set(OUTPUTS)
    if unknown:
        raise ValueError(f"simulate_joint: unknown outputs {sorted(unknown)}; known: {OUTPUTS}")
    scratch = np.empty(n) if len(set(outputs)) < len(OUTPUTS) else None
    out = tuple(np.empty(n) if name in outputs else scratch for name in OUTPUTS)
    if observer is None:
        obs, oc_pos, oc_neg = np.zeros(0), np.zeros(9), np.zeros(9)
    else:
        gain, s0, s1, oc_pos, oc_neg = observer
        obs = np.array([gain, s0[0], s0[1], s1[0], s1[1]], dtype=float)
        oc_pos, oc_neg = np.asarray(oc_pos, dtype=float), np.asarray(oc_neg, dtype=float)
    _closed_loop(h, nsub, mode, q_ref, qd_ref, tau_ff, Tenv, payload, reset_T, gmul, fmul,
                 nq, nqd, p, c_pos, c_neg, dc_pos, dc_neg, th_code, theta, state0, obs, oc_pos, oc_neg, *out)
    return tuple(a if name in outputs else None for name, a in zip(OUTPUTS, out))


@njit(cache=True, error_model="numpy", fastmath=_FM)
def _closed_loop(h, nsub, mode, q_ref, qd_ref, tau_ff, Tenv, payload, reset_T, gmul, fmul,
                 nq, nqd, p, c_pos, c_neg, dc_pos, dc_neg, th_code, theta, state0, obs, oc_pos, oc_neg,
                 q_o, w_o, z_o, F_o, T_o, u_o, qm_o, qdm_o):
    """The loop of :func:`simulate_joint`, filling the output arrays q_o ... qdm_o (length n each).

    The parameters are unpacked into scalars once (the loop then keeps them in registers), and the
    thermal law enters as a scale and an offset of the map (see :func:`_map_at`). An input one value long
    holds for every sample (its index stays 0).
    """
    n = q_ref.shape[0]
    s_md = 1 if mode.shape[0] > 1 else 0
    s_te = 1 if Tenv.shape[0] > 1 else 0
    s_pa = 1 if payload.shape[0] > 1 else 0
    s_rs = 1 if reset_T.shape[0] > 1 else 0
    s_gm = 1 if gmul.shape[0] > 1 else 0
    s_fm = 1 if fmul.shape[0] > 1 else 0
    s_nq = 1 if nq.shape[0] > 1 else 0
    s_nd = 1 if nqd.shape[0] > 1 else 0
    cp, dp = _branch(c_pos, dc_pos)
    cn, dn = _branch(c_neg, dc_neg)
    q = state0[0]
    w = state0[1]
    z = state0[2]
    T = state0[3]
    iJ = 1.0 / p[P_J]
    s0p = p[P_S0P]
    s0n = p[P_S0N]
    s1p = p[P_S1P]
    s1n = p[P_S1N]
    per_sign = s0p != s0n
    goff = p[P_GOFF]
    px = p[P_PX]
    py = p[P_PY]
    parm = p[P_PAY]
    hamp = p[P_HAMP]
    harm = (hamp, 2.0 * math.pi / p[P_HPER] if hamp != 0.0 else 0.0, p[P_HPH])
    tmax = p[P_TMAX]
    kp = p[P_KP]
    kd = p[P_KD]
    ki = p[P_KI]
    kv = p[P_KV]
    kvi = p[P_KVI]
    qres = p[P_QRES]
    iqres = 1.0 / qres if qres > 0.0 else 0.0
    amp = p[P_PAMP]
    kper = 2.0 * math.pi / p[P_PPER]
    ph = p[P_PPH]
    load = p[P_LOAD]
    alpha = theta[0]
    beta = theta[1]
    lam = theta[2]
    T0 = theta[3]
    eK = math.exp(-p[P_K] * h / p[P_C])
    iK = 1.0 / p[P_K]
    hs = h / nsub
    integ = 0.0
    prev_mode = -1
    obs_on = obs.shape[0] > 0
    ocp, odp = _branch(oc_pos, oc_pos)  # the observer's map (its thermal slopes unused: dT = 0)
    ocn, odn = _branch(oc_neg, oc_neg)
    zh = 0.0
    T_used = -1e300
    trig = px != 0.0 or py != 0.0 or parm != 0.0
    qg = q
    cg = math.cos(q)
    sg = math.sin(q)
    pe = kper * q + ph
    ce = math.cos(pe)
    se = math.sin(pe)
    s_th = 1.0
    dT = 0.0
    for k in range(n):
        if reset_T[k * s_rs]:
            T = Tenv[k * s_te]
        # the map at temperature T; T moves slowly, so refresh only after a change of 1e-4 K
        if th_code != 0 and abs(T - T_used) > 1e-4:
            s_th, dT = thermal_factors_nb(th_code, T - T0, alpha, beta, lam)
            T_used = T
        # sensors
        qm = q + nq[k * s_nq]
        if qres > 0.0:
            qm = np.floor(qm * iqres + 0.5) * qres   # float floor: no round trip through int64
        qdm = w + nqd[k * s_nd]
        # controller
        md = mode[k * s_md]
        if md != prev_mode:
            integ = 0.0
            prev_mode = md
        if md == MODE_TORQUE:
            u = tau_ff[k]
            integ_new = 0.0
        elif md == MODE_PID:
            e = q_ref[k] - qm
            integ_new = integ + ki * e * h
            u = tau_ff[k] + kp * e + kd * (qd_ref[k] - qdm) + integ_new
        else:
            e = qd_ref[k] - qdm
            integ_new = integ + kvi * e * h
            u = tau_ff[k] + kv * e + integ_new
        if obs_on and md != MODE_TORQUE:
            if obs[1] > 0.0 or obs[2] > 0.0:
                Fh, zh = _observer(qdm, qm - q_ref[k], zh, h, obs[0], ocp, ocn, odp, odn, obs[1], obs[2], obs[3], obs[4])
            else:   # zh: the filtered velocity
                Fh, zh = _measured_map(qdm, zh, h, obs[0], ocp, ocn, odp, odn)
            u += Fh
        if u > tmax:
            u = tmax
        elif u < -tmax:
            u = -tmax
        else:
            integ = integ_new
        q_o[k] = q
        w_o[k] = w
        z_o[k] = z
        T_o[k] = T
        u_o[k] = u
        qm_o[k] = qm
        qdm_o[k] = qdm
        lmul = gmul[k * s_gm] * (1.0 + load * abs(u))
        fm = fmul[k * s_fm]
        pay = payload[k * s_pa]
        w_k = w
        # the map at the sample (its level at the current position: the friction output and the
        # refinement test use it; the step's level is at its predicted end position)
        g0, dg0, f0, fp0 = _map_at(w, cp, cn, dp, dn, s_th, dT)
        g = lmul * g0
        if amp != 0.0:
            # the position effect's phase at the sample, rotated from the previous step's predicted end
            # (a fraction of the step's own rotation away: the prediction misses by the velocity change)
            pa = kper * q + ph
            ce, se = _rotate(pa, pe, ce, se, False)
            pe = pa
            g *= 1.0 + amp * se
        ig = 1.0 / g
        s0 = s0p if z >= 0.0 else s0n
        if amp != 0.0:
            s1 = s1p if z >= 0.0 else s1n
            Fk = s0 * z + s1 * (w - s0 * abs(w) * ig * z) + fm * f0
        for s in range(nsub):
            if s > 0:
                g0, dg0, f0, fp0 = _map_at(w, cp, cn, dp, dn, s_th, dT)
            # gravity at the step's midpoint position, its cos/sin rotated from the previous step's
            qmid = q + 0.5 * hs * w
            G = goff
            if trig:
                cg, sg = _rotate(qmid, qg, cg, sg, (k & (RESYNC - 1)) == 0 and s == 0)
                qg = qmid
                G += px * cg + py * sg + pay * parm * cg
            if hamp != 0.0:
                G += hamp * math.sin(harm[1] * qmid + harm[2])
            sin_end = 0.0
            if amp != 0.0:
                # the position effect's phase at the step's predicted end, rotated likewise
                phe = kper * (q + hs * w) + ph
                ce, se = _rotate(phe, pe, ce, se, (k & (RESYNC - 1)) == 0 and s == 0)
                pe = phe
                sin_end = se
            q1, w1, z1, F0 = _step_map(q, w, z, u, hs, g0, dg0, f0, fp0, lmul, fm, amp, sin_end, G,
                                       iJ, s0p, s0n, s1p, s1n)
            if s == 0 and amp == 0.0:
                Fk = F0   # the step's start friction is the sample's (same level without a position effect)
            if _needs_refine(w, w1, z, z1, s0, hs, ig, per_sign):
                # the linearisation at the step's start does not hold across the |w| kink of dz/dt
                # (z' jumps from ~0 to ~2w when w reverses in sliding), across z = 0 with per-sign
                # stiffness, or along a steep Stribeck curve: redo this step in REFINE pieces (rare:
                # starts, stops and reversals; dithering at rest does not qualify)
                q1, w1, z1 = _refined(q, w, z, u, hs, cp, cn, dp, dn, s_th, dT, lmul, fm, amp, kper, ph, pay,
                                      iJ, s0p, s0n, s1p, s1n, goff, px, py, parm, harm)
            q, w, z = q1, w1, z1
        F_o[k] = Fk
        Tss = Tenv[k * s_te] + Fk * w_k * iK
        T = Tss + (T - Tss) * eK


def command_ref(md, integ, e_q, e_qd, tff, p, h):
    """The controller of :func:`simulate_joint` for one sample, in plain python (the twins' shared law):
    the command and the integrator after it, from the position and velocity errors (reference minus
    measured). Torque mode passes the feedforward; PID and PI act with conditional-integration anti-windup
    at ``tau_max``."""
    if md == MODE_TORQUE:
        u, new = tff, 0.0
    elif md == MODE_PID:
        new = integ + p[P_KI] * e_q * h
        u = tff + p[P_KP] * e_q + p[P_KD] * e_qd + new
    else:
        new = integ + p[P_KVI] * e_qd * h
        u = tff + p[P_KV] * e_qd + new
    if abs(u) > p[P_TMAX]:
        return float(np.clip(u, -p[P_TMAX], p[P_TMAX])), integ
    return u, new


def simulate_joint_ref(h, nsub, mode, q_ref, qd_ref, tau_ff, Tenv, payload, reset_T, gmul, fmul,
                       nq, nqd, p, c_pos, c_neg, dc_pos, dc_neg, th_code, theta, state0):
    """Plain-python twin of :func:`simulate_joint` (numpy map functions, scipy expm step). Slow."""
    from ..models.thermal import canonical_at

    n = len(q_ref)
    mode, Tenv, payload, reset_T, gmul, fmul, nq, nqd = (np.broadcast_to(x, (n,)) for x in (
        mode, Tenv, payload, reset_T, gmul, fmul, nq, nqd))  # one value long: the same for every sample
    out = {k: np.empty(n) for k in ("q", "w", "z", "F", "T", "u", "qm", "qdm")}
    q, w, z, T = (float(x) for x in state0)
    integ, prev = 0.0, -1
    cp, cn, T_used = c_pos, c_neg, None
    for k in range(n):
        if reset_T[k]:
            T = Tenv[k]
        if th_code and (T_used is None or abs(T - T_used) > 1e-4):  # same refresh rule as the kernel
            cp = canonical_at(c_pos, T, th_code, theta, dc_pos)
            cn = canonical_at(c_neg, T, th_code, theta, dc_neg)
            T_used = T
        qm = q + nq[k]
        if p[P_QRES] > 0:
            qm = np.floor(qm / p[P_QRES] + 0.5) * p[P_QRES]
        qdm = w + nqd[k]
        if mode[k] != prev:
            integ, prev = 0.0, mode[k]
        u, integ = command_ref(mode[k], integ, q_ref[k] - qm, qd_ref[k] - qdm, tau_ff[k], p, h)
        for key, val in (("q", q), ("w", w), ("z", z), ("T", T), ("u", u), ("qm", qm), ("qdm", qdm)):
            out[key][k] = val
        hs = h / nsub
        gm0 = gmul[k] * (1 + p[P_LOAD] * abs(u))
        c = cp if w >= 0 else cn
        g_now = gm0 * float(canonical_level(w, c))
        if p[P_PAMP]:
            g_now *= 1 + p[P_PAMP] * np.sin(2 * np.pi / p[P_PPER] * q + p[P_PPH])
        s0, s1 = (p[P_S0P], p[P_S1P]) if z >= 0 else (p[P_S0N], p[P_S1N])
        out["F"][k] = s0 * z + s1 * (w - s0 * abs(w) / g_now * z) + fmul[k] * float(canonical_viscous(w, c))

        def step(q, w, z, hs, k=k, gm0=gm0, cp=cp, cn=cn, u=u):
            c = cp if w >= 0 else cn
            gm = gm0
            if p[P_PAMP]:
                gm = gm0 * (1 + p[P_PAMP] * np.sin(2 * np.pi / p[P_PPER] * (q + hs * w) + p[P_PPH]))
            g = gm * float(canonical_level(w, c))
            dv = 1e-6 * max(1e-3, abs(w))
            lo = max(abs(w) - dv, 0.0)
            dg = gm * float((canonical_level(abs(w) + dv, c) - canonical_level(lo, c)) / (abs(w) + dv - lo))
            f = fmul[k] * float(canonical_viscous(w, c))
            dw = 1e-7 * max(1.0, abs(w))
            fp = fmul[k] * float((canonical_viscous(w + dw, c) - canonical_viscous(w - dw, c)) / (2 * dw))
            s0, s1 = (p[P_S0P], p[P_S1P]) if z >= 0 else (p[P_S0N], p[P_S1N])
            qmid = q + 0.5 * hs * w
            G = (p[P_GOFF] + p[P_PX] * np.cos(qmid) + p[P_PY] * np.sin(qmid)
                 + payload[k] * p[P_PAY] * np.cos(qmid))
            if p[P_HAMP]:
                G += p[P_HAMP] * np.sin(2 * np.pi / p[P_HPER] * qmid + p[P_HPH])
            return lugre_step_ref(q, w, z, u - G, hs, p[P_J], s0, s1, g, dg, f, fp)

        for _s in range(nsub):
            q1, w1, z1 = step(q, w, z, hs)
            if _needs_refine.py_func(w, w1, z, z1, s0, hs, 1.0 / g_now, p[P_S0P] != p[P_S0N]):
                q1, w1, z1 = q, w, z
                for _ in range(REFINE):
                    q2, w2, z2 = step(q1, w1, z1, hs / REFINE)
                    if w2 * w1 < 0:
                        q2, w2, z2 = q1, w1, z1
                        for _ in range(REFINE):
                            q2, w2, z2 = step(q2, w2, z2, hs / REFINE**2)
                    q1, w1, z1 = q2, w2, z2
            q, w, z = q1, w1, z1
        P = out["F"][k] * out["w"][k]
        Tss = Tenv[k] + P / p[P_K]
        T = Tss + (T - Tss) * np.exp(-p[P_K] * h / p[P_C])
    return tuple(out[k] for k in ("q", "w", "z", "F", "T", "u", "qm", "qdm"))
