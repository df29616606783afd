"""Synthetic joint logs with known parameters and known segments, for the fit tests.

Kinematics are prescribed and the torque follows from inverse dynamics with a static friction map (a
fast stand-in for the plant); ramps are simulated with the LuGre step of :mod:`frictid.identify.presliding`.
"""
from __future__ import annotations

import numpy as np

from frictid.data import JointLog, Segment
from frictid.models import static as sm

TRUE = dict(J=0.8, Px=6.0, Py=-2.0, offset=0.3,
            stribeck=dict(Fc=2.0, Fs=3.0, vs=0.08, delta=2.0, sigma2=1.2))


def smooth_step(x):
    x = np.clip(x, 0, 1)
    return x * x * x * (10 - 15 * x + 6 * x * x)


def synth_log(speeds=None, dt=2e-3, hold=1.5, move=0.6, noise=0.02, seed=0, true=TRUE, excitation=True,
              ramps=0, joint="1", pos_amp=0.0, pos_period=0.5) -> JointLog:
    """Plateaus at ``speeds`` (rad/s) joined by smooth transitions, an excitation part, and optional ramps.

    pos_amp, pos_period [rad] : the Coulomb/Stribeck level times ``1 + pos_amp sin(2 pi q / pos_period)``
    (a position-periodic friction, 004's linear slides)."""
    rng = np.random.default_rng(seed)
    if speeds is None:
        v = np.geomspace(0.01, 2.0, 10)
        speeds = np.concatenate([v, -v])
    ts, ws, kinds = [], [], []
    t = 0.0
    w_prev = 0.0
    for v in speeds:
        n_m = int(move / dt)
        x = np.arange(n_m) / n_m
        ws.append(w_prev + (v - w_prev) * smooth_step(x))
        kinds += ["other"] * n_m
        n_h = int(hold / dt)
        ws.append(np.full(n_h, v))
        kinds += ["constant_velocity"] * n_h
        w_prev = v
    n_m = int(move / dt)
    ws.append(w_prev * (1 - smooth_step(np.arange(n_m) / n_m)))
    kinds += ["other"] * n_m
    if excitation:
        tt = np.arange(int(20.0 / dt)) * dt
        we = 1.2 * np.sin(2 * np.pi * 0.3 * tt) * np.sin(np.pi * tt / 20.0) + 0.6 * np.sin(2 * np.pi * 0.9 * tt) \
            * np.sin(np.pi * tt / 20.0) ** 2
        ws.append(we)
        kinds += ["other"] * tt.size
    w = np.concatenate(ws)
    n = w.size
    t = np.arange(n) * dt
    q = np.cumsum(w) * dt - 1.0
    a = np.gradient(w, dt)
    F = sm.stribeck(w, **true["stribeck"])
    if pos_amp:
        visc = true["stribeck"]["sigma2"] * w
        F = (F - visc) * (1.0 + pos_amp * np.sin(2 * np.pi * q / pos_period)) + visc
    tau = true["J"] * a + F + true["Px"] * np.cos(q) + true["Py"] * np.sin(q) + true["offset"]
    tau = tau + rng.normal(0, noise, n)
    qn = q + rng.normal(0, 1e-6, n)
    lab = np.array(kinds)
    log = JointLog(joint=joint, t=t, tau=tau, q=qn, qd=None, channels={"temp_env": np.full(n, 21.0)})
    log.truth = {"segment": lab, "params": true, "w": w, "a": a}
    return log


def truth_segments(log: JointLog) -> list[Segment]:
    """Segments from the truth labels (tests only)."""
    lab = log.truth["segment"]
    out = []
    i = 0
    n = lab.size
    cyc_all = np.asarray(log.truth.get("cycle", np.full(n, -1)))
    run_all = np.asarray(log.truth.get("run", np.zeros(n, int)))
    while i < n:
        j = i
        while j < n and lab[j] == lab[i] and cyc_all[j] == cyc_all[i] and run_all[j] == run_all[i]:
            j += 1
        c = int(cyc_all[i])
        cyc = c if c >= 0 else None
        out.append(Segment(str(lab[i]), i, j, float(log.t[i]), float(log.t[j - 1]), cycle=cyc))
        i = j
    return out


def truth_derivatives(log: JointLog):
    """Exact velocity and acceleration (tests only)."""
    return log.truth["w"], log.truth["a"]


def duty_log(n_cycles=20, cycle=20.0, dt=0.01, tau_c=60.0, drop=0.08, noise=0.02, seed=1, true=TRUE,
             joint="1") -> JointLog:
    """Duty cycles (back-and-forth sine moves for 3/4 of each cycle, then still) whose friction falls as the
    joint warms: ``F (1 - drop x)``, x [K] the heat balance of the friction power with time constant tau_c
    (K = 1 W/K), starting cold. Labels: ``duty_cycle`` with the cycle index."""
    from frictid.models.thermal import heat_balance

    rng = np.random.default_rng(seed)
    t = np.arange(int(n_cycles * cycle / dt)) * dt
    tc = t % cycle
    env = np.where(tc < 0.75 * cycle, np.sin(np.pi * tc / (0.75 * cycle)) ** 2, 0.0)
    w = 1.5 * env * np.sin(2 * np.pi * tc / 2.5)
    a = np.gradient(w, dt)
    q = np.cumsum(w) * dt - 1.0
    F0 = sm.stribeck(w, **true["stribeck"])
    x = heat_balance(F0 * w, t, 0.0, tau_c, 1.0)
    F = F0 * (1 - drop * x)
    tau = true["J"] * a + F + true["Px"] * np.cos(q) + true["Py"] * np.sin(q) + true["offset"]
    tau = tau + rng.normal(0, noise, t.size)
    log = JointLog(joint=joint, t=t, tau=tau, q=q + rng.normal(0, 1e-6, t.size), qd=None,
                   channels={"temp_env": np.full(t.size, 21.0)})
    log.truth = {"segment": np.full(t.size, "duty_cycle"), "cycle": (t // cycle).astype(int), "params": true,
                 "w": w, "a": a}
    return log
