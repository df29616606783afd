"""Rigid-body base parameters and each joint's friction, identified jointly from multi-joint motion.

``tau_j = Y_base(q, qd, qdd)_j beta + fv_j qd_j + fc_j sgn(qd_j) + fo_j`` for every joint j, by weighted
least squares (Gaz et al. 2019, "classical" identification; Gautier's base parameters):

1. the joints' logs on one time base (a non-uniform one resampled to its median period);
2. position and velocity low-passed, zero phase, with the cut-off from the data: ten times the frequency
   below which 99 % of the velocity's spectral energy lies (at most 0.4 of the sample rate); acceleration
   is the derivative of the filtered velocity;
3. the regressor built at every sample, then *parallel filtering* (Gautier): every regressor column and the
   measured torque pass the same low-pass filter and are decimated to five samples per cut-off period, so
   the torque and the model stay comparable across the friction's sign changes;
4. ordinary least squares, then rows weighted by each joint's residual standard deviation, and solved
   again; standard errors from the weighted fit, widened by the residuals' correlation in time (each
   joint's lag-one autocorrelation rho: factor ``(1 + rho) / (1 - rho)`` on the variance, the effective
   number of independent samples);
5. the condition number of the weighted regressor with its columns scaled to unit norm, and the relative
   torque error ``||tau - Y pi|| / ||tau||`` on the samples used; :func:`heldout_errors` predicts a
   held-out tail.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import butter, sosfiltfilt

from ..errors import ConfigError
from ..parallel import one_blas_thread
from ..result import ParamEstimate
from .description import Robot
from .feasibility import feasibility_note, nearest_consistent
from .hold import hold_level, hold_torque, last_sign
from .regressor import BaseParameters, base_parameters, full_regressor, rigid_torque

FRICTION = ("fv", "fc", "fo")
#: Above this condition number (columns scaled to unit norm) the excitation does not separate the
#: parameters: every estimate is marked not identifiable.
COND_LIMIT = 1000.0


@dataclass
class RobotData:
    """The joints' signals on one uniform time base: t [s], q, qd, qdd (filtered), tau (as measured),
    (n, nv); cutoff [Hz] of the filter; step: the decimation after parallel filtering."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    cutoff: float
    step: int = 1
    #: per joint, the speed [rad/s] below which the joint counts as standing still (velocity noise)
    still: np.ndarray | None = None

    def moving(self) -> np.ndarray:
        """(n, nv) True where a joint moves: its friction has a sign."""
        return np.abs(self.qd) > (0.0 if self.still is None else self.still)


@dataclass
class RobotFit:
    base_names: list[str]
    base: list[ParamEstimate]
    friction: dict[str, dict[str, ParamEstimate]]
    condition: float
    rel_error: float
    rms_per_joint: dict[str, float]
    cutoff_hz: float
    n_samples: int
    #: the estimate vector [base | fv fc fo per joint] and the base parameters' definition (for predict)
    x: np.ndarray | None = None
    bp: BaseParameters | None = None
    #: the base parameters' covariance (the physical-consistency check weighs departures by it)
    base_cov: np.ndarray | None = None
    #: what the checks found (excitation, friction signs, physical feasibility), one sentence each
    notes: list[str] = field(default_factory=list)
    #: per joint, the speeds [rad/s] and positions [rad] the moving samples covered ([lo, hi] each)
    validity: dict[str, dict[str, list[float]]] = field(default_factory=dict)
    #: where the rigid body came from: {"mode": "identify"} (the base parameters above) or {"mode": "known",
    #: ...} (the robot description's own inertial parameters, :mod:`.known`; then ``bp`` is None and ``x``
    #: holds the friction only)
    rigid: dict = field(default_factory=lambda: {"mode": "identify", "source": "the base parameters identified "
                                                                         "from the logs (base_parameters)"})


def align(robot: Robot, logs) -> tuple[np.ndarray, list]:
    """The logs in the robot's joint order on the first log's time base (others interpolated)."""
    by = {str(lg.joint): lg for lg in logs}
    missing = [j for j in robot.joints if j not in by]
    if missing:
        raise ConfigError(f"robot {robot.name}: no log for joint {', '.join(missing)} (logs: {', '.join(by)}); "
                          "name the log's joints as the robot's; a log of one joint moved alone needs the standing "
                          "joints' angles too (its pose): map every joint's columns, docs/robots.md")
    extra = [j for j in by if j not in robot.joints]
    if extra:
        raise ConfigError(f"robot {robot.name}: the logs hold joint {', '.join(extra)}, which the robot does not "
                          f"have (its joints: {', '.join(robot.joints)}); the torque of a joint left out would "
                          "be missing from the model")
    return by[robot.joints[0]].t, [by[j] for j in robot.joints]


