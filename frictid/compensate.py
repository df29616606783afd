"""Compensation what-if: the plant's closed loop on a tracking recipe, with and without friction
feed-forward, judged as the papers judge a friction model (tracking error, stick-slip).

Runs, per joint (:data:`RUNS`):

- ``none``: the plant's own controller, no friction compensation;
- ``model``: the identified model as feed-forward, ``FrictionModel.simulate`` along the reference velocity
  (its bristle state, its thermal law driven by the ambient temperature, its position/load/drift terms
  along the reference); a thermal law that reads a measured joint temperature gets the joint
  temperature of the ``none`` run;
- ``measured``: the identified model's static map (its steady state, at the model's reference temperature)
  as feed-forward from the *measured* velocity, low-passed a decade above the loop's natural frequency
  (:data:`MEASURED_BAND`; the observer's gain below) inside the plant's control loop, instead of the reference (the issue's other
  velocity source: what a controller without a planned trajectory would do); position, load and drift
  terms are left out;
- ``observer``: the LuGre friction observer of the seed 000 (Canudas de Wit et al. 1995, eq. 17) built on
  the identified LuGre model, run at the controller rate on the measured velocity and the tracking error
  (``dz/dt = w - sigma0 |w| z / g(w) - k e``, ``F = sigma0 z + sigma1 dz/dt + f(w)``, integrated exactly
  per step), its estimate added to the controller's torque; the gain ``k`` is the loop's natural
  frequency (``sqrt(kp / J)``, or ``kv / J`` for a velocity loop, J the identified inertia). Only for a
  model with a presliding stiffness (``sigma0`` identified): otherwise the run is left out and
  :func:`compensation_runs` says why;
- ``true``: the plant's true friction along the reference, the same feed-forward with perfect knowledge
  (the ideal this structure of compensation can reach).

The feed-forward enters only where the recipe runs the loop closed; torque-mode stretches are left as
they are. Every run uses the same sensor noise (the same seed), so the differences are the compensation's.

Metrics (:class:`RunMetrics`) over the closed-loop samples, on the true position: RMS and peak tracking
error, the RMS error where the reference moves at constant velocity (the steady state of a ramp), and
stick episodes: stretches of at least :data:`STICK_MIN_S` seconds (and five samples) where the
reference moves but the joint stands (``|w| < STICK_FRACTION |qd_ref|``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .errors import FrictidInputError
from .model import FrictionModel
from .models.replay_kernel import replay_friction
from .plant.config import load_plant, load_recipe, resolve_plant_path
from .plant.kernel import (MODE_TORQUE, P_C, P_J, P_K, P_KP, P_KV, P_PAMP, P_PPER, P_PPH, P_S0N, P_S0P, P_S1N,
                           P_S1P)
from .plant.simulate import kernel_inputs, prepare_joint, simulate_joint

RUNS = ("none", "model", "measured", "observer", "true")
STICK_FRACTION = 0.1
STICK_MIN_S = 0.02


@dataclass
class RunMetrics:
    """Tracking of one run [q]: rms_error, peak_error, steady_error (RMS on constant-velocity reference
    stretches, None without any), stick_slip_episodes (count), stick_seconds (their total duration)."""

    rms_error: float
    peak_error: float
    steady_error: float | None
    stick_slip_episodes: int
    stick_seconds: float

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class Run:
    """One closed-loop run: the samples (T: the joint temperature [degC]; part: the index of the recipe's
    experiment each sample belongs to) and their metrics."""

    name: str
    t: np.ndarray
    q_ref: np.ndarray
    q: np.ndarray
    w: np.ndarray
    u: np.ndarray
    ff: np.ndarray
    T: np.ndarray
    metrics: RunMetrics
    part: np.ndarray
    closed: np.ndarray
    qd_ref: np.ndarray

    def metrics_from(self, first_part: int) -> RunMetrics:
        """The metrics over the recipe's experiments from ``first_part`` on (e.g. the tracking after a
        warm-up experiment)."""
        sel = self.closed & (self.part >= first_part)
        return run_metrics(self.t, self.q_ref, self.qd_ref, self.q, self.w, sel)


def stick_episodes(t, w, qd_ref, closed) -> tuple[int, float]:
    """Count and total duration [s] of the stretches where the reference moves and the joint stands."""
    moving = closed & (np.abs(qd_ref) > 1e-3 * max(float(np.max(np.abs(qd_ref))), 1e-300))
    stuck = (moving & (np.abs(w) < STICK_FRACTION * np.abs(qd_ref))).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.r_[0, stuck, 0]))
    h = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    n_min = max(5, int(np.ceil(STICK_MIN_S / h))) if h > 0 else 5
    lengths = [i1 - i0 for i0, i1 in zip(edges[::2], edges[1::2]) if i1 - i0 >= n_min]
    return len(lengths), float(sum(lengths) * h)


def run_metrics(t, q_ref, qd_ref, q, w, closed) -> RunMetrics:
    e = (q_ref - q)[closed]
    qdd = np.gradient(qd_ref, t)
    ramp = closed & (np.abs(qd_ref) > 0) & (np.abs(qdd) <= 1e-9 * max(float(np.max(np.abs(qdd))), 1e-300))
    count, seconds = stick_episodes(t, w, qd_ref, closed)
    return RunMetrics(rms_error=float(np.sqrt(np.mean(e**2))) if e.size else 0.0,
                      peak_error=float(np.max(np.abs(e))) if e.size else 0.0,
                      steady_error=float(np.sqrt(np.mean((q_ref - q)[ramp] ** 2))) if ramp.any() else None,
                      stick_slip_episodes=count, stick_seconds=seconds)


def model_feedforward(m: FrictionModel, t, prog, T_joint=None) -> np.ndarray:
    """The identified model's friction along the reference (q_ref, qd_ref) of a compiled program."""
    q_ref, qd_ref = prog["q_ref"], prog["qd_ref"]
    qdd = np.gradient(qd_ref, t)
    payload = prog["payload"] if np.any(prog["payload"] != 0) else None
    load = np.abs(m.J * qdd + m.gravity(q_ref, payload) - m.offset)
    thermal = m.thermal or {}
    if thermal and (thermal.get("C") is None or thermal.get("K") is None):
        F, _, _ = m.simulate(t, qd_ref, T=T_joint, q=q_ref, load=load, payload=payload)
    else:
        F, _, _ = m.simulate(t, qd_ref, Tenv=prog["temp_env"], q=q_ref, load=load, payload=payload)
    return F


