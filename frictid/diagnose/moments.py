"""Gauss-Newton for the factor terms from cached moments: no pass over the samples per iteration.

A model with factors (:mod:`.model`) predicts ``sum_k a_k u_k prod_i (1 + phi_i . gamma_i)`` plus additive
terms, each product over the factors that multiply column ``u_k`` (level factors multiply the level
columns, whole-map factors every friction column, nothing the additive terms). Expanded, it is a linear
combination of *monomial* columns ``u_k phi_i1,j1 phi_i2,j2 ...`` (one column or none of each factor) whose
coefficients are products of the model's coefficients; so is every column of its Jacobian. With ``U`` the
monomial columns, the Gauss-Newton normal equations are ``C' (U'U) C`` and ``C' (U'y - U'U c)``, with c
the prediction's and C the Jacobian's coefficients over the monomials: the sums ``U'U`` and ``U'y`` are
accumulated once per fold and column pair (:meth:`frictid.diagnose.model.Context.pair_sums`, cached like
the linear normal equations) and every iteration works on matrices of the monomials' size. The result is
the Gauss-Newton of the samples (the same iterates up to rounding: ``tests/test_diagnose.py`` compares
them), at a cost per fit of the new column pairs only.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import product

import numpy as np


@dataclass(frozen=True)
class Monomial:
    """One monomial column: linear item ``item`` (its index in the item list) times the factor columns
    ``choice`` (per factor that multiplies the item: -1 for none, else the column's index)."""

    item: int
    factors: tuple  # indices (into the factor list) of the factors that multiply the item
    choice: tuple


def monomials(n_items: int, applies: list[tuple], sizes: list[int]) -> list[Monomial]:
    """Every monomial of the items: ``applies[k]`` the factors multiplying item k, ``sizes[i]`` the number
    of columns of factor i."""
    out = []
    for k in range(n_items):
        fs = applies[k]
        for ch in product(*[range(-1, sizes[i]) for i in fs]):
            out.append(Monomial(k, fs, tuple(ch)))
    return out


def coefficients(monos: list[Monomial], amp: np.ndarray, gam: list[np.ndarray], free_items: list[int],
                 free_gamma: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """The prediction's coefficients c over the monomials and the Jacobian's C (one column per free
    coefficient: the free items' amplitudes, then the free factor coefficients ``(i, j)``).

    amp : amplitude of every item; gam : coefficients of every factor.

    Each monomial's product of its factors' coefficients (1 where it takes none of a factor's columns) is
    formed left to right over its factors, for all monomials at once (:func:`_plan`: where each reads its
    coefficients, kept per layout): a Gauss-Newton run asks for it at every iteration."""
    items, gidx, item_rc, gam_rc = _plan(tuple(monos), tuple(free_items), tuple(free_gamma),
                                         tuple(int(np.size(g)) for g in gam))
    amp = np.asarray(amp, float)
    gflat = np.concatenate([np.atleast_1d(np.asarray(g, float)) for g in gam] + [np.ones(1)])
    vals = gflat[gidx]   # (monomials, factor places); index -1 reads the 1 at the end
    n_places = vals.shape[1]
    prod_all = np.ones(len(monos)) if not n_places else vals[:, 0].copy()
    for p in range(1, n_places):
        prod_all = prod_all * vals[:, p]
    c = amp[items] * prod_all
    C = np.zeros((len(monos), len(free_items) + len(free_gamma)))
    rows, cols = item_rc
    C[rows, cols] = prod_all[rows]
    for p, (rows, cols) in enumerate(gam_rc):
        if not rows.size:
            continue
        others = [q for q in range(n_places) if q != p]
        prod = vals[rows, others[0]].copy() if others else np.ones(rows.size)
        for q in others[1:]:
            prod = prod * vals[rows, q]
        C[rows, cols] = amp[items[rows]] * prod
    return c, C


@lru_cache(maxsize=1024)
def _plan(monos: tuple, free_items: tuple, free_gamma: tuple, sizes: tuple) -> tuple:
    """Where :func:`coefficients` reads each monomial's coefficients: its item, the flat index of each of
    its factors' coefficients (-1: none of that factor's columns; places beyond its factors -1 too), the
    (rows, columns) of C taking a free item's product, and per factor place those taking a free factor
    coefficient's derivative."""
    off = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    n_places = max((len(mo.factors) for mo in monos), default=0)
    gidx = np.full((len(monos), n_places), -1, dtype=int)
    col_of_item = {k: n for n, k in enumerate(free_items)}
    col_of_gam = {ij: len(free_items) + n for n, ij in enumerate(free_gamma)}
    item_r, item_c = [], []
    gam_r, gam_c = [[] for _ in range(n_places)], [[] for _ in range(n_places)]
    for m, mo in enumerate(monos):
        if mo.item in col_of_item:
            item_r.append(m)
            item_c.append(col_of_item[mo.item])
        for p, (i, j) in enumerate(zip(mo.factors, mo.choice)):
            if j >= 0:
                gidx[m, p] = off[i] + j
                if (i, j) in col_of_gam:
                    gam_r[p].append(m)
                    gam_c[p].append(col_of_gam[(i, j)])
    items = np.array([mo.item for mo in monos], dtype=int)
    as_idx = lambda x: np.array(x, dtype=int)   # noqa: E731
    return (items, gidx, (as_idx(item_r), as_idx(item_c)),
            tuple((as_idx(r), as_idx(c)) for r, c in zip(gam_r, gam_c)))


def gauss_newton_step(G: np.ndarray, b: np.ndarray, yty: float, n: int, c: np.ndarray, C: np.ndarray
                      ) -> tuple[np.ndarray, float]:
    """The Gauss-Newton step (scaled columns, pseudo-inverse with rcond 1e-10, as the samples' solve) and
    the residual sum of squares at c. G, b, yty : ``U'U``, ``U'y``, ``y'y``; n the sample count."""
    Gc = G @ c
    cost = float(yty - 2.0 * c @ b + c @ Gc)
    if not C.shape[1]:
        return np.zeros(0), max(cost, 0.0)
    A = C.T @ G @ C
    g = C.T @ (b - Gc)
    d = np.sqrt(np.maximum(A.diagonal(), 0.0) / max(n, 1))
    d[~(d > 0)] = 1.0
    step = np.linalg.pinv(A / np.outer(d, d), rcond=1e-10, hermitian=True) @ (g / d)
    return step / d, max(cost, 0.0)


def rss(G: np.ndarray, b: np.ndarray, yty: float, c: np.ndarray) -> float:
    """Residual sum of squares of the prediction with monomial coefficients c."""
    return max(float(yty - 2.0 * c @ b + c @ G @ c), 0.0)
