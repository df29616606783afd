"""An independent joint simulator for frictid's foreign scorecards (issue 19).

Written from ``/work/shared/MODELS.md`` alone: it does not import ``frictid.plant`` or ``frictid.models``
(nor anything else of frictid), so frictid's own assumptions about its plant cannot leak into the logs.

Physics (MODELS.md sections 1 and 3)::

    J dw/dt = tau - F - G(q),             G(q) = Px cos q + Py sin q
    dz/dt   = w - sigma0 |w| z / g(w) - D(z)              (D: optional creep)
    D(z)    = v_cr tanh(z / z_eps) max(0, 1 - sigma0 |z| / g(w)),   z_eps = 0.05 Fc / sigma0
    F       = sigma0 z + sigma1 dz/dt + sigma2 w
    g(w)    = Fc + (Fs - Fc) exp(-|w / vs|^delta)

Integrator: linearly implicit Euler at an internal step ``h = dt / m`` (``m`` >= 5 sub-steps per log
sample, more when the presliding natural frequency ``sqrt(sigma0 / J)`` needs it: ``h wn <= 0.5``). The
bristle decay rate ``sigma0 |w| / g(w)`` is taken from the previous sub-step; with it frozen, z, w and the
friction are solved together in closed form, so the stiff bristle equation (sigma0/g up to 1e5 1/rad) and
the presliding spring cannot go unstable, and at constant velocity z lands exactly on ``g sgn(w)/sigma0``
(the static map). The creep term D, taken from the previous sub-step, makes a loaded joint below
break-away creep at ``v_cr`` in steady state whatever its load (from dz/dt = 0 with F = sigma0 z: w (1 -
sigma0 z / g) = D), and vanishes as the load goes to zero. Compiled with numba.

Control: per log sample a mode (closed loop, or open-loop torque). The closed loop is a PID / PD position
loop or a PI velocity loop with gravity feed-forward (its model error drawn by the scenario), updated at
every sub-step from the drive's own (ideal, motor-side) state; the logged encoder is a separate, coarser
sensor. References are relative: when the loop takes over after an open-loop stretch it holds the
position where the joint is (bumpless: its integrator starts at the torque applied).

Sensors: the logged position is the encoder count times its step (``2 pi / 2^bits`` per revolution, or a
screw lead / 2^bits for a linear axis) with a random phase; torque with white noise and a bias; ``qd``
exact, the drive's backward difference of the quantised position, or absent.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numba
import numpy as np
import pandas as pd

#: Segment kinds, in frictid's documented order (docs/segments.md); label codes index this tuple.
KINDS = ("constant_velocity", "ramp_presliding", "step", "duty_cycle", "rest", "other")
CODE = {k: i for i, k in enumerate(KINDS)}
#: Control modes per sample.
CLOSED, OPEN = 0, 1
#: Controller types.
CONTROLLERS = ("pid", "pd", "pi_velocity")


@dataclass
class Plant:
    """One joint: inertia J [kg m^2 | kg], LuGre friction (Fc, Fs [N m | N], vs [q/s], delta [1], sigma2
    [N m s/rad | N s/m], sigma0 [N m/rad | N/m], sigma1 [N m s/rad | N s/m]), gravity G = Px cos q +
    Py sin q [N m], creep speed c_cr [q/s] of a loaded joint below break-away (0: none), axis ``rotary`` or ``linear``."""

    J: float
    Fc: float
    Fs: float
    vs: float
    delta: float
    sigma2: float
    sigma0: float
    sigma1: float
    Px: float = 0.0
    Py: float = 0.0
    c_cr: float = 0.0
    axis: str = "rotary"

    def g(self, w):
        """Stribeck level g(w) [N m] of velocity w [q/s]."""
        return self.Fc + (self.Fs - self.Fc) * np.exp(-np.abs(np.asarray(w) / self.vs) ** self.delta)

    def static(self, w):
        """Steady-state friction F_ss(w) = g(w) sgn(w) + sigma2 w [N m]."""
        w = np.asarray(w, dtype=float)
        return self.g(w) * np.sign(w) + self.sigma2 * w


@dataclass
class Controller:
    """Loop gains: kind (``pid``, ``pd``, ``pi_velocity``), Kp [N m/rad], Kd [N m s/rad], Ki [N m/(rad s)],
    and the gravity feed-forward's relative error ff_err [1] (0 = exact model, -1 = no feed-forward)."""

    kind: str
    Kp: float
    Kd: float
    Ki: float
    ff_err: float = 0.0