def true_feedforward(plant, joint, t, prog, args) -> np.ndarray:
    """The plant's true friction along the reference: its canonical map, bristles, thermal law (heat
    balance from the ambient) and position effect, as the replay kernel evaluates them."""
    p, c_pos, c_neg, dc9, code, theta, _, _ = kernel_inputs(plant, joint)
    gmul = np.broadcast_to(args["gmul"], t.shape).astype(float)
    if p[P_PAMP]:
        gmul = gmul * (1.0 + p[P_PAMP] * np.sin(2 * np.pi / p[P_PPER] * prog["q_ref"] + p[P_PPH]))
    thermal = None
    if code:
        thermal = {"code": code, "theta": theta, "dc_pos": dc9, "dc_neg": dc9, "C": p[P_C], "K": p[P_K],
                   "Tenv": prog["temp_env"], "T_init": float(prog["temp_env"][0])}
    F, _, _ = replay_friction(t, prog["qd_ref"], c_pos, c_neg, gmul=gmul, fmul=args["fmul"],
                              sigma0=(p[P_S0P], p[P_S0N]), sigma1=(p[P_S1P], p[P_S1N]), thermal=thermal)
    return F


def plant_friction_model(plant, joint) -> FrictionModel:
    """A plant joint's own friction (its canonical map, bristles and thermal law; hidden effects left out)
    as a :class:`~frictid.model.FrictionModel`: what a perfect identification would return."""
    p, c_pos, c_neg, dc9, code, theta, _, _ = kernel_inputs(plant, joint)
    m = FrictionModel(name="plant", map="stribeck_2exp_asym", c_pos=c_pos, c_neg=c_neg, J=joint.J,
                      joint=joint.name, sigma0=(p[P_S0P], p[P_S0N]), sigma1=(p[P_S1P], p[P_S1N]))
    if code:
        law = {1: "thermal4", 2: "thermal6", 3: "exponential"}[code]
        m.thermal = {"law": law, "alpha": theta[0], "beta": theta[1], "lam": theta[2], "T0": theta[3],
                     "dc": [dc9[i] for i in (0, 6, 7, 8)], "C": p[P_C], "K": p[P_K]}
    return m


