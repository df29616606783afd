"""Hand-made joint logs with known segments, for the segmentation tests (independent of the plant).

Kinematic, not a simulation: positions and torques are written down piece by piece (smooth velocity
transitions, steady-state friction on plateaus, an elastic presliding spring under torque ramps, a damped
second-order transient after torque steps, trapezoidal point-to-point moves), then sensor noise and an
encoder quantum are added. Labels follow the plant's convention (one kind per sample, ``cycle`` for duty
cycles, -1 elsewhere).
"""
from __future__ import annotations

import math

import numpy as np

from frictid.data import JointLog


class Session:
    """Build a log piece by piece. Units: rad, rad/s, N m (or m, m/s, N with ``axis="linear"``)."""

    def __init__(self, fs=1000.0, J=1.0, Fc=10.0, Fs=14.0, vs=0.1, sigma2=2.0, sigma0=2e4, zeta=0.3,
                 seed=0, axis="rotary"):
        self.fs, self.dt = float(fs), 1.0 / fs
        self.J, self.Fc, self.Fs, self.vs, self.sigma2, self.sigma0, self.zeta = J, Fc, Fs, vs, sigma2, sigma0, zeta
        self.rng = np.random.default_rng(seed)
        self.axis = axis
        self.q, self.tau, self.lab, self.cyc = [], [], [], []
        self.q_end, self.tau_end = 0.0, 0.0

    # -- helpers
    def _n(self, T):
        return max(1, int(round(T * self.fs)))

    def _add(self, q, tau, label, cycle=-1):
        q = np.asarray(q, float)
        tau = np.broadcast_to(np.asarray(tau, float), q.shape).copy()
        self.q.append(q)
        self.tau.append(tau)
        self.lab.append(np.full(q.size, label, dtype=object))
        self.cyc.append(np.full(q.size, cycle, dtype=np.int64))
        self.q_end, self.tau_end = float(q[-1]), float(tau[-1])
        return self

    def friction(self, w):
        w = np.asarray(w, float)
        g = self.Fc + (self.Fs - self.Fc) * np.exp(-(w / self.vs) ** 2)
        return g * np.sign(w) + self.sigma2 * w

    # -- pieces
    def rest(self, T, tau=None, label="rest", cycle=-1):
        n = self._n(T)
        return self._add(np.full(n, self.q_end), self.tau_end if tau is None else tau, label, cycle)

    def _velocity_profile(self, w, label, cycle, J=None):
        """Integrate a velocity profile from q_end; torque = J a + F(w)."""
        J = self.J if J is None else J
        a = np.gradient(w, self.dt)
        q = self.q_end + np.cumsum(w) * self.dt
        return self._add(q, J * a + self.friction(w), label, cycle)

    def transition(self, w0, w1, T, label="other", cycle=-1):
        n = self._n(T)
        s = (1 - np.cos(np.pi * (np.arange(1, n + 1) / n))) / 2
        return self._velocity_profile(w0 + (w1 - w0) * s, label, cycle)

    def plateau(self, w, T, ripple=0.002, label="constant_velocity", cycle=-1):
        n = self._n(T)
        t = np.arange(n) * self.dt
        ww = w * (1 + ripple * np.sin(2 * np.pi * 1.3 * t))
        return self._velocity_profile(ww, label, cycle)

    def cv_sweep(self, velocities, T=3.0, accel=5.0, gap=0.3):
        for v in velocities:
            for s in (1, -1):
                w = s * v
                Ta = max(abs(w) / accel * 1.57, 0.05)
                self.transition(0.0, w, Ta)
                self.plateau(w, T)
                self.transition(w, 0.0, Ta)
                self.rest(gap, tau=0.0)
        return self

    def ramp(self, tau1, T, label="ramp_presliding"):
        n = self._n(T)
        tau0 = self.tau_end
        tau = tau0 + (tau1 - tau0) * np.arange(1, n + 1) / n
        q = self.q_end + (tau - tau0) / self.sigma0
        return self._add(q, tau, label)

    def presliding(self, peaks=(0.6,), up=4.0, hold=1.0, down=4.0, settle=1.0):
        for p in peaks:
            for s in (1, -1):
                self.rest(settle, tau=0.0)
                self.ramp(s * p * self.Fs, up)
                self.rest(hold, label="rest")
                self.ramp(0.0, down)
        return self

    def step(self, tau1, T, label="step"):
        n = self._n(T)
        t = np.arange(1, n + 1) * self.dt
        dtau = tau1 - self.tau_end
        wn = math.sqrt(self.sigma0 / self.J)
        z = self.zeta
        wd = wn * math.sqrt(1 - z * z)
        resp = 1 - np.exp(-z * wn * t) * (np.cos(wd * t) + z / math.sqrt(1 - z * z) * np.sin(wd * t))
        q = self.q_end + dtau / self.sigma0 * resp
        return self._add(q, np.full(n, tau1), label)

    def steps(self, levels=(0.3, 0.6), hold=0.5, release=0.3, settle=0.5):
        for lv in levels:
            for s in (1, -1):
                self.rest(settle, tau=0.0)
                self.step(s * lv * self.Fs, hold)
                self.step(0.0, release)
        return self

    def p2p(self, dq, vmax, amax, label="other", cycle=-1):
        """Trapezoidal point-to-point move of dq."""
        d = abs(dq)
        if d <= 0:
            return self
        ta = vmax / amax
        if amax * ta * ta > d:  # triangular
            ta = math.sqrt(d / amax)
            vmax = amax * ta
        tc = (d - amax * ta * ta) / vmax
        T = 2 * ta + tc
        n = self._n(T)
        t = np.arange(1, n + 1) * self.dt
        w = np.where(t < ta, amax * t, np.where(t < ta + tc, vmax, np.maximum(vmax - amax * (t - ta - tc), 0)))
        w = math.copysign(1.0, dq) * w
        return self._velocity_profile(w, label, cycle)

    def duty(self, cycles=4, cycle_time=20.0, slots=4, duty=0.5, speeds=(0.3, 0.6, 1.0), vmax=2.0, amax=10.0,
             span=(-0.8, 1.2)):
        slot_T = cycle_time / slots
        moving = int(round(duty * slots))
        for c in range(cycles):
            n0 = sum(x.size for x in self.q)
            for k in range(slots):
                start = sum(x.size for x in self.q)
                if k < moving:
                    i = 0
                    while True:
                        target = span[1] if self.q_end < 0.5 * (span[0] + span[1]) else span[0]
                        v = speeds[i % len(speeds)] * vmax
                        self.p2p(target - self.q_end, v, amax, label="duty_cycle", cycle=c)
                        i += 1
                        used = (sum(x.size for x in self.q) - start) * self.dt
                        if used > slot_T - 2.0:
                            break
                    left = slot_T - (sum(x.size for x in self.q) - start) * self.dt
                    if left > 0:
                        self.rest(left, tau=0.0, label="duty_cycle", cycle=c)
                else:
                    self.rest(slot_T, tau=0.0, label="duty_cycle", cycle=c)
            del n0
        return self

    def random_p2p(self, moves=20, vmax=2.0, amax=10.0, span=(-1.5, 1.5), dwell=(0.1, 2.0)):
        for _ in range(moves):
            target = self.rng.uniform(*span)
            v = self.rng.uniform(0.05, 1.0) * vmax
            self.p2p(target - self.q_end, v, amax * self.rng.uniform(0.3, 1.0))
            self.rest(self.rng.uniform(*dwell), tau=0.0, label="other")
        return self

    # -- output
    def build(self, q_noise=0.0, q_step=2 * np.pi / 2**20, tau_noise=0.02, qd_logged=False, qd_noise=0.002,
              joint="j1") -> JointLog:
        q = np.concatenate(self.q)
        tau = np.concatenate(self.tau)
        n = q.size
        t = np.arange(n) * self.dt
        qd_true = np.gradient(q, self.dt)
        qm = q + self.rng.normal(0, q_noise, n) if q_noise else q.copy()
        if q_step:
            qm = np.round(qm / q_step) * q_step
        taum = tau + self.rng.normal(0, tau_noise, n) if tau_noise else tau
        qd = qd_true + self.rng.normal(0, qd_noise, n) if qd_logged else None
        return JointLog(joint=joint, t=t, tau=taum, q=qm, qd=qd, axis=self.axis, source="segsynth",
                        truth={"segment": np.concatenate(self.lab).astype(str), "cycle": np.concatenate(self.cyc)})


def session_log(fs=1000.0, qd_logged=False, seed=0, **noise) -> JointLog:
    """A long session: CV sweep, presliding ramps, torque steps, two duty-cycle blocks, rests between."""
    s = Session(fs=fs, seed=seed)
    s.rest(1.0)
    s.cv_sweep([0.02, 0.1, 0.5, 1.5], T=2.0)
    s.rest(2.0)
    s.presliding(peaks=(0.6,))
    s.rest(1.0)
    s.steps()
    s.rest(2.0)
    s.p2p(-0.8 - s.q_end, 1.0, 5.0)
    s.rest(2.0)
    s.duty(cycles=4, cycle_time=24.0, duty=0.5)
    s.rest(2.0)
    return s.build(qd_logged=qd_logged, **noise)
