"""Random scenarios for the foreign scorecards: a plant, a controller, sensors and an experiment layout,
all drawn from one seed (``np.random.default_rng(seed)``; the same seed gives the same log, byte for byte).

    from scenarios import make_log
    path, truth = make_log(123, "issue19_sweep", "/tmp/out")

Families (``FAMILIES``) are layouts a lab or a machine produces; ``issue19_sweep`` and ``issue19_ramps`` are
the two named failure layouts of issue 19. Seeds: the tests use seeds < 1000, the scorecards >= 100000.
The ranges drawn are listed in ``docs/scorecards.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

try:
    from . import sim
    from .layouts import BUILDERS, T_REST
except ImportError:  # run as a script from this folder
    import sim
    from layouts import BUILDERS, T_REST

#: Every layout family, for the segments scorecard.
FAMILIES = ("sweep", "issue19_sweep", "ramps", "issue19_ramps", "steps", "duty", "ptp", "session")
#: Identification layouts, for the fit scorecard.
FIT_FAMILIES = ("sweep", "issue19_sweep", "sweep_ramps_steps", "issue19_ramps_sweep", "ptp_excitation")
#: Families that need a rotary joint (their speeds are given in rad/s).
ROTARY_ONLY = ("issue19_sweep", "issue19_ramps", "issue19_ramps_sweep")


@dataclass
class Scenario:
    """One draw: seed, family, plant, controller, sensors, top speed w_top [q/s], creep speed [q/s]."""

    seed: int
    family: str
    plant: sim.Plant
    ctl: sim.Controller
    sensors: sim.Sensors
    w_top: float
    creep: float = 0.0


def loguniform(rng, lo: float, hi: float) -> float:
    """One value log-uniform on [lo, hi]."""
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_plant(rng, axis: str, w_top: float) -> sim.Plant:
    """A random joint: inertia 1e-3..10 kg m^2 (0.1..50 kg), Coulomb 0.02..500 N m (N) with Fc/J in
    0.5..500 [1/s^2], Fs/Fc 1..1.6, vs 0.005..0.3 w_top, delta 0.5..2.5, viscous share 5..60 % of the
    friction at w_top [q/s], presliding deflection Fc/sigma0 2e-5..2e-3 rad (1e-6..1e-4 m), damping
    ratio 0.3..1 (sigma1 = 2 zeta sqrt(sigma0 J) - sigma2, at least a tenth of its first term), gravity
    (rotary, half the draws) 0.5..20 Fc at a random phase."""
    lin = axis == "linear"
    for _ in range(1000):
        J = loguniform(rng, 0.1, 50.0) if lin else loguniform(rng, 1e-3, 10.0)
        Fc = loguniform(rng, 0.02, 500.0)
        if 0.5 <= Fc / J <= 500.0:
            break
    Fs = Fc * rng.uniform(1.0, 1.6)
    vs = w_top * loguniform(rng, 0.005, 0.3)
    delta = rng.uniform(0.5, 2.5)
    share = rng.uniform(0.05, 0.6)
    sigma2 = share / (1.0 - share) * Fc / w_top
    zc = loguniform(rng, 1e-6, 1e-4) if lin else loguniform(rng, 2e-5, 2e-3)
    sigma0 = Fc / zc
    crit = 2.0 * rng.uniform(0.3, 1.0) * math.sqrt(sigma0 * J)
    sigma1 = max(crit - sigma2, 0.1 * crit)
    Px = Py = 0.0
    if not lin and rng.random() < 0.5:
        A, phi = Fc * loguniform(rng, 0.5, 20.0), rng.uniform(-math.pi, math.pi)
        Px, Py = A * math.cos(phi), A * math.sin(phi)
    return sim.Plant(J=J, Fc=Fc, Fs=Fs, vs=vs, delta=delta, sigma2=sigma2, sigma0=sigma0, sigma1=sigma1,
                     Px=Px, Py=Py, axis=axis)


def draw_controller(rng, plant: sim.Plant, kind: str | None = None) -> sim.Controller:
    """A PID / PD position loop or a PI velocity loop: bandwidth 15..60 rad/s, stiff enough that the
    Coulomb level deflects it by at most 1e-3..1e-2 rad (1e-5..1e-4 m); damping 0.7..1; integrator at a
    fifth of the bandwidth; gravity feed-forward with 0..10 % error (a quarter of the draws: none)."""
    kind = kind or str(rng.choice(sim.CONTROLLERS))
    wb = loguniform(rng, 15.0, 60.0)
    e_max = loguniform(rng, 1e-5, 1e-4) if plant.axis == "linear" else loguniform(rng, 1e-3, 1e-2)
    Kp = max(plant.J * wb ** 2, plant.Fc / e_max)
    wn = math.sqrt(Kp / plant.J)
    Kd = 2.0 * rng.uniform(0.7, 1.0) * plant.J * wn
    ff = -1.0 if rng.random() < 0.25 else rng.uniform(-0.1, 0.1)
    if kind == "pi_velocity":
        Kv = max(plant.J * wb * 4.0, plant.Fc / (e_max * wb))
        return sim.Controller(kind, Kp=0.0, Kd=Kv, Ki=Kv * wb, ff_err=ff)
    return sim.Controller(kind, Kp=Kp, Kd=Kd, Ki=Kp * wn / 5.0 if kind == "pid" else 0.0, ff_err=ff)


def draw_sensors(rng, plant: sim.Plant, temp: bool = False) -> sim.Sensors:
    """Log rate 100 Hz..10 kHz (log-uniform), encoder 12..24 bits per revolution (a linear axis: a screw
    lead of 5..20 mm per revolution), torque noise 0.1..5 % of Fc, a bias of up to 2 % of Fc in half the
    draws, qd exact / backward difference / absent, CSV or Parquet, temp_env in 30 % of the draws."""
    fs = float(round(loguniform(rng, 100.0, 10000.0)))
    bits = int(rng.integers(12, 25))
    lead = rng.uniform(0.005, 0.02) if plant.axis == "linear" else 0.0
    noise = plant.Fc * loguniform(rng, 1e-3, 5e-2)
    bias = plant.Fc * rng.uniform(-0.02, 0.02) if rng.random() < 0.5 else 0.0
    qd_mode = str(rng.choice(["exact", "diff", "none"]))
    fmt = str(rng.choice(["csv", "parquet"]))
    t_env = rng.uniform(18.0, 28.0) if (temp or rng.random() < 0.3) else None
    return sim.Sensors(fs=fs, bits=bits, tau_noise=noise, tau_bias=bias, qd_mode=qd_mode, fmt=fmt,
                       lead=lead, temp_env=t_env, meta_encoder=bool(rng.random() < 0.3))


def draw(seed: int, family: str | None = None, families=FAMILIES) -> Scenario:
    """The scenario of ``seed``: its family (drawn from ``families`` unless given), plant, controller and
    sensors. Issue-19 families get a rotary joint with a 2 rad/s top speed, the creep 0.2..0.6 mrad/s."""
    rng = np.random.default_rng(seed)
    drawn = str(rng.choice(list(families)))   # always drawn: a given family keeps the seed's other draws
    family = family or drawn
    issue19 = family in ROTARY_ONLY
    axis = "rotary" if issue19 or rng.random() < 0.8 else "linear"
    w_top = 2.0 if issue19 else (loguniform(rng, 0.05, 1.0) if axis == "linear" else loguniform(rng, 0.5, 4.0))
    plant = draw_plant(rng, axis, w_top)
    ctl = draw_controller(rng, plant)
    sensors = draw_sensors(rng, plant, temp=family == "duty")
    creep = rng.uniform(2e-4, 6e-4) if family in ("issue19_ramps", "issue19_ramps_sweep") else 0.0
    return Scenario(seed, family, plant, ctl, sensors, w_top, creep)


def make_log(seed: int, family: str | None = None, outdir=".", families=FAMILIES) -> tuple[Path, dict]:
    """Draw, build the layout, simulate, measure and write one log (``<outdir>/foreign_<seed>``) with its
    truth sidecar. Returns (log path, truth)."""
    sc = draw(seed, family, families)
    rng = np.random.default_rng([seed, 1])
    prog = sim.Program(fs=sc.sensors.fs)
    info = BUILDERS[sc.family](prog, sc, rng)
    if sc.creep > 0:
        sc.plant.c_cr = sc.creep
    out = sim.simulate(sc.plant, sc.ctl, prog)
    labels, demoted = refine_labels(out, sc.sensors.tau_noise, sc.sensors.q_step)
    df = sim.measure(out, sc.sensors, np.random.default_rng([seed, 2]))
    truth = sim.truth_record(sc.plant, sc.ctl, sc.sensors, labels, out["index"],
                             {"seed": seed, "family": sc.family, "w_top": sc.w_top, "creep": sc.creep,
                              "plateaus_demoted": demoted, "layout": info})
    path = sim.write_log(Path(outdir) / f"foreign_{seed}", df, sc.sensors, sc.plant.axis, truth)
    return path, truth


#: Time over which the true torque is averaged to judge whether it is steady [s] (half frictid's T_MIN,
#: the scale at which it averages anything) and the standard errors a change must exceed (its K_NOISE).
T_STEADY, K_STEADY = 0.1, 5.0
#: The longest rise of a torque jump [s] (frictid's T_JUMP).
T_JUMP = 0.01
#: A duty cycle's joint stops below this share of the cycle's top speed (frictid's R_STILL).
R_STOP = 0.01


def _close_gaps(mask: np.ndarray, n: int) -> np.ndarray:
    """``mask`` with its gaps shorter than ``n`` samples between two runs filled: one change through a
    sign flip of its slope (a stop and its settling)."""
    e = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    out = mask.copy()
    for a, b in zip(e[1:-1:2], e[2::2]):
        if b - a < n:
            out[a:b] = True
    return out


def steady_torque(tau: np.ndarray, fs: float, noise: float, moving: np.ndarray | None = None) -> np.ndarray:
    """Per sample: the true torque ``tau`` [N m] is steady. It changes where the means over the
    ``T_STEADY`` before and after a sample differ by more than ``thr`` = ``K_STEADY`` standard errors of
    that difference under the logged torque noise ``noise`` [N m] (``noise sqrt(2 / k)``, k samples: a
    change the log's torque could show); each such stretch is then edged where the torque, averaged over
    ``T_STEADY`` / 2, leaves the level of the ``T_STEADY`` before it (and reaches that after it) by
    ``K_STEADY`` standard errors of the two means, so that a change starts where it starts, not where a
    window first sees it (frictid's edges, docs/segments.md). A change no longer than a torque jump
    (``T_JUMP``, seen through the ``T_STEADY`` / 2 means) does not end a steady stretch, as in frictid,
    unless the joint still moves (``moving``) ``T_STEADY`` / 2 to ``T_STEADY`` after it: a move starts where
    its torque starts to change (docs/segments.md, "What a rest is"); a jolt the jump gives the joint is
    over by then."""
    k = max(1, int(round(T_STEADY * fs)))
    c = np.concatenate(([0.0], np.cumsum(np.pad(tau, (k, k), mode="edge"))))
    i = np.arange(tau.size) + k
    before, after = (c[i] - c[i - k]) / k, (c[i + k] - c[i]) / k
    z = np.abs(after - before) / (K_STEADY * noise * math.sqrt(2.0 / k))
    changing = np.concatenate(([False], _close_gaps(z > 1.0, k), [False]))
    kf = max(1, k // 2)  # the edges: means over k / 2 samples against the k-sample levels
    cf = np.concatenate(([0.0], np.cumsum(np.pad(tau, (kf // 2, kf - kf // 2), mode="edge"))))
    fine = (cf[kf:] - cf[:-kf])[:tau.size] / kf
    thr = K_STEADY * noise * math.sqrt(1.0 / k + 1.0 / kf)
    edge = np.flatnonzero(changing[1:] != changing[:-1])
    steady = np.ones(tau.size, dtype=bool)
    for a, b in zip(edge[::2], edge[1::2]):
        off = np.flatnonzero(np.abs(fine[a:b] - before[a]) > thr)
        if off.size:
            a0 = a + int(off[0])
            off = np.flatnonzero(np.abs(fine[a0:b] - after[b - 1]) > thr)
            e = a0 + (int(off[-1]) + 1 if off.size else 0)
            # a torque jump alone is no change (frictid), unless a move follows it
            if e - a0 > kf + max(1, int(round(T_JUMP * fs))) or (
                    moving is not None and bool(np.any(moving[e + k // 2:e + k]))):
                steady[a0:e] = False
    return steady


def refine_labels(out: dict, tau_noise: float, q_step: float) -> tuple[np.ndarray, int]:
    """The program's labels made physical: a constant-velocity piece starts where the true velocity has
    settled for good within 5 % of its reference (the samples before are ``other``: the loop still
    settling); a piece whose settled remainder is shorter than ``T_REST`` (0.2 s, frictid's ``T_MIN``: a
    plateau is near-constant velocity long enough to average, docs/segments.md) is ``other`` altogether
    (a slow transient, stick-slip, a ripple, a drift that never settles). Until 2026-11-27 (session 18) a
    piece not settled by its middle was ``other``: a 0.53 s plateau whose loop settled 0.26 s before its
    end (foreign card 101154, a PID overshooting at 0.04 rad/s) was no plateau, though it held its speed
    within 0.1 % over that stretch. A ``rest`` right after a step is the step's still tail (nothing in the data
    marks where one ends: a step lasts until the next input). Dwells and moves (closed-loop ``rest`` and
    ``other``) are relabelled by docs/segments.md's definition of a rest: ``rest`` where the joint is
    still to the encoder of step ``q_step`` [q] (:func:`still_to_encoder`) and its torque steady
    (:func:`steady_torque` under the logged noise ``tau_noise`` [N m]) for at least ``T_REST``, ``other``
    elsewhere: a move starts where its torque starts to change or the joint to move, a dwell where the
    torque has settled after the move. Returns (labels, plateaus demoted)."""
    lab = out["label"].copy()
    idx = out["index"]                       # changed in place: a rest after a step joins the step
    w, wr = out["w"], out["wr"]
    change = np.flatnonzero((lab[1:] != lab[:-1]) | (idx[1:] != idx[:-1])) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [lab.size]))
    demoted = 0
    n_plateau = int(round(T_REST / float(out["t"][1] - out["t"][0])))
    for a, b in zip(starts, ends):
        if lab[a] == sim.CODE["constant_velocity"]:
            bad = np.flatnonzero(np.abs(w[a:b] - wr[a:b]) > 0.05 * np.abs(wr[a:b]))
            s = int(bad[-1]) + 1 if bad.size else 0
            if b - a - s < n_plateau:
                s = b - a
                demoted += 1
            lab[a:a + s] = sim.CODE["other"]
        elif lab[a] == sim.CODE["rest"] and a > 0 and lab[a - 1] == sim.CODE["step"]:
            idx[a:b] = idx[a - 1]        # a still joint after a step: the step lasts until the next input
            lab[a:b] = sim.CODE["step"]
    _duty_cycles_by_definition(lab, out, q_step)
    _rests_by_definition(lab, out, tau_noise, q_step)
    return lab, demoted


def _duty_cycles_by_definition(lab: np.ndarray, out: dict, q_step: float) -> None:
    """A duty cycle is a repeated motion-and-rest pattern (docs/segments.md): a run of ``duty_cycle``
    cycles one of which never stops the joint for ``T_REST`` (the moves fill the drawn period, the dwells
    between them are shorter than a rest) is back-and-forth motion, not a duty cycle: its samples become
    ``other`` (and, where still and steady, ``rest``), their index -1 (in place). Stopped: still to the
    encoder (:func:`still_to_encoder`) and the true speed at most ``R_STOP`` of the cycle's fastest
    (frictid's ``R_STILL``: the tail of a move is still below 1 % of its speed). Stillness to the encoder
    alone is not enough next to a move: the encoder's scatter about a cubic over half of ``T_REST`` is
    then the move's own curvature, and a 0.09 s dwell between two moves at 0.26 rad/s read as 0.21 s of
    still joint turning at up to 0.18 rad/s (foreign card 100751, until 2026-11-27, session 18)."""
    fs = 1.0 / float(out["t"][1] - out["t"][0])
    duty = np.concatenate(([False], lab == sim.CODE["duty_cycle"], [False]))
    edge = np.flatnonzero(duty[1:] != duty[:-1])
    still = still_to_encoder(out["q"], fs, q_step)
    speed = np.abs(out["w"])
    n_min = int(round(T_REST * fs))
    for a, b in zip(edge[::2], edge[1::2]):
        idx = out["index"][a:b]
        cut = np.flatnonzero(idx[1:] != idx[:-1]) + 1
        for c0, c1 in zip(np.concatenate(([0], cut)) + a, np.concatenate((cut, [b - a])) + a):
            st = still[c0:c1] & (speed[c0:c1] <= R_STOP * float(speed[c0:c1].max()))
            e = np.flatnonzero(np.diff(np.concatenate(([0], st.astype(np.int8), [0]))))
            if not np.any(e[1::2] - e[::2] >= n_min):
                lab[a:b] = sim.CODE["other"]
                out["index"][a:b] = -1
                break


def hold_scatter(x: np.ndarray, h: int) -> np.ndarray:
    """Per sample: the scatter of ``x`` about a cubic over ``h`` samples (docs/segments.md, "What a rest
    is"): median |fourth difference of samples ``h / 4`` apart| / 0.6745 / sqrt(70) per block of ``2 h``
    samples, the larger of a block and its neighbours (0 where ``h / 4`` rounds to one sample)."""
    n, lag = x.size, int(round(h / 4))
    if lag <= 1 or n <= 4 * lag + 8:
        return np.zeros(n)
    m = n - 4 * lag
    d = np.abs(x[4 * lag:] - 4 * x[3 * lag:n - lag] + 6 * x[2 * lag:n - 2 * lag] - 4 * x[lag:n - 3 * lag] + x[:m])
    d = np.concatenate((np.full(2 * lag, d[0]), d, np.full(2 * lag, d[-1])))
    block = max(8, 2 * h)
    nb = -(-n // block)
    level = np.array([np.median(d[k * block:(k + 1) * block]) for k in range(nb)]) / 0.6745 / math.sqrt(70.0)
    if nb > 1 and n - (nb - 1) * block < 8:  # a tail too short for a median takes the block before
        level[-1] = level[-2]
    padded = np.concatenate(([level[0]], level, [level[-1]]))
    return np.repeat(np.maximum(np.maximum(padded[:-2], padded[1:-1]), padded[2:]), block)[:n]


def still_to_encoder(q: np.ndarray, fs: float, q_step: float) -> np.ndarray:
    """Per sample: the joint is still to its encoder (docs/segments.md, "What a rest is": stillness is what
    the sensors resolve, not a fraction of a speed): the true position ``q`` [q] moves over each half of a
    window of ``T_REST`` that holds the sample by at most ``K_STEADY`` standard errors of a difference of two logged
    positions, ``sqrt(2) sigma_q``, ``sigma_q`` the noise of the encoder's reading at the scale of a half:
    its white-noise level (median |fourth difference| / 0.6745 / sqrt(70)), its scatter about a cubic over
    a half (:func:`hold_scatter`: a loop's jitter in a hold, correlated over more than one sample), at
    least ``q_step / sqrt(12)`` (quantisation)."""
    n, h = q.size, max(1, int(round(0.5 * T_REST * fs)))
    read = np.round(q / q_step) * q_step
    jitter = float(np.median(np.abs(np.diff(read, 4)))) / 0.6745 / math.sqrt(70.0) if n > 8 else 0.0
    sigma = np.maximum(hold_scatter(read, h), max(jitter, q_step / math.sqrt(12.0)))
    i = np.arange(n)
    half = np.abs(q[np.minimum(i + h, n - 1)] - q) <= K_STEADY * math.sqrt(2.0) * sigma  # each half: a reversal moves
    half[h:] &= half[:n - h].copy()
    centre = np.concatenate(([0], np.cumsum(half)))
    # still where a still window of T_REST holds the sample (frictid's rule)
    return centre[np.minimum(i + h + 1, n)] > centre[np.maximum(i - h, 0)]


def _rests_by_definition(lab: np.ndarray, out: dict, tau_noise: float, q_step: float) -> None:
    """Closed-loop ``rest`` and ``other`` samples become ``rest`` where the joint is still and its torque
    steady (:func:`steady_torque`), in runs of at least ``T_REST``, else ``other`` (in place). Open-loop rests (a ramp's hold or
    settle: the input torque is constant) stay as the program wrote them."""
    fs = 1.0 / float(out["t"][1] - out["t"][0])
    closed = (out["mode"] == sim.CLOSED) & ((lab == sim.CODE["rest"]) | (lab == sim.CODE["other"]))
    still = still_to_encoder(out["q"], fs, q_step)
    calm = still & steady_torque(out["tau"], fs, tau_noise, ~still)
    rest = np.concatenate(([False], closed & calm, [False]))
    edge = np.flatnonzero(rest[1:] != rest[:-1])
    lab[closed] = sim.CODE["other"]
    n_min = int(round(T_REST * fs))
    for a, b in zip(edge[::2], edge[1::2]):
        if b - a >= n_min:
            lab[a:b] = sim.CODE["rest"]

