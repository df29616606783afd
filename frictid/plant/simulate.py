"""simulate_recipe: run a recipe on a plant and return one JointLog per joint, with truth labels."""
from __future__ import annotations

import sys

import numpy as np

from ..data import SEGMENT_KINDS, JointLog
from ..errors import ConfigError
from ..models.static import canonical_pair
from ..models.thermal import thermal_code
from .config import Joint, Plant, friction_params, load_plant, load_recipe, resolve_plant_path
from .effects import compile_effects
from .kernel import (N_P, P_C, P_HAMP, P_HPER, P_HPH, P_GOFF, P_J, P_K, P_KD, P_KI, P_KP, P_KV, P_KVI, P_LOAD, P_PAMP, P_PAY,
                     P_PPER, P_PPH, P_PX, P_PY, P_QRES, P_S0N, P_S0P, P_S1N, P_S1P, P_TMAX,
                     simulate_joint, simulate_joint_ref)
from .recipe import G0, compile_recipe, encoder_step, refine_labels, still_to_sensors
from .sensors import draw_noise, logged_signals

_KINDS = np.asarray(SEGMENT_KINDS, dtype=object)


def controller_gains(joint: Joint) -> dict[str, float]:
    """PID and velocity-PI gains: from the plant's explicit gains or from bandwidth and inertia.

    ``kp = J wn^2``, ``kd = 2 zeta J wn``, ``ki = kp * integral * wn`` (position loop, wn = 2 pi
    bandwidth); the velocity loop uses twice the bandwidth: ``kv = J 2 wn``, ``kvi = kv * integral * 2 wn``.
    """
    c = joint.control
    wn = 2 * np.pi * c.bandwidth_hz
    J = joint.J
    kp = c.kp if c.kp is not None else J * wn * wn
    kd = c.kd if c.kd is not None else 2 * c.damping * J * wn
    ki = c.ki if c.ki is not None else kp * c.integral * wn
    kv = c.kv if c.kv is not None else J * 2 * wn
    kvi = c.kvi if c.kvi is not None else kv * c.integral * 2 * wn
    return dict(kp=float(kp), kd=float(kd), ki=float(ki), kv=float(kv), kvi=float(kvi))


def kernel_inputs(plant: Plant, joint: Joint):
    """Parameter vector, canonical vectors and thermal packing of one joint."""
    fr = joint.friction
    c_pos, c_neg = canonical_pair(fr.map, friction_params(fr))
    ce = compile_effects(joint.effects)
    c_neg = c_neg.copy()
    for i in (0, 1, 4, 6, 7, 8):  # amplitudes, not shapes
        c_neg[i] *= ce.neg_factor
    th = joint.thermal
    code, theta, dc9 = thermal_code(th.law, th.alpha, th.beta, th.lam, th.T0,
                                    (th.dc0, th.dc1, th.dc2, th.dc3))
    gains = controller_gains(joint)
    p = np.zeros(N_P)
    p[P_J] = joint.J
    p[P_S0P] = fr.sigma0
    p[P_S0N] = fr.sigma0 if fr.sigma0_neg is None else fr.sigma0_neg
    p[P_S1P] = fr.sigma1
    p[P_S1N] = fr.sigma1 if fr.sigma1_neg is None else fr.sigma1_neg
    g = joint.gravity
    p[P_PX], p[P_PY], p[P_GOFF], p[P_PAY] = g.Px, g.Py, g.offset, G0 * g.payload_arm
    p[P_TMAX] = joint.limits.torque
    p[P_KP], p[P_KD], p[P_KI], p[P_KV], p[P_KVI] = (gains[k] for k in ("kp", "kd", "ki", "kv", "kvi"))
    p[P_PAMP], p[P_PPER], p[P_PPH] = ce.pos_amp, ce.pos_period, ce.pos_phase
    p[P_LOAD] = ce.load_coeff
    p[P_HAMP], p[P_HPER], p[P_HPH] = ce.ptq_amp, ce.ptq_period, ce.ptq_phase
    p[P_C], p[P_K] = th.C, th.K
    p[P_QRES] = plant.q_quantum
    return p, c_pos, c_neg, dc9, code, theta, ce, gains


