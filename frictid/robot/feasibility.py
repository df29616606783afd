"""Physical consistency of identified base parameters: is there a rigid body that has them?

Least squares treats the base parameters as free numbers, so an estimate can belong to no physical robot (a
negative mass, an inertia tensor that breaks the triangle inequality). A set of link parameters is
*physically consistent* when every link's pseudo-inertia matrix

    J = [[S, h], [h^T, m]],   S = tr(I)/2 * 1 - I   (I the rotational inertia about the link frame's origin,
                                                      h = m c the first moments, m the mass)

is positive semidefinite (Wensing, Kim and Slotine 2017): a non-negative mass distribution with those
moments exists. The base parameters are combinations of the link parameters (``beta = K pi``, see
:mod:`.regressor`), so an estimate is consistent when some consistent ``pi`` maps onto it. Searched here as
the nearest consistent set in the estimate's own metric,

    d^2 = min over consistent pi of (K pi - beta)^T Cov(beta)^-1 (K pi - beta),

with each link's J written as ``U U^T`` (U upper triangular: a Cholesky factor, which reaches every
positive semidefinite J, the singular ones on the cone's boundary included; Rucker and Wensing 2022 use its
log-diagonal form for the interior) and a drive's reflected rotor inertia as a square. The problem is convex
in ``pi`` (a quadratic over a convex cone), and a factor of full size has no spurious local minima (Burer and
Monteiro), so the local search (analytic Jacobian) from the nearest projected start finds its minimum. ``d`` is compared with the
95 % quantile of the chi distribution with as many degrees of freedom as base parameters: below it, the
estimate is consistent within its uncertainty.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2

from .regressor import BaseParameters

#: Confidence level of the consistency test.
LEVEL = 0.95
#: Weight of the pull to the start [per unit factor entry, in standard errors]
DAMP = 1e-4
#: Evaluations per start of the search
MAX_EVALS = 1000
_TRI = np.triu_indices(4, 1)


class _Reached(Exception):
    """The search met a consistent set within the limit (its factor entries in ``x``)."""

    def __init__(self, x: np.ndarray):
        super().__init__("consistent set found")
        self.x = x


@dataclass
class Feasibility:
    """The nearest physically consistent link parameters to an estimate of the base parameters."""

    #: Mahalanobis distance of the nearest consistent base parameters from the estimate [standard errors]
    distance: float
    #: the distance a consistent estimate stays below with probability LEVEL
    limit: float
    #: the nearest consistent full parameter set (10 per link, then the rotor inertias if any)
    full: np.ndarray
    #: each base parameter's move to the nearest consistent set, in its own standard errors
    moves: np.ndarray
    #: the search met its tolerance (else it stopped at its evaluation budget, and ``distance`` is an upper
    #: bound: the nearest consistent set may lie closer)
    converged: bool = True

    @property
    def consistent(self) -> bool:
        return self.distance <= self.limit


_DIAG = (np.arange(4), np.arange(4))
#: the factor's 10 free entries: the diagonal, then above it row by row
_SLOTS = (np.concatenate([_DIAG[0], _TRI[0]]), np.concatenate([_DIAG[1], _TRI[1]]))


def _params_of(J: np.ndarray) -> np.ndarray:
    """(..., 10) link parameters in Pinocchio's order (m, mc_x, mc_y, mc_z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz;
    inertia about the frame origin) of (..., 4, 4) pseudo-inertias (a linear map)."""
    S = J[..., :3, :3]
    tr = np.trace(S, axis1=-2, axis2=-1)
    return np.stack([J[..., 3, 3], J[..., 0, 3], J[..., 1, 3], J[..., 2, 3], tr - S[..., 0, 0], -S[..., 0, 1],
                     tr - S[..., 1, 1], -S[..., 0, 2], -S[..., 1, 2], tr - S[..., 2, 2]], axis=-1)


def _factor(u: np.ndarray) -> np.ndarray:
    U = np.zeros(u.shape[:-1] + (4, 4))
    U[..., _SLOTS[0], _SLOTS[1]] = u
    return U


def link_parameters(u: np.ndarray) -> np.ndarray:
    """(n, 10) link parameters of the pseudo-inertias ``U U^T``, U upper triangular with its 10 entries in
    ``u`` (n, 10): the diagonal, then above it row by row."""
    U = _factor(u)
    return _params_of(U @ np.swapaxes(U, -1, -2))


def _link_jacobian(u: np.ndarray) -> np.ndarray:
    """(n, 10, 10): d link parameters / d u, per link (rows: parameters, columns: u)."""
    U = _factor(u)
    E = np.zeros((10, 4, 4))
    E[np.arange(10), _SLOTS[0], _SLOTS[1]] = 1.0
    EU = E[None] @ np.swapaxes(U, -1, -2)[:, None]          # (n, 10, 4, 4): dU_k U^T
    return np.swapaxes(_params_of(EU + np.swapaxes(EU, -1, -2)), 1, 2)


def pseudo_inertia(p: np.ndarray) -> np.ndarray:
    """(n, 4, 4) pseudo-inertia matrices of (n, 10) link parameters (the inverse of :func:`_params_of`)."""
    m, h = p[:, 0], p[:, 1:4]
    ixx, ixy, iyy, ixz, iyz, izz = p[:, 4:].T
    inertia = np.stack([np.stack([ixx, ixy, ixz], -1), np.stack([ixy, iyy, iyz], -1),
                        np.stack([ixz, iyz, izz], -1)], 1)
    J = np.zeros((p.shape[0], 4, 4))
    J[:, :3, :3] = 0.5 * np.trace(inertia, axis1=1, axis2=2)[:, None, None] * np.eye(3) - inertia
    J[:, :3, 3] = J[:, 3, :3] = h
    J[:, 3, 3] = m
    return J


def factor_of(J: np.ndarray, floor: float) -> np.ndarray:
    """The 10 factor entries of the positive definite matrices nearest to J (eigenvalues raised to
    ``floor``): the start of the search."""
    w, V = np.linalg.eigh(0.5 * (J + np.swapaxes(J, -1, -2)))
    Jp = V @ (np.maximum(w, floor)[:, :, None] * np.swapaxes(V, -1, -2))
    # U U^T with U upper triangular: the Cholesky factor of the matrix with rows and columns reversed
    U = np.linalg.cholesky(Jp[:, ::-1, ::-1])[:, ::-1, ::-1]
    return U[:, _SLOTS[0], _SLOTS[1]]


def nearest_consistent(bp: BaseParameters, beta: np.ndarray, cov: np.ndarray, n_links: int) -> Feasibility:
    """The physically consistent link parameters whose base parameters lie nearest ``beta`` (covariance
    ``cov``), and how far they lie. Rotor inertias (columns after the links') are kept non-negative."""
    nl = 10 * n_links
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    whiten = (V / np.sqrt(np.maximum(w, 1e-12 * max(w.max(), 1e-300)))).T   # W with W^T W = cov^-1
    K = np.zeros((bp.n, bp.n_full))
    K[np.arange(bp.n), bp.columns] = 1.0
    K[:, bp.others] = bp.combine
    WK = whiten @ K

    def full_of(x):
        return np.concatenate([link_parameters(x[:nl].reshape(n_links, 10)).reshape(-1), x[nl:] ** 2])

    def resid(x):
        return WK @ full_of(x) - whiten @ beta

    def jac(x):
        links = np.einsum("bkp,kpu->bku", WK[:, :nl].reshape(-1, n_links, 10),
                          _link_jacobian(x[:nl].reshape(n_links, 10))).reshape(bp.n, nl)
        return np.hstack([links, WK[:, nl:] * (2.0 * x[nl:])])

    # start: the minimum-norm full set with these base parameters, each link's J pushed into the cone
    start = np.linalg.lstsq(K, beta, rcond=None)[0]
    J0 = pseudo_inertia(start[:nl].reshape(n_links, 10))
    scale = max(float(np.max(np.abs(J0))), 1e-6)
    limit = float(np.sqrt(chi2.ppf(LEVEL, bp.n)))

    def fun(x):
        r = resid(x)
        if r @ r <= limit * limit:   # consistent within the uncertainty: that answers the question
            raise _Reached(x.copy())
        return np.concatenate([r, DAMP * (x - x0)])

    best, converged = None, False
    for floor in (1e-3, 1e-1):   # two starts: a convex problem, but a flat start can stall the search
        x0 = np.concatenate([factor_of(J0, floor * scale).reshape(-1), np.sqrt(np.abs(start[nl:]))])
        # a faint pull to the start makes the problem overdetermined for MINPACK's Levenberg-Marquardt
        # (the base parameters fix fewer numbers than the factors have); it moves the distance by ~DAMP
        try:
            sol = least_squares(fun, x0, method="lm", jac=lambda x: np.vstack([jac(x), DAMP * np.eye(x.size)]),
                                max_nfev=MAX_EVALS, xtol=1e-14, ftol=1e-14, gtol=1e-14)
        except _Reached as hit:
            best, converged = hit.x, True
            break
        # compare the starts by the distance alone (``sol.cost`` also holds the pull to the start)
        if best is None or np.sum(resid(sol.x) ** 2) < np.sum(resid(best) ** 2):
            best, converged = sol.x, sol.status > 0
    full = full_of(best)
    se = np.sqrt(np.maximum(np.diag(cov), 1e-300))
    return Feasibility(float(np.linalg.norm(resid(best))), limit, full, (K @ full - beta) / se, bool(converged))


def feasibility_note(f: Feasibility, names: list[str]) -> str:
    """One sentence for the parameter file and the console."""
    if f.consistent:
        return (f"physical feasibility: a set of link inertias with positive semidefinite pseudo-inertias "
                f"reproduces the base parameters within their uncertainty (Mahalanobis distance "
                f"{f.distance:.2g}, 95 % limit {f.limit:.2g})")
    worst = np.argsort(-np.abs(f.moves))[:3]
    moves = ", ".join(f"{names[k]} {f.moves[k]:+.1f}" for k in worst)
    if not f.converged:
        return (f"physical feasibility not shown: the nearest consistent set of link inertias found lies "
                f"{f.distance:.3g} standard errors from the identified base parameters (95 % limit "
                f"{f.limit:.2g}), and the search stopped at its budget; largest moves: {moves}")
    return (f"link inertias not physically consistent: the nearest consistent set lies {f.distance:.3g} "
            f"standard errors from the identified base parameters (95 % limit {f.limit:.2g}); largest moves, "
            f"in standard errors: {moves}. The rigid-body estimate absorbs something else (friction, "
            f"unmodelled dynamics, a mismatched robot description)")
