"""The samples the diagnosis works on, their held-out groups and folds, and the slow variables.

From each log of a joint (as the fit prepared it: velocity, acceleration, friction torque
``F = tau - J a - G``, segments) the diagnosis keeps the *sliding* samples: moving faster than
``v_min`` (on constant-velocity plateaus 0.2 % of the top speed and 5 velocity noise levels, elsewhere
2 %), outside ramp, step and rest segments, away from the start and end of
every run of one velocity sign (the first and last ``edge`` samples, 50 ms: differentiation transients and
the presliding lag of a reversal, which the static map does not describe and which the ``presliding``
cause handles on its own), and with an inertial torque ``|J a|`` no larger than the median friction.

Held-out groups are whole segments (a plateau, a duty cycle, a transition), long ones cut into chunks of
at most :data:`MAX_GROUPS_TARGET`-th of the sliding time, never single samples: samples are strongly
autocorrelated, so every comparison is made on groups that no fit saw. Groups are assigned to folds in
time order, group ``k`` to fold ``k mod n_folds``, so that each fold spans the whole recording (slow
effects are interpolated, not extrapolated).

Slow variables: the drift clock (hours, from each log's metadata ``start_time`` when every log has one,
else the logs laid end to end in the given order) and the thermal state of the heat balance
``C dT/dt = P - K (T - Tenv)`` (K held at 1 W/K: without a measured joint temperature only ``C/K`` and
the slopes per watt are identifiable), driven by a friction power per sample and integrated exactly
(first-order hold of nothing: the power is held over each sample period) by a compiled loop
(:func:`_rise_nb`, 3x faster than its twin :func:`scipy.signal.lfilter`, which the tests compare it with).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit, types as nt

from ..data import finite
from ..segments import noise_sigma
from ..segments.runs import paint, runs

#: Segment kinds the sliding samples never come from.
EXCLUDED_KINDS = ("ramp_presliding", "step", "rest")
#: Aim for at least this many held-out groups (long segments are cut into chunks).
MAX_GROUPS_TARGET = 60
#: Sliding samples move faster than this fraction of the top speed on constant-velocity plateaus ...
V_MIN_FRACTION = 0.002
#: ... and than this many velocity noise levels; elsewhere (accelerating through low speed, where the
#: bristle lag of a reversal dominates) faster than this fraction of the top speed.
K_NOISE = 5.0
V_MOVE_FRACTION = 0.02
#: Sliding samples have an inertial torque |J a| of at most this many times the median friction.
INERTIA_RATIO = 1.0
#: Fewest sliding samples, in all and per group on average, for a diagnosis.
MIN_SAMPLES, MIN_PER_GROUP = 500, 20
#: Group keys are ``log index * LOG_KEY + run * 100000 + chunk``.
LOG_KEY = 10 ** 12


@dataclass
class DiagLog:
    """One log of a joint, as the fit prepared it (arrays of one value per sample).

    t [s], q [q] or None, w [q/s], a [q/s^2], tau [F], F [F] friction torque ``tau - J a - G``, G [F]
    the gravity torque removed (without the offset), offset [F] the offset removed, segments, channels
    (temp_env, temp_joint, payload, ...), start [s] on the drift clock or None (metadata start time).
    """

    t: np.ndarray
    q: np.ndarray | None
    w: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    F: np.ndarray
    G: np.ndarray
    offset: float
    segments: list
    channels: dict = field(default_factory=dict)
    start: float | None = None
    source: int = 0

    @property
    def n(self) -> int:
        return int(self.t.shape[0])


@dataclass
class Samples:
    """The sliding samples of all logs of a joint (concatenated, decimated) and their groups.

    Per sample: t [s] log time, th [h] drift clock, q, w, a, tau, F, G, payload, temp_env, temp_joint
    (NaN where absent), li (log index), k (index in its log), group, fold. Per log: the full arrays the
    thermal state needs. w0 [q/s] velocity scale, F_rms [F] friction scale, v_min [q/s].
    """

    t: np.ndarray
    th: np.ndarray
    q: np.ndarray | None
    w: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    F: np.ndarray
    G: np.ndarray
    payload: np.ndarray | None
    temp_env: np.ndarray | None
    temp_joint: np.ndarray | None
    li: np.ndarray
    k: np.ndarray
    group: np.ndarray
    fold: np.ndarray
    logs: list
    n_folds: int
    v_min: float
    w0: float
    T0: float
    clock_t0: float
    clock_real: bool
    group_t: np.ndarray
    decimation: int = 1
    axis: str = "rotary"
    #: the bristle length [q] of the fit's LuGre (its level at rest over sigma0, where the fit identified
    #: sigma0), None otherwise: the travel after a reversal over which the friction's presliding state acts
    #: (:func:`frictid.diagnose.signals.settled`)
    bristle: float | None = None
    #: per-log inputs of the thermal state and other values derived from the full logs, computed once
    _memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def axis_rotary(self) -> bool:
        return self.axis == "rotary"

    @property
    def load(self) -> np.ndarray:
        """The torque the transmission carries besides friction, ``|J a + G| = |tau - F|`` [F]."""
        return np.abs(self.tau - self.F)

    @property
    def n(self) -> int:
        return int(self.w.shape[0])

    @property
    def n_groups(self) -> int:
        return int(self.group_t.shape[0])

    def train(self, f: int) -> np.ndarray:
        return self.fold != f

    def cached(self, key, compute):
        """``compute()``, computed once per key: values that depend on these samples and logs alone."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def forget(self, key) -> None:
        """Drop ``key`` from what :meth:`cached` holds."""
        self._memo.pop(key, None)

    def has(self, key) -> bool:
        """Whether :meth:`cached` holds ``key``."""
        return key in self._memo

    def group_sums(self, x: np.ndarray) -> np.ndarray:
        """Per group: the sum of x over its samples (``np.bincount(group, weights=x)``). A group's samples are
        one run in the samples' order (:func:`_fold_major`: a fold's samples in time, a group in one fold):
        then summed run by run (``np.add.reduceat``, ten times faster on the one-hour bench log; the same
        sums but for the order of the additions)."""
        def runs():
            g = self.group
            if not g.size:
                return None
            st = np.concatenate(([0], np.flatnonzero(np.diff(g)) + 1))
            ids = g[st]
            return (st, ids) if np.unique(ids).size == ids.size else None   # one run per group, or none
        r = self.cached("group_runs", runs)
        if r is None:
            return np.bincount(self.group, weights=x, minlength=self.n_groups)
        out = np.zeros(self.n_groups)
        out[r[1]] = np.add.reduceat(x, r[0])
        return out

    def dt(self, i: int = 0) -> float:
        """Sample period [s] of log i (the median step of its clock; 1 for a log of one sample)."""
        lg = self.logs[i]
        return self.cached(("dt", i), lambda: float(np.median(np.diff(lg.t))) if lg.n > 1 else 1.0)

    def power(self, i: int) -> np.ndarray:
        """The measured friction power ``F w`` [W] of every sample of log i (NaN as zero), formed at each call
        and not kept: its few readers (the heat balance's input once per conductance, kept; the conductances;
        the energy's evidence) each read it once, and a kept array of the log's length sat in the
        diagnosis' peak (29 MB on a joint-hour, issue 20)."""
        lg = self.logs[i]
        return finite(lg.F * lg.w)

    def log_w(self, i: int) -> np.ndarray:
        """The velocity [q/s] of every sample of log i (NaN as zero)."""
        return self.cached(("log_w", i), lambda: finite(self.logs[i].w))

    def log_a(self, i: int) -> np.ndarray:
        """The acceleration [q/s^2] of every sample of log i (NaN as zero)."""
        return self.cached(("log_a", i), lambda: finite(self.logs[i].a))

    def _rows(self, i: int):
        """(mask of the samples of log i, their indices in the log, the largest of them + 1)."""
        def rows():
            sel = self.li == i
            k = self.k[sel]
            return sel, k, int(k.max()) + 1 if k.size else 0
        return self.cached(("rows", i), rows)

    def thermal_state(self, tau_c: float, power: list[np.ndarray] | None = None,
                      measured: bool = False, K: float = 1.0) -> np.ndarray:
        """Joint temperature rise ``T - T0`` [K] at the samples, for a time constant tau_c [s].

        power : friction power [W] per sample of each full log (default: the measured ``F w``).
        measured : use the logged ``temp_joint`` instead of the heat balance.
        K : the heat balance's conductance [W/K], the weight of the power against the ambient's change
        (:meth:`conductances`).
        """
        out = np.empty(self.n)
        for i, lg in enumerate(self.logs):
            sel, k, end = self._rows(i)
            if not k.size:
                continue
            if measured:
                x = np.asarray(lg.channels["temp_joint"], float)[k] - self.T0
            else:
                # the filter is causal: the samples after the last one kept are not needed
                if power is None:
                    u, x0 = self._heat_input(i, K)
                else:
                    u, x0 = _heat_input(power[i], self._dTenv(i), K)
                y = _rise(u[:max(end, 2)], self.dt(i), x0, tau_c)
                if k.size == self.n:   # one log: its samples read into out (mode "clip": k is in range, and
                    np.take(y, k, out=out, mode="clip")   # "raise" writes through a fresh copy of out)
                    continue
                x = y[k]
            out[sel] = x
        return out

    def _dTenv(self, i: int) -> np.ndarray:
        lg = self.logs[i]
        Tenv = lg.channels.get("temp_env")
        Tenv = np.full(lg.n, self.T0) if Tenv is None else np.asarray(Tenv, float)
        return Tenv - self.T0

    def _heat_input(self, i: int, K: float = 1.0):
        """(u, x0) of :func:`heat_balance_rise` for log i with the measured power (computed once per K)."""
        key = ("heat_input", i) if K == 1.0 else ("heat_input", i, K)
        # without a logged ambient its change is zero (T0 - T0): not formed as a column of every sample
        ambient = self.logs[i].channels.get("temp_env") is not None or not math.isfinite(self.T0)
        return self.cached(key, lambda: _heat_input(self.power(i), self._dTenv(i) if ambient else None, K))

    def _ambient_spread(self, i: int) -> float:
        """The largest change of log i's ambient, ``ptp(finite(Tenv - T0))``: of a finite Tenv from its extremes
        alone (``x - T0`` rounds monotonically: its extremes are those of Tenv less T0, the same numbers),
        without the column of every sample."""
        Tenv = np.asarray(self.logs[i].channels["temp_env"], float)
        if Tenv.size and math.isfinite(self.T0) and np.isfinite(Tenv).all():
            lo, hi = float(Tenv.min()) - self.T0, float(Tenv.max()) - self.T0
            if math.isfinite(lo) and math.isfinite(hi):
                return hi - lo
        d = finite(self._dTenv(i))
        return float(np.ptp(d)) if d.size else 0.0

    def conductances(self) -> tuple[float, ...]:
        """The heat balance's conductances K [W/K] tried: 1 (the ambient's kelvin and the power's watt weigh
        alike, as the fit's own thermal law is written), and, where a logged ambient ``temp_env`` changes
        within a log, one that weighs the power :data:`AMBIENT_WEIGHT` times the ambient's change: the
        power's share of the rise ``P / K`` (its RMS over all logs) against the ambient's largest change
        within a log. Which one holds is a property of the joint that the data choose (the lower training
        error, :func:`frictid.diagnose.causes.propose`): with 1 W/K a joint whose friction dissipates 0.03 W
        warms by 0.03 K while a logged ambient wanders by 0.7 K, so the ambient's wander, not the work,
        made the state of a 35 % warm-up (foreign card seed 316068; 316561 named no temperature beside an
        asymmetry for the same reason)."""
        def compute():
            spread = 0.0
            for i, lg in enumerate(self.logs):
                if "temp_env" in lg.channels and lg.n:
                    spread = max(spread, self._ambient_spread(i))
            if spread <= 0:
                return (1.0,)
            p = np.concatenate([self.power(i) for i in range(len(self.logs))])
            p_rms = float(np.sqrt(np.mean(p * p))) if p.size else 0.0
            if p_rms <= 0:
                return (1.0,)
            return (1.0, p_rms / (AMBIENT_WEIGHT * spread))
        return self.cached("conductances", compute)


