"""Replay: what an identified model predicts along a measured log, and what it gets wrong.

:func:`joint_model` turns one model of a parameter file (any of ``models:``, the chosen one by default)
into a :class:`ReplayModel`: canonical static vectors, LuGre stiffness and damping, a thermal law, the
rigid-body terms (inertia, gravity, offset) and the diagnosis extensions (position, load, drift, offset).
:func:`replay` then runs it along a :class:`~frictid.data.JointLog`:

- ``F_model``: friction along the measured velocity (LuGre state integrated along it, the thermal state
  along the predicted friction power), by the compiled kernel of :mod:`frictid.models.replay_kernel`.
  Within :data:`STICK_NOISE` velocity noise levels of zero every model follows Karnopp's stick law (the
  friction balances the net applied torque, up to the level); LuGre's bristles there follow the measured
  velocity, and where the joint stands (:func:`~frictid.models.replay_kernel.standing`: still on every
  sample within the acceleration filter's window) they carry the load that torque puts on them, so motion
  resumes from the rest's load, not from the last motion's state; a log that starts sliding starts them in
  the steady state of that motion (a cut from a longer recording does not start with unloaded bristles);
- ``tau_model = J a + G(q) + offset + F_model`` and the residual ``tau - tau_model``;
- optionally (:func:`closed_loop`) the closed loop re-simulated with the identified model, the log's
  references and a known controller, giving the simulated motion ``q_model``.

The extension multipliers are functions of measured quantities only (:func:`level_multiplier`), the same
functions the diagnosis fits with, so that what :mod:`frictid.diagnose` measures is what replay predicts.
Numbers only: no files, no pandas. True plant parameters (``JointLog.truth``) are never read.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

from .data import JointLog, finite
from .errors import ConfigError, FrictidInputError
from .model import (EXTENSION_PARAMS, FrictionModel, drift_factor, load_factor, position_factor,
                    rigid_torque)
from .models import static as sm
from .models.replay_kernel import replay_friction, standing

#: The channels only :func:`closed_loop` reads: the references and the feedforward torque.
REFERENCE_CHANNELS = ("q_ref", "qd_ref", "tau_ref")

#: The identified model is :class:`frictid.model.FrictionModel`; ``ReplayModel`` is its former name.
ReplayModel = FrictionModel

__all__ = ["FrictionModel", "ReplayModel", "ReplayResult", "joint_model", "replay", "closed_loop", "replay_logs",
           "controller_from_meta", "log_start_time", "thermal_input", "rigid_torque",
           "position_factor", "load_factor", "drift_factor", "EXTENSION_PARAMS", "REFERENCE_CHANNELS"]


def log_start_time(log: JointLog) -> float | None:
    """Recording start of a log [s since the epoch] from metadata ``start_time`` / ``recorded_at``
    (a number of seconds or an ISO 8601 date-time), or None."""
    for key in ("start_time", "recorded_at"):
        v = (log.meta or {}).get(key)
        if v is None:
            continue
        if isinstance(v, (int, float)):
            return float(v)
        if isinstance(v, datetime):
            return v.timestamp()
        try:
            return datetime.fromisoformat(str(v).replace("Z", "+00:00")).timestamp()
        except ValueError:
            continue
    return None


# ---------------------------------------------------------------------------------------------------
# From the parameter file


def joint_model(jf, name: str | None = None) -> FrictionModel:
    """The :class:`~frictid.model.FrictionModel` of model ``name`` (default: the selected one) of a joint's
    fit (:class:`frictid.result.JointFit`): :meth:`FrictionModel.from_joint`."""
    return FrictionModel.from_joint(jf, name)


# ---------------------------------------------------------------------------------------------------
# Replay along a log

#: A static model's stick zone: |w| up to this many velocity noise levels (Karnopp).
STICK_NOISE = 5.0


@dataclass
class ReplayResult:
    """Per-sample output of :func:`replay` (one value per log sample).

    F_model [F] friction, tau_model [F] torque, tau [F] the measured torque, z [q] bristle deflection,
    T [degC] joint temperature (NaN without a thermal law), w, a [q/s, q/s^2] the velocity and
    acceleration used; q_model, qd_model, tau_cmd from :func:`closed_loop` (None unless it ran).
    ``residual`` [F] = tau - tau_model is formed when first read (kept then): a caller that needs the
    model torque alone (the report's replays) never holds a third array of the log's length.
    """

    F_model: np.ndarray
    tau_model: np.ndarray
    tau: np.ndarray
    z: np.ndarray
    T: np.ndarray
    w: np.ndarray
    a: np.ndarray
    q_model: np.ndarray | None = None
    qd_model: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)

    @functools.cached_property
    def residual(self) -> np.ndarray:
        return self.tau - self.tau_model

    @property
    def rms(self) -> float:
        r = self.residual[np.isfinite(self.residual)]
        return float(np.sqrt(np.mean(r * r))) if r.size else math.nan


def thermal_input(model: FrictionModel, log: JointLog, n: int) -> dict | None:
    """The thermal dict of :func:`frictid.models.replay_kernel.replay_friction` for a log, or None: the log's
    ``temp_joint`` for a law identified on it, else the heat balance from its ``temp_env``
    (:meth:`FrictionModel.thermal_input`)."""
    if not model.thermal:
        return None
    if model.thermal.get("source") == "temp_joint":
        if "temp_joint" not in log.channels:
            raise FrictidInputError(f"{log.source or 'log'}: joint {log.joint}: model {model.name} reads the "
                                    "joint temperature, but the log has no temp_joint column")
        return model.thermal_input(n, T=log.channels["temp_joint"])
    return model.thermal_input(n, Tenv=log.channels.get("temp_env"))


def stands(w: np.ndarray, sc) -> np.ndarray:
    """Where the joint stands along the velocity ``w`` of a log of scales ``sc``
    (:func:`~frictid.models.replay_kernel.standing` within :data:`STICK_NOISE` velocity noise levels of rest,
    over half the acceleration filter's window either side): where LuGre's bristles carry the load the
    applied torque puts on them, in the replay and in the fit that identifies them from the reversals."""
    return standing(w, STICK_NOISE * sc.sigma_w, sc.window_a // 2)


def replay(log: JointLog, model: FrictionModel, w=None, a=None, t_offset: float | None = None,
           scales=None, G=None) -> ReplayResult:
    """Predicted friction and torque of ``model`` along ``log`` (one value per sample).

    w, a : velocity [q/s] and acceleration [q/s^2] to use (default: :func:`frictid.segments.derivatives`,
    as the fit uses them). t_offset [s] : where the log starts on the drift clock (default: its metadata
    ``start_time`` when the model was identified with one, else 0). scales : the log's
    :class:`frictid.segments.Scales` when the caller has them; measured only when needed (for the
    derivatives, and for the stick zone). G [F] : ``model.gravity`` along the log when the
    caller has it (models of one joint share it); not modified.
    """
    sc = scales
    if w is None or a is None:
        from .segments import derivatives, estimate_scales
        sc = sc or estimate_scales(log)
        w0, a0 = derivatives(log, sc)
        w = w0 if w is None else w
        a = a0 if a is None else a
    w = np.asarray(w, dtype=float)
    a = np.asarray(a, dtype=float)
    wf, af = finite(w), finite(a)
    n = log.n
    notes = []
    payload = log.channels.get("payload")
    q = None if log.q is None else np.asarray(log.q, dtype=float)
    if G is None:
        G = model.gravity(q, payload) if q is not None else np.full(n, model.offset)
    if q is None and (model.Px or model.Py):
        notes.append("velocity-only log: gravity not applied")
    if t_offset is None:
        start = log_start_time(log)
        t_offset = (start if (start is not None and model.ext.get("drift_t0")) else 0.0)
    t_abs = log.t + t_offset if model.ext.get("drift_per_hour") else None
    G_ext = None
    if q is not None and (model.ext.get("load_torque") or model.ext.get("load_gravity")):
        G_ext = G - model.offset
    gmul, fmul = model.multipliers(t_abs, q, af, payload, G_ext)
    th = thermal_input(model, log, n)
    sig0 = model.sigma0
    off = model.ext.get("tau_offset", 0.0)
    tau = np.asarray(log.tau, dtype=float)
    Ja = model.J * af
    # Karnopp's stick zone: the net applied torque, within STICK_NOISE velocity noise levels of rest
    # (LuGre's bristles there hold the deflection that torque loads them with)
    if sc is None:
        from .segments import estimate_scales
        sc = estimate_scales(log)
    u_net = tau - Ja
    u_net -= G
    u_net -= off
    w_stick = STICK_NOISE * sc.sigma_w
    hold = stands(wf, sc) if sig0 is not None else None
    # the friction is written over the net torque, read sample by sample before it
    F, z, T = replay_friction(log.t, wf, model.c_pos, model.c_neg, gmul=gmul, fmul=fmul, thermal=th,
                              sigma0=sig0, sigma1=model.sigma1 if sig0 is not None else 0.0, z0="steady",
                              u_stick=u_net, w_stick=w_stick, hold=hold, out=u_net)
    del u_net
    if off:
        F += off
    tau_model = Ja
    tau_model += G
    tau_model += F
    return ReplayResult(F_model=F, tau_model=tau_model, tau=tau, z=z, T=T, w=w, a=a,
                        notes=notes)


# ---------------------------------------------------------------------------------------------------
# Closed loop


def controller_from_meta(meta: dict) -> dict | None:
    """Controller gains from log metadata ``control: {kp, kd, ki}`` (position PID) or ``{kv, kvi}``
    (velocity PI), with optional ``type`` (``position`` / ``velocity``) and ``tau_max``; None when absent."""
    c = (meta or {}).get("control")
    if not isinstance(c, dict):
        return None
    out = {}
    for k in ("kp", "kd", "ki", "kv", "kvi", "tau_max"):
        if c.get(k) is not None:
            try:
                out[k] = float(c[k])
            except (TypeError, ValueError):
                raise FrictidInputError(f"log metadata control.{k}: not a number ({c[k]!r})") from None
    if not out:
        return None
    out["type"] = str(c.get("type") or ("velocity" if "kv" in out and "kp" not in out else "position"))
    return out


def closed_loop(log: JointLog, model: FrictionModel, gains: dict, rigid_stiffness: float | None = None,
                a=None, G=None, velocity: bool = True) -> tuple[np.ndarray, np.ndarray | None, list[str]]:
    """Re-simulate the closed loop with the identified model; returns (q_model, qd_model, notes).

    The log's ``q_ref`` (``qd_ref`` and ``tau_ref`` as feedforward when present) drive the controller
    ``gains`` (``kp, kd, ki`` position PID or ``kv, kvi`` velocity PI, ``type``, ``tau_max``) on the plant
    kernel of :mod:`frictid.plant.kernel`, at the log's median sample period, noise-free, from the log's
    first measured position. A static model runs with stiff, critically damped bristles (presliding
    displacement 1e-6 of the position scale), which reproduces its steady state. ``a``: the measured
    acceleration [q/s^2] when the caller has it (default: :func:`frictid.segments.derivatives`); ``G``:
    ``model.gravity`` along the measured position when the caller has it. ``velocity=False``: qd_model is
    None (not kept: the simulation then touches two arrays of the log's length instead of eight).
    """
    from .plant.kernel import (MODE_PID, MODE_VEL, N_P, P_C, P_GOFF, P_J, P_K, P_KD, P_KI, P_KP, P_KV, P_KVI,
                               P_PAMP, P_PAY, P_PPER, P_PPH, P_PX, P_PY, P_S0N, P_S0P, P_S1N, P_S1P, P_TMAX,
                               simulate_joint)
    notes = []
    if "q_ref" not in log.channels:
        raise FrictidInputError(f"joint {log.joint}: closed-loop replay needs a q_ref column")
    if model.J <= 0:
        raise FrictidInputError(f"joint {log.joint}: closed-loop replay needs a positive inertia in the model")
    n = log.n
    h = log.dt
    q_ref = np.asarray(log.channels["q_ref"], dtype=float)
    qd_ref = np.asarray(log.channels["qd_ref"] if "qd_ref" in log.channels else np.gradient(q_ref, log.t),
                        dtype=float)
    tau_ff = np.asarray(log.channels["tau_ref"] if "tau_ref" in log.channels else np.zeros(n), dtype=float)
    velocity_loop = gains.get("type") == "velocity"
    # what is the same for every sample goes in one value long (the kernel holds it): the controller's
    # mode, no payload, no temperature reset, no sensor noise, constant multipliers and ambient
    mode = np.full(1, MODE_VEL if velocity_loop else MODE_PID, dtype=np.int64)
    pay_in = log.channels.get("payload")
    payload = np.zeros(1) if pay_in is None else np.asarray(pay_in, dtype=float)
    ext = model.ext
    p = np.zeros(N_P)
    p[P_J] = model.J
    q_scale = float(np.ptp(log.q)) if log.q is not None and n else 1.0
    g_max = float(np.max(np.abs(sm.canonical_level(np.array([0.0]), model.c_pos)))) or 1.0
    if model.sigma0 is not None:
        p[P_S0P], p[P_S0N] = model.sigma0
        p[P_S1P], p[P_S1N] = model.sigma1
    else:
        s0 = rigid_stiffness or g_max / max(1e-6 * max(q_scale, 1e-9), 1e-15)
        s1 = 2.0 * math.sqrt(s0 * model.J)
        p[P_S0P] = p[P_S0N] = s0
        p[P_S1P] = p[P_S1N] = s1
        notes.append(f"static model: stiff bristles sigma0 = {s0:.3g}, critically damped, in the closed loop")
    p[P_PX], p[P_PY], p[P_GOFF] = model.Px, model.Py, model.offset + ext.get("tau_offset", 0.0)
    p[P_TMAX] = gains.get("tau_max", 1e300)
    for key, idx in (("kp", P_KP), ("kd", P_KD), ("ki", P_KI), ("kv", P_KV), ("kvi", P_KVI)):
        p[idx] = gains.get(key, 0.0)
    # position (periodic) and load (|u|) act inside the kernel; the rest through gmul/fmul
    if ext.get("pos_amp"):
        p[P_PAMP], p[P_PPER], p[P_PPH] = ext["pos_amp"], ext["pos_period"], ext.get("pos_phase", 0.0)
    sub = dict(ext)
    for k in ("pos_amp", "tau_offset"):
        sub.pop(k, None)
    side = ReplayModel(**{**model.__dict__, "ext": sub})
    q_meas = np.asarray(log.q if log.q is not None else q_ref, dtype=float)
    G_meas = None  # the gravity torque without the offset: only the load extensions read it
    if ext.get("load_torque") or ext.get("load_gravity") or ext.get("load_payload"):
        G_meas = (model.gravity(q_meas, pay_in) if G is None or log.q is None else G) - model.offset
    if model.Mx and model.axis == "rotary":
        p[P_PAY] = model.Mx  # the kernel's payload gravity: m P_PAY cos q
    if model.My or (model.Mx and model.axis != "rotary"):
        notes.append("closed loop: payload gravity other than Mx m cos q is not simulated")
    if ext.get("rip_period"):
        notes.append("closed loop: the torque ripple that follows the position is not simulated")
    start = log_start_time(log)
    t_off = start if (start is not None and ext.get("drift_t0")) else 0.0
    if a is None:
        from .segments import derivatives
        _, a = derivatives(log)
    a_meas = np.asarray(a, dtype=float)
    t_abs = log.t + t_off if ext.get("drift_per_hour") else None  # the drift clock, only when it acts
    gmul, fmul = (np.ascontiguousarray(m, dtype=float)  # length 1 when the same for every sample
                  for m in side.multipliers(t_abs, q_meas, a_meas, pay_in, G_meas))
    th = thermal_input(model, log, n)
    if th is not None:
        if "T" in th:
            notes.append("closed loop: the thermal law reads temp_joint, which the kernel cannot; thermal "
                         "part held at the first temperature")
            code, theta, dc9 = th["code"], th["theta"], th["dc_pos"]
            Tenv = np.full(1, float(th["T"][0]))
            C, K = 1e300, 1.0
        else:
            code, theta, dc9 = th["code"], th["theta"], th["dc_pos"]
            Tenv, C, K = th["Tenv"], th["C"], th["K"]
        p[P_C], p[P_K] = C, K
    else:
        code, theta, dc9 = 0, np.zeros(4), np.zeros(9)
        Tenv = np.full(1, 25.0)
        p[P_C], p[P_K] = 1.0, 1.0
    w0 = float(log.qd[0]) if log.qd is not None else 0.0
    state0 = np.array([float(q_meas[0]), w0, 0.0, float(Tenv[0])])
    zero = np.zeros(1)
    out = simulate_joint(h=h, nsub=1, mode=mode, q_ref=q_ref, qd_ref=qd_ref, tau_ff=tau_ff,
                         Tenv=np.ascontiguousarray(Tenv, dtype=float), payload=payload,
                         reset_T=np.zeros(1, dtype=np.bool_), gmul=gmul, fmul=fmul, nq=zero, nqd=zero, p=p,
                         c_pos=model.c_pos, c_neg=model.c_neg, dc_pos=dc9, dc_neg=dc9, th_code=code,
                         theta=theta, state0=state0, outputs=("q", "w") if velocity else ("q",))
    q_model, qd_model = out[0], out[1]
    if velocity_loop:
        notes.append("velocity PI loop on qd_ref")
    return q_model, qd_model, notes


# ---------------------------------------------------------------------------------------------------
# The command's pipeline


def replay_logs(logs: list[JointLog], result, model: str | None = None, plant=None,
                closed: bool | None = None) -> tuple[list[ReplayResult], dict]:
    """Replay every joint log with its joint's model from a parameter file.

    logs : joint logs (from :func:`frictid.io.logs.read_logs`). result : a
    :class:`frictid.result.FitResult`. model : model name (default: each joint's ``selected``).
    plant : a plant (path, name or loaded) whose joints' controllers close the loop. closed : force the
    closed-loop re-simulation on (True: an error when impossible) or off (False); None: whenever the log
    has ``q_ref`` and a controller is known (the plant, or ``control:`` gains in the log's metadata).

    Returns (results, info) with info = per joint the model used, the residual RMS and notes.
    """
    pl = None
    if plant is not None:
        from .plant import load_plant
        pl = load_plant(plant)
    out, info = [], {}
    for lg in logs:
        j = str(lg.joint)
        if j not in result.joints:
            raise FrictidInputError(f"joint {j} of the log is not in the parameter file (joints: "
                                    + ", ".join(result.joints) + ")")
        jf = result.joints[j]
        if jf.axis != lg.axis:
            raise FrictidInputError(f"joint {j}: the log is {lg.axis} but the parameter file is {jf.axis}")
        m = joint_model(jf, model)
        r = replay(lg, m)
        gains = None
        if pl is not None:
            try:
                from .plant.simulate import controller_gains
                pj = pl.joint(j)
                gains = dict(controller_gains(pj), type="position", tau_max=float(pj.limits.torque))
            except ConfigError:
                gains = None
        gains = gains or controller_from_meta(lg.meta)
        can = "q_ref" in lg.channels and gains is not None and m.J > 0
        if closed and not can:
            why = ("no q_ref column" if "q_ref" not in lg.channels else
                   "no controller (give --plant, or control: gains in the log metadata)" if gains is None
                   else "no positive inertia in the model")
            raise FrictidInputError(f"joint {j}: cannot re-simulate the closed loop: {why}")
        if can and closed is not False:
            r.q_model, r.qd_model, notes = closed_loop(lg, m, gains)
            r.notes.extend(notes)
        rec = {"model": m.name, "rms_residual": r.rms, "closed_loop": r.q_model is not None}
        if r.q_model is not None and lg.q is not None:
            rec["rms_q_error"] = float(np.sqrt(np.mean((np.asarray(lg.q) - r.q_model) ** 2)))
        if r.notes:
            rec["notes"] = list(r.notes)
        info[j] = rec
        out.append(r)
    return out, info
