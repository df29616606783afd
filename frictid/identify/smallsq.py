"""Nonlinear least squares for small problems: a few parameters, within bounds.

:func:`least_squares` fits the LuGre parameters (:mod:`.presliding`: sigma0 on the ramps, one parameter
against thousands of residuals; sigma1 by simulated steps, one bounded parameter). On these problems
scipy's ``least_squares`` spent most of its time in its own loop (its wrappers of the residual and
Jacobian, argument checks, finite-difference bookkeeping, BLAS products of every residual vector per
iteration, multi-threaded for long vectors) against a few microseconds of arithmetic; this is the same kind of method without that loop.
Large problems (many parameters) stay with scipy.

The method: Levenberg-Marquardt (Marquardt's damping by the diagonal of J^T J in the parameters' scales)
solved by the normal equations (the products over the residuals by ``einsum``: see :func:`_half_square`); a step is accepted only when it lowers the cost, the damping grows by 4 on
a rejected step and shrinks by 3 on an accepted one. Bounds: a step that leaves the box is cut back onto
it, and a parameter at a bound whose gradient points out of the box is held there for the step (the
projected gradient is what the gradient test reads). Tests, as scipy's: the projected gradient's largest
cosine with the residual below ``gtol`` (MINPACK's test, which the residual's units do not move; status
1), the cost's relative decrease below ``ftol`` on a step whose
decrease is at least a quarter of the model's prediction (status 2), the step below ``xtol`` relative to
the parameters (status 3), the budget ``max_nfev`` spent (status 0). The Jacobian is analytic when
``jac`` is given, else forward differences with scipy's step (``sqrt(eps) max(1, |x|)``, turned back at
a bound). What it reports is named as scipy's ``OptimizeResult`` (``x``, ``fun``, ``cost``, ``jac`` at
``x``, ``active_mask``, ``nfev``, ``njev``, ``status``, ``success``), and as scipy it raises
``ValueError`` for a start outside the bounds or residuals that are not finite at the start.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Relative step of the forward differences (scipy's ``2-point``).
FD_STEP = float(np.sqrt(np.finfo(float).eps))


@dataclass
class Result:
    x: np.ndarray
    fun: np.ndarray
    cost: float
    jac: np.ndarray
    active_mask: np.ndarray
    nfev: int
    njev: int
    status: int
    success: bool
    message: str


def least_squares(fun, x0, jac=None, bounds=(-np.inf, np.inf), x_scale=1.0, ftol: float = 1e-8,
                  xtol: float = 1e-8, gtol: float = 1e-8, max_nfev: int | None = None) -> Result:
    """Minimise ``0.5 |fun(x)|^2`` within ``bounds`` (lower, upper; scalars or per parameter) from ``x0``.

    jac : callable ``jac(x)`` -> (residuals, parameters), or None for forward differences.
    x_scale : the parameters' typical sizes (steps and tests are in ``x / x_scale``).
    max_nfev : budget of residual evaluations (without the differences', as scipy's trf); default 100 per
    parameter.
    """
    x = np.atleast_1d(np.asarray(x0, dtype=float)).copy()
    n = x.size
    lo = np.broadcast_to(np.asarray(bounds[0], dtype=float), (n,))
    hi = np.broadcast_to(np.asarray(bounds[1], dtype=float), (n,))
    scale = np.broadcast_to(np.asarray(x_scale, dtype=float), (n,)).copy()
    if np.any(lo >= hi) or np.any(x < lo) or np.any(x > hi):
        raise ValueError("x0 is infeasible or the bounds are inconsistent")
    if np.any(~np.isfinite(scale)) or np.any(scale <= 0):
        raise ValueError("x_scale must be positive and finite")
    budget = 100 * n if max_nfev is None else int(max_nfev)
    r = np.atleast_1d(np.asarray(fun(x), dtype=float))
    if not np.all(np.isfinite(r)):
        raise ValueError("Residuals are not finite in the initial point.")
    counts = {"nfev": 1, "njev": 0}

    def jacobian(x, r):
        counts["njev"] += 1
        if jac is not None:
            return np.atleast_2d(np.asarray(jac(x), dtype=float)).reshape(r.size, n)
        return _forward_differences(fun, x, r, lo, hi)

    cost = _half_square(r)
    J = jacobian(x, r)
    status, message, lam = 0, "the evaluation budget is spent", None
    while status == 0:
        Js = J * scale
        g = np.einsum("ij,i->j", Js, r)
        held = ((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0))
        gf = np.where(held, 0.0, g)
        d = np.einsum("ij,ij->j", Js, Js)
        d = np.maximum(d, 1e-12 * max(float(d.max()), np.finfo(float).tiny))
        if float(np.max(np.abs(gf) / np.sqrt(d))) <= gtol * max(math.sqrt(2.0 * cost), np.finfo(float).tiny):
            status, message = 1, "gradient below gtol"
            break
        lam = 1e-3 * float(d.max()) if lam is None else lam
        step = _accepted_step(fun, x, r, cost, Js, gf, d, lam, held, scale, lo, hi, budget, xtol, counts)
        if step is None:
            status = 0 if counts["nfev"] >= budget else 3
            message = "the evaluation budget is spent" if status == 0 else "step below xtol"
            break
        x_new, r_new, c_new, lam, ratio = step
        dx = float(np.max(np.abs((x_new - x) / scale)))
        small_f = cost - c_new <= ftol * cost and ratio > 0.25
        small_x = dx <= xtol * (xtol + float(np.max(np.abs(x_new / scale))))
        x, r, cost = x_new, r_new, c_new
        J = jacobian(x, r)
        if small_f or small_x:
            status, message = (2, "cost decrease below ftol") if small_f else (3, "step below xtol")
        elif counts["nfev"] >= budget:
            break
    return Result(x, r, cost, J, _active(x, lo, hi, xtol), counts["nfev"], counts["njev"], status, status > 0,
                  message)


def _accepted_step(fun, x, r, cost, Js, gf, d, lam, held, scale, lo, hi, budget, xtol, counts):
    """The first damped step from x that lowers the cost (damping times 4 after each that does not):
    (x, residual, cost, the next damping, actual over predicted decrease), or None when the budget is
    spent or the step has shrunk below xtol first."""
    free = ~held
    while counts["nfev"] < budget:
        dz = np.zeros_like(x)
        Jf = Js[:, free]
        dz[free] = damped_step(np.einsum("ij,ik->jk", Jf, Jf), Jf, r, gf[free], lam * d[free])
        x_new = np.clip(x + scale * dz, lo, hi)
        dz = (x_new - x) / scale
        r_new = np.atleast_1d(np.asarray(fun(x_new), dtype=float))
        counts["nfev"] += 1
        c_new = _half_square(r_new)
        if np.isfinite(c_new) and c_new < cost:
            predicted = -(float(gf @ dz) + _half_square(np.einsum("ij,j->i", Js, dz)))
            return x_new, r_new, c_new, lam / 3.0, (cost - c_new) / predicted if predicted > 0 else 0.0
        lam *= 4.0
        if float(np.max(np.abs(dz))) <= xtol * (xtol + float(np.max(np.abs(x / scale)))):
            return None
    return None


def damped_step(JtJ, J, r, g, damp) -> np.ndarray:
    """The Levenberg-Marquardt step: (J^T J + diag(damp)) dz = -g by the normal equations (``JtJ``, computed
    by the caller: by ``einsum`` here, over long residual vectors; by ``@`` in :mod:`.varpro`, on a few
    points), or, where their matrix is singular in floating point (nearly parallel columns: the normal
    equations square the conditioning), as the least-squares solution of [J; sqrt(damp)] dz = [-r; 0].
    One and two parameters (every call of :mod:`.varpro` and of the LuGre fits) are solved in Python floats
    by LAPACK's own steps (:func:`_solve_small`: the same numbers as ``np.linalg.solve``, without its call)."""
    if g.shape[0] <= 2:
        dz = _solve_small(JtJ, damp, g)
        if dz is not None:
            return dz
    try:
        return np.linalg.solve(JtJ + np.diag(damp), -g)
    except np.linalg.LinAlgError:
        Jd = np.vstack([J, np.diag(np.sqrt(damp))])
        return np.linalg.lstsq(Jd, np.concatenate([-r, np.zeros(J.shape[1])]), rcond=None)[0]