#: How many times the ambient's largest change within a log the power's rise weighs in the second
#: conductance tried (:meth:`Samples.conductances`): the ambient's share of the state is then under 0.1 %.
AMBIENT_WEIGHT = 1000.0


def heat_balance_rise(t, P, dTenv, tau_c, K: float = 1.0, ref: bool = False) -> np.ndarray:
    """``x = T - T0`` [K] of ``C dT/dt = P - K (T - Tenv)`` with C = K tau_c, from x(0) = dTenv[0].

    Exact for P and Tenv held over each sample period (a uniform period is assumed: the median).
    ref : by :func:`scipy.signal.lfilter` instead of the compiled loop (the twin the tests compare).
    """
    t = np.asarray(t, float)
    u, x0 = _heat_input(P, dTenv, K)
    if t.size < 2:
        return u.copy()
    return _rise(u, float(np.median(np.diff(t))), x0, tau_c, ref=ref)


def _heat_input(P, dTenv, K: float = 1.0):
    """The input ``u = dTenv + P / K`` [K] of the heat balance and its start ``x0 = dTenv[0]``. dTenv None: no
    change of the ambient (zero), added as a scalar in place (the same numbers as a column of zeros: ``0 + x``
    is x, and +0 for -0). The sum is formed in the quotient's array (the same sum: addition commutes)."""
    u = np.asarray(P, float) / K
    if dTenv is None:
        u += 0.0
        return u, 0.0
    dTenv = np.asarray(dTenv, float)
    if u.shape != np.broadcast_shapes(u.shape, dTenv.shape):
        return dTenv + u, float(dTenv[0]) if dTenv.size else 0.0
    u += dTenv
    return u, float(dTenv[0]) if dTenv.size else 0.0