@dataclass
class Sensors:
    """fs [Hz] log rate; bits per revolution of the encoder; lead [m/rev] for a linear axis (else 0);
    tau_noise [N m] white-noise standard deviation; tau_bias [N m]; qd_mode ``exact``, ``diff`` or
    ``none``; fmt ``csv`` or ``parquet``; temp_env [degC] or None; meta_encoder: write the encoder step
    into the log's metadata sidecar."""

    fs: float
    bits: int
    tau_noise: float
    tau_bias: float = 0.0
    qd_mode: str = "exact"
    fmt: str = "parquet"
    lead: float = 0.0
    temp_env: float | None = None
    meta_encoder: bool = False

    @property
    def q_step(self) -> float:
        """Encoder step [rad | m]."""
        per_rev = self.lead if self.lead > 0 else 2.0 * math.pi
        return per_rev / 2.0 ** self.bits


@dataclass
class Program:
    """References at the log rate: mode (CLOSED / OPEN), qr [q], wr [q/s], u [N m] open-loop torque (on top
    of the gravity torque held at the open-loop stretch's start), label (code of KINDS) and index (the
    segment's number within its kind, -1 when none)."""

    fs: float
    mode: list = field(default_factory=list)
    qr: list = field(default_factory=list)
    wr: list = field(default_factory=list)
    u: list = field(default_factory=list)
    label: list = field(default_factory=list)
    index: list = field(default_factory=list)
    q_now: float = 0.0
    counters: dict = field(default_factory=dict)

    def ns(self, seconds: float) -> int:
        """Samples in ``seconds`` [s] (at least 1)."""
        return max(1, int(round(seconds * self.fs)))

    def next_index(self, kind: str) -> int:
        """A new segment number for ``kind``."""
        k = self.counters.get(kind, -1) + 1
        self.counters[kind] = k
        return k

    def add(self, mode, qr, wr, u, label: str, index: int = -1):
        """Append one piece (arrays of equal length, or scalars broadcast to the length of the others)."""
        n = max(np.size(x) for x in (qr, wr, u))
        self.mode.append(np.full(n, mode, dtype=np.int8))
        for lst, x in ((self.qr, qr), (self.wr, wr), (self.u, u)):
            lst.append(np.broadcast_to(np.asarray(x, dtype=float), (n,)).copy())
        self.label.append(np.full(n, CODE[label], dtype=np.int8))
        self.index.append(np.full(n, index, dtype=np.int32))
        if mode == CLOSED:
            self.q_now = float(self.qr[-1][-1])

    def arrays(self) -> dict:
        """The program as arrays of one length."""
        return {k: np.concatenate(getattr(self, k)) for k in ("mode", "qr", "wr", "u", "label", "index")}

    @property
    def n(self) -> int:
        return int(sum(a.size for a in self.mode))


@numba.njit(cache=True)
def _g(w, Fc, Fs, vs, delta):
    return Fc + (Fs - Fc) * math.exp(-abs(w / vs) ** delta)


#: Hidden-effect parameters of the kernel (``fx``, see ``effects.py``): their positions in the array.
FX = ("on", "kT", "tau_th", "P_ref", "kL", "L_ref", "aP", "period", "phiP", "kA_level", "kA_visc",
      "kW", "t0W", "s0W", "w_still", "bG2", "phiG2", "cC", "nC", "phiC", "m_all", "tau_load", "aCyc", "Tcyc",
      "phiCyc", "kM", "sM", "fM", "w_stillM")
FXI = {k: i for i, k in enumerate(FX)}