def _solve_small(JtJ, damp, g) -> np.ndarray | None:
    """(JtJ + diag(damp)) dz = -g for one or two unknowns as LAPACK's ``dgesv`` (OpenBLAS) computes it: LU with
    partial pivoting (a row swap only when the second row's pivot is larger), the multiplier by the pivot's
    reciprocal, back substitution by division. None where that meets a zero or non-finite pivot or result
    (``np.linalg.solve`` then decides). Checked against ``np.linalg.solve`` bit for bit on random damped
    normal equations (tests/test_smallsq_solve.py)."""
    M = JtJ.tolist()  # + diag(damp), as numpy adds it (0.0 off the diagonal: -0.0 + 0.0 is 0.0)
    for i, d in enumerate(damp.tolist()):
        M[i] = [e + (d if j == i else 0.0) for j, e in enumerate(M[i])]
    b = [-v for v in g.tolist()]
    if not all(math.isfinite(v) for v in (*b, *(e for row in M for e in row))):
        return None
    if len(b) == 1:
        a = M[0][0]
        x = [b[0] / a] if a != 0.0 else None
    else:
        (a11, a12), (a21, a22) = M
        b1, b2 = b
        if abs(a21) > abs(a11):
            a11, a12, a21, a22, b1, b2 = a21, a22, a11, a12, b2, b1
        if a11 == 0.0:
            return None
        m = a21 * (1.0 / a11)
        u22 = a22 - m * a12
        if u22 == 0.0:
            return None
        x2 = (b2 - m * b1) / u22
        x = [(b1 - a12 * x2) / a11, x2]
    if x is None or not all(math.isfinite(v) for v in x):
        return None
    return np.array(x)


