"""Recipe compilation: experiments -> per-sample reference profiles, control mode and truth labels.

Each experiment of a recipe appends pieces to a :class:`Program` for one joint. A piece has a control
mode (open-loop torque, position PID, velocity PI), references ``q_ref``, ``qd_ref``, a feedforward or
open-loop torque ``tau_ff`` (closed loop: ``J a_ref + G(q_ref)``; open loop: ``G(q_hold)`` plus the
experiment's torque), and a provisional label. Velocity plateaus and closed-loop rests are refined
after the simulation from the true velocity (see :func:`refine_labels`), so that the labels say where
the joint really was at constant velocity or at rest, not where the reference was.

Velocities are fractions of ``limits.velocity``, accelerations of ``limits.acceleration``, torques of
the joint's break-away level (the lowest level ``g`` over the velocity range, the largest torque that
cannot make the joint slide) unless an experiment sets ``relative: false``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..data import SEGMENT_KINDS
from ..models.static import canonical_level, canonical_pair
from .config import Joint, Plant, friction_params
from .effects import compile_effects
from .kernel import MODE_PID, MODE_TORQUE, MODE_VEL

L = {k: i for i, k in enumerate(SEGMENT_KINDS)}
G0 = 9.81


@dataclass
class Program:
    """Per-sample inputs of one joint's run, built piece by piece."""

    plant: Plant
    joint: Joint
    scale: float = 1.0
    q: float = 0.0                       # reference position at the end of the program [q]
    temp_env: float = 25.0
    payload: float = 0.0
    run: int = 0
    cycle: int = -1
    pieces: list = field(default_factory=list)
    plateaus: list = field(default_factory=list)   # (i0, i1, v_ref)
    rests: list = field(default_factory=list)      # (i0, i1) closed-loop rests to refine
    index: dict = field(default_factory=lambda: {"ramp": 0, "step": 0})  # next ramp / step index
    n: int = 0
    _reset_next: bool = False

    @property
    def fs(self) -> float:
        return float(self.plant.sensors.sample_rate)

    @property
    def h(self) -> float:
        return 1.0 / self.fs

    def ns(self, duration: float, scaled: bool = True) -> int:
        """Samples in a duration [s] (times the duration scale when ``scaled``), at least 1."""
        d = duration * (self.scale if scaled else 1.0)
        return max(1, int(round(d * self.fs)))

    def G(self, q):
        """Gravity torque [F] at reference positions q (the controller's model feedforward)."""
        g = self.joint.gravity
        out = g.offset + 0.0 * np.asarray(q, dtype=float)
        if g.Px or g.Py:
            out = out + g.Px * np.cos(q) + g.Py * np.sin(q)
        if self.payload and g.payload_arm:
            out = out + self.payload * G0 * g.payload_arm * np.cos(q)
        return out

    # -- raw append -----------------------------------------------------------------------------
    def add(self, mode, q_ref, qd_ref, tau_ff, label, cycle=None):
        n = len(q_ref)
        reset = self._reset_next
        self._reset_next = False
        # constant fields are kept as scalars and expanded once in finish()
        self.pieces.append((n, int(mode), np.asarray(q_ref, float), np.asarray(qd_ref, float),
                            np.asarray(tau_ff, float), L[label], self.cycle if cycle is None else cycle,
                            self.temp_env, self.payload, self.run, reset))
        i0 = self.n
        self.n += n
        return i0, self.n

    # -- pieces -------------------------------------------------------------------------------------
    def hold(self, n, label="rest", refine=True):
        """Closed-loop (PID) rest at the current reference position for n samples."""
        i0, i1 = self.add(MODE_PID, np.full(n, self.q), np.zeros(n), np.full(n, self.G(self.q)), label)
        if refine and label == "rest":
            self.rests.append((i0, i1))
        return i0, i1

    def next_index(self, kind: str) -> int:
        """The next index of a repeated labelled piece (``ramp``, ``step``), written to ``cycle``."""
        k = self.index[kind]
        self.index[kind] = k + 1
        return k

    def open_loop(self, tau, label, cycle=None):
        """Open-loop torque ``G(q_hold) + tau`` (array) at the current reference position."""
        n = len(tau)
        return self.add(MODE_TORQUE, np.full(n, self.q), np.zeros(n), self.G(self.q) + np.asarray(tau), label,
                        cycle)

    def velocity_piece(self, v0, v1, n, label, mode=MODE_PID):
        """Velocity ramp v0 -> v1 [q/s] over n samples (constant if equal); position integrates exactly."""
        h = self.h
        D = n * h
        a = (v1 - v0) / D
        t = np.arange(n) * h
        qd = v0 + a * t
        q = self.q + v0 * t + 0.5 * a * t * t
        tau = self.joint.J * a + self.G(q)
        idx = self.add(mode, q, qd, tau, label)
        self.q = self.q + v0 * D + 0.5 * a * D * D
        return idx

    def ptp(self, q_target, vmax, amax, label="other", mode=MODE_PID):
        """Trapezoidal point-to-point move to q_target with peak speed vmax [q/s], acceleration amax."""
        d = q_target - self.q
        if abs(d) < 1e-15:
            return
        sgn = np.sign(d)
        d = abs(d)
        h = self.h
        vp = min(vmax, np.sqrt(d * amax))
        na = max(1, int(round(vp / amax / h)))
        nc = max(0, int(round((d - vp * vp / amax) / vp / h)))
        vp = d / (h * (na + nc))
        self.velocity_piece(0.0, sgn * vp, na, label, mode)
        if nc:
            self.velocity_piece(sgn * vp, sgn * vp, nc, label, mode)
        self.velocity_piece(sgn * vp, 0.0, na, label, mode)
        self.q = float(q_target)

    def finish(self) -> dict:
        """Per-sample arrays of the whole program."""
        cols = list(zip(*self.pieces))
        ns = np.array(cols[0], dtype=np.int64)
        out = {
            "mode": np.repeat(np.array(cols[1], dtype=np.int64), ns),
            "q_ref": np.concatenate(cols[2]),
            "qd_ref": np.concatenate(cols[3]),
            "tau_ff": np.concatenate(cols[4]),
            "label": np.repeat(np.array(cols[5], dtype=np.int8), ns),
            "cycle": np.repeat(np.array(cols[6], dtype=np.int64), ns),
            "temp_env": np.repeat(np.array(cols[7], dtype=float), ns),
            "payload": np.repeat(np.array(cols[8], dtype=float), ns),
            "run": np.repeat(np.array(cols[9], dtype=np.int64), ns),
        }
        reset = np.zeros(self.n, dtype=np.bool_)
        starts = np.concatenate([[0], np.cumsum(ns)[:-1]])
        reset[starts[np.array(cols[10], dtype=bool)]] = True
        out["reset"] = reset
        return out