@numba.njit(cache=True)
def _effects(fx, q, w, st, h, Fc, t):
    """The hidden effects' level factor mL, viscous factor mV, added level dg [N m] and non-friction
    torque E [N m] at one sub-step; ``st`` = (thermal state, transmitted torque (low-passed over
    fx[21] s, 0: none), rest time, rest time before this motion, travel since it started, and for the
    memory effect the travel of the current move, that of the previous one and the current direction (0 at
    rest)) is advanced for the dwell and memory clocks here."""
    mL = fx[20] * (1.0 + fx[1] * st[0])
    mV = mL
    if fx[4] != 0.0:                          # load: the torque the transmission carries
        mL *= 1.0 + fx[4] * abs(st[1]) / fx[5]
    if fx[6] != 0.0:                          # position ripple of the level
        mL *= 1.0 + fx[6] * math.sin(2.0 * math.pi * q / fx[7] + fx[8])
    if fx[22] != 0.0:                         # a level cycling in time t [s] (not driven by the motion)
        mL *= 1.0 + fx[22] * math.sin(2.0 * math.pi * t / fx[23] + fx[24])
    if w < 0.0:                               # asymmetry: the negative branch scaled
        mL *= 1.0 + fx[9]
        mV *= 1.0 + fx[10]
    dg = 0.0
    if fx[11] != 0.0:                         # dwell: break-away grows with the rest before a move
        if abs(w) < fx[14]:
            st[2] += h
            st[3] = st[2]
            st[4] = 0.0
        else:
            st[2] = 0.0
            st[4] += abs(w) * h
        dg = Fc * fx[11] * math.log1p(st[3] / fx[12]) * math.exp(-st[4] / fx[13])
    if fx[25] != 0.0:                         # memory: the level of a move grows with the previous move's travel
        sg = 0.0 if abs(w) < fx[28] else (1.0 if w > 0.0 else -1.0)
        if sg != st[7] and st[5] > 0.0:       # a rest or a reversal ends a move: its travel is remembered
            st[6] = st[5]
            st[5] = 0.0
        st[7] = sg
        if sg != 0.0:
            st[5] += abs(w) * h
            mL *= 1.0 + fx[25] * (1.0 - math.exp(-st[6] / fx[26])) * math.exp(-st[5] / fx[27])
    E = fx[15] * math.sin(2.0 * q + fx[16]) + fx[17] * math.sin(fx[18] * q + fx[19])
    return mL, mV, dg, E