def _forward_differences(fun, x, r, lo, hi) -> np.ndarray:
    """Forward differences of ``fun`` at x (residual r there), scipy's step: sqrt(eps) max(1, |x|) with
    x's sign, turned back where it would leave the bounds. Not counted in ``nfev`` (as scipy's trf)."""
    J = np.empty((r.size, x.size))
    for j in range(x.size):
        h = FD_STEP * max(1.0, abs(float(x[j]))) * (1.0 if x[j] >= 0 else -1.0)
        if not lo[j] <= x[j] + h <= hi[j]:
            h = -h
        xj = x.copy()
        xj[j] = x[j] + h
        h = xj[j] - x[j]  # the step as represented
        J[:, j] = (np.atleast_1d(np.asarray(fun(xj), dtype=float)) - r) / h
    return J


def _active(x, lo, hi, rtol) -> np.ndarray:
    """-1 where x is at its lower bound, 1 at its upper, else 0, within ``rtol max(1, |bound|)`` (scipy's
    ``find_active_constraints``)."""
    out = np.zeros(x.size, dtype=int)
    low = np.isfinite(lo) & (x - lo <= np.minimum(hi - x, rtol * np.maximum(1.0, np.abs(lo))))
    up = np.isfinite(hi) & (hi - x <= np.minimum(x - lo, rtol * np.maximum(1.0, np.abs(hi))))
    out[low], out[up] = -1, 1
    return out


def _half_square(r) -> float:
    """0.5 |r|^2, summed by numpy's own loop (``einsum``): a BLAS dot of a long vector wakes OpenBLAS's
    threads, whose waiting on a loaded machine cost up to 1000 times the sum (20 ms for 50 000 residuals,
    counted as the process's CPU time)."""
    return 0.5 * float(np.einsum("i,i->", r, r))