def ptp_time(d, vmax, amax) -> float:
    """Duration [s] of a trapezoidal move over distance d."""
    d = abs(d)
    vp = min(vmax, np.sqrt(d * amax))
    return vp / amax * 2 + max(0.0, (d - vp * vp / amax) / vp) if d > 0 else 0.0


# ---------------------------------------------------------------------------------------------------
# Plant-derived scales


def travel(joint: Joint, axis: str) -> tuple[float, float]:
    """Usable travel [q]: declared position limits shrunk by 5 % each side, else unbounded."""
    lim = joint.limits.position
    if lim is None:
        return -np.inf, np.inf
    span = lim[1] - lim[0]
    return lim[0] + 0.05 * span, lim[1] - 0.05 * span


def breakaway(joint: Joint) -> tuple[float, float]:
    """Largest torque [F] per sign (w > 0, w < 0) that cannot make the joint slide (lowest level g)."""
    c_pos, c_neg = canonical_pair(joint.friction.map, friction_params(joint.friction))
    ce = compile_effects(joint.effects)
    v = np.concatenate([[0.0], np.geomspace(1e-6, 1.0, 200)]) * joint.limits.velocity
    low = (1.0 - ce.pos_amp)
    return (float(canonical_level(v, c_pos).min()) * low,
            float(canonical_level(v, c_neg).min()) * low * ce.neg_factor)


def _signs(s: str) -> list[float]:
    return {"both": [1.0, -1.0], "positive": [1.0], "negative": [-1.0]}[s]


def _levels(spec) -> np.ndarray:
    if isinstance(spec, list):
        return np.asarray(spec, dtype=float)
    if spec.count == 1:
        return np.array([spec.min])
    if spec.spacing == "log":
        return np.geomspace(spec.min, spec.max, spec.count)
    return np.linspace(spec.min, spec.max, spec.count)


# ---------------------------------------------------------------------------------------------------
# Experiments