def _rise(u, h, x0, tau_c, ref: bool = False) -> np.ndarray:
    """``x[k+1] = e x[k] + (1 - e) u[k]`` from ``x[0] = x0``, with ``e = exp(-h / tau_c)`` (h [s] the sample
    period). ref : by :func:`scipy.signal.lfilter` (the twin of the compiled loop)."""
    if u.size < 2:
        return u.copy()
    e = math.exp(-h / tau_c)
    if ref:
        from scipy.signal import lfilter  # only the tests' twin: scipy.signal costs ~0.5 s to import
        y, _ = lfilter([0.0, 1.0 - e], [1.0, -e], u, zi=[x0])
        return y
    return _rise_nb(np.ascontiguousarray(u, dtype=float), e, float(x0))


@njit(cache=True)
def _rise_nb(u, e, x0):  # pragma: no cover - compiled; twin: _rise(..., ref=True)
    """``y[0] = x0``, ``y[k+1] = e y[k] + (1 - e) u[k]`` for k < n - 1: a sequential recursion, which numpy
    cannot vectorise; the same products and sums as lfilter's, so the same values for a finite u."""
    n = u.shape[0]
    y = np.empty(n)
    x = x0
    c = 1.0 - e
    for k in range(n):
        y[k] = x
        x = u[k] * c + x * e
    return y