def true_params(plant: Plant, joint: Joint, gains: dict) -> dict:
    """The truth['params'] dict: everything that generated the data."""
    fr = joint.friction
    sp = friction_params(fr)
    c_pos, c_neg = canonical_pair(fr.map, sp)
    d = joint.model_dump(mode="json")
    s0n = fr.sigma0 if fr.sigma0_neg is None else fr.sigma0_neg
    s1n = fr.sigma1 if fr.sigma1_neg is None else fr.sigma1_neg
    return {
        "plant": plant.name,
        "joint": joint.name,
        "axis": plant.axis,
        "map": fr.map,
        "static": sp,
        "canonical_pos": c_pos.tolist(),
        "canonical_neg": c_neg.tolist(),
        "sigma0": float(fr.sigma0), "sigma0_neg": float(s0n),
        "sigma1": float(fr.sigma1), "sigma1_neg": float(s1n),
        "J": float(joint.J),
        "gravity": d["gravity"],
        "thermal": d["thermal"],
        "effects": d["effects"],
        "sensors": plant.sensors.model_dump(mode="json"),
        "control": gains,
        "limits": d["limits"],
    }


def _progress_bar(enabled: bool, total: int):
    if not enabled or not sys.stderr.isatty():
        return None
    try:
        from rich.progress import Progress
    except ImportError:  # pragma: no cover
        return None
    prog = Progress(transient=True)
    prog.start()
    task = prog.add_task("simulating", total=total)
    return prog, task


def prepare_joint(plant: Plant, joint: Joint, recipe, seed_seq=0, scale=1.0):
    """Compile a recipe for one joint; returns (program, kernel_args dict, extras) ready for the kernel.

    kernel_args are the keyword arguments of :func:`frictid.plant.kernel.simulate_joint`.
    """
    pr = compile_recipe(recipe, plant, joint, scale)
    prog = pr.finish()
    n = pr.n
    h = 1.0 / pr.fs
    t = np.arange(n) * h
    rng = np.random.default_rng(seed_seq)
    nq, nqd, ntau = draw_noise(rng, n, plant.sensors)
    p, c_pos, c_neg, dc9, code, theta, ce, gains = kernel_inputs(plant, joint)
    gmul, fmul = ce.multipliers(t, prog["run"], prog["payload"], prog["q_ref"], prog["qd_ref"])
    state0 = np.array([float(prog["q_ref"][0]), 0.0, 0.0, float(prog["temp_env"][0])])
    args = dict(h=h, nsub=int(plant.substeps), mode=prog["mode"], q_ref=prog["q_ref"],
                qd_ref=prog["qd_ref"], tau_ff=prog["tau_ff"], Tenv=prog["temp_env"],
                payload=prog["payload"], reset_T=prog["reset"], gmul=gmul, fmul=fmul, nq=nq, nqd=nqd,
                p=p, c_pos=c_pos, c_neg=c_neg, dc_pos=dc9, dc_neg=dc9, th_code=code, theta=theta,
                state0=state0)
    extras = dict(program=pr, t=t, ntau=ntau, effects=ce, gains=gains)
    return prog, args, extras