def _constant_velocity(pr: Program, ex, axis: str):
    j = pr.joint
    vmax, amax = j.limits.velocity, j.limits.acceleration
    levels = _levels(ex.velocities) * (vmax if ex.relative else 1.0)
    acc = ex.accel * amax
    lo, hi = travel(j, axis)
    bounded = np.isfinite(lo)
    mode = MODE_VEL if ex.control == "velocity_pi" else MODE_PID
    signs = _signs(ex.signs)
    for v in levels:
        v = float(v)
        if bounded:
            room = (hi - lo) - v * v / acc
            tp = min(ex.plateau * pr.scale, room / v)
            tp = max(tp, ex.min_plateau * pr.scale)
        else:
            tp = ex.plateau * pr.scale
        na = max(1, int(round(v / acc * pr.fs)))
        npl = max(1, int(round(tp * pr.fs)))
        for k, s in enumerate(signs):
            start = lo if s > 0 else hi
            if bounded and (k == 0 or len(signs) == 1):
                if abs(pr.q - start) > 1e-12:
                    pr.ptp(start, 0.5 * vmax, 0.5 * amax)
                    pr.hold(pr.ns(ex.gap))
            pr.velocity_piece(0.0, s * v, na, "other", mode)
            i0, i1 = pr.velocity_piece(s * v, s * v, npl, "other", mode)
            pr.plateaus.append((i0, i1, s * v))
            pr.velocity_piece(s * v, 0.0, na, "other", mode)
            pr.hold(pr.ns(ex.gap))


def _ramp_presliding(pr: Program, ex):
    """Settle, ramp up, hold, ramp down per peak and sign. Each monotonic ramp is one labelled
    ``ramp_presliding`` piece with its own index in ``cycle`` (up and down are two ramps: with
    ``hold: 0`` they touch); the hold at the peak and the settles are ``rest`` (still joint, flat torque)."""
    fb = breakaway(pr.joint)
    for s in _signs(ex.signs):
        ref = fb[0] if s > 0 else fb[1]
        for peak in ex.peaks:
            P = s * peak * (ref if ex.relative else 1.0)
            pr.open_loop(np.zeros(pr.ns(ex.settle)), "rest")
            nu, nh, nd = pr.ns(ex.ramp_up), pr.ns(ex.hold), pr.ns(ex.ramp_down)
            pr.open_loop(P * np.arange(1, nu + 1) / nu, "ramp_presliding", cycle=pr.next_index("ramp"))
            if ex.hold > 0:
                pr.open_loop(np.full(nh, P), "rest")
            pr.open_loop(P * (1.0 - np.arange(1, nd + 1) / nd), "ramp_presliding", cycle=pr.next_index("ramp"))
        pr.open_loop(np.zeros(pr.ns(ex.settle)), "rest")


def _torque_steps(pr: Program, ex):
    """Open-loop steps to each level and back to zero. Every jump of the torque is one ``step``, with
    its own index in ``cycle``, lasting until the next input: the next jump, or the end of the open-loop
    experiment (the controller taking the joint back). Only the settle before the first step is ``rest``;
    the release and the settles after it are the step back's transient and its still tail."""
    fb = breakaway(pr.joint)
    first = True
    for s in _signs(ex.signs):
        ref = fb[0] if s > 0 else fb[1]
        for lvl in ex.levels:
            P = s * lvl * (ref if ex.relative else 1.0)
            if first:
                pr.open_loop(np.zeros(pr.ns(ex.settle)), "rest")
                first = False
            else:  # still the previous step back, until this step's jump
                pr.open_loop(np.zeros(pr.ns(ex.settle)), "step", cycle=pr.index["step"] - 1)
            pr.open_loop(np.full(pr.ns(ex.hold), P), "step", cycle=pr.next_index("step"))
            pr.open_loop(np.zeros(pr.ns(ex.release)), "step", cycle=pr.next_index("step"))
        pr.open_loop(np.zeros(pr.ns(ex.settle)), "step", cycle=pr.index["step"] - 1)


def _ptp_endpoints(pr: Program, ex, axis: str) -> tuple[float, float]:
    j = pr.joint
    lo, hi = travel(j, axis)
    a, b = ex.positions_deg
    if axis == "rotary" and not ex.relative_positions:
        qa, qb = np.deg2rad(a), np.deg2rad(b)
        if not (np.isfinite(lo) and (qa < lo or qb > hi)):
            return float(qa), float(qb)
    # linear axes and ranges that cannot hold the degrees: 15 % .. 85 % of the travel
    if not np.isfinite(lo):
        span = 2.0 * j.limits.velocity  # two seconds at full speed
        lo, hi = -0.5 * span, 0.5 * span
    return lo + 0.15 * (hi - lo), lo + 0.85 * (hi - lo)