#: The kernel with its signature (numba types), for :func:`frictid.api.compile_kernels`.
KERNELS = ((_rise_nb, (nt.float64[::1], nt.float64, nt.float64)),)


def _sliding_rows(lg: DiagLog, w: np.ndarray, fin_w: np.ndarray, v_min: float, v_move: float, J: float,
                  F_level: float, e: int) -> tuple[np.ndarray, np.ndarray]:
    """The samples of one log that enter the diagnosis and their segment indices: finite, sliding faster
    than ``v_min`` on constant-velocity plateaus and ``v_move`` elsewhere, outside the excluded kinds, with
    an inertial torque ``|J a|`` within :data:`INERTIA_RATIO` of the typical friction ``F_level``, and at
    least ``e`` samples inside a run of such samples. w : the velocity with NaN as zero; fin_w : where it
    was finite."""
    n = lg.n
    seg_id = np.full(n, -1, dtype=np.int32 if len(lg.segments) < 2**31 else np.int64)
    kind_ok = np.ones(n, dtype=bool)
    vlim = np.full(n, v_move)
    for si, s in enumerate(lg.segments):
        seg_id[s.i0:s.i1] = si
        if s.kind in EXCLUDED_KINDS:
            kind_ok[s.i0:s.i1] = False
        elif s.kind == "constant_velocity":
            vlim[s.i0:s.i1] = v_min
    ok = np.isfinite(lg.F) & fin_w & np.isfinite(lg.a) & kind_ok
    if J > 0:
        ok &= np.abs(J * finite(lg.a)) <= INERTIA_RATIO * F_level
    pos, neg = (w > vlim) & ok, (w < -vlim) & ok
    keep = np.zeros(n, dtype=bool)
    # the runs longer than 2 e, less their e samples at each end (painted at once: a Python loop over the
    # runs took 37 ms per joint-hour)
    for m in (pos, neg):
        a, b = runs(m)
        long = b - a > 2 * e
        paint(keep, a[long] + e, b[long] - e, True)
    idx = np.flatnonzero(keep)
    return idx, seg_id[idx]


