"""Thermal friction models from duty-cycle segments (MODELS.md section 5; 002 eq 12-31).

1. Cycle by cycle: the polynomial friction ``c0 sgn(w) + c1 w + c2 w|w| + c3 w^3`` is identified by
   least squares on each duty cycle's moving samples (:func:`prepare`).
2. The joint temperature ``T`` is not measured: it follows the heat balance
   ``C dT/dt = W - K (T - Tenv)`` driven by the model's own friction power ``W = F(w, T) w``. ``W`` is
   affine in ``T`` for both laws, so over short bins of the log (power held per bin, computed from the
   measured velocity) the balance is integrated exactly. This refines 002's once-per-cycle update.
3. All thermal parameters are fitted together (002 used fmincon) by least squares on the difference
   between each cycle's identified friction and the model's friction at that cycle's mean temperature,
   measured as the RMS over the cycle's own samples (``(c_model - c_cycle)^T M (c_model - c_cycle)`` with
   ``M = X^T X / n`` of the cycle).

Laws: ``thermal4``: ``c_i(T) = c_i0 [alpha (T - T0) + beta]`` with ``c_i0`` from the cold first cycle of
the first run (002: identified at ``T0 = Tenv``), free: alpha, beta, C. ``thermal6``:
``c_i(T) = c_i0 + c_i' (T - T0)``, free: c_i0, c_i', C.

The temperature scale. Without a joint temperature measurement, scaling K, C by ``lambda`` and the
temperature slopes by ``lambda`` leaves every friction prediction unchanged: only ``C/K`` (the time
constant) and the slopes per watt are identifiable. K is then held at :data:`K_REF` (1 W/K) and the file
says so; with a ``temp_joint`` channel, K is fitted too (the measured cycle temperatures enter the fit).
The time constant ``t_c = C / (K - dW/dT)`` (002 eq 23, 31) is reported at the mean duty-cycle power.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.optimize import least_squares

from frictid.models.thermal import heat_balance_bins

#: Heat transfer held fixed when T is unmeasured [W/K]; sets the temperature scale only.
K_REF = 1.0

#: Heat-balance bins per duty cycle (power held per bin).
BINS_PER_CYCLE = 8

#: Relative size (of the friction scale) below which an uncertain parameter does not matter.
NEGLIGIBLE = 0.01

#: Thermal models this module fits.
THERMAL_MODELS = ("thermal4", "thermal6")


def _basis(w, a=None):
    """Regressors of the polynomial friction: sgn(w), w, w|w|, w^3, and a column of the acceleration
    ``a`` [q/s^2] when given. Filled column by column into one Fortran-ordered array (no stacking copies);
    powers as products (numpy's ``w**3`` of a signed array runs tens of times slower, exact to an ulp)."""
    X = np.empty((w.size, 4 if a is None else 5), order="F")
    np.sign(w, out=X[:, 0])
    X[:, 1] = w
    np.multiply(w, np.abs(w), out=X[:, 2])
    np.multiply(w * w, w, out=X[:, 3])
    if a is not None:
        X[:, 4] = a
    return X


def _power_bins(b, w, nb: int) -> np.ndarray:
    """(nb, 4) sums per bin ``b`` of each polynomial term's friction power basis_i(w) w: |w|, w^2, |w|^3,
    w^4 [q^i/s^i], non-finite speeds counted as 0 (the reference of :func:`_bin_sums`; for the tests)."""
    w = np.where(np.isfinite(w), w, 0.0)
    v = np.abs(w)
    w2 = w * w
    return np.column_stack([np.bincount(b, weights=x, minlength=nb) for x in (v, w2, v * w2, w2 * w2)])


def _bin_sums(b, w, te, tj, nb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per bin ``b`` (ints in [0, nb)): the samples, the sums of the friction power basis of
    :func:`_power_bins`, of ``te`` and of ``tj`` (None: not summed, NaN). One compiled pass over the samples
    in their order, each sum accumulated as ``np.bincount`` does (the same numbers to the last bit), with no
    per-sample arrays (the four bincounts, their products and a copy of the speeds were 0.1-0.2 s of a
    2 x 15 min fit and up to 54 MB)."""
    has_tj = tj is not None
    return _bin_sums_nb(np.ascontiguousarray(b, dtype=np.int64), np.ascontiguousarray(w, dtype=float),
                        np.ascontiguousarray(te, dtype=float),
                        np.ascontiguousarray(tj if has_tj else te[:0], dtype=float), nb, has_tj)


@njit(cache=True)
def _bin_sums_nb(b, w, te, tj, nb, has_tj):
    counts = np.zeros(nb)
    P = np.zeros((nb, 4))
    sum_te = np.zeros(nb)
    sum_tj = np.zeros(nb) if has_tj else np.full(nb, np.nan)
    for i in range(b.shape[0]):
        k = b[i]
        wi = w[i]
        if not np.isfinite(wi):
            wi = 0.0
        v = abs(wi)
        w2 = wi * wi
        counts[k] += 1.0
        P[k, 0] += v
        P[k, 1] += w2
        P[k, 2] += v * w2
        P[k, 3] += w2 * w2
        sum_te[k] += te[i]
        if has_tj:
            sum_tj[k] += tj[i]
    return counts, P, sum_te, sum_tj


@dataclass
class ThermalRun:
    """One duty-cycle run (one log): bins for the heat balance and the per-cycle friction.

    bin_h [s]: bin lengths; bin_P: (nbins, 4) mean power basis per bin; bin_Tenv [degC]; bin_T_meas
    [degC] or NaN. cycle_c: (ncycles, 4) cycle LS coefficients; cycle_L: (ncycles, 4, 4) Cholesky factors
    of the cycles' M = X^T X / n; cycle_bins: (ncycles, nbins) weights of each bin in each cycle's
    mean temperature; cycle_n: samples; cycle_id; cycle_t: (start, end) [s]; T_init [degC].
    """

    bin_h: np.ndarray
    bin_P: np.ndarray
    bin_Tenv: np.ndarray
    bin_T_meas: np.ndarray
    cycle_c: np.ndarray
    cycle_L: np.ndarray
    cycle_W: np.ndarray
    cycle_n: np.ndarray
    cycle_id: np.ndarray
    cycle_t: np.ndarray
    cycle_T_meas: np.ndarray
    T_init: float
    has_T: bool = False
    notes: list[str] = field(default_factory=list)
    bin_e: np.ndarray | None = None  # bin_Tenv - bin_e_T0, cached for the heat balance
    bin_e_T0: float = math.nan

    @property
    def n_cycles(self) -> int:
        return int(self.cycle_c.shape[0])


def prepare(t, w, F, cycles: list[tuple[int, int, int]], temp_env=None, temp_joint=None,
            min_speed: float = 0.0, bin_s: float | None = None, max_bins: int = 4000, a=None) -> ThermalRun | None:
    """Bin one log for the heat balance and identify the friction of each duty cycle.

    t [s], w [q/s], F [F] (friction torque tau - J a - G - offset), temp_env, temp_joint [degC] or None.
    cycles : (i0, i1, cycle id) per duty cycle, in time order. a [q/s^2] : acceleration; when given, each
    cycle's least squares also fits an inertia correction ``dJ a`` (002 identifies J with the friction on
    every cycle), so that an error of the inertia used in F does not leak into the friction coefficients;
    the comparison metric ``M`` is then the information on the four coefficients with ``dJ`` profiled out.
    Returns None when no cycle has moving samples.
    """
    t = np.asarray(t, float)
    w = np.asarray(w, float)
    F = np.asarray(F, float)
    cycles = sorted(cycles, key=lambda c: c[0])
    i_start, i_end = cycles[0][0], max(c[1] for c in cycles)
    span = t[i_end - 1] - t[i_start]
    if span <= 0:
        return None
    if bin_s is None:
        bin_s = max(1.0, span / max_bins)
    nb = max(1, int(math.ceil(span / bin_s)))
    edges_t = t[i_start] + np.arange(nb + 1) * (span / nb)
    tt, wt = t[i_start:i_end], w[i_start:i_end]
    b = np.minimum(((tt - t[i_start]) / (span / nb)).astype(int), nb - 1)
    te = (np.full(tt.size, 20.0) if temp_env is None else np.asarray(temp_env[i_start:i_end], float))
    has_T = temp_joint is not None
    tj = np.asarray(temp_joint[i_start:i_end], float) if has_T else None
    counts, bin_P, bin_Tenv, bin_T_meas = _bin_sums(b, wt, te, tj, nb)
    bin_P = bin_P / np.maximum(counts, 1)[:, None]
    bin_h = np.diff(edges_t)
    bin_Tenv = bin_Tenv / np.maximum(counts, 1)
    empty = counts == 0
    if empty.any():  # carry the last known ambient temperature over empty bins
        for k in np.flatnonzero(empty):
            bin_Tenv[k] = bin_Tenv[k - 1] if k > 0 else float(te[0])
    if has_T:
        bin_T_meas = bin_T_meas / np.maximum(counts, 1)
        bin_T_meas[empty] = np.nan
    rows = []
    for i0, i1, cid in cycles:
        ww, ff = w[i0:i1], F[i0:i1]
        m = np.isfinite(ww) & np.isfinite(ff) & (np.abs(ww) > min_speed)
        wm = ww[m]
        n = wm.size
        if n < 20 or not (wm > 0).any() or not (wm < 0).any():
            continue
        X = _basis(wm, None if a is None else np.nan_to_num(np.asarray(a[i0:i1], float)[m]))
        G = X.T @ X / n
        d = np.sqrt(np.diag(G))  # column scales (RMS) of the least squares
        d[d == 0] = 1
        X /= d
        c, *_ = np.linalg.lstsq(X, ff[m], rcond=None)
        c = (c / d)[:4]
        if a is not None and G[4, 4] > 0:  # Schur complement: information on c with dJ profiled out
            M = G[:4, :4] - np.outer(G[:4, 4], G[4, :4]) / G[4, 4]
        else:
            M = G[:4, :4]
        try:
            L = np.linalg.cholesky(M + 1e-12 * np.trace(M) * np.eye(4))
        except np.linalg.LinAlgError:
            continue
        # weight of each bin in the cycle's mean temperature: its moving samples in this cycle
        wts = np.bincount(b[i0 - i_start:i1 - i_start][m], minlength=nb).astype(float)
        Tm = float(np.nanmean(np.asarray(temp_joint[i0:i1], float)[m])) if has_T else math.nan
        rows.append((c, L, wts / wts.sum(), n, cid, (float(t[i0]), float(t[i1 - 1])), Tm))
    if not rows:
        return None
    T_init = float(bin_T_meas[0]) if has_T and np.isfinite(bin_T_meas[0]) else float(bin_Tenv[0])
    return ThermalRun(bin_h, bin_P, bin_Tenv, bin_T_meas,
                      np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                      np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
                      np.array([r[4] for r in rows]), np.array([r[5] for r in rows]),
                      np.array([r[6] for r in rows]), T_init, has_T)


def simulate_temperature(run: ThermalRun, c0, s_alpha, s_beta, dc, C, K, T0):
    """Mean temperature per bin [degC] of the heat balance with power ``sum_i c_i(T) P_i`` affine in T.

    c_i(T) = c0_i (s_alpha (T - T0) + s_beta) + dc_i (T - T0). The bins are integrated exactly by the
    compiled :func:`frictid.models.thermal.heat_balance_bins` (this runs at every residual evaluation).
    """
    W0 = run.bin_P @ (np.asarray(c0, float) * s_beta)
    W1 = run.bin_P @ (np.asarray(c0, float) * s_alpha + np.asarray(dc, float))
    if run.bin_e is None or run.bin_e_T0 != T0:
        run.bin_e = np.ascontiguousarray(run.bin_Tenv - T0)
        run.bin_e_T0 = T0
    return heat_balance_bins(run.bin_h, run.bin_e, W0, W1, float(C), float(K), float(run.T_init - T0)) + T0


@dataclass
class _Layout:
    """Which numbers of the parameter vector are free for a law."""

    model: str
    names: list
    c_ref: np.ndarray
    fit_K: bool


def _unpack(lay: _Layout, x):
    d = dict(zip(lay.names, x))
    C = math.exp(d["logC"])
    K = math.exp(d["logK"]) if lay.fit_K else K_REF
    if lay.model == "thermal4":
        return lay.c_ref, d["alpha"], d["beta"], np.zeros(4), C, K
    c0 = np.array([d[f"c{i}"] if f"c{i}" in d else lay.c_ref[i] for i in range(4)])
    dc = np.array([d[f"dc{i}"] for i in range(4)])
    return c0, 0.0, 1.0, dc, C, K


def _coef_at(c0, sa, sb, dc, dT):
    return c0 * (sa * dT + sb) + dc * dT


def _residuals(x, lay: _Layout, runs, T0, use, T_scale, F_scale):
    c0, sa, sb, dc, C, K = _unpack(lay, x)
    out = []
    for r, u in zip(runs, use):
        Tb = simulate_temperature(r, c0, sa, sb, dc, C, K, T0)
        Tc = r.cycle_W @ Tb
        ks = np.flatnonzero(u)
        # every used cycle at once: L_k^T (c(T_k) - c_k), the same products as cycle by cycle (a stacked
        # matmul runs the per-slice one; einsum would sum in another order)
        cm = _coef_at(c0, sa, sb, dc, (Tc[ks] - T0)[:, None])
        out.append((np.matmul(r.cycle_L[ks].transpose(0, 2, 1), (cm - r.cycle_c[ks])[:, :, None])[:, :, 0]
                    / F_scale).ravel())
        if lay.fit_K and r.has_T:
            ok = np.isfinite(r.cycle_T_meas) & u
            out.append((Tc[ok] - r.cycle_T_meas[ok]) / T_scale)
    return np.concatenate(out) if out else np.zeros(0)


@dataclass
class ThermalFit:
    """Result of one thermal law: values, stderr, reasons, T0, the time constant and metrics."""

    model: str
    values: dict
    stderr: dict
    reasons: dict
    fixed: dict
    T0: float
    time_constant: float | None
    time_constant_se: float | None
    rms: float | None
    n_cycles: int
    k: int
    cost: float
    success: bool
    cycle_T: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def _pred_rms(lay, x, runs, T0, mask_list):
    """RMS [F] over cycles in mask_list of the model against each cycle's identified friction."""
    r = _residuals(x, lay, runs, T0, mask_list, 1.0, 1.0)
    if lay.fit_K:  # drop temperature residuals: they come after the friction ones of each run
        n = sum(4 * int(m.sum()) for m in mask_list)
        parts, pos = [], 0
        for run, m in zip(runs, mask_list):
            parts.append(r[pos:pos + 4 * int(m.sum())])
            pos += 4 * int(m.sum())
            if run.has_T:
                pos += int((np.isfinite(run.cycle_T_meas) & m).sum())
        r = np.concatenate(parts) if parts else r[:n]
    n_c = sum(int(m.sum()) for m in mask_list)
    return math.sqrt(float(r @ r) / n_c) if n_c else None


def nested_start(tf4: "ThermalFit") -> dict:
    """thermal6's parameters at a thermal4 optimum: ``c_i0 = c_ref,i beta``, ``dc_i = c_ref,i alpha`` (the
    same friction at every temperature: thermal4 is nested in thermal6), same C (and K)."""
    v = tf4.values
    out = {"C": v["C"]}
    if "K" in v:
        out["K"] = v["K"]
    for i in range(4):
        c = tf4.fixed[f"c{i}"]
        out[f"c{i}"] = c * v["beta"]
        out[f"dc{i}"] = c * v["alpha"]
    return out


def fit_thermal(runs: list[ThermalRun], model: str, masks=None, n_starts: int = 4,
                start: dict | None = None) -> ThermalFit | None:
    """Fit ``thermal4`` or ``thermal6`` to duty-cycle runs. masks : per run, the cycles used (training).

    start : named values (``alpha``, ``beta``, ``C``, ``c0``.., ``dc0``.., ``K``) of a single start instead
    of the grid of time constants: the full-data optimum for the held-out refits, or thermal4's optimum
    for thermal6 (:func:`nested_start`), from which thermal6 can only fit the cycles as well or better.
    """
    runs = [r for r in runs if r is not None and r.n_cycles > 0]
    if not runs:
        return None
    masks = [np.ones(r.n_cycles, bool) for r in runs] if masks is None else masks
    T0 = runs[0].T_init
    fit_K = all(r.has_T for r in runs)
    c_ref = runs[0].cycle_c[0].copy()
    F_scale = max(float(np.sqrt(np.mean([np.sum((r.cycle_L[k].T @ r.cycle_c[k]) ** 2) / 4
                                         for r in runs for k in range(r.n_cycles)]))), 1e-12)
    names = _thermal_names(model, fit_K)
    lay = _Layout(model, names, c_ref, fit_K)
    n_obs = sum(4 * int(m.sum()) for m in masks)
    if sum(int(m.sum()) for m in masks) < 3 or n_obs <= len(names):
        return None
    span = sum(float(r.bin_h.sum()) for r in runs) / len(runs)
    starts = _thermal_starts(start, span, n_starts, 1.0 if not fit_K else K_REF, c_ref)
    best = None
    for st in starts:
        x0 = np.array([st[n] for n in names])
        try:
            res = least_squares(_residuals, x0, args=(lay, runs, T0, masks, 1.0, F_scale), method="trf",
                                max_nfev=400)
        except (ValueError, OverflowError, FloatingPointError):
            continue
        if not np.all(np.isfinite(res.fun)):
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        return None
    x = best.x
    values, stderr, reasons, cov = _thermal_estimates(best, names)
    c0, sa, sb, dc, C, K = _unpack(lay, x)
    fixed = {}
    if model == "thermal4":
        for i in range(4):
            fixed[f"c{i}"] = float(c_ref[i])
    if not fit_K:
        fixed["K"] = K_REF
    tc, tc_se = _time_constant(lay, x, cov, runs)
    rms = _pred_rms(lay, x, runs, T0, masks)
    cycle_T = []
    for r in runs:
        Tb = simulate_temperature(r, c0, sa, sb, dc, C, K, T0)
        cycle_T.append((r.cycle_W @ Tb).tolist())
    _impact_reasons(values, stderr, reasons, runs, cycle_T, T0, F_scale)
    notes = []
    if not fit_K:
        notes.append(f"joint temperature not measured: K held at {K_REF} W/K (it only sets the temperature "
                     "scale; C/K and the slopes per watt are what the data identify)")
    tf = ThermalFit(model, values, stderr, reasons, fixed, T0, tc, tc_se, rms,
                    sum(int(m.sum()) for m in masks), len(names), float(best.cost), bool(best.success), cycle_T,
                    notes)
    tf._lay = lay  # for held-out evaluation
    tf._x = x
    return tf


def _thermal_names(model: str, fit_K: bool) -> list[str]:
    """The least-squares variables of a thermal law (C and K by their logarithms; K only when the joint
    temperature is measured)."""
    if model == "thermal4":
        names = ["alpha", "beta", "logC"]
    elif model == "thermal6":
        names = [f"c{i}" for i in range(4)] + [f"dc{i}" for i in range(4)] + ["logC"]
    else:
        raise KeyError(f"unknown thermal model {model!r}; known: {', '.join(THERMAL_MODELS)}")
    if fit_K:
        names.append("logK")
    return names


def _thermal_starts(start: dict | None, span: float, n_starts: int, K0: float, c_ref) -> list[dict]:
    """The given start, or a grid of ``n_starts`` time constants from span/30 to span [s] with no
    temperature effect."""
    if start is not None:
        st = {k: v for k, v in start.items() if k not in ("C", "K")}
        st["logC"] = math.log(start["C"])
        st["logK"] = math.log(start.get("K", K0))
        return [st]
    starts = []
    for tau in np.geomspace(span / 30, span, n_starts):
        st = {"alpha": 0.0, "beta": 1.0, "logC": math.log(K0 * tau), "logK": math.log(K0)}
        for i in range(4):
            st[f"c{i}"] = c_ref[i]
            st[f"dc{i}"] = 0.0
        starts.append(st)
    return starts


def _thermal_covariance(Jm: np.ndarray, s2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Covariance ``s2 (J^T J)^+``, standard errors, the weak (near-null) directions and, per variable,
    whether its Jacobian column is not finite (then it is left out and its error is NaN).

    A heat balance whose temperature runs away between bins (a time constant collapsed towards zero, a
    friction power that grows faster with temperature than the losses) has overflowing derivatives; an SVD
    of such a Jacobian fails (LAPACK does not converge), so those columns are set aside and every variable
    gets NaN errors when even the rest cannot be decomposed."""
    p = Jm.shape[1]
    broken = ~np.all(np.isfinite(Jm), axis=0)
    keep = np.flatnonzero(~broken)
    cov = np.full((p, p), np.nan)
    se = np.full(p, np.nan)
    weak = np.zeros((0, p))
    try:
        U, sv, Vt = np.linalg.svd(Jm[:, keep], full_matrices=False)
    except np.linalg.LinAlgError:
        return cov, se, np.eye(p), np.ones(p, bool)
    if not sv.size or not sv.max() > 0:
        return cov, se, np.eye(p), broken
    ok = sv > 1e-10 * sv.max()
    sub = s2 * (Vt[ok].T / sv[ok] ** 2) @ Vt[ok]
    cov[np.ix_(keep, keep)] = sub
    if np.isfinite(s2):
        se[keep] = np.sqrt(np.maximum(np.diag(sub), 0))
    w = Vt[sv < 1e-7 * sv.max()]
    weak = np.zeros((w.shape[0], p))
    weak[:, keep] = w
    return cov, se, weak, broken


def _thermal_estimates(best, names: list[str]) -> tuple[dict, dict, dict, np.ndarray]:
    """Values, standard errors and reasons (rank-deficient, or a log-variable's error above 100 %) of the
    least-squares optimum ``best``, and the covariance of its variables."""
    x = best.x
    p = len(names)
    dof = best.fun.size - p
    s2 = 2 * best.cost / dof if dof > 0 else math.nan
    cov, se, weak, broken = _thermal_covariance(np.asarray(best.jac, float), s2)
    values, stderr, reasons = {}, {}, {}
    for j, n in enumerate(names):
        if n.startswith("log"):
            v = math.exp(x[j])
            values[n[3:]] = v
            stderr[n[3:]] = v * se[j] if np.isfinite(se[j]) else None
            key = n[3:]
        else:
            values[n] = float(x[j])
            stderr[n] = float(se[j]) if np.isfinite(se[j]) else None
            key = n
        if broken[j]:
            reasons[key] = ("no finite derivative at the optimum (the fitted heat balance runs away between "
                            "bins) or the Jacobian cannot be decomposed: the cycles do not pin it down")
        elif weak.size and np.max(np.abs(weak[:, j])) > 0.1:
            reasons[key] = "not separable from other parameters (Jacobian rank-deficient)"
        elif n.startswith("log") and np.isfinite(se[j]) and se[j] > 1.0:
            reasons[key] = f"relative error {100 * math.expm1(min(se[j], 50.0)):.3g} % (above 100 %)"
    return values, stderr, reasons, cov


def _time_constant(lay, x: np.ndarray, cov: np.ndarray, runs: list[ThermalRun]) -> tuple[float, float | None]:
    """The time constant [s] at the mean duty power, ``t_c = C / (K - dW/dT)``, and its standard error by
    the delta method (None when it or the covariance is not finite)."""
    P_mean = np.concatenate([r.bin_P for r in runs]).mean(axis=0)

    def tc_of(xx):
        c0_, sa_, sb_, dc_, C_, K_ = _unpack(lay, xx)
        W1 = float(P_mean @ (c0_ * sa_ + dc_))
        den = K_ - W1
        return C_ / den if den > 0 else math.inf

    tc = tc_of(x)
    tc_se = None
    if np.isfinite(tc) and np.all(np.isfinite(cov)):
        p = x.size
        g = np.zeros(p)
        for j in range(p):
            hstep = 1e-6 * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += hstep
            g[j] = (tc_of(xp) - tc) / hstep
        tc_se = math.sqrt(max(float(g @ cov @ g), 0.0))
    return tc, tc_se


def _impact_reasons(values: dict, stderr: dict, reasons: dict, runs: list[ThermalRun], cycle_T: list,
                    T0: float, F_scale: float) -> None:
    """Relative error above 100 % where it matters: its friction over the cycles' temperature span exceeds
    NEGLIGIBLE of the friction scale (a slope that changes the friction by less is harmless)."""
    dT_span = max((abs(T - T0) for ct in cycle_T for T in ct), default=0.0)
    rms_basis = np.sqrt(np.mean([np.diag(r.cycle_L[k] @ r.cycle_L[k].T) for r in runs
                                 for k in range(r.n_cycles)], axis=0))
    for n in values:
        e, v = stderr.get(n), values[n]
        if n in reasons or e is None or e <= abs(v) or n in ("C", "K"):
            continue
        if n in ("alpha", "beta"):
            impact = e * F_scale * (dT_span if n == "alpha" else 1.0)
        else:
            impact = e * rms_basis[int(n[-1])] * (dT_span if n.startswith("dc") else 1.0)
        if impact > NEGLIGIBLE * F_scale:
            reasons[n] = (f"relative error {100 * e / abs(v):.3g} % (above 100 %)" if v else
                          "relative error above 100 %")


def heldout(runs: list[ThermalRun], model: str, n_folds: int = 3, full: ThermalFit | None = None
            ) -> tuple[float | None, float | None]:
    """Held-out RMS [F] of a thermal law and of a temperature-blind constant polynomial, by cycles.

    Cycles are assigned to folds by their order (every ``n_folds``-th cycle), so each fold spans the
    warm-up; the heat balance still runs through held-out cycles (their power comes from the measured
    velocity), but their friction never enters the fit. full : the law fitted on all cycles; each fold
    starts from its optimum (one start instead of the grid). Returns (rms_thermal, rms_constant).
    """
    runs = [r for r in runs if r is not None and r.n_cycles > 0]
    if not runs or sum(r.n_cycles for r in runs) < 2 * n_folds:
        return None, None
    se_t = se_c = 0.0
    n_t = 0
    for f in range(n_folds):
        train = [np.arange(r.n_cycles) % n_folds != f for r in runs]
        test = [~m for m in train]
        tf = fit_thermal(runs, model, masks=train, n_starts=3,
                         start=None if full is None else dict(full.values, **{k: v for k, v in full.fixed.items()
                                                                                if k == "K"}))
        if tf is None:
            return None, None
        r_t = _pred_rms(tf._lay, tf._x, runs, tf.T0, test)
        # constant polynomial: the sample-weighted mean of the training cycles' coefficients
        cs = np.concatenate([r.cycle_c[m] for r, m in zip(runs, train)])
        ns = np.concatenate([r.cycle_n[m] for r, m in zip(runs, train)])
        cbar = (cs * ns[:, None]).sum(0) / ns.sum()
        e2 = 0.0
        nc = 0
        for r, m in zip(runs, test):
            for k in np.flatnonzero(m):
                d = r.cycle_L[k].T @ (cbar - r.cycle_c[k])
                e2 += float(d @ d)
                nc += 1
        se_t += r_t**2 * nc
        se_c += e2
        n_t += nc
    return math.sqrt(se_t / n_t), math.sqrt(se_c / n_t)


def predict_coefficients(tf: ThermalFit, T) -> np.ndarray:
    """Polynomial coefficients c0..c3 of a fitted law at joint temperature(s) T [degC]."""
    T = np.atleast_1d(np.asarray(T, float))
    v = tf.values
    if tf.model == "thermal4":
        c0 = np.array([tf.fixed[f"c{i}"] for i in range(4)])
        return c0[None, :] * (v["alpha"] * (T[:, None] - tf.T0) + v["beta"])
    c0 = np.array([v[f"c{i}"] for i in range(4)])
    dc = np.array([v[f"dc{i}"] for i in range(4)])
    return c0[None, :] + dc[None, :] * (T[:, None] - tf.T0)
