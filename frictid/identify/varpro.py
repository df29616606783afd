"""Variable projection (Golub and Pereyra 1973) for the separable static maps.

Every static map of :mod:`frictid.models.static` is linear in its levels and slopes (Fc, Fs, sigma2, the
alphas, the polynomial's c) once its shape parameters (Stribeck speed and exponent, the two-exponential
speeds) are given; the map's Jacobian columns of the linear parameters are then the regressors. For each
value ``theta`` of the free shape parameters the linear ones are solved exactly (weighted least squares,
within their bounds: a bounded-variable solve only where the plain one leaves them), and the optimiser
works on ``theta`` alone (1-2 parameters) against the reduced residual, with Kaufman's Jacobian (the shape
columns projected off the regressors' span: the exact gradient of the reduced cost). A cold fit first scans
the reduced cost over a grid of shape values spread over the points' speeds (one batched SVD for the whole
grid) and refines the best point of each of its lowest valleys (:data:`N_VALLEYS`) briefly, and the best of
these to convergence; a warm start (a held-out fold or a profile refit from the full-data
optimum) refines from where it is. The stationary points of the reduced problem are those of the full one,
so this replaces the multi-start on all parameters without changing what a converged fit finds; the
standard errors still come from the full problem's Jacobian at the optimum (:func:`.static._branch_errors`).
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
from numba import njit, types as nt

from frictid.models import static as sm
from .smallsq import damped_step

#: Grid points per shape parameter of a cold scan (speeds log-spaced over the points' speeds) and the
#: exponents tried for a free Stribeck exponent (000/003 hold it at 2; 1 is 001/004's exponential).
SCAN_POINTS = {1: 16, 2: 8}
DELTA_SCAN = (1.0, 2.0, 3.0)
#: Exponents scanned along a speed's upper bound (:func:`_edge_lines`): log-spaced over the exponent's
#: bounds (0.3-5), a step of 13 %.
EDGE_DELTA_POINTS = 24
#: Stribeck speeds scanned in each gap between neighbouring point speeds with a step-like drop
#: (:func:`_step_line`).
STEP_PER_GAP = 4
#: Valleys of the scan refined per map (the best grid point of each), and how far apart (a ratio of some shape
#: value, about one step of the speed grids) two grid points must be to count as two valleys: a Stribeck map
#: that drops at a low speed and one that rises at a high speed can fit equally well, and the better one is
#: not always the better grid point. The two-exponential map gets more: where its speeds meet it has a
#: degenerate valley (amplitudes that cancel and run to their bounds, a bump of a third shape) that holds the
#: scan's best points more often than not: with 6 valleys 2 of 34 random fits (tests/test_fit_varpro.py's
#: family) ended a unit of chi-square or more above the old multi-start, with 10 none.
N_VALLEYS = {"stribeck": 3, "stribeck_2exp": 10}
APART = 2.0
#: First trust radius of a refinement, in the logarithm of the shape values (a factor 1.28): the scan (or a
#: warm start) has put the start in its valley, and a first step as long as the grid's spacing (a factor 2
#: for 8 speeds) jumped from a Stribeck drop's valley into the two-exponential map's degenerate one.
RADIUS = 0.25
EPS, TINY = float(np.finfo(float).eps), float(np.finfo(float).tiny)
#: Relative tolerance of an active bound (scipy's ``find_active_constraints`` with ``ftol``).
ACTIVE_RTOL = 1e-8
#: Tolerances of the refinement (:func:`levenberg_marquardt`): relative cost decrease, relative step, and
#: the largest gradient component in the parameters' scales. scipy's default 1e-8 stopped a Stribeck exponent
#: that drifts along a drop of nearly no amplitude half-way to its bound, 1 % above the full problem's cost.
FTOL = XTOL = GTOL = 1e-10


@dataclass
class Solution:
    """What :func:`.static.fit_branch` reads of a solve, named as scipy's ``OptimizeResult``: the free
    parameters ``x``, the residual ``fun`` and cost, the full problem's Jacobian at ``x`` (free columns,
    weighted), the bounds each parameter is at (-1 lower, 1 upper), and how the refinement ended."""

    x: np.ndarray
    fun: np.ndarray
    cost: float
    jac: np.ndarray
    active_mask: np.ndarray
    status: int
    success: bool
    message: str
    #: a Stribeck search's rise that fits as well as this drop (name -> value; :meth:`.static._Branch.search`)
    rival: dict | None = None


class Projection:
    """The reduced problem of one branch (:class:`.static._Branch` ``pb``) by the map's separable form
    (:data:`frictid.models.static.SEPARABLE`): ``nl`` are the indices, into the free parameters, of the free
    shape parameters, ``lin`` those of the free linear ones; held parameters of either kind stay held."""

    def __init__(self, pb):
        self.pb = pb
        lin_names, self.shape_names, self.columns = sm.SEPARABLE[pb.smap.name]
        free_names = [pb.names[k] for k in pb.free]
        self.nl = [free_names.index(nm) for nm in self.shape_names if nm in free_names]
        self.lin = [free_names.index(nm) for nm in lin_names if nm in free_names]
        self.free_lin = np.array([nm in free_names for nm in lin_names])
        self.free_shape = np.array([nm in free_names for nm in self.shape_names], dtype=bool)
        self.b_held = np.array([pb.fixed.get(nm, 0.0) for nm in lin_names])
        self.shape_held = {nm: pb.fixed[nm] for nm in self.shape_names if nm in pb.fixed}
        self.lo, self.hi = pb.lo_f[self.lin], pb.hi_f[self.lin]
        self._memo = (None, None)
        # what every evaluation reuses: the free shape names, the columns' indices, and the weighted target
        # when no linear parameter is held (it does not depend on the shape then)
        self._free_shapes = [nm for nm, f in zip(self.shape_names, self.free_shape) if f]
        self._lin_cols = np.flatnonzero(self.free_lin)
        self._held_cols = np.flatnonzero(~self.free_lin)
        self._b_held_part = self.b_held[self._held_cols]
        self._shape_rows = np.flatnonzero(self.free_shape)
        self._y_free = pb.F * pb.wts if self._held_cols.size == 0 else None
        self._wt = pb.wts[:, None]
        # every linear / shape column free (the usual case): the columns as they come, no index copy
        self._all_lin = bool(self.free_lin.all())
        self._all_shapes = bool(self.free_shape.all())
        self._lo_l, self._hi_l = self.lo.tolist(), self.hi.tolist()

    def _x(self, theta, b):
        xf = np.empty(len(self.pb.free))
        xf[self.nl] = theta
        xf[self.lin] = b
        return xf

    def _shapes(self, theta):
        """Keyword arguments of the columns: free shape values from ``theta`` (last axis), held ones."""
        theta = np.asarray(theta, dtype=float)
        kw = dict(self.shape_held)
        if theta.ndim > 1:
            kw.update({nm: theta[..., i, None] for i, nm in enumerate(self._free_shapes)})
        else:
            kw.update(zip(self._free_shapes, theta.tolist()))
        return kw

    def regressors(self, theta):
        """Weighted regressors of the free linear parameters, the weighted target (the held linear
        parameters' part taken off the points) and the weighted columns' shape derivatives, at ``theta``
        (or a grid of them, rows)."""
        pb = self.pb
        cols, dcols = self.columns(pb.w, **self._shapes(theta))
        wt = self._wt
        # (the index copy is in Fortran order, and the products and sums below are of that layout: a single
        # shape's columns are multiplied into it directly)
        A = np.multiply(cols, wt, order="F") if self._all_lin and cols.ndim == 2 else cols[..., self._lin_cols] * wt
        y = self._y_free if self._y_free is not None else \
            (pb.F - cols[..., self._held_cols] @ self._b_held_part) * pb.wts
        return A, y, (dcols if self._all_shapes else dcols[..., self._shape_rows, :, :]) * wt

    def linear(self, A, y):
        """The linear parameters' weighted least-squares values within their bounds, and the orthonormal
        basis of the regressors that are not at a bound (for the projection)."""
        if A.shape[1] == 0:
            return np.zeros(0), A[:, :0]
        norms = np.sqrt(np.einsum("ij,ij->j", A, A))
        if not norms.all():
            norms[norms == 0] = 1.0
        An = A / norms
        U, sv, Vt = np.linalg.svd(An, full_matrices=False)
        ok = sv > sv[0] * max(A.shape) * EPS
        U = U[:, ok]  # a copy in Fortran order, which the products below (and their rounding) are of
        if not ok.all():  # (Vt[ok] would be a C-ordered copy of the C-ordered Vt: the same products)
            Vt, sv = Vt[ok], sv[ok]
        b = (Vt.T @ ((U.T @ y) / sv)) / norms
        if all(lo <= v <= hi for v, lo, hi in zip(b.tolist(), self._lo_l, self._hi_l)):
            return b, U
        x, on_bound = bvls(An, y, b * norms, self.lo * norms, self.hi * norms)
        b = np.clip(x / norms, self.lo, self.hi)
        # bvls's own active set: its solution at a bound may sit a rounding error inside it, and a column
        # counted free there would be projected off the shape columns (a wrong reduced gradient)
        inside = (on_bound == 0) & (b > self.lo) & (b < self.hi)
        b = np.where(on_bound < 0, self.lo, np.where(on_bound > 0, self.hi, b))
        if not inside.any():
            return b, A[:, :0]
        U, sv, _ = np.linalg.svd(A[:, inside], full_matrices=False)
        return b, U[:, sv > sv[0] * max(A.shape) * EPS]

    def _eval(self, theta):
        """(linear parameters, reduced residual, Kaufman's Jacobian) at ``theta``: the shape columns of the
        full Jacobian at the projected linear parameters, with their part in the span of the free
        regressors removed (the exact gradient of the reduced cost)."""
        theta = np.asarray(theta, dtype=float)
        key = theta.tobytes()
        if self._memo[0] == key:
            return self._memo[1]
        A, y, dA = self.regressors(theta)
        out = self._projected(A, y, dA)
        if out is None:
            out = self._eval_numpy(A, y, dA)
        self._memo = (key, out)
        return out

    def _eval_numpy(self, A, y, dA):
        """:meth:`_eval` on numpy's calls (the reference of :func:`_project_nb`)."""
        b, U = self.linear(A, y)
        r = A @ b - y
        if self._all_lin:
            b_all = b
        else:
            b_all = self.b_held.copy()
            b_all[self._lin_cols] = b
        Jn = (dA @ b_all).T  # (n, free shapes): d model / d shape at the projected linear parameters
        Jn = Jn - U @ (U.T @ Jn)
        return b, r, Jn

    def _projected(self, A, y, dA):
        """:meth:`_eval`'s numbers in one compiled pass (:func:`_project_nb`), or None where numpy's path
        decides (numbers that are not finite, a layout the pass does not take)."""
        if A.shape[1] == 0 or not A.flags.f_contiguous or not dA.flags.c_contiguous:
            return None
        norms = np.sqrt(np.einsum("ij,ij->j", A, A))
        if not norms.all():
            norms[norms == 0] = 1.0
        try:
            return _project_nb(A, np.ascontiguousarray(y), dA, norms, self.b_held, self._lin_cols, self._all_lin,
                               self.lo, self.hi)
        except (np.linalg.LinAlgError, ValueError):  # not finite: numpy's path decides
            return None

    def resid(self, theta):
        return self._eval(theta)[1]

    def _jac_log(self, z):
        """The Jacobian in the logarithms ``z`` of the shape values."""
        t = np.exp(z)
        return self.jac(t) * t

    def jac(self, theta):
        return self._eval(theta)[2]

    def scan(self, grid: np.ndarray, n_best: int = 1) -> np.ndarray:
        """The ``n_best`` grid points (rows of shape values) with the lowest reduced cost, best first, each
        apart from the better ones (:func:`_apart`: distinct valleys, not neighbours of one). One batched SVD
        solves every grid point; a point whose solution leaves the bounds is solved again within them when it
        could be picked."""
        A, y, _ = self.regressors(grid)
        y = np.ascontiguousarray(np.broadcast_to(y, A.shape[:-1]))
        norms = np.linalg.norm(A, axis=1, keepdims=True)
        norms[norms == 0] = 1.0
        U, sv, Vt = np.linalg.svd(A / norms, full_matrices=False)
        cut = sv > sv[:, :1] * max(A.shape[1:]) * np.finfo(float).eps
        inv = np.where(cut, 1.0 / np.where(cut, sv, 1.0), 0.0)
        coef = np.einsum("gji,gj,gkj,gk->gi", Vt, inv, U, y) / norms[:, 0, :]
        cost = np.sum((np.einsum("gki,gi->gk", A, coef) - y) ** 2, axis=1)
        cost[~np.isfinite(cost)] = np.inf
        # best first; a point whose unbounded solution leaves the bounds has its unbounded cost as a lower
        # bound, and is solved within the bounds (a bounded solve each) only when that bound reaches the top
        # of the queue and the point is apart from the valleys already picked: the same picks as solving all
        outside = np.any((coef < self.lo) | (coef > self.hi), axis=1)
        queue = [(float(c), g, not out) for g, (c, out) in enumerate(zip(cost, outside)) if np.isfinite(c)]
        heapq.heapify(queue)
        picked: list[int] = []
        while queue and len(picked) < n_best:
            c, g, exact = heapq.heappop(queue)
            if not all(_apart(grid[g], grid[h]) for h in picked):
                continue
            if exact:
                picked.append(g)
                continue
            b, _ = self.linear(A[g], y[g])
            c = float(np.sum((A[g] @ b - y[g]) ** 2))
            if np.isfinite(c):
                heapq.heappush(queue, (c, g, True))
        return grid[picked]

    def refine(self, theta0, budget: int) -> Solution:
        """Bounded least squares on the shape parameters from ``theta0`` (``budget`` residual evaluations),
        then the full solution with the full problem's Jacobian at it."""
        pb = self.pb
        lo, hi = pb.lo_f[self.nl], pb.hi_f[self.nl]
        status, message = 1, "linear least squares (no free shape parameter)"
        theta = np.zeros(0)
        if self.nl:
            margin = 1e-9 * (hi - lo)
            t0 = np.clip(np.asarray(theta0, dtype=float), lo + margin, hi - margin)
            # in the logarithms of the shape values (speeds and exponents are positive and act by ratio: a
            # step of one is a factor e, and a flat direction cannot throw a speed onto its bound in one step)
            z, status, message = levenberg_marquardt(lambda z: self.resid(np.exp(z)), self._jac_log, np.log(t0),
                                                     np.log(lo), np.log(hi), np.ones(len(self.nl)), budget,
                                                     RADIUS)
            theta = np.clip(np.exp(z), lo, hi)
        b, _, _ = self._eval(theta)
        return self.solution(self._x(theta, b), status, message)

    def solution(self, xf, status: int = 1, message: str = "") -> Solution:
        """The :class:`Solution` at free parameters ``xf``: residual, cost, the full problem's Jacobian."""
        pb = self.pb
        fun = pb.resid(xf)
        return Solution(xf, fun, 0.5 * float(fun @ fun), pb.jac(xf), _active(xf, pb.lo_f, pb.hi_f),
                        status, status > 0, message)


@njit(cache=True, error_model="numpy")
def _project_nb(A, y, dA, norms, b_held, lin_cols, all_lin, lo, hi):
    """:meth:`Projection.linear` and :meth:`Projection._eval` for one shape, compiled: the regressors ``A``
    (Fortran order) normalised by ``norms``, their SVD (LAPACK's ``gesdd``, as numpy's), the rank cut, the
    linear parameters, and when they are within ``lo``..``hi`` the residual and Kaufman's Jacobian. The
    products are BLAS calls on arrays laid out as numpy's (``U`` and ``Vt`` as its SVD returns them, the
    index copies in Fortran order, a one-column Jacobian by matrix-vector products as numpy's ``matmul``
    takes it), so the numbers are numpy's to the last bit; a plain solution outside the bounds is bounded by
    :func:`_bvls_nb` and projected as :meth:`Projection.linear` does. Returns (b, r, Jn)."""
    n, L = A.shape
    An = np.empty((L, n)).T
    for j in range(L):
        for i in range(n):
            An[i, j] = A[i, j] / norms[j]
    U, sv, Vt = _svd_thin(An)
    cut = sv[0] * float(max(n, L)) * EPS
    keep = _above(sv, cut)
    k = keep.size
    Uk = _columns(U, keep)
    Vk = np.empty((k, L))
    svk = np.empty(k)
    for c in range(k):
        for j in range(L):
            Vk[c, j] = Vt[keep[c], j]
        svk[c] = sv[keep[c]]
    t = _mv(Uk.T, y) / svk
    b = _mv(Vk.T, t) / norms
    if not _within(b, lo, hi):  # the bounded solve (Projection.linear's other branch)
        x, on_bound = _bvls_nb(An, y, b * norms, lo * norms, hi * norms, 1e-10)
        b = _clip_nb(x / norms, lo, hi)
        inside = _inside(on_bound, b, lo, hi)
        for j in range(L):
            if on_bound[j] != 0:
                b[j] = lo[j] if on_bound[j] < 0 else hi[j]
        Ai = _columns(A, inside)
        Uk = np.empty((0, n)).T  # (Fortran order, as every Uk here: BLAS sees one layout)
        if inside.size:
            U, sv, _ = _svd_thin(Ai)
            keep = _above(sv, sv[0] * float(max(n, L)) * EPS)
            Uk = _columns(U, keep)
    r = _mv(A, b) - y
    if all_lin:
        b_all = b
    else:
        b_all = b_held.copy()
        for j in range(L):
            b_all[lin_cols[j]] = b[j]
    S = dA.shape[0]
    JnT = np.empty((S, n))
    for s_ in range(S):
        col = _mv(dA[s_], b_all)
        for i in range(n):
            JnT[s_, i] = col[i]
    Jn = JnT.T
    out = np.empty((n, S))
    if Uk.shape[1] == 0:  # nothing to project off (every level at a bound)
        for i in range(n):
            for s_ in range(S):
                out[i, s_] = Jn[i, s_]
    elif S == 1:
        P1 = _mv(Uk, _mv(Uk.T, JnT[0]))
        for i in range(n):
            out[i, 0] = Jn[i, 0] - P1[i]
    else:
        P = np.dot(Uk, np.dot(Uk.T, Jn))
        for i in range(n):
            for s_ in range(S):
                out[i, s_] = Jn[i, s_] - P[i, s_]
    return b, r, out


@njit(cache=True, error_model="numpy")
def _svd_thin(a):
    """``np.linalg.svd(a, full_matrices=False)`` (numba's, LAPACK's ``gesdd``) for the one signature the kernels
    call it with, compiled once as its own function."""
    return np.linalg.svd(a, full_matrices=False)


@njit(cache=True)
def _above(v, cut):
    """The indices where ``v > cut`` (``np.flatnonzero(v > cut)``)."""
    n = 0
    for j in range(v.shape[0]):
        if v[j] > cut:
            n += 1
    out = np.empty(n, dtype=np.int64)
    n = 0
    for j in range(v.shape[0]):
        if v[j] > cut:
            out[n] = j
            n += 1
    return out


@njit(cache=True)
def _inside(on_bound, b, lo, hi):
    """The indices of the free entries strictly within their bounds
    (``np.flatnonzero((on_bound == 0) & (b > lo) & (b < hi))``)."""
    n = 0
    for j in range(b.shape[0]):
        if on_bound[j] == 0 and b[j] > lo[j] and b[j] < hi[j]:
            n += 1
    out = np.empty(n, dtype=np.int64)
    n = 0
    for j in range(b.shape[0]):
        if on_bound[j] == 0 and b[j] > lo[j] and b[j] < hi[j]:
            out[n] = j
            n += 1
    return out


@njit(cache=True)
def _columns(M, idx):
    """The columns ``idx`` of ``M``, copied in Fortran order (element by element: a slice assignment compiles
    numba's shape-mismatch message, a second of a first run)."""
    n = M.shape[0]
    out = np.empty((idx.size, n)).T
    for c in range(idx.size):
        j = idx[c]
        for i in range(n):
            out[i, c] = M[i, j]
    return out


@njit(cache=True)
def _mv(M, v):
    """``M @ v`` as numpy's ``matmul`` computes it: a one-row matrix by a dot product, else by BLAS's
    matrix-vector product."""
    if M.shape[0] == 1:
        m = M.shape[1]
        row = np.empty(m)  # (a copy of the row, element by element: np.ascontiguousarray compiled its own code)
        for j in range(m):
            row[j] = M[0, j]
        out = np.empty(1)
        out[0] = np.dot(row, v)
        return out
    return np.dot(M, v)


@njit(cache=True)
def _within(b, lo, hi) -> bool:
    for j in range(b.shape[0]):
        if not (lo[j] <= b[j] <= hi[j]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _bvls_nb(A, y, x_lsq, lo, hi, tol):
    """The work of :func:`bvls` (``A`` in Fortran order): scipy's bounded-variable least squares step for
    step, with the minimum-norm least squares at numpy's ``rcond`` on each free set (:func:`_lstsq_free`).
    The index sets are built and applied element by element (the same arithmetic on each element as numpy's
    fancy indexing and concatenation, whose generic code was most of this kernel's compilation on a first
    run)."""
    n, L = A.shape
    x = x_lsq.copy()
    on_bound = np.empty(L)
    for j in range(L):
        on_bound[j] = -1.0 if x[j] <= lo[j] else (1.0 if x[j] >= hi[j] else 0.0)
    x = _clip_nb(x, lo, hi)
    free = _free_of(on_bound)
    while free.size:  # initialisation: free variables whose solution is feasible
        z = _lstsq_free(A, y, x, on_bound, free)
        kept = 0
        for c in range(free.size):
            j = free[c]
            if z[c] < lo[j]:
                x[j], on_bound[j] = lo[j], -1.0
            elif z[c] > hi[j]:
                x[j], on_bound[j] = hi[j], 1.0
            else:
                x[j] = z[c]
                free[kept] = j
                kept += 1
        if kept == free.size:
            break
        free = free[:kept].copy()
    r = _mv(A, x) - y
    cost, g = 0.5 * np.dot(r, r), _mv(A.T, r)
    for _ in range(L):  # loop A: free the bound variable whose gradient points most into the box
        if _kkt_nb(g, on_bound) < tol:
            break
        on_bound[np.argmax(g * on_bound)] = 0.0
        while True:  # loop B: solve on the free set, step back to the first bound crossed
            free = _free_of(on_bound)
            nf = free.size
            xf = np.empty(nf)
            for c in range(nf):
                xf[c] = x[free[c]]
            z = _lstsq_free(A, y, x, on_bound, free)
            n_lo = n_hi = 0
            for c in range(nf):
                if z[c] < lo[free[c]]:
                    n_lo += 1
                elif z[c] > hi[free[c]]:
                    n_hi += 1
            if n_lo + n_hi == 0:
                for c in range(nf):
                    x[free[c]] = z[c]
                break
            v = np.empty(n_lo + n_hi, dtype=np.int64)  # the free entries below their bound, then those above
            alphas = np.empty(n_lo + n_hi)
            k_lo, k_hi = 0, n_lo
            for c in range(nf):
                if z[c] < lo[free[c]]:
                    v[k_lo] = c
                    alphas[k_lo] = (lo[free[c]] - xf[c]) / (z[c] - xf[c])
                    k_lo += 1
            for c in range(nf):
                if z[c] > hi[free[c]]:
                    v[k_hi] = c
                    alphas[k_hi] = (hi[free[c]] - xf[c]) / (z[c] - xf[c])
                    k_hi += 1
            i = np.argmin(alphas)
            a = alphas[i]
            b = 1 - a
            for c in range(nf):
                x[free[c]] = xf[c] * b + a * z[c]
            on_bound[free[v[i]]] = -1.0 if i < n_lo else 1.0
        r = _mv(A, x) - y
        cost_new = 0.5 * np.dot(r, r)
        stalled = cost - cost_new < tol * cost
        cost, g = cost_new, _mv(A.T, r)
        if stalled:
            break
    return x, on_bound


@njit(cache=True)
def _free_of(on_bound):
    """The indices where ``on_bound`` is 0 (``np.flatnonzero(on_bound == 0)``)."""
    n = 0
    for j in range(on_bound.shape[0]):
        if on_bound[j] == 0:
            n += 1
    out = np.empty(n, dtype=np.int64)
    n = 0
    for j in range(on_bound.shape[0]):
        if on_bound[j] == 0:
            out[n] = j
            n += 1
    return out


@njit(cache=True, error_model="numpy")
def _lstsq_free(A, y, x, on_bound, free):
    """The least-squares solution on the free columns with the bound ones' part moved to the right-hand
    side (numpy's ``lstsq(A[:, free], y - A @ where(on_bound != 0, x, 0), rcond=None)``): the minimum-norm
    solution with singular values at or below ``rcond`` times the largest taken as zero (what LAPACK's
    ``gelsd``, numpy's ``lstsq``, solves), from the thin SVD :func:`_svd_thin` the projection compiles
    anyway: ``V diag(1/s) U^T rhs``. numba's ``np.linalg.lstsq`` was 3 s of a first run's compilation (its
    residuals, its rank and a copy of ``b`` whose shape check compiles numba's error message); the answers
    differ from ``gelsd``'s by rounding (a different factorisation of the same 7-40 x 2-5 system)."""
    n = A.shape[0]
    L = free.size
    if L == 0:
        return np.empty(0)
    xb = np.empty(x.shape[0])
    for j in range(x.shape[0]):
        xb[j] = x[j] if on_bound[j] != 0 else 0.0
    rhs = _mv(A, xb)
    for i in range(n):
        rhs[i] = y[i] - rhs[i]
    U, sv, Vt = _svd_thin(_columns(A, free))
    z = np.empty(L)
    for j in range(L):
        z[j] = 0.0
    cut = sv[0] * (EPS * max(n, L))
    for c in range(sv.shape[0]):
        if not sv[c] > cut:
            break
        t = 0.0
        for i in range(n):
            t += U[i, c] * rhs[i]
        t /= sv[c]
        for j in range(L):
            z[j] += Vt[c, j] * t
    return z


@njit(cache=True)
def _clip_nb(x, lo, hi):
    """``np.clip(x, lo, hi)`` as numpy computes it (a NaN stays, a tie keeps the bound: ``clip(-0.0, 0.0)``
    is 0.0, where ``maximum`` would keep -0.0)."""
    out = np.empty(x.shape[0])
    for j in range(x.shape[0]):
        v = x[j]
        if not np.isnan(v):
            v = v if v > lo[j] else lo[j]
        if not np.isnan(v):
            v = v if v < hi[j] else hi[j]
        out[j] = v
    return out


@njit(cache=True)
def _kkt_nb(g, on_bound):
    m = -np.inf
    for j in range(g.shape[0]):
        v = abs(g[j]) if on_bound[j] == 0 else g[j] * on_bound[j]
        if v > m or v != v:
            m = v
    return m


_C1 = nt.float64[::1]
#: The kernels with their signature (numba types), for :func:`frictid.api.compile_kernels`: the regressors in
#: Fortran order (:meth:`Projection._projected` passes only those), every other array contiguous.
KERNELS = ((_project_nb, (nt.Array(nt.float64, 2, "F"), _C1, nt.Array(nt.float64, 3, "C"), _C1, _C1, nt.int64[::1],
                          nt.boolean, _C1, _C1)),
           (_bvls_nb, (nt.Array(nt.float64, 2, "F"), _C1, _C1, _C1, _C1, nt.float64)))


def levenberg_marquardt(resid, jac, x0, lo, hi, scale, budget: int, radius: float = 1.0
                        ) -> tuple[np.ndarray, int, str]:
    """Levenberg-Marquardt on the 1-2 bounded shape parameters of a reduced problem: ``resid(x)`` and
    ``jac(x)`` the residual and its Jacobian, ``scale`` the parameters' typical sizes, ``budget`` residual
    evaluations. Returns x, a status (scipy's codes: 0 budget spent, 1 gradient, 2 cost, 3 step test met)
    and a message.

    What it shares with scipy's ``least_squares``: Marquardt's damping by the diagonal of J^T J in the
    parameters' scales, a step accepted only when it lowers the cost, scipy's tests on the gradient
    (:data:`GTOL`), the cost's relative decrease (:data:`FTOL`) and the step (:data:`XTOL`), an evaluation
    budget, a trust radius in the scaled parameters (``radius`` at first, quartered on a rejected step,
    doubled past an accepted one) that caps the damped step. What it does not do: no trust-region
    subproblem solved by SVD and no Coleman-Li scaling near the bounds; a step that leaves the box is cut
    back onto it, and a parameter at a bound whose gradient points out of the box is held there for the
    step. For two parameters that is enough, and it saves scipy's set-up of each iteration (the problems are
    7-30 points: the arithmetic is microseconds, scipy's loop was 0.3-0.5 ms an iteration)."""
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    # the 1-2 parameters' arithmetic in Python floats (numpy's calls on 2-vectors cost microseconds each; the
    # same IEEE operations, so the same numbers), the products over the points in numpy
    n = x.shape[0]
    lo_, hi_, sc_ = (np.broadcast_to(np.asarray(v, dtype=float), (n,)).tolist() for v in (lo, hi, scale))
    xl = x.tolist()
    unit = all(v == 1.0 for v in sc_)  # (J * 1 is J: the product is skipped)
    r = resid(x)
    cost, nfev, lam = 0.5 * float(r @ r), 1, None
    while True:
        J = jac(x) if unit else jac(x) * scale
        g = (J.T @ r).tolist()
        held = [(xi <= a and gi > 0) or (xi >= b and gi < 0) for xi, gi, a, b in zip(xl, g, lo_, hi_)]
        gf = [0.0 if h else gi for gi, h in zip(g, held)]
        if _absmax(gf) <= GTOL:
            return x, 1, "gradient below GTOL"
        # Marquardt's diagonal of J^T J, floored (a column the residual does not feel, e.g. an exponent
        # along a drop of no amplitude, would leave the damped system singular)
        d = (J * J).sum(axis=0)
        d = np.maximum(d, 1e-12 * max(float(d.max()), TINY))
        lam = 1e-3 * float(d.max()) if lam is None else lam
        free = [not h for h in held]
        Jf = J if all(free) else J[:, np.array(free)]  # (J^T J: the same products either way)
        dl = d.tolist()
        gfree = np.array([v for v, f in zip(gf, free) if f])
        while True:
            if nfev >= budget:
                return x, 0, "the evaluation budget is spent"
            step = iter(damped_step(Jf.T @ Jf, Jf, r, gfree, np.array([lam * v for v, f in zip(dl, free) if f]))
                        .tolist())
            dz = [next(step) if f else 0.0 for f in free]
            cut = min(1.0, radius / max(_absmax(dz), TINY))
            dz = [v * cut for v in dz]
            xl_new = [min(max(xi + si * v, a), b) for xi, si, v, a, b in zip(xl, sc_, dz, lo_, hi_)]
            x_new = np.array(xl_new)
            r_new = resid(x_new)
            nfev += 1
            c_new = 0.5 * float(r_new @ r_new)
            if math.isfinite(c_new) and c_new < cost:
                break
            lam, radius = lam * 4.0, _absmax(dz) / 4.0
            if radius <= XTOL * (XTOL + _absmax([xi / si for xi, si in zip(xl, sc_)])):
                return x, 3, "step below XTOL"
        step = _absmax([(b - a) / si for a, b, si in zip(xl, xl_new, sc_)])
        done = (cost - c_new <= FTOL * cost, step <= XTOL * (XTOL + _absmax([b / si for b, si in zip(xl_new, sc_)])))
        x, xl, r, cost, lam, radius = x_new, xl_new, r_new, c_new, lam / 3.0, max(radius, 2.0 * step)
        if done[0] or done[1]:
            return x, 2 if done[0] else 3, "cost decrease below FTOL" if done[0] else "step below XTOL"


def _absmax(v: list) -> float:
    """The largest |v_i| of a short list, NaN when any is NaN (as numpy's ``abs(v).max()``)."""
    m = 0.0 if v else math.nan
    for e in v:
        a = abs(e)
        if a != a:
            return math.nan
        if a > m:
            m = a
    return m


def bvls(A, y, x_lsq, lo, hi, tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
    """Bounded-variable least squares (Stark and Parker 1995) of ``A x = y`` within ``lo <= x <= hi``, from
    the unbounded solution ``x_lsq``: scipy's ``lsq_linear(method="bvls")`` step for step (its
    initialisation, then loops A and B, the same tolerance ``tol``), without its argument checks, its second
    unbounded solve and its result object, which were 60 % of its time on the maps' 2-5 columns (it runs at
    every evaluation of a reduced residual whose levels leave their bounds), compiled (:func:`_bvls_nb`, which
    the projection's compiled pass calls directly). Returns x and the bound each parameter is at (-1 lower,
    1 upper, 0 free)."""
    return _bvls_nb(np.asfortranarray(A, dtype=float), np.ascontiguousarray(y, dtype=float),
                    np.array(x_lsq, dtype=float), np.ascontiguousarray(lo, dtype=float),
                    np.ascontiguousarray(hi, dtype=float), tol)


def _apart(a, b) -> bool:
    """Two shape vectors in different valleys of the scan: some shape value differs by more than a factor
    :data:`APART` (speeds and exponents alike are compared by ratio)."""
    return bool(np.any(np.abs(np.log(np.asarray(a) / np.asarray(b))) > np.log(APART)))


def _active(x, lo, hi) -> np.ndarray:
    """-1 where x is at its lower bound, 1 at its upper, else 0 (scipy's rule for a bounded solve)."""
    out = np.zeros(x.shape[0], dtype=int)
    out[x - lo <= ACTIVE_RTOL * np.maximum(1.0, np.abs(lo))] = -1
    out[hi - x <= ACTIVE_RTOL * np.maximum(1.0, np.abs(hi))] = 1
    return out


def shape_grid(names: list[str], w, lo, hi, extra: list[dict]) -> np.ndarray:
    """Shape values a cold fit scans: each speed log-spaced from half the slowest point's speed to 0.7 of
    the fastest (:data:`SCAN_POINTS` per speed; the two-exponential speeds with ws1 < ws2 only, the other
    half the same curves), a Stribeck exponent over :data:`DELTA_SCAN`, the lines along each speed's upper
    bound (:func:`_edge_lines`), a step-like drop in each gap between the points (:func:`_step_line`) and
    the ``extra`` starts (name -> value); clipped to the bounds ``lo``, ``hi`` (arrays over ``names``).
    The two-exponential map's speeds start at a tenth of the slowest point's: a term that has died out by
    the slowest point with its amplitude at the bound still bends the first point (a 16-point curve ended 2
    chi-square units above the old multi-start with half, 0.4 at worst of 150 random ones with a tenth)."""
    v = np.abs(np.asarray(w, dtype=float))
    vmin = max(float(v.min()), 1e-9)
    vmax = max(float(v.max()), vmin * 10)
    n_speed = SCAN_POINTS[min(sum(nm != "delta" for nm in names), 2) or 1]
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    axes = [np.asarray(DELTA_SCAN) if nm == "delta" else
            np.geomspace(max(vmin * (0.5 if "delta" in names else 0.1), lo[i]),
                        max(min(hi[i], vmax * 0.7), lo[i]), n_speed)
            for i, nm in enumerate(names)]
    grid = np.vstack([_mesh(axes)] + _edge_lines(names, axes, lo, hi) + _step_line(names, v, lo, hi))
    if "ws1" in names and "ws2" in names:  # the two-exponential map's mirror images: one half of the grid
        grid = grid[grid[:, names.index("ws1")] < grid[:, names.index("ws2")]]  # (models.static.stribeck_2exp_swapped)
    more = np.array([[st[nm] for nm in names] for st in extra], dtype=float).reshape(-1, len(names))
    return np.clip(np.vstack([grid, more]), lo, hi)


def _mesh(axes) -> np.ndarray:
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(axes))


def _step_line(names, v, lo, hi) -> list[np.ndarray]:
    """Grid points with the Stribeck exponent at its upper bound (a step-like drop) and the Stribeck speed
    at :data:`STEP_PER_GAP` log-spaced places between each two neighbouring point speeds: on a few points
    a step between two of them can fit better than any smooth drop, each gap its own valley, narrow in the
    speed (where in the gap the step sits sets how much of it the slower point sees: a factor 1.15 in vs
    doubled the cost on a 7-point curve), which the main grid's exponents (:data:`DELTA_SCAN`) and speeds
    are too coarse to start in (that curve ended 0.05 chi-square units above the old multi-start, whose
    refinement had crossed over into the step)."""
    if "delta" not in names or "vs" not in names:
        return []
    u = np.unique(v[v > 0])
    frac = np.arange(1, STEP_PER_GAP + 1) / (STEP_PER_GAP + 1)
    mids = (u[:-1, None] * (u[1:, None] / u[:-1, None]) ** frac).ravel()
    out = np.empty((mids.size, len(names)))
    out[:, names.index("vs")] = mids
    out[:, names.index("delta")] = hi[names.index("delta")]
    return [out]


def _edge_lines(names, axes, lo, hi) -> list[np.ndarray]:
    """Grid lines with one speed at its upper bound (twice the fastest point's speed) and a Stribeck
    exponent on a fine axis (:data:`EDGE_DELTA_POINTS` over its bounds). A drop whose speed lies beyond
    every point is a power law of the speed with the exponent as its power (``Fs + (Fc - Fs) (v/vs)^delta``
    for v << vs), a valley that runs out to the bound, narrow in the exponent (0.06 of a unit of
    exponent wide on random 10-point curves) and fitting better than any drop within the points on a few
    noisy points: the coarse exponents of the main grid step over it."""
    out = []
    for i, nm in enumerate(names):
        if nm == "delta":
            continue
        ax = [np.array([hi[i]]) if j == i else
              (np.geomspace(lo[j], hi[j], EDGE_DELTA_POINTS) if other == "delta" else axes[j])
              for j, other in enumerate(names)]
        out.append(_mesh(ax))
    return out