def build_samples(logs: list[DiagLog], n_folds: int = 5, edge: int | None = None,
                  n_max: int | None = None, axis: str = "rotary", J: float = 0.0,
                  why: dict | None = None, bristle: float | None = None) -> Samples | None:
    """The :class:`Samples` of a joint's logs, or None when fewer than ``2 n_folds`` groups slide (or fewer
    than :data:`MIN_SAMPLES` samples, :data:`MIN_PER_GROUP` per group on average); then ``why['reason']``
    says which, with the numbers.

    n_max : at most this many samples (evenly decimated within groups, for experiments only); the default,
    None, keeps every sliding sample: the fits cost time linear in the samples and memory of one block.

    J [kg m^2 | kg] : the inertia the friction torque was computed with; samples whose inertial torque
    ``|J a|`` exceeds :data:`INERTIA_RATIO` times the typical friction are left out (there the friction
    torque is a small difference of large numbers, dominated by the error of the acceleration estimate).

    bristle [q] : the bristle length of the fit's LuGre, or None (:attr:`Samples.bristle`).
    """
    fin_w = [np.isfinite(lg.w) for lg in logs]
    why = {} if why is None else why
    lim = _speed_limits(logs, fin_w)
    if lim is None:
        why["reason"] = "no motion in the logs"
        return None
    w0, v_min, v_move = lim
    w_nan0 = [lg.w if f.all() else np.nan_to_num(lg.w) for lg, f in zip(logs, fin_w)]   # NaN as zero
    movF = np.concatenate([np.abs(lg.F[np.isfinite(lg.F) & (np.abs(w) > v_move)]) for lg, w in zip(logs, w_nan0)])
    F_level = float(np.median(movF)) if movF.size else np.inf
    del movF  # the function's large temporaries go as soon as they are used: its peak is the fit's
    dts = [float(np.median(np.diff(lg.t))) if lg.n > 1 else 1.0 for lg in logs]   # sample periods [s]
    offs, clock_t0, real = _drift_clock(logs, dts)
    rows = [_sliding_rows(lg, w_nan0[i], fin_w[i], v_min, v_move, J, F_level,
                          edge if edge is not None else max(5, int(round(0.05 / dts[i]))))
            for i, lg in enumerate(logs)]   # per log: (indices, seg id per index)
    total = sum(r[0].size for r in rows)
    if total == 0:
        why["reason"] = "no sliding samples (moving outside ramps, steps and rests, away from reversals)"
        return None
    cat = _group_keys(logs, rows, dts, edge)
    cat, dec = _cap_groups(cat, total, n_max) if n_max is not None else (cat, 1)
    # the log of each sample (its group key carries it) and its time on the drift clock [h], for the
    # samples kept only
    cat["li"] = cat["gkey"] // LOG_KEY
    cat["th"] = (cat["t"] + np.asarray(offs)[cat["li"]] - clock_t0) / 3600.0
    grouped = _groups(cat["gkey"], cat["th"], n_folds)
    if grouped is None:
        why["reason"] = (f"{cat['gkey'].size} sliding samples in {np.unique(cat['gkey']).size} segments: "
                         f"at least {2 * n_folds} segments of {MIN_PER_GROUP} samples on average "
                         f"({MIN_SAMPLES} in all) are needed to hold some out")
        return None
    group, fold, gt = grouped
    # the samples ordered by fold first (:func:`_fold_major`): each log's arrays are then gathered once, in
    # that order
    order = _fold_major(fold)
    group, fold = group[order], fold[order]
    for name in ("t", "th", "li", "k"):
        cat[name] = cat[name][order]
    take = _taker(logs, cat["li"], cat["k"])

    has_q = all(lg.q is not None for lg in logs)
    env = take("temp_env")
    T0 = 25.0
    for lg in logs:
        if "temp_env" in lg.channels and lg.n:
            T0 = float(np.asarray(lg.channels["temp_env"], float)[0])
            break
    S = Samples(
        t=cat["t"], th=cat["th"], q=take("q", lambda lg: lg.q) if has_q else None,
        w=take("w", lambda lg: lg.w), a=take("a", lambda lg: lg.a), tau=take("tau", lambda lg: lg.tau),
        F=take("F", lambda lg: lg.F), G=take("G", lambda lg: lg.G), payload=take("payload"),
        temp_env=env, temp_joint=take("temp_joint"), li=cat["li"], k=cat["k"], group=group, fold=fold,
        logs=logs, n_folds=n_folds, v_min=v_min, w0=w0, T0=T0, clock_t0=clock_t0, clock_real=real,
        group_t=gt, decimation=dec, axis=axis, bristle=bristle)
    S._memo.update((("dt", i), dt) for i, dt in enumerate(dts))
    S._memo.update((("log_w", i), w) for i, w in enumerate(w_nan0))
    return S