@numba.njit(cache=True)
def _kernel(mode, qr, wr, u, m, dt, par, ctl, q0, fx):
    """Integrate the joint over the program. par = (J, Fc, Fs, vs, delta, sigma2, sigma0, sigma1, Px, Py,
    c_cr); ctl = (kind 0 pid / 1 pd / 2 pi_velocity, Kp, Kd, Ki, ff_err); fx the hidden effects (``FX``;
    fx[0] = 0: none, and the arithmetic is that of the plain joint). Returns q, w, z, tau, F at the log
    samples [q, q/s, q, N m, N m] and, per sample, the effects' level g_eff [N m], viscous factor, torque E
    [N m] and thermal state [1]."""
    J, Fc, Fs, vs, delta, s2, s0, s1, Px, Py, c_cr = par
    kind, Kp, Kd, Ki, ff_err = ctl
    n = mode.size
    h = dt / m
    Q = np.empty(n)
    W = np.empty(n)
    Z = np.empty(n)
    T = np.empty(n)
    FF = np.empty(n)
    GL = np.empty(n)
    MV = np.ones(n)
    EE = np.zeros(n)
    TH = np.zeros(n)
    on = fx[0] != 0.0
    st = np.zeros(8)
    s2e = s2
    q, w, z, integ, off, g_hold, tau = q0, 0.0, 0.0, 0.0, q0 - qr[0], 0.0, 0.0
    prev_mode = CLOSED
    G0 = Px * math.cos(q) + Py * math.sin(q)   # the loop was holding the joint before the log starts
    integ = G0 - ((1.0 + ff_err) * G0 if ff_err > -1.0 else 0.0)
    tau = G0
    for i in range(n):
        if mode[i] == OPEN and prev_mode != OPEN:
            g_hold = Px * math.cos(q) + Py * math.sin(q)
        if mode[i] == CLOSED and prev_mode == OPEN:
            off = q - qr[i]
            ff = (1.0 + ff_err) * (Px * math.cos(q) + Py * math.sin(q)) if ff_err > -1.0 else 0.0
            integ = tau - ff
        prev_mode = mode[i]
        j = i + 1 if i + 1 < n else i
        for k in range(m):
            a = k / m
            r_q = qr[i] + a * (qr[j] - qr[i]) + off
            r_w = wr[i] + a * (wr[j] - wr[i])
            G = Px * math.cos(q) + Py * math.sin(q)
            if mode[i] == OPEN:
                tau = g_hold + u[i] + a * (u[j] - u[i]) if mode[j] == OPEN else g_hold + u[i]
            else:
                ff = (1.0 + ff_err) * G if ff_err > -1.0 else 0.0
                if kind == 2:
                    e = r_w - w
                    integ += Ki * e * h
                    tau = Kd * e + integ + ff
                else:
                    e = r_q - q
                    if kind == 0:
                        integ += Ki * e * h
                    tau = Kp * e + Kd * (r_w - w) + integ + ff
            if k == 0:
                T[i] = tau
            gw = _g(w, Fc, Fs, vs, delta)
            if on:
                mL, mV, dg, E = _effects(fx, q, w, st, h, Fc, (i + a) * dt)
                gw = gw * mL + dg
                s2e = s2 * mV
                G = G + E
            c = s0 * abs(w) / gw
            D = 0.0
            if c_cr > 0.0:
                D = c_cr * math.tanh(z * s0 / (0.05 * Fc)) * max(0.0, 1.0 - s0 * abs(z) / gw)
            A = (z - h * D) / (1.0 + h * c)
            B = h / (1.0 + h * c)
            F0 = s0 * A - s1 * (c * A + D)
            Fw = s0 * B + s1 * (1.0 - c * B) + s2e
            if k == 0:
                Q[i] = q
                W[i] = w
                Z[i] = z
                FF[i] = s0 * z + s1 * (w - c * z - D) + s2e * w
                GL[i] = gw
                if on:
                    MV[i] = mV
                    EE[i] = E
                    TH[i] = st[0]
            w = (J * w / h + tau - G - F0) / (J / h + Fw)
            z = A + B * w
            q = q + h * w
            if on:                            # friction power heats; the transmission carries tau - F
                Fn = F0 + Fw * w
                st[0] += h * (abs(Fn * w) / fx[3] - st[0]) / fx[2]
                st[1] += (tau - Fn - st[1]) * (min(1.0, h / fx[21]) if fx[21] > 0.0 else 1.0)
    return Q, W, Z, T, FF, GL, MV, EE, TH


#: Highest internal rate [Hz].
F_INTERNAL_MAX = 1.0e6


def substeps(plant: Plant, ctl: Controller, fs: float) -> int:
    """Internal sub-steps per log sample: at least 5, and enough that ``h wn <= 0.1`` for the presliding
    natural frequency ``sqrt(sigma0 / J)`` and the loop's ``sqrt(Kp / J)``, ``Kd / J`` [rad/s] (implicit
    Euler then adds under 0.05 of damping to the presliding oscillation), up to F_INTERNAL_MAX."""
    wn = max(math.sqrt(plant.sigma0 / plant.J), math.sqrt(ctl.Kp / plant.J), ctl.Kd / plant.J)
    need = max(5 * fs, wn / 0.1)
    return int(max(5, math.ceil(min(need, F_INTERNAL_MAX) / fs)))