def _loop_frequency(m: FrictionModel, args) -> float:
    """The closed loop's natural frequency [rad/s]: ``sqrt(kp / J)``, or ``kv / J`` for a velocity loop, J
    the identified inertia (the plant's where the model has none)."""
    p = args["p"]
    J = m.J if m.J and m.J > 0 else p[P_J]
    return float(np.sqrt(p[P_KP] / J)) if p[P_KP] > 0 else float(p[P_KV] / J)


def _map_at_reference(m: FrictionModel):
    """The model's canonical map vectors at its reference temperature (the map alone where it has no law)."""
    return m.canonical_at(m.thermal["T0"]) if m.thermal else (m.c_pos, m.c_neg)


def observer_of(m: FrictionModel, args) -> tuple | None:
    """The friction observer's settings for the plant kernel (gain, sigma0, sigma1 and the map's canonical
    vectors at the model's reference temperature), or None for a model without a presliding stiffness."""
    if m.sigma0 is None or not all(np.isfinite(m.sigma0)) or min(m.sigma0) <= 0:
        return None
    cp, cn = _map_at_reference(m)
    return _loop_frequency(m, args), tuple(m.sigma0), tuple(m.sigma1 or (0.0, 0.0)), cp, cn


#: The measured velocity's low-pass sits this far above the loop's natural frequency (a decade: its lag
#: there is about 6 degrees, so the filter does not reshape the loop; at the loop's own frequency its lag
#: cost the direct drive's joint 2 two thirds of its reduction on tracking_lv and left 4 stick episodes).
MEASURED_BAND = 10.0


def measured_of(m: FrictionModel, args) -> tuple:
    """The kernel's settings of the static map fed forward from the measured velocity: the observer's slot
    with no presliding stiffness (the kernel then evaluates the map at the measured velocity, low-passed at
    MEASURED_BAND times the loop's natural frequency)."""
    cp, cn = _map_at_reference(m)
    return MEASURED_BAND * _loop_frequency(m, args), (0.0, 0.0), (0.0, 0.0), cp, cn


def _run(name, args, t, prog, ff, closed, observer=None) -> Run:
    a = dict(args, tau_ff=np.where(closed, prog["tau_ff"] + ff, prog["tau_ff"]))
    q, w, _, _, T, u, _, _ = simulate_joint(**a, observer=observer)
    return Run(name, t, prog["q_ref"], q, w, u, ff, T, run_metrics(t, prog["q_ref"], prog["qd_ref"], q, w, closed),
               np.broadcast_to(prog["run"], t.shape), closed, prog["qd_ref"])


def compensation_runs(models: dict[str, FrictionModel], recipe, plant=None, seed: int = 0,
                      duration_scale: float = 1.0) -> dict[str, dict[str, Run]]:
    """The runs of :data:`RUNS` for each joint of ``models`` (joint name -> identified model) on the
    recipe's plant (or ``plant``)."""
    rec, base = load_recipe(recipe)
    pl = load_plant(plant if plant is not None else resolve_plant_path(rec.default_plant, base))
    names = {j.name for j in pl.joints}
    missing = [j for j in models if j not in names]
    if missing:
        raise FrictidInputError(f"plant {pl.name}: no joint {', '.join(missing)} (its joints: "
                                f"{', '.join(sorted(names))}); compensate the plant the parameters were "
                                "identified on, or give it with --plant")
    seeds = np.random.SeedSequence(seed).spawn(len(pl.joints))
    out = {}
    for joint, ss in zip(pl.joints, seeds):
        if joint.name not in models:
            continue
        prog, args, ex = prepare_joint(pl, joint, rec, ss, duration_scale)
        t = ex["t"]
        closed = np.broadcast_to(prog["mode"] != MODE_TORQUE, t.shape)
        runs = {"none": _run("none", args, t, prog, np.zeros_like(t), closed)}
        m = models[joint.name]
        runs["model"] = _run("model", args, t, prog, model_feedforward(m, t, prog, runs["none"].T), closed)
        runs["measured"] = _run("measured", args, t, prog, np.zeros_like(t), closed, measured_of(m, args))
        obs = observer_of(m, args)
        if obs is not None:
            runs["observer"] = _run("observer", args, t, prog, np.zeros_like(t), closed, obs)
        runs["true"] = _run("true", args, t, prog, true_feedforward(pl, joint, t, prog, args), closed)
        out[joint.name] = runs
    return out