def _taker(logs: list[DiagLog], li: np.ndarray, k: np.ndarray):
    """``take(name, full=None)``: the samples' values of a per-sample array of the logs (``full(log)``, or the
    channel ``name``; None when a log lacks it), sample ``j`` from log ``li[j]`` at index ``k[j]``: one gather
    per log, in the samples' order."""
    per_log = [li == i for i in range(len(logs))] if len(logs) > 1 else None

    def take(name, full=None):
        arrs = [full(lg) if full else lg.channels.get(name) for lg in logs]
        if any(arr is None for arr in arrs):
            return None
        if per_log is None:
            return np.asarray(arrs[0], float)[k]
        out = np.empty(k.size)
        for sel, arr in zip(per_log, arrs):
            out[sel] = np.asarray(arr, float)[k[sel]]
        return out
    return take


#: The per-sample arrays of :class:`Samples`.
PER_SAMPLE = ("t", "th", "q", "w", "a", "tau", "F", "G", "payload", "temp_env", "temp_joint", "li", "k", "group",
              "fold")


def _fold_major(fold: np.ndarray) -> np.ndarray:
    """The samples' order by fold (in time within a fold, stably), in which :func:`build_samples` gathers
    them: every fold's samples are then one contiguous block, so the per-fold sums of the fits
    (:meth:`frictid.diagnose.model.Context.fold_products`) stream over slices, not gathers. Nothing else
    depends on the order (the thermal state and the groups are looked up by each sample's log, index and
    group)."""
    return np.argsort(fold, kind="stable")


def _speed_limits(logs: list[DiagLog], fin_w: list[np.ndarray]) -> tuple[float, float, float] | None:
    """w0 (99.5th percentile of |w|), the sliding speed on constant-velocity plateaus and elsewhere
    (accelerating through low speed) [q/s]; None without motion. fin_w : where each log's w is finite."""
    w_fin = [lg.w if f.all() else lg.w[f] for lg, f in zip(logs, fin_w)]   # the finite velocities
    allw = np.abs(np.concatenate(w_fin))
    if not allw.size:
        return None
    w0 = float(np.percentile(allw, 99.5))
    del allw  # the function's large temporaries go as soon as they are used: its peak is the fit's
    if w0 <= 0:
        return None
    sig_w = max((noise_sigma(wf) for lg, wf in zip(logs, w_fin) if lg.n > 10), default=0.0)
    v_min = max(V_MIN_FRACTION * w0, K_NOISE * sig_w)          # on constant-velocity plateaus
    v_move = max(V_MOVE_FRACTION * w0, v_min)                    # elsewhere (accelerating through low speed)
    return w0, v_min, v_move


def _drift_clock(logs: list[DiagLog], dts: list[float]) -> tuple[list[float], float, bool]:
    """The drift clock: per log the offset of its times [s], the clock's origin [s], and whether the logs'
    start times are real (else the logs are laid end to end)."""
    starts = [lg.start for lg in logs]
    real = all(s is not None for s in starts)
    offs = []
    acc = 0.0
    for lg, s, dt in zip(logs, starts, dts):
        if real:
            offs.append(float(s))
        else:
            offs.append(acc - float(lg.t[0]))
            acc += float(lg.t[-1] - lg.t[0]) + (dt if lg.n > 1 else 0.0)
    clock_t0 = min(o + float(lg.t[0]) for o, lg in zip(offs, logs))
    return offs, clock_t0, real