def simulate(plant: Plant, ctl: Controller, prog: Program, q0: float = 0.0, fx=None) -> dict:
    """Run ``prog`` on ``plant`` under ``ctl``. Returns the true signals per log sample: t [s], q [q],
    w [q/s], z [q], tau [N m] (applied), F [N m] (friction), and the program's label / index / mode.
    ``fx``: hidden effects (an array laid out as ``FX``, made by ``effects.py``); with them the output
    also holds g_eff [N m] (the friction level the effects made), mV [1] (their viscous factor), E [N m]
    (their non-friction torque) and theta [1] (the thermal state)."""
    arr = prog.arrays()
    dt = 1.0 / prog.fs
    par = np.array([plant.J, plant.Fc, plant.Fs, plant.vs, plant.delta, plant.sigma2, plant.sigma0,
                    plant.sigma1, plant.Px, plant.Py, plant.c_cr])
    ck = np.array([float(CONTROLLERS.index(ctl.kind)), ctl.Kp, ctl.Kd, ctl.Ki, ctl.ff_err])
    fxa = np.zeros(len(FX)) if fx is None else np.asarray(fx, dtype=float)
    Q, W, Z, T, F, GL, MV, EE, TH = _kernel(arr["mode"], arr["qr"], arr["wr"], arr["u"],
                                            substeps(plant, ctl, prog.fs), dt, par, ck, q0, fxa)
    out = {"t": np.arange(arr["mode"].size) * dt, "q": Q, "w": W, "z": Z, "tau": T, "F": F}
    if fx is not None:
        out.update(g_eff=GL, mV=MV, E=EE, theta=TH)
    out.update(label=arr["label"], index=arr["index"], mode=arr["mode"], wr=arr["wr"])
    return out


def measure(sim: dict, sensors: Sensors, rng: np.random.Generator) -> pd.DataFrame:
    """The log as a drive records it: quantised q, noisy tau, qd per ``sensors.qd_mode`` (columns t, q,
    [qd], tau, [temp_env]) [s, q, q/s, N m, degC]."""
    step = sensors.q_step
    phase = rng.uniform(0.0, 1.0)
    counts = np.floor(sim["q"] / step + phase)
    q = counts * step
    tau = sim["tau"] + sensors.tau_bias + rng.normal(0.0, sensors.tau_noise, sim["tau"].size)
    cols = {"t": sim["t"], "q": q}
    if sensors.qd_mode == "exact":
        cols["qd"] = sim["w"].copy()
    elif sensors.qd_mode == "diff":
        cols["qd"] = np.concatenate(([0.0], np.diff(counts))) * step * sensors.fs
    cols["tau"] = tau
    if sensors.temp_env is not None:
        drift = np.cumsum(rng.normal(0.0, 0.002, tau.size)) / math.sqrt(max(1.0, sensors.fs / 100.0))
        cols["temp_env"] = sensors.temp_env + np.round(drift, 1)
    return pd.DataFrame(cols)


def write_log(path: Path, df: pd.DataFrame, sensors: Sensors, axis: str, truth: dict) -> Path:
    """Write the log (CSV or Parquet by ``sensors.fmt``; ``path`` without suffix), a metadata sidecar
    ``<log>.meta.yaml`` when the format needs one (a linear axis, a declared encoder step) and the truth
    ``<log>.truth.json`` (which frictid never reads). Returns the log's path."""
    path = Path(path).with_suffix("." + ("csv" if sensors.fmt == "csv" else "parquet"))
    if sensors.fmt == "csv":
        df.to_csv(path, index=False, float_format="%.15g")
    else:
        df.to_parquet(path, index=False)
    meta = {}
    if axis == "linear":
        meta["axis"] = "linear"
    if sensors.meta_encoder:
        meta.setdefault("meta", {})["encoder_resolution"] = sensors.q_step
    if meta:
        import yaml
        Path(str(path) + ".meta.yaml").write_text(yaml.safe_dump(meta))
    Path(str(path) + ".truth.json").write_text(json.dumps(truth))
    return path


def truth_record(plant: Plant, ctl: Controller, sensors: Sensors, labels: np.ndarray, index: np.ndarray,
                 extra: dict | None = None) -> dict:
    """The truth sidecar: per-sample labels as runs [kind, i0, i1, index] (i1 exclusive), the plant, the
    controller and the sensors."""
    change = np.flatnonzero((labels[1:] != labels[:-1]) | (index[1:] != index[:-1])) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [labels.size]))
    runs = [[KINDS[int(labels[a])], int(a), int(b), int(index[a])] for a, b in zip(starts, ends)]
    return {"n": int(labels.size), "segments": runs, "plant": asdict(plant), "controller": asdict(ctl),
            "sensors": asdict(sensors) | {"q_step": sensors.q_step}, **(extra or {})}


def read_truth(log_path) -> dict:
    """The truth sidecar of a log written by :func:`write_log`."""
    return json.loads(Path(str(log_path) + ".truth.json").read_text())