def _ptp_program(pr: Program, ex, qa, qb, slot_samples: int, label: str):
    """Moves qa -> qb -> qa at each speed, repeated while they fit in the slot, then hold at qa."""
    j = pr.joint
    vmax, amax = j.limits.velocity, ex.accel * j.limits.acceleration
    speeds = [s * vmax for s in ex.speeds]
    budget = 0.97 * slot_samples / pr.fs

    def prog_time(d):
        return sum(2 * ptp_time(d, v, amax) for v in speeds)

    d = abs(qb - qa)
    if prog_time(d) > budget:
        lo_, hi_ = 0.0, 1.0
        for _ in range(40):
            mid = 0.5 * (lo_ + hi_)
            lo_, hi_ = (mid, hi_) if prog_time(d * mid) <= budget else (lo_, mid)
        qb = qa + (qb - qa) * lo_
    start = pr.n
    T = prog_time(abs(qb - qa))
    reps = max(1, int(budget // T)) if T > 0 else 0
    for _ in range(reps):
        for v in speeds:
            pr.ptp(qb, v, amax, label)
            pr.ptp(qa, v, amax, label)
    used = pr.n - start
    if slot_samples - used > 0:
        pr.hold(slot_samples - used, label, refine=False)


def _duty_cycle(pr: Program, ex, axis: str, cycle_counter: list):
    qa, qb = _ptp_endpoints(pr, ex, axis)
    j = pr.joint
    if abs(pr.q - qa) > 1e-12:
        pr.ptp(qa, 0.5 * j.limits.velocity, 0.5 * j.limits.acceleration)
        pr.hold(pr.ns(1.0))
    if ex.cold_start:
        pr._reset_next = True
    cyc_n = pr.ns(ex.cycle_time)
    slot_n = cyc_n // ex.slots
    moving = max(1, int(round(ex.duty * ex.slots)))
    for _ in range(ex.cycles):
        pr.cycle = cycle_counter[0]
        cycle_counter[0] += 1
        start = pr.n
        for s in range(ex.slots):
            n_s = slot_n if s < ex.slots - 1 else cyc_n - slot_n * (ex.slots - 1)
            if s < moving:
                _ptp_program(pr, ex, qa, qb, n_s, "duty_cycle")
            else:
                pr.hold(n_s, "duty_cycle", refine=False)
        assert pr.n - start == cyc_n
    pr.cycle = -1


def _multisine(pr: Program, ex, axis: str):
    j = pr.joint
    n = pr.ns(ex.duration)
    t = np.arange(n) / pr.fs
    N = ex.harmonics
    f0 = max(ex.f0, 1.0 / (n / pr.fs))  # at least one base period in a shortened run
    kk = np.arange(1, N + 1)
    phi = -np.pi * kk * (kk - 1) / N  # Schroeder phases: low crest factor
    shape = np.sin(2 * np.pi * f0 * np.outer(t, kk) + phi).sum(axis=1)
    # smooth fade-in/out over one base period (or 20 % of the run)
    tf = min(1.0 / f0, 0.2 * t[-1] if n > 1 else 1.0)
    env = np.ones(n)
    if tf > 0:
        a = np.clip(t / tf, 0, 1)
        b = np.clip((t[-1] - t) / tf, 0, 1)
        env = np.sin(0.5 * np.pi * a) ** 2 * np.sin(0.5 * np.pi * b) ** 2
    x = env * shape
    xd = np.gradient(x, t) if n > 2 else np.zeros(n)
    xdd = np.gradient(xd, t) if n > 2 else np.zeros(n)
    lo, hi = travel(j, axis)
    centre = pr.q if not np.isfinite(lo) else 0.5 * (lo + hi)
    amp_pos = ex.amplitude if ex.amplitude is not None else (0.45 * (hi - lo) if np.isfinite(lo) else np.inf)
    k = min(ex.velocity * j.limits.velocity / max(np.abs(xd).max(), 1e-12),
            j.limits.acceleration / max(np.abs(xdd).max(), 1e-12),
            amp_pos / max(np.abs(x).max(), 1e-12))
    if abs(pr.q - centre) > 1e-12:
        pr.ptp(centre, 0.5 * j.limits.velocity, 0.5 * j.limits.acceleration)
        pr.hold(pr.ns(0.5))
    q = centre + k * x
    tau = j.J * k * xdd + pr.G(q)
    pr.add(MODE_PID, q, k * xd, tau, "other")
    pr.q = float(q[-1])


def _random_ptp(pr: Program, ex, axis: str):
    """Closed-loop moves to random targets over the travel (two seconds at full speed each side of the
    start on an unbounded axis), each followed by a dwell; moves ``other``, dwells ``rest``."""
    j = pr.joint
    rng = np.random.default_rng(ex.seed)
    lo, hi = travel(j, axis)
    if not np.isfinite(lo):
        lo, hi = pr.q - 2.0 * j.limits.velocity, pr.q + 2.0 * j.limits.velocity
    for _ in range(ex.moves):
        target = float(rng.uniform(lo, hi))
        v = float(rng.uniform(*ex.speed)) * j.limits.velocity
        a = float(rng.uniform(*ex.accel)) * j.limits.acceleration
        pr.ptp(target, v, a)
        pr.hold(pr.ns(float(rng.uniform(*ex.dwell))))


def compile_recipe(recipe, plant: Plant, joint: Joint, scale: float = 1.0) -> Program:
    """The full per-sample program of one joint for a recipe."""
    th = joint.thermal
    base_env = recipe.temp_env if recipe.temp_env is not None else th.Tenv
    lo, hi = travel(joint, plant.axis)
    if not np.isfinite(lo):
        q0 = 0.0
    elif plant.axis == "linear":
        q0 = 0.5 * (lo + hi)
    else:
        q0 = float(np.clip(0.0, lo, hi))
    pr = Program(plant=plant, joint=joint, scale=scale, q=q0, temp_env=base_env, payload=recipe.payload)
    pr.hold(pr.ns(recipe.start_rest))
    cycles = [0]
    for run, ex in enumerate(recipe.experiments):
        pr.run = run
        pr.temp_env = ex.temp_env if ex.temp_env is not None else base_env
        pr.payload = ex.payload if ex.payload is not None else recipe.payload
        if ex.cold_start and ex.kind not in ("duty_cycle", "validation_ptp"):
            pr._reset_next = True
        k = ex.kind
        if k == "constant_velocity":
            _constant_velocity(pr, ex, plant.axis)
        elif k == "ramp_presliding":
            _ramp_presliding(pr, ex)
        elif k == "torque_steps":
            _torque_steps(pr, ex)
        elif k in ("duty_cycle", "validation_ptp"):
            _duty_cycle(pr, ex, plant.axis, cycles)
        elif k == "multisine":
            _multisine(pr, ex, plant.axis)
        elif k == "random_ptp":
            _random_ptp(pr, ex, plant.axis)
        elif k == "rest":
            pr.hold(pr.ns(ex.duration))
        if ex.rest > 0:
            pr.hold(pr.ns(ex.rest))
    return pr


# ---------------------------------------------------------------------------------------------------
# Labels from the simulated motion


def _smooth(x, m):
    if m <= 1:
        return x
    xp = np.pad(x, (m // 2, m - 1 - m // 2), mode="edge")
    c = np.concatenate([[0.0], np.cumsum(xp)])
    return (c[m:] - c[:-m]) / m


#: Time scale [s] over which the true velocity is averaged to judge a plateau (half ``T_MIN``, the time
#: over which frictid averages anything): the controller's jitter on a noisy sensor is not a change of speed.
T_PLATEAU = 0.1
#: Time scale [s] over which the true velocity is averaged to judge a stop.
T_STILL = 0.01
#: A joint is still when that average is below this fraction of ``limits.velocity``.
R_STILL = 5e-3
#: A still joint's torque is steady while the means of its drive torque over the ``T_LOAD`` / 2 before
#: and after a sample differ by at most ``K_LOAD`` standard errors of that difference under the logged
#: torque noise (docs/segments.md, "What the truth labels are": T_MIN and K_NOISE).
K_LOAD = 5.0
T_LOAD = 0.2
#: A still, unloaded stretch within a move or an excitation is a rest when at least this long [s]
#: (docs/segments.md: T_MIN, the shortest segment).
T_REST = 0.2
#: The longest rise of a torque jump [s] (docs/segments.md: T_JUMP): a jump alone does not end a rest.
T_JUMP = 0.01


def refine_labels(label: np.ndarray, w: np.ndarray, pr: Program, u: np.ndarray | None = None,
                  cycle: np.ndarray | None = None, tau_noise: float = 0.0, still: np.ndarray | None = None
                  ) -> np.ndarray:
    """Honest labels from the true velocity ``w``:

    - plateau samples become constant_velocity once the true velocity (``T_PLATEAU`` mean) has settled
      within 2 % (plus 0.1 % of the velocity limit) of the reference for the rest of the plateau;
    - leading samples of a closed-loop rest stay ``other`` until the joint has stopped (``T_STILL`` mean
      below ``R_STILL`` of the limit);
    - with the drive torque ``u`` [F] and the torque sensor's noise ``tau_noise`` [F] (with the drive
      torque's own jitter, the logged torque's noise level), the closed-loop
      rests and moves follow docs/segments.md's definition of a rest: ``rest`` where the joint is still
      and its torque steady (:func:`_steady`: no change beyond ``K_LOAD`` standard errors between
      means over ``T_LOAD``/2) for at least ``T_REST``, ``other`` elsewhere (the still start of a move
      before its torque changes is rest, a wound-up start or a settling torque after a stop is not);
      still there is ``still`` when given (:func:`still_to_sensors`: what the sensors resolve), else
      below ``R_STILL`` of the velocity limit;
    - with the cycle indices ``cycle`` (changed in place): a duty cycle starts where its motion starts
      (the joint breaks away a little after its program starts) and lasts one period."""
    label = label.copy()
    vmax = pr.joint.limits.velocity
    m = max(1, int(round(T_PLATEAU * pr.fs)))
    for i0, i1, v in pr.plateaus:
        seg = _smooth(w[i0:i1], m)
        tol = 0.02 * abs(v) + 1e-3 * vmax
        bad = np.flatnonzero(np.abs(seg - v) > tol)
        start = i0 if bad.size == 0 else i0 + int(bad[-1]) + 1
        if (i1 - start) >= 0.3 * (i1 - i0) and (i1 - start) > 2 * m:
            label[start:i1] = L["constant_velocity"]
    m = max(1, int(round(T_STILL * pr.fs)))
    tol_rest = R_STILL * vmax
    for i0, i1 in pr.rests:
        seg = _smooth(w[i0:i1], m)
        bad = np.flatnonzero(np.abs(seg) > tol_rest)
        if bad.size:
            last = int(bad[-1]) + 1
            if last <= 0.5 * (i1 - i0):
                label[i0:i0 + last] = L["other"]
            else:
                label[i0:i1] = L["other"]
    moving = moving_mask(w, pr.fs, vmax)
    if cycle is not None:
        _cycles_from_onsets(label, cycle, moving)
    if u is None:
        return label
    if still is not None:  # a rest is still to the sensors (docs/segments.md, "What a rest is")
        moving = ~still
    return closed_loop_rests(label, moving, u, closed_loop(pr), pr.fs, tau_noise)


def closed_loop(pr: Program) -> np.ndarray:
    """Per sample: the joint is under a closed loop (not an open-loop torque input)."""
    return np.repeat([p[1] != MODE_TORQUE for p in pr.pieces], [p[0] for p in pr.pieces])


def moving_mask(w: np.ndarray, fs: float, v_limit: float) -> np.ndarray:
    """Per sample: the true velocity ``w`` [q/s] (``T_STILL`` mean) above ``R_STILL`` of the velocity
    limit ``v_limit``: the joint moves (plateau settling and duty-cycle onsets)."""
    return np.abs(_smooth(w, max(1, int(round(T_STILL * fs))))) > R_STILL * v_limit


def white_noise(x: np.ndarray) -> float:
    """White-noise level of ``x``: median |fourth difference| / 0.6745 / sqrt(70), as frictid measures a
    channel's noise (the sensor's noise and the joint's own jitter in a hold)."""
    return float(np.median(np.abs(np.diff(x, 4)))) / 0.6745 / math.sqrt(70.0) if x.size > 8 else 0.0


def hold_scatter(x: np.ndarray, h: int) -> np.ndarray:
    """Per sample: the scatter of ``x`` about a cubic over ``h`` samples (docs/segments.md, "What a rest
    is": a hold's own jitter at the scale of half a window of ``T_REST``), median |fourth difference of
    samples ``h / 4`` apart| / 0.6745 / sqrt(70) per block of ``2 h`` samples, the larger of a block and its
    neighbours (0 where ``h / 4`` rounds to one sample: the white-noise level covers that)."""
    n, lag = x.size, int(round(h / 4))
    if lag <= 1 or n <= 4 * lag + 8:
        return np.zeros(n)
    d = np.empty(n)
    m = n - 4 * lag
    d[2 * lag:2 * lag + m] = np.abs(x[4 * lag:] - 4 * x[3 * lag:n - lag] + 6 * x[2 * lag:n - 2 * lag]
                                    - 4 * x[lag:n - 3 * lag] + x[:m])
    d[:2 * lag], d[2 * lag + m:] = d[2 * lag], d[2 * lag + m - 1]
    block = max(8, 2 * h)
    nb = -(-n // block)
    blocks = np.array([np.median(d[k * block:(k + 1) * block]) for k in range(nb)]) / 0.6745 / math.sqrt(70.0)
    if nb > 1 and n - (nb - 1) * block < 8:  # a tail too short for a median takes the block before
        blocks[-1] = blocks[-2]
    padded = np.concatenate(([blocks[0]], blocks, [blocks[-1]]))
    return np.repeat(np.maximum(np.maximum(padded[:-2], padded[1:-1]), padded[2:]), block)[:n]


def still_to_sensors(q: np.ndarray, fs: float, q_logged: np.ndarray, q_step: float) -> np.ndarray:
    """Per sample: the joint is still to its sensors (docs/segments.md, "What a rest is"): the true
    position ``q`` [q] moves over each half of a window of ``T_REST`` that holds the sample by at most ``K_LOAD`` standard errors
    of a logged position difference, ``sqrt(2) sigma_q``, ``sigma_q`` the logged position's noise at the
    scale of a half (``q_logged``): its white-noise level, its scatter about a cubic over a half
    (:func:`hold_scatter`: a loop's jitter in a hold), at least the encoder's ``q_step / sqrt(12)`` [q].
    Nothing relative to a speed of the log or of the joint."""
    n, h = q.size, max(1, int(round(0.5 * T_REST * fs)))
    logged = q if q_logged is None else np.asarray(q_logged, dtype=float)
    sigma = np.maximum(hold_scatter(logged, h), max(white_noise(logged), q_step / math.sqrt(12.0),
                                                     1e-9 * max(float(np.ptp(q)) if n else 0.0, 1e-300)))
    i = np.arange(n)
    half = np.abs(q[np.minimum(i + h, n - 1)] - q) <= K_LOAD * math.sqrt(2.0) * sigma  # each half: a reversal moves
    half[h:] &= half[:n - h].copy()
    centre = np.concatenate(([0], np.cumsum(half)))
    # still where a still window of T_REST holds the sample (frictid's rule)
    return centre[np.minimum(i + h + 1, n)] > centre[np.maximum(i - h, 0)]


def encoder_step(sensors, axis: str) -> float:
    """The position quantum [q] of ``sensors`` (0 for a continuous position)."""
    if sensors.encoder_step:
        return float(sensors.encoder_step)
    return 2.0 * math.pi / sensors.encoder_counts if sensors.encoder_counts and axis == "rotary" else 0.0


def closed_loop_rests(label: np.ndarray, moving: np.ndarray, u: np.ndarray, closed: np.ndarray, fs: float,
                      tau_noise: float) -> np.ndarray:
    """docs/segments.md's rest on the closed-loop ``rest`` and ``other`` samples of a log sampled at
    ``fs`` [Hz]: still (not ``moving``) and the drive torque ``u`` [F] steady against the logged torque's
    noise at that rate (``tau_noise`` [F], the sensor's, with the drive torque's own jitter). A log kept
    at a lower rate than the drive runs (every k-th sample) is judged on its own samples: a 0.1 s mean
    there holds k times fewer samples, and the standard errors the definition allows are larger."""
    u = np.asarray(u, dtype=float)
    # the logged torque's white-noise level along the log: the sensor's and the drive torque's own
    # jitter (the controller's reaction to sensor noise), as frictid measures it on the log
    noise = np.hypot(tau_noise, _local_jitter(u, int(round(T_REST * fs))))
    np.maximum(noise, 1e-9 * float(np.subtract(*np.percentile(u, [99.9, 0.1]))), out=noise)
    k = max(1, int(round(0.5 * T_LOAD * fs)))
    calm = ~moving & _steady(u, k, K_LOAD * noise, max(1, int(round(T_JUMP * fs))), moving)
    return _rests_by_definition(label, closed, calm, int(round(T_REST * fs)))


def _local_jitter(u: np.ndarray, block: int) -> np.ndarray:
    """Per-sample white-noise level of ``u`` [F]: median |fourth difference| / 0.6745 / sqrt(70) in
    blocks of ``block`` samples, the larger of a block's and its neighbours' (docs/segments.md, local
    sigma_tau)."""
    n, block = u.size, max(8, block)
    if n < 2 * block:
        return np.full(n, float(np.median(np.abs(np.diff(u, 4)))) / 0.6745 / math.sqrt(70.0) if n > 8 else 0.0)
    d = np.abs(np.diff(u, 4))
    nb = d.size // block
    sig = np.median(d[:nb * block].reshape(nb, block), axis=1) / 0.6745 / math.sqrt(70.0)
    p = np.concatenate(([sig[0]], sig, [sig[-1]]))
    sig = np.maximum(np.maximum(p[:-2], p[1:-1]), p[2:])
    return sig[np.minimum(np.arange(n) // block, nb - 1)]


def _close_gaps(mask: np.ndarray, n: int) -> np.ndarray:
    """``mask`` with its gaps shorter than ``n`` samples between two runs filled: one change through a
    sign flip of its slope (a stop and its settling)."""
    e = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    out = mask.copy()
    for a, b in zip(e[1:-1:2], e[2::2]):
        if b - a < n:
            out[a:b] = True
    return out


def _steady(u: np.ndarray, k: int, k_noise: np.ndarray, jump: int, moving: np.ndarray | None = None) -> np.ndarray:
    """Per sample: the drive torque ``u`` [F] is steady. It changes where its means over the k samples
    before and after a sample differ by more than ``k_noise sqrt(2 / k)`` (``K_LOAD`` standard errors of
    that difference under the logged noise: a change the log could show); each such stretch
    is edged where the torque, averaged over k / 2 samples, leaves the level of the k samples before it
    (and reaches that after it) by more than ``k_noise`` standard errors of the two means: a change
    starts where it starts, not where the window first sees it (frictid's edges, docs/segments.md). A
    change no longer than a torque jump (``jump`` samples, seen through the k / 2 means) does not end a
    steady stretch, as in frictid: a controller switched on or off under a still joint; unless the joint
    still moves (``moving``) k / 2 to k samples after it: then the jump is the start of a move, and a move
    starts where its torque starts to change (docs/segments.md, "What a rest is"); a jolt the jump gives
    the joint is over by then."""
    c = np.concatenate(([0.0], np.cumsum(np.pad(u, (k, k), mode="edge"))))
    i = np.arange(u.size) + k
    before, after = (c[i] - c[i - k]) / k, (c[i + k] - c[i]) / k
    z = np.abs(after - before) / (k_noise * math.sqrt(2.0 / k))
    changing = np.concatenate(([False], _close_gaps(z > 1.0, k), [False]))
    us = _smooth(u, max(1, k // 2))  # the edges: means over k / 2 against the k-sample levels
    thr = k_noise * math.sqrt(1.0 / k + 2.0 / k)  # per sample
    edge = np.flatnonzero(changing[1:] != changing[:-1])
    steady = np.ones(u.size, dtype=bool)
    for a, b in zip(edge[::2], edge[1::2]):
        off = np.flatnonzero(np.abs(us[a:b] - before[a]) > thr[a])
        if off.size:
            a0 = a + int(off[0])
            off = np.flatnonzero(np.abs(us[a0:b] - after[b - 1]) > thr[a])
            e = a0 + (int(off[-1]) + 1 if off.size else 0)
            # a torque jump alone (its edges smeared by the k / 2 means) is no change, unless a move follows
            if e - a0 > k // 2 + jump or (moving is not None and bool(np.any(moving[e + k // 2:e + k]))):
                steady[a0:e] = False
    return steady


def _cycles_from_onsets(label: np.ndarray, cycle: np.ndarray, moving: np.ndarray) -> None:
    """Shift each run of contiguous duty cycles so that every cycle starts at the first moving sample of
    its program's cycle and lasts as long as the program's: the samples before the first onset go to the
    piece before the run, the last cycle reaches as far into the rest after the run."""
    is_c = np.concatenate(([False], (cycle >= 0) & (label == L["duty_cycle"]), [False]))
    edge = np.flatnonzero(is_c[1:] != is_c[:-1])
    for a, b in zip(edge[::2], edge[1::2]):
        cut = np.flatnonzero(cycle[a + 1:b] != cycle[a:b - 1]) + a + 1
        starts = np.concatenate(([a], cut))
        ends = np.concatenate((cut, [b]))
        ids = cycle[starts].copy()
        shift = np.zeros(starts.size, dtype=np.int64)
        for k, (s0, e0) in enumerate(zip(starts, ends)):
            mv = np.flatnonzero(moving[s0:e0])
            shift[k] = mv[0] if mv.size else 0
        before_lab = label[a - 1] if a > 0 else L["rest"]
        stop = b + int(shift[-1])
        nxt = np.flatnonzero(label[b:stop] != L["rest"])   # reach only into a rest
        stop = b + int(nxt[0]) if nxt.size else min(stop, label.size)
        label[a:a + shift[0]] = before_lab
        cycle[a:a + shift[0]] = -1
        new = np.concatenate((starts + shift, [stop]))
        for k in range(starts.size):
            label[new[k]:new[k + 1]] = L["duty_cycle"]
            cycle[new[k]:new[k + 1]] = ids[k]


def _rests_by_definition(label: np.ndarray, closed: np.ndarray, calm: np.ndarray, n_min: int) -> np.ndarray:
    """docs/segments.md's definition of a rest on the closed-loop ``rest`` and ``other`` samples (holds,
    moves, excitations): ``rest`` where the joint is still and its torque steady (``calm``) for at least
    ``n_min`` samples, ``other`` elsewhere. A move starts where its torque starts to change or the joint
    to move, a hold after it where the torque has settled; a stop of ``n_min`` within a move is a rest.
    Open-loop rests (a ramp's hold, a settle before steps: a constant input torque) stay as written."""
    cand = closed & ((label == L["rest"]) | (label == L["other"]))
    ok = np.concatenate(([False], cand & calm, [False]))
    edge = np.flatnonzero(ok[1:] != ok[:-1])
    label[cand] = L["other"]
    for a, b in zip(edge[::2], edge[1::2]):
        if b - a >= n_min:
            label[a:b] = L["rest"]
    return label