def simulate_joint_program(plant: Plant, joint: Joint, recipe, seed_seq, scale=1.0, reference=False):
    """Compile and run one joint; returns a JointLog."""
    prog, args, ex = prepare_joint(plant, joint, recipe, seed_seq, scale)
    pr, t, ntau, ce, gains = ex["program"], ex["t"], ex["ntau"], ex["effects"], ex["gains"]
    fs = pr.fs
    fn = simulate_joint_ref if reference else simulate_joint
    q, w, z, F, T, u, qm, qdm = fn(**args)
    del args  # the kernel inputs (noise, multipliers, modes) are not needed any more: lower the peak
    q_log, qd_log, tau_log = logged_signals(qm, qdm, u, ntau, plant.sensors, ce.torque_offset)
    still = still_to_sensors(q, fs, q_log, encoder_step(plant.sensors, plant.axis))
    labels = refine_labels(prog["label"], w, pr, u, prog["cycle"], plant.sensors.tau_noise, still)
    channels = {"q_ref": prog["q_ref"], "qd_ref": prog["qd_ref"], "tau_ref": prog["tau_ff"]}
    uses_temp = joint.thermal.law != "none" or recipe.temp_env is not None or any(
        getattr(e, "temp_env", None) is not None or e.kind in ("duty_cycle", "validation_ptp")
        for e in recipe.experiments)
    if uses_temp:
        channels["temp_env"] = prog["temp_env"]
    if np.any(prog["payload"] != 0):
        channels["payload"] = prog["payload"]
    units = {"rotary": {"q": "rad", "qd": "rad/s", "tau": "N m"},
             "linear": {"q": "m", "qd": "m/s", "tau": "N"}}[plant.axis]
    meta = {
        "robot": plant.robot or plant.name,
        "plant": plant.name,
        "joint": joint.name,
        "recipe": recipe.name,
        "sample_rate": fs,
        "units": units,
        "axis": plant.axis,
        "generator": "frictid.plant.simulate_recipe",
        "duration_scale": scale,
        # the drive's controller is known to whoever ran the experiment (used by closed-loop replay)
        "control": dict(gains, type="position", tau_max=float(joint.limits.torque)),
    }
    truth = {
        "segment": _KINDS[labels],
        "cycle": prog["cycle"].astype(np.int64),
        "params": true_params(plant, joint, gains),
        "temp_joint": T,
        "friction": F,
        "velocity": w,
        "position": q,
        "bristle": z,
        "run": prog["run"].astype(np.int32),
    }
    return JointLog(joint=joint.name, t=t, tau=tau_log, q=q_log, qd=qd_log, channels=channels,
                    axis=plant.axis, meta=meta, source=f"simulate:{recipe.name}@{plant.name}", truth=truth)


def simulate_recipe(recipe, plant=None, seed: int = 0, progress: bool = False,
                    duration_scale: float = 1.0, joints=None) -> list[JointLog]:
    """Simulate a recipe on a plant; one :class:`~frictid.data.JointLog` per joint.

    recipe : path to a recipe YAML (or a shipped recipe's name, or a loaded :class:`Recipe`).
    plant : path / name / loaded :class:`Plant`; default: the recipe's ``default_plant``.
    seed : seeds ``np.random.default_rng`` (one independent stream per joint); same seed, same logs.
    progress : show a progress bar (only on a terminal).
    duration_scale : multiplies every duration of the recipe (plateaus, ramps, cycles), e.g. 0.01 in tests.
    joints : names of joints to simulate (default: the recipe's ``joints`` or all).

    Truth: ``truth['segment']`` (kind per sample), ``truth['cycle']`` (-1 outside duty cycles),
    ``truth['params']`` (true parameters), ``truth['temp_joint']`` [degC], ``truth['friction']`` [F],
    ``truth['velocity']``, ``truth['position']``, ``truth['bristle']`` (true states).
    """
    if not duration_scale > 0:
        raise ConfigError(f"duration_scale must be > 0, got {duration_scale}")
    rec, base = load_recipe(recipe)
    if plant is None:
        plant = resolve_plant_path(rec.default_plant, base)
    pl = load_plant(plant)
    names = joints or rec.joints or [j.name for j in pl.joints]
    sel = [pl.joint(nm) for nm in names]
    seeds = np.random.SeedSequence(seed).spawn(len(sel))
    bar = _progress_bar(progress, len(sel))
    logs = []
    try:
        for j, ss in zip(sel, seeds):
            logs.append(simulate_joint_program(pl, j, rec, ss, duration_scale))
            if bar:
                bar[0].advance(bar[1])
    finally:
        if bar:
            bar[0].stop()
    return logs