def _group_keys(logs: list[DiagLog], rows: list, dts: list[float], edge: int | None) -> dict:
    """The kept samples' times, indices and group keys: groups are (log, segment, chunk) with chunks of at
    most L seconds (the sliding time over :data:`MAX_GROUPS_TARGET`)."""
    sliding_time = sum(dt * r[0].size for lg, dt, r in zip(logs, dts, rows) if lg.n > 1)
    L = max(sliding_time / MAX_GROUPS_TARGET, 1e-9)
    parts = {k: [] for k in ("t", "k", "gkey")}
    for i, (lg, (idx, sid)) in enumerate(zip(logs, rows)):
        if not idx.size:
            continue
        # a new group starts at a segment change or a gap in the kept samples, and every L seconds
        brk = np.ones(idx.size, dtype=bool)
        brk[1:] = (np.diff(sid) != 0) | (np.diff(idx) > 1 + 2 * (edge or 1) + 10)
        run_id = np.cumsum(brk) - 1
        t = lg.t[idx]
        run_t0 = t[brk][run_id]
        chunk = np.floor((t - run_t0) / L).astype(np.int64)
        gkey = run_id * 100000 + chunk
        parts["t"].append(t)
        parts["k"].append(idx)
        parts["gkey"].append(gkey + i * LOG_KEY)
    return {k: v[0] if len(v) == 1 else np.concatenate(v) for k, v in parts.items()}  # one log: no copy


def _cap_groups(cat: dict, total: int, n_max: int) -> tuple[dict, int]:
    """At most n_max samples: the same cap for every group (each segment weighs alike, a one-hour run does
    not drown a short sweep), groups below it kept whole, evenly spaced samples within a group. Returns
    the kept samples and the decimation factor."""
    if total <= n_max:
        return cat, 1
    _, ginv, gcount = np.unique(cat["gkey"], return_inverse=True, return_counts=True)
    lo, hi = 1.0, float(gcount.max())
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.minimum(gcount, mid).sum() <= n_max else (lo, mid)
    cap = max(int(lo), MIN_PER_GROUP)
    rank = np.empty(ginv.size, dtype=np.int64)
    order = np.argsort(ginv, kind="stable")
    starts = np.concatenate([[0], np.cumsum(gcount)[:-1]])
    rank[order] = np.arange(ginv.size) - np.repeat(starts, gcount)
    step = np.maximum(gcount / cap, 1.0)[ginv]
    keep = np.floor(rank / step) != np.floor((rank - 1) / step)
    keep &= rank < np.ceil(gcount[ginv] / step) * step
    cat = {k: v[keep] for k, v in cat.items()}
    return cat, int(math.ceil(total / max(int(keep.sum()), 1)))


def _groups(gkey: np.ndarray, th: np.ndarray, n_folds: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Group index, fold and start time on the drift clock [h] per group, groups of fewer than 5 samples
    merged into their predecessor in time and folds dealt by start time; None when there are fewer than
    ``2 n_folds`` groups or too few samples."""
    _, group = np.unique(gkey, return_inverse=True)
    ng = int(group.max()) + 1
    counts = np.bincount(group, minlength=ng)
    gt = np.full(ng, np.inf)
    np.minimum.at(gt, group, th)
    order = np.argsort(gt, kind="stable")
    remap = np.arange(ng)
    anchor = None
    for g in order:
        if counts[g] >= 5 or anchor is None:
            anchor = g
        else:
            remap[g] = anchor
    group = remap[group]
    _, group = np.unique(group, return_inverse=True)
    ng = int(group.max()) + 1
    if ng < 2 * n_folds or group.size < max(MIN_SAMPLES, MIN_PER_GROUP * ng):
        return None
    gt = np.full(ng, np.inf)
    np.minimum.at(gt, group, th)
    rank = np.empty(ng, dtype=np.int64)
    rank[np.argsort(gt, kind="stable")] = np.arange(ng)
    return group, rank[group] % n_folds, gt