def _cutoff(qd: np.ndarray, fs: float) -> float:
    """Ten times the frequency holding 99 % of the velocity's spectral energy, at most 0.4 fs [Hz]."""
    f99 = 0.0
    for col in qd.T:
        p = np.abs(np.fft.rfft(col - col.mean())) ** 2
        f = np.fft.rfftfreq(col.size, 1.0 / fs)
        c = np.cumsum(p)
        if c[-1] > 0:
            f99 = max(f99, float(f[np.searchsorted(c, 0.99 * c[-1])]))
    return float(min(max(10.0 * f99, 1e-3 * fs), 0.4 * fs))


def prepare(robot: Robot, logs, cutoff: float | None = None) -> RobotData:
    """The joints' signals on one uniform time base, filtered (cut-off from the data unless ``cutoff`` [Hz]
    is given), with each joint's standing band."""
    t0, ordered = align(robot, logs)
    dt = np.diff(t0)
    h = float(np.median(dt))
    t = np.arange(t0[0], t0[-1], h)

    def col(name):
        return np.column_stack([np.interp(t, lg.t, getattr(lg, name)) for lg in ordered])
    q, tau = col("q"), col("tau")
    qd = col("qd") if all(lg.qd is not None for lg in ordered) else np.gradient(q, h, axis=0)
    fc = _cutoff(qd, 1.0 / h) if cutoff is None else float(min(cutoff, 0.4 / h))
    sos = butter(4, fc, fs=1.0 / h, output="sos")
    raw = qd
    # padded by odd extension over three periods of the cut-off: the filter's start-up transient then falls
    # outside a log that starts or ends in motion
    pad = min(q.shape[0] - 1, 3 * int(round(1.0 / (h * fc))))
    q, qd = (sosfiltfilt(sos, x, axis=0, padlen=pad) for x in (q, qd))
    qdd = np.gradient(qd, h, axis=0)
    # standing still: within five noise levels of zero (the noise: what the filter removed, robust scale)
    noise = 1.4826 * np.median(np.abs(raw - qd), axis=0)
    still = np.maximum(5.0 * noise, 1e-9)
    return RobotData(t, q, qd, qdd, tau, fc, max(1, int((1.0 / h) / (5.0 * fc))), still)


