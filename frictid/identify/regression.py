"""Inertia, gravity, torque offset and polynomial friction by linear least squares (002 eq 4-11).

``tau = J a + c0 sgn(w) + c1 w + c2 w|w| + c3 w^3 + Px cos q + Py sin q + offset (+ payload terms)``

One row per moving sample is never stacked into a matrix: the normal equations ``X^T X`` and ``X^T y``
are accumulated chunk by chunk (:class:`NormalEquations`), one set per segment so that held-out
(leave-segments-out) fits are a subtraction. Columns are rescaled before solving, and columns that the
data cannot separate (a joint that never moves through a gravity angle, no acceleration) are reported.

The standard errors account for the autocorrelation of the residuals (consecutive samples are not
independent): the classical covariance ``s^2 (X^T X)^-1`` is inflated by ``(1 + rho) / (1 - rho)`` with
``rho`` the lag-1 autocorrelation of the residuals within segments; with enough segments the larger of
that and the cluster-robust (sandwich) covariance by segment is reported (:func:`cluster_covariance`),
which also covers a residual that is biased differently from one segment to the next.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: Regressor names in their canonical order.
ALL_COLUMNS = ("J", "c0", "c1", "c2", "c3", "Px", "Py", "Mx", "My", "offset")

#: Default chunk length [samples] of the accumulation.
CHUNK = 262_144


#: The longest dot product, and the size (rows x columns) a matrix-vector product must stay below, that
#: OpenBLAS computes on the calling thread (measured: 10 000 and 460 800). Past them it wakes its worker
#: threads, which then wait for more work for tens of milliseconds, counted as the process's CPU time (about
#: 45 ms a call on this project's 2-core machines, for a product of microseconds). The normal equations'
#: ``X^T y`` and ``y^T y`` of a long segment are therefore summed over blocks within these sizes
#: (:func:`_blocked`): a product within them is the same call as before, a longer one is summed in one order
#: whatever the machine's core count (a threaded one's rounding depended on it).
DOT_BLOCK = 10_000
GEMV_BLOCK = 460_800


def _blocked(product, n: int, block: int):
    """``product(0, n)``, or for ``n`` above ``block`` the sum of ``product(a, b)`` over consecutive blocks."""
    if n <= block:
        return product(0, n)
    out = product(0, block)
    for a in range(block, n, block):
        out = out + product(a, min(a + block, n))
    return out


def column(name: str, q, w, a, payload, axis: str = "rotary", trig=None) -> np.ndarray:
    """One regressor evaluated on a chunk: q [q], w [q/s], a [q/s^2], payload [kg]; ``trig``: (cos q, sin q)
    of the same samples when the caller has them (the gravity columns are then taken, not computed)."""
    if trig is not None and name in ("Px", "Py", "Mx", "My"):
        return _trig_column(name, trig, payload, axis)
    if name == "J":
        return a
    if name == "c0":
        return np.sign(w)
    if name == "c1":
        return w
    if name == "c2":
        return w * np.abs(w)
    if name == "c3":
        return w * w * w
    if name == "Px":
        return np.cos(q)
    if name == "Py":
        return np.sin(q)
    if name == "Mx":
        return payload * (np.cos(q) if axis == "rotary" else 1.0)
    if name == "My":
        return payload * np.sin(q)
    if name == "offset":
        return np.ones_like(w)
    raise KeyError(name)


def _trig_column(name: str, trig, payload, axis: str) -> np.ndarray:
    """A gravity column from cos q and sin q given (``np.cos`` and ``np.sin`` are elementwise: the same
    numbers as :func:`column` computes from q)."""
    cos_q, sin_q = trig
    if name == "Px":
        return cos_q
    if name == "Py":
        return sin_q
    if name == "Mx":
        return payload * (cos_q if axis == "rotary" else 1.0)
    return payload * sin_q


def _trig_at(trig, a0: int, a1: int, m=None):
    """(cos q, sin q) of samples a0..a1 (and of the mask ``m`` within them), or None."""
    if trig is None:
        return None
    if m is None:
        return trig[0][a0:a1], trig[1][a0:a1]
    return trig[0][a0:a1][m], trig[1][a0:a1][m]


@dataclass
class NormalEquations:
    """Sufficient statistics of a linear least-squares problem: X^T X, X^T y, y^T y and n."""

    p: int
    XtX: np.ndarray = None
    Xty: np.ndarray = None
    yty: float = 0.0
    n: int = 0
    # lag-1 products of the residuals, filled by a second pass (see residual_autocorrelation)

    def __post_init__(self):
        if self.XtX is None:
            self.XtX = np.zeros((self.p, self.p))
        if self.Xty is None:
            self.Xty = np.zeros(self.p)

    def add(self, X: np.ndarray, y: np.ndarray) -> None:
        self.XtX += X.T @ X
        self.Xty += _blocked(lambda a, b: X[a:b].T @ y[a:b], y.shape[0], (GEMV_BLOCK - 1) // max(X.shape[1], 1))
        self.yty += float(_blocked(lambda a, b: y[a:b] @ y[a:b], y.shape[0], DOT_BLOCK))
        self.n += int(y.shape[0])

    def __add__(self, other: "NormalEquations") -> "NormalEquations":
        return NormalEquations(self.p, self.XtX + other.XtX, self.Xty + other.Xty, self.yty + other.yty,
                               self.n + other.n)

    def __sub__(self, other: "NormalEquations") -> "NormalEquations":
        return NormalEquations(self.p, self.XtX - other.XtX, self.Xty - other.Xty, self.yty - other.yty,
                               self.n - other.n)

    def within(self, k: int) -> "NormalEquations":
        """The equations with the constant column ``k`` (all ones) partialled out: the residual of every
        column and of ``y`` about its mean over these samples (a free level of their own, the "within"
        estimator of a fixed effect). Column ``k`` becomes zero."""
        if self.n < 2:
            return NormalEquations(self.p)
        c = self.XtX[k].copy()  # column sums
        sy = self.Xty[k]
        XtX = self.XtX - np.outer(c, c) / self.n
        Xty = self.Xty - c * sy / self.n
        XtX[k, :] = XtX[:, k] = 0.0
        Xty[k] = 0.0
        return NormalEquations(self.p, XtX, Xty, self.yty - sy * sy / self.n, self.n - 1)

    @staticmethod
    def total(parts) -> "NormalEquations":
        parts = list(parts)
        out = NormalEquations(parts[0].p)
        for s in parts:
            out = out + s
        return out


@dataclass
class LinearFit:
    """Solution of the normal equations.

    names, coef, stderr (None where not identifiable), cov, s2 (residual variance), n, dof, rho (lag-1
    residual autocorrelation used to inflate the errors), dependent (names the data cannot separate).
    """

    names: tuple[str, ...]
    coef: np.ndarray
    cov: np.ndarray
    s2: float
    n: int
    dof: int
    rho: float = 0.0
    dependent: list[str] = field(default_factory=list)
    #: the inertia refitted on parallel-filtered equations: {"window": samples, "J": value, "se": stderr}
    bandwidth: dict | None = None
    #: the inertia on the slower and the faster half of the moving samples: {"speed": split [q/s],
    #: "J_low", "se_low", "J_high", "se_high"}
    speed_split: dict | None = None
    #: the inertia of the same regression with the other friction model (stage 1's polynomial for stage 2's
    #: plateau map): {"J": value}
    friction_change: dict | None = None

    def value(self, name: str) -> float:
        return float(self.coef[self.names.index(name)])

    def stderr(self, name: str) -> float | None:
        if name in self.dependent:
            return None
        k = self.names.index(name)
        v = self.cov[k, k]
        return math.sqrt(v) if np.isfinite(v) and v >= 0 else None

    def as_dict(self) -> dict[str, float]:
        return {n: float(c) for n, c in zip(self.names, self.coef)}

    def predict(self, X: np.ndarray) -> np.ndarray:
        return X @ self.coef


def solve(ne: NormalEquations, names: tuple[str, ...], rcond: float = 1e-10, rho: float = 0.0) -> LinearFit:
    """Least-squares solution of the normal equations with column scaling and a rank check."""
    d = np.sqrt(np.maximum(np.diag(ne.XtX), 0.0))
    d[d == 0] = 1.0
    A = ne.XtX / np.outer(d, d)
    U, sv, Vt = np.linalg.svd(A)
    ok = sv > rcond * (sv.max() if sv.size and sv.max() > 0 else 1.0)
    # a looser threshold flags columns that are numerically nearly collinear
    weak = sv < 1e-7 * (sv.max() if sv.size and sv.max() > 0 else 1.0)
    Ainv = (Vt[ok].T / sv[ok]) @ Vt[ok]
    b = (Ainv @ (ne.Xty / d)) / d
    rss = float(ne.yty - 2 * b @ ne.Xty + b @ ne.XtX @ b)
    rank = int(ok.sum())
    dof = ne.n - rank
    s2 = max(rss, 0.0) / dof if dof > 0 else math.nan
    infl = (1 + rho) / (1 - rho) if 0 < rho < 1 else 1.0
    cov = s2 * infl * Ainv / np.outer(d, d)
    dependent = []
    if weak.any():
        null = Vt[weak]
        for j, nm in enumerate(names):
            if np.max(np.abs(null[:, j])) > 0.1 or np.diag(ne.XtX)[j] == 0:
                dependent.append(nm)
    for j, nm in enumerate(names):
        if np.diag(ne.XtX)[j] == 0 and nm not in dependent:
            dependent.append(nm)
    return LinearFit(tuple(names), b, cov, s2, ne.n, dof, rho, dependent)


#: Fewest clusters (segments) for the cluster-robust covariance; with fewer its estimate is too noisy.
MIN_CLUSTERS = 8


def robust_stderr(cov_classical: np.ndarray, cov_robust: np.ndarray | None) -> np.ndarray:
    """The larger standard error of two covariance estimates, per parameter, with the robust estimate's
    correlations: ``S C S`` with ``S = diag(max(se_classical, se_robust))`` (positive semi-definite)."""
    if cov_robust is None or not np.all(np.isfinite(cov_robust)):
        return cov_classical
    se_c = np.sqrt(np.maximum(np.diag(cov_classical), 0.0))
    se_r = np.sqrt(np.maximum(np.diag(cov_robust), 0.0))
    se = np.maximum(se_c, se_r)
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov_robust / np.outer(se_r, se_r)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return corr * np.outer(se, se)


def cluster_covariance(fit: LinearFit, parts: list[NormalEquations]) -> np.ndarray | None:
    """Cluster-robust (sandwich) covariance of a fit from the normal equations of its clusters (segments):
    ``G/(G-1) B (sum_g s_g s_g^T) B`` with ``s_g = X_g^T y_g - X_g^T X_g b`` each cluster's score and
    ``B = (X^T X)^-1``. It reflects the segment-to-segment scatter of the residual, correlated in time
    within a segment and biased differently from one segment to the next (a friction map that does not
    follow the data), where the classical ``s^2 (X^T X)^-1`` assumes independent samples. None with fewer
    than :data:`MIN_CLUSTERS` non-empty clusters."""
    parts = [ne for ne in parts if ne.n > 0]
    G = len(parts)
    if G < MIN_CLUSTERS:
        return None
    total = NormalEquations.total(parts)
    d = np.sqrt(np.maximum(np.diag(total.XtX), 0.0))
    d[d == 0] = 1.0
    U, sv, Vt = np.linalg.svd(total.XtX / np.outer(d, d))
    ok = sv > 1e-10 * (sv.max() if sv.size and sv.max() > 0 else 1.0)
    B = ((Vt[ok].T / sv[ok]) @ Vt[ok]) / np.outer(d, d)
    S = np.array([ne.Xty - ne.XtX @ fit.coef for ne in parts])
    return G / (G - 1) * B @ (S.T @ S) @ B


def _chunks(i0: int, i1: int, chunk: int):
    for a in range(i0, i1, chunk):
        yield a, min(a + chunk, i1)


def sample_mask(w, a, min_speed: float) -> np.ndarray:
    """Moving samples: |w| above ``min_speed`` and finite w, a."""
    return np.isfinite(w) & np.isfinite(a) & (np.abs(w) > min_speed)


def accumulate(ranges, names, q, w, a, tau, payload=None, known: dict | None = None, min_speed: float = 0.0,
               axis: str = "rotary", chunk: int = CHUNK, friction=None, smooth: int = 0,
               max_speed: float = math.inf, trig=None) -> list[NormalEquations]:
    """Normal equations of ``tau - known terms = X(names) b``, one set per index range (i0, i1).

    q [q] (may be None if no gravity column is asked), w [q/s], a [q/s^2], tau [F], payload [kg] or None.
    known : regressor name -> known coefficient, moved to the left-hand side. friction : optional known
    friction map w -> F [F], also moved to the left-hand side. Only samples with |w| > min_speed enter.
    smooth : when above 1, the torque and every regressor column are low-pass filtered alike (a moving
    average of ``smooth`` samples, computed per sample and then averaged: the model is linear in its
    coefficients, so the filtered equations hold exactly: Gautier's parallel filtering) before the
    moving samples are taken (:func:`bandwidth_check`). max_speed : only samples with |w| at most this
    enter (not with ``smooth``). trig : (cos q, sin q) of every sample, when the caller has them (not
    computed again for each call and chunk).
    """
    known = dict(known or {})
    out = []
    for i0, i1 in ranges:
        ne = NormalEquations(len(names))
        for a0, a1 in _chunks(i0, i1, chunk):
            if smooth > 1:
                _add_filtered(ne, names, q, w, a, tau, payload, known, min_speed, axis, friction, a0, a1, smooth,
                              trig)
                continue
            ww = w[a0:a1]
            aa = a[a0:a1]
            m = sample_mask(ww, aa, min_speed) & np.isfinite(tau[a0:a1])
            if max_speed < math.inf:  # (non-finite speeds are out of m already)
                with np.errstate(invalid="ignore"):
                    m &= np.abs(ww) <= max_speed
            if q is not None:
                m &= np.isfinite(q[a0:a1])
            if not m.any():
                continue
            ww, aa = ww[m], aa[m]
            qq = q[a0:a1][m] if q is not None else None
            pl = payload[a0:a1][m] if payload is not None else None
            tr = _trig_at(trig, a0, a1, m)
            y = tau[a0:a1][m].astype(float)
            for nm, val in known.items():
                y = y - val * column(nm, qq, ww, aa, pl, axis, tr)
            if friction is not None:
                y = y - friction(ww)
            X = np.empty((ww.shape[0], len(names)))
            for j, nm in enumerate(names):
                X[:, j] = column(nm, qq, ww, aa, pl, axis, tr)
            ne.add(X, y)
        out.append(ne)
    return out


def _add_filtered(ne: NormalEquations, names, q, w, a, tau, payload, known, min_speed, axis, friction,
                  a0: int, a1: int, smooth: int, trig=None) -> None:
    """Add the parallel-filtered equations of samples a0..a1 to ``ne``: every column and the torque are
    evaluated per sample, averaged over ``smooth`` samples, and the samples whose whole window is finite
    and moving enter."""
    from scipy.ndimage import uniform_filter1d

    ww, aa = w[a0:a1], a[a0:a1]
    fin = np.isfinite(ww) & np.isfinite(aa) & np.isfinite(tau[a0:a1])
    if q is not None:
        fin &= np.isfinite(q[a0:a1])
    # only windows of moving samples: one reaching into a reversal would bring the friction's
    # near-zero-speed dynamics (presliding, the Stribeck lag), which the raw fit leaves out, into the sum
    fin &= np.abs(np.where(np.isfinite(ww), ww, 0.0)) > min_speed
    if fin.sum() <= smooth:
        return
    ww, aa = np.where(fin, ww, 0.0), np.where(fin, aa, 0.0)
    qq = np.where(fin, q[a0:a1], 0.0) if q is not None else None
    pl = payload[a0:a1] if payload is not None else None
    # cos 0 = 1 and sin 0 = 0 exactly: the columns of q set to 0 outside fin
    tr = None if trig is None else (np.where(fin, trig[0][a0:a1], 1.0), np.where(fin, trig[1][a0:a1], 0.0))
    y = np.where(fin, tau[a0:a1], 0.0).astype(float)
    for nm, val in known.items():
        y = y - val * column(nm, qq, ww, aa, pl, axis, tr)
    if friction is not None:
        y = y - friction(ww)
    # in Fortran order: the filter runs along contiguous columns (its output, and so the sums below, as before)
    X = np.empty((ww.shape[0], len(names) + 2), order="F")
    for j, nm in enumerate(names):
        X[:, j] = column(nm, qq, ww, aa, pl, axis, tr)
    X[:, -2] = y
    X[:, -1] = fin
    X = uniform_filter1d(X, smooth, axis=0, mode="nearest")
    m = X[:, -1] > 1 - 1e-9
    if m.any():
        ne.add(X[m, :-2], X[m, -2])


def residual_autocorrelation(fit: LinearFit, ranges, q, w, a, tau, payload=None, known: dict | None = None,
                             min_speed: float = 0.0, axis: str = "rotary", chunk: int = CHUNK,
                             friction=None, trig=None) -> float:
    """Lag-1 autocorrelation of the residuals of ``fit`` over consecutive moving samples in the ranges
    (``trig`` as in :func:`accumulate`)."""
    known = dict(known or {})
    s0 = s1 = 0.0
    for i0, i1 in ranges:
        prev = None
        for a0, a1 in _chunks(i0, i1, chunk):
            ww, aa = w[a0:a1], a[a0:a1]
            m = sample_mask(ww, aa, min_speed) & np.isfinite(tau[a0:a1])
            if q is not None:
                m &= np.isfinite(q[a0:a1])
            qq = q[a0:a1] if q is not None else None
            pl = payload[a0:a1] if payload is not None else None
            tr = _trig_at(trig, a0, a1)
            y = tau[a0:a1].astype(float)
            for nm, val in known.items():
                y = y - val * column(nm, qq, ww, aa, pl, axis, tr)
            if friction is not None:
                y = y - np.nan_to_num(friction(np.nan_to_num(ww)))
            pred = np.zeros_like(y)
            for j, nm in enumerate(fit.names):
                pred += fit.coef[j] * column(nm, qq, ww, aa, pl, axis, tr)
            r = np.where(m, y - pred, np.nan)
            if prev is not None:
                r = np.concatenate([[prev], r])
            both = np.isfinite(r[1:]) & np.isfinite(r[:-1])
            s1 += float(np.sum(r[1:][both] * r[:-1][both]))
            fin = np.isfinite(r[1:]) if prev is not None else np.isfinite(r)
            s0 += float(np.sum((r[1:] if prev is not None else r)[fin] ** 2))
            prev = r[-1]
    if s0 <= 0:
        return 0.0
    return float(np.clip(s1 / s0, 0.0, 0.999))