def parallel_filter(d: RobotData, A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The design matrix and torque low-passed alike (zero phase, the data's cut-off) and decimated; rows
    of a joint standing still are left out (its friction there is whatever holds it: not a law of the
    velocity), so the fit sees moving joints only. Returns (A, y, joint index of each row)."""
    n, nv = d.q.shape
    fs = 1.0 / float(np.median(np.diff(d.t)))
    sos = butter(4, d.cutoff, fs=fs, output="sos")
    A3 = sosfiltfilt(sos, A.reshape(n, nv, -1), axis=0)[::d.step]
    y2 = sosfiltfilt(sos, y.reshape(n, nv), axis=0)[::d.step]
    keep = d.moving()[::d.step].reshape(-1)
    jid = np.tile(np.arange(nv), y2.shape[0])
    return A3.reshape(-1, A.shape[1])[keep], y2.reshape(-1)[keep], jid[keep]


def friction_columns(d: RobotData) -> np.ndarray:
    """Each joint's viscous, Coulomb and offset columns: (n nv, 3 nv), rows sample-major (joint fastest)."""
    n, nv = d.q.shape
    F = np.zeros((n * nv, 3 * nv))
    mov = d.moving()
    for j in range(nv):
        rows = np.arange(n) * nv + j
        F[rows, 3 * j] = d.qd[:, j]
        F[rows, 3 * j + 1] = np.sign(d.qd[:, j]) * mov[:, j]  # at rest the friction has no sign
        F[rows, 3 * j + 2] = 1.0
    return F


def design(robot: Robot, bp: BaseParameters, d: RobotData) -> np.ndarray:
    """[Y_base | friction columns]: (n nv, n_base + 3 nv), rows sample-major (joint fastest)."""
    Y = full_regressor(robot, d.q, d.qd, d.qdd, robot.armature)[:, bp.columns]
    return np.hstack([Y, friction_columns(d)])


def _lag1(r: np.ndarray) -> float:
    r = r - r.mean()
    den = float(r @ r)
    return float(np.clip((r[1:] @ r[:-1]) / den, 0.0, 0.95)) if den > 0 else 0.0


def solve(A: np.ndarray, y: np.ndarray, jid: np.ndarray, nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """WLS with per-joint weights (jid: each row's joint); returns (x, covariance, residuals, condition
    number)."""
    x = np.linalg.lstsq(A, y, rcond=None)[0]
    r = y - A @ x
    sd = np.array([r[jid == j].std() if np.any(jid == j) else 1.0 for j in range(nv)])
    sd = np.maximum(sd, 1e-12 * np.max(np.abs(y)))
    w = 1.0 / sd[jid]
    Aw, yw = A * w[:, None], y * w
    scale = np.maximum(np.linalg.norm(Aw, axis=0), 1e-300)
    xs, *_ = np.linalg.lstsq(Aw / scale, yw, rcond=None)
    x = xs / scale
    rw = yw - Aw @ x
    infl = np.ones(nv)
    for j in range(nv):
        if np.sum(jid == j) > 2:
            rho = _lag1(rw[jid == j])
            infl[j] = (1 + rho) / (1 - rho)
    dof = max(y.size - A.shape[1], 1)
    s2 = float(np.sum((rw**2) * infl[jid])) / dof
    sv = np.linalg.svd(Aw / scale, compute_uv=False)
    cov = s2 * np.linalg.pinv((Aw / scale).T @ (Aw / scale)) / np.outer(scale, scale)
    return x, cov, y - A @ x, float(sv[0] / sv[-1])


def _errors(robot: Robot, A: np.ndarray, y: np.ndarray, x: np.ndarray, jid) -> tuple[float, dict[str, float]]:
    r = y - A @ x
    rel = float(np.linalg.norm(r) / max(np.linalg.norm(y), 1e-300))
    return rel, {j: float(np.sqrt(np.mean(r[jid == i] ** 2))) if np.any(jid == i) else float("nan")
                 for i, j in enumerate(robot.joints)}


def identify_robot(robot: Robot, logs) -> RobotFit:
    """Base parameters and per-joint Coulomb, viscous and offset friction from the joints' logs (a held-out
    prediction: :func:`heldout_errors`). BLAS on one thread (:func:`frictid.parallel.one_blas_thread`: the
    regressor is a few dozen columns; a second thread spun for most of its CPU time, 0.46 against 0.09 s CPU
    on the UR10e harmonic run, ``benchmarks/bench_robot_speed.py``)."""
    with one_blas_thread():
        return _identify(robot, logs)


def _identify(robot: Robot, logs) -> RobotFit:
    """:func:`identify_robot`'s work."""
    fit_d = prepare(robot, logs)
    bp = base_parameters(robot, robot.armature)
    A_full = design(robot, bp, fit_d)
    A, y, jid = parallel_filter(fit_d, A_full, fit_d.tau.reshape(-1))
    x, cov, _, cond = solve(A, y, jid, robot.nv)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    nb = bp.n
    names = bp.names(robot)
    base = [ParamEstimate(n, float(v), float(s), "") for n, v, s in zip(names, x[:nb], se[:nb])]
    friction = friction_estimates(robot, x, se, nb)
    _hold(friction, fit_d, fit_d.tau - (A_full @ x).reshape(fit_d.tau.shape))
    rel, rms = _errors(robot, A, y, x, jid)
    out = RobotFit(names, base, friction, cond, rel, rms, fit_d.cutoff, int(y.size), x=x, bp=bp,
                   base_cov=cov[:nb, :nb])
    out.notes = check(out, bp, robot)
    out.validity = validity(robot, fit_d)
    return out


def friction_estimates(robot: Robot, x: np.ndarray, se: np.ndarray, nb: int) -> dict[str, dict[str, ParamEstimate]]:
    """Each joint's fv, fc, fo from the estimate vector ``x`` (standard errors ``se``) after ``nb`` base
    parameters."""
    units = {"fv": "N m s/rad", "fc": "N m", "fo": "N m"}
    return {j: {k: ParamEstimate(k, float(x[nb + 3 * i + m]), float(se[nb + 3 * i + m]), units[k])
                for m, k in enumerate(FRICTION)} for i, j in enumerate(robot.joints)}


def validity(robot: Robot, d: RobotData) -> dict[str, dict[str, list[float]]]:
    """Per joint, the speeds [rad/s] and positions [rad] its moving samples covered."""
    mov, out = d.moving(), {}
    for i, j in enumerate(robot.joints):
        v, q = np.abs(d.qd[mov[:, i], i]), d.q[mov[:, i], i]
        if v.size:
            out[j] = {"speed": [float(np.quantile(v, 0.005)), float(np.quantile(v, 0.995))],
                      "position": [float(q.min()), float(q.max())]}
    return out


def _hold(friction: dict, d: RobotData, resid: np.ndarray) -> None:
    """Each joint's standstill hold ``fh`` (:mod:`.hold`) from the joint estimate's residual ``resid``
    (n, nv) at the full rate, added to its friction."""
    mov = d.moving()
    s = last_sign(d.qd, mov)
    for i, j in enumerate(friction):
        friction[j]["fh"] = hold_level(resid[:, i], s[:, i], ~mov[:, i], friction[j]["fc"])


def holds(fit: RobotFit, joints) -> np.ndarray:
    """Each joint's identified hold [N m] (0 where none is identified or the fit has none)."""
    out = np.zeros(len(joints))
    for i, j in enumerate(joints):
        p = fit.friction.get(j, {}).get("fh")
        if p is not None and p.identifiable and p.value is not None:
            out[i] = p.value
    return out


def check(fit: RobotFit, bp: BaseParameters, robot: Robot) -> list[str]:
    """Mark what the data cannot support and say so: every estimate when the excitation is too poorly
    conditioned; a base parameter with a relative standard error over 100 %; a Coulomb level or viscous
    coefficient negative by more than two standard errors (not a dissipative friction); whether some
    physically consistent set of link inertias has the identified base parameters (:mod:`.feasibility`)."""
    notes = []
    every = fit.base + [p for f in fit.friction.values() for p in f.values()]
    if fit.condition > COND_LIMIT:
        why = f"the excitation is too poorly conditioned (condition number {fit.condition:.3g} > {COND_LIMIT:g})"
        for p in every:
            p.identifiable, p.reason = False, why
        notes.append(why + ": every estimate is marked not identifiable; excite with frictid design")
    for p in fit.base:
        if p.identifiable and p.stderr is not None and abs(p.value) < p.stderr:
            p.identifiable, p.reason = False, "relative standard error over 100 %"
    for j, f in fit.friction.items():
        for k in ("fc", "fv"):
            p = f[k]
            if p.identifiable and p.value < -2.0 * p.stderr:
                p.identifiable = False
                p.reason = f"negative ({p.value:.3g} +- {p.stderr:.2g}): not a dissipative friction"
                notes.append(f"joint {j}: {k} {p.reason}")
    if fit.base_cov is not None and fit.x is not None and fit.condition <= COND_LIMIT:
        feas = nearest_consistent(bp, fit.x[:bp.n], fit.base_cov, robot.nv)
        notes.append(feasibility_note(feas, fit.base_names))
    return notes


@dataclass
class Prediction:
    """The identified model along logs, at each log's own samples, per robot joint: tau (the whole torque),
    F (the friction and offset part), qd, qdd (the filtered velocity and acceleration the model used),
    moving (True where the joint's friction has a sign) and held (the friction held at standstill, part of
    F: :mod:`.hold`)."""

    tau: dict[str, np.ndarray]
    F: dict[str, np.ndarray]
    qd: dict[str, np.ndarray]
    qdd: dict[str, np.ndarray]
    moving: dict[str, np.ndarray]
    held: dict[str, np.ndarray] = field(default_factory=dict)


def predict(robot: Robot, fit: RobotFit, logs) -> Prediction:
    """The identified model's torque along the joints' logs: positions and velocities filtered as for the
    fit on a uniform time base, the model evaluated there and read back at each log's own instants (the
    measured torque is never resampled: a prediction is judged against the torque as logged). The signals
    pass the fit's own filter (its cut-off, ``fit.cutoff_hz``): the parameters describe the torque of
    signals filtered so, and a cut-off found anew on another log (a short one, or one slowing to rest, whose
    velocity spectrum reaches further into the noise) would not match them."""
    cut = fit.cutoff_hz if fit.cutoff_hz is not None and np.isfinite(fit.cutoff_hz) and fit.cutoff_hz > 0 else None
    d = prepare(robot, logs, cut)
    nv = robot.nv
    if fit.bp is None:  # the rigid body known: the description's own inertial parameters
        nb, rigid = 0, rigid_torque(robot, d.q, d.qd, d.qdd)
        A = friction_columns(d)
    else:
        A = design(robot, fit.bp, d)
        nb = fit.bp.n
        rigid = (A[:, :nb] @ fit.x[:nb]).reshape(-1, nv)
    mov = d.moving()
    held = hold_torque(holds(fit, robot.joints), last_sign(d.qd, mov), mov)
    F = (A[:, nb:] @ fit.x[nb:]).reshape(-1, nv) + held
    tau = rigid + F
    mov = mov.astype(float)
    _, ordered = align(robot, logs)
    out = Prediction({}, {}, {}, {}, {})
    for i, (j, lg) in enumerate(zip(robot.joints, ordered)):
        for name, y in (("tau", tau), ("F", F), ("qd", d.qd), ("qdd", d.qdd), ("held", held)):
            getattr(out, name)[j] = np.interp(lg.t, d.t, y[:, i])
        out.moving[j] = np.interp(lg.t, d.t, mov[:, i]) > 0.5
    return out


def cut_log(lg, sl: slice):
    """A copy of joint log ``lg`` holding only the samples ``sl`` (its signals and channels)."""
    out = copy.copy(lg)
    out.t, out.q, out.tau = lg.t[sl], None if lg.q is None else lg.q[sl], lg.tau[sl]
    out.qd = None if lg.qd is None else lg.qd[sl]
    out.channels = {k: v[sl] for k, v in lg.channels.items()}
    return out


def friction_log(lg, tau_model: np.ndarray, F_model: np.ndarray):
    """A copy of joint log ``lg`` whose torque is the joint's friction torque: the measured torque less the
    rigid-body part (``tau_model - F_model``) of the robot model's prediction at the log's samples. Its
    inertia and gravity are given as zero (the rigid body is taken out): what is left of the torque is the
    joint's friction and offset, which the single-joint fit and the report's joint sections read."""
    out = copy.copy(lg)
    out.tau = np.asarray(lg.tau, float) - (np.asarray(tau_model, float) - np.asarray(F_model, float))
    out.meta = {**lg.meta, "inertia": 0.0, "gravity": [0.0, 0.0]}
    out.warnings = list(lg.warnings)
    return out


def heldout_errors(robot: Robot, logs, fraction: float = 0.3, smooth_hz: float | None = None,
                   estimate=identify_robot) -> dict:
    """Identify on the first ``1 - fraction`` of the joints' logs and predict the rest: per joint the RMS of
    (measured - predicted) torque at the log's own samples over the whole held-out part and over its moving
    samples, against the measured torque as logged or low-passed at ``smooth_hz`` (zero phase, at the
    log's median rate); ``estimate``: :func:`identify_robot` or :func:`frictid.robot.known.identify_known`.
    Returns {'fit', 'whole', 'moving'}."""
    n = min(lg.n for lg in logs)
    k = int(round((1.0 - fraction) * n))
    fit = estimate(robot, [cut_log(lg, slice(0, k)) for lg in logs])
    test = [cut_log(lg, slice(k, None)) for lg in logs]
    p = predict(robot, fit, test)
    _, ordered = align(robot, test)
    whole, moving = {}, {}
    for j, lg in zip(robot.joints, ordered):
        tau = np.asarray(lg.tau, float)
        if smooth_hz is not None:
            fs = 1.0 / float(np.median(np.diff(lg.t)))
            if smooth_hz < 0.5 * fs:
                tau = sosfiltfilt(butter(4, smooth_hz, fs=fs, output="sos"), tau)
        r = tau - p.tau[j]
        whole[j] = float(np.sqrt(np.mean(r ** 2)))
        moving[j] = float(np.sqrt(np.mean(r[p.moving[j]] ** 2)))
    return {"fit": fit, "whole": whole, "moving": moving}
