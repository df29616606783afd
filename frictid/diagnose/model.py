"""The diagnosis' model family: a base static map and the extension terms, fitted by alternating least
squares, converted to parameter-file entries that :mod:`frictid.replay` runs.

A model predicts the friction torque of a sliding sample as (the same structure as the replay kernel)::

    F = mA (mL (g(w) + dc0 x sgn w) + f(w) + x (dc1 w + dc2 w|w| + dc3 w^3)) + sum_j gamma_j phi_j

- ``g(w) = sgn(w) [a0 + a1 e1(|w|) + a2 e2(|w|)]`` and ``f(w) = b1 w + b2 w|w| + b3 w^3``: the base map's
  canonical form (:mod:`frictid.models.static`) with its shape parameters (Stribeck velocities and
  exponent) held at the base fit's values, so the amplitudes enter linearly; per-sign amplitudes when
  the ``asym`` extension is in; a Stribeck column when the ``stribeck`` extension adds one;
- ``mL = prod_i (1 + phi_i gamma_i)``: level factors (``position_periodic`` sin/cos of ``2 pi q / P``,
  ``position_smooth`` ``q - q0`` and ``(q - q0)^2``, ``load_*`` the transmitted torque, the gravity torque or
  the payload);
- ``mA``: whole-map factors (``drift`` hours on the drift clock, ``thermal4`` the thermal state ``x``);
- ``thermal6``: slopes of a0, b1, b2, b3 per kelvin of ``x`` (002's c0'..c3');
- additive terms: ``offset`` (1), ``inertia`` (acceleration), ``gravity`` (cos q, sin q).

Given the factors the model is linear in the amplitudes and additive terms; given everything else it is
linear in each factor's coefficients. :meth:`Evaluator.fit` starts from the exact linear solution with
the factors at one and solves the coupled (bilinear) problem by Gauss-Newton.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field, replace

import numpy as np

from ..identify.regression import NormalEquations, solve
from ..models.static import low_speed_name
from . import moments as mo
from .binned import equal_count_bins
from .gathered import Gathered
from .samples import Samples
from .previous import previous_columns
from .signals import delay_column, dwell_state

#: Extensions the parameter file's friction models do not carry: causes the diagnosis names (a finding with
#: its numbers, in ``selection.diagnosis.outside_model`` and the warnings) but never exports. Their terms
#: stay in the chain's structure, so the friction terms found after them are fitted on a clean residual.
OUTSIDE_MODEL = ("dwell", "delay", "position_torque")

#: Canonical slots: level (a0, a1, a2) and viscous (b1, b2, b3).
LEVEL_SLOTS = (0, 1, 4)
VISCOUS_SLOTS = (6, 7, 8)

#: Which canonical slots each base map uses.
MAP_SLOTS = {
    "coulomb_viscous": (0, 6),
    "stribeck": (0, 1, 6),
    "stribeck_2exp": (0, 1, 4, 6, 7),
    "polynomial": (0, 6, 7, 8),
}


@dataclass(frozen=True)
class Term:
    """One extension. ext : its name; role : how it enters; nl : its nonlinear settings (period, time
    constant, variable, ...), chosen before the linear fit."""

    cause: str
    ext: str
    role: str  # level_factor, whole_factor, thermal6, additive, stribeck, asym
    nl: tuple = ()
    in_base: bool = False  # part of the base (re-estimated rigid-body terms), not a finding

    @property
    def settings(self) -> dict:
        return dict(self.nl)


@dataclass
class Structure:
    """A base map (symmetric, shapes fixed) and the extension terms, in the order they were found."""

    map: str
    shapes: np.ndarray  # canonical vector of the base fit (only vs1, d1, vs2 are used)
    terms: tuple = ()

    @property
    def asym(self) -> bool:
        """Per-sign amplitudes (the ``asym`` extension)."""
        return any(t.role == "asym" for t in self.terms)

    @property
    def per_sign(self) -> bool:
        """The model has a per-sign map: per-sign amplitudes or the w < 0 branch scaled (``asym_scale``)."""
        return any(t.ext in ("asym", "asym_scale", "asym_level") for t in self.terms)

    def has(self, ext_or_cause: str) -> bool:
        return any(t.ext == ext_or_cause or t.cause == ext_or_cause for t in self.terms)

    def plus(self, term: Term) -> "Structure":
        return replace(self, terms=tuple(self.terms) + (term,))

    @property
    def name(self) -> str:
        return "+".join([self.map] + [t.ext for t in self.terms if not t.in_base and t.ext not in OUTSIDE_MODEL])

    def slots(self) -> tuple:
        s = list(MAP_SLOTS[self.map])
        if any(t.role == "stribeck" for t in self.terms) and 1 not in s:
            s.append(1)
        return tuple(sorted(s))


@dataclass
class Coef:
    """Coefficients of a fitted :class:`Structure`: base amplitudes per canonical slot (and per sign),
    thermal6 slopes, and each term's gamma (by term index)."""

    base_pos: dict
    base_neg: dict
    dc: np.ndarray = field(default_factory=lambda: np.zeros(4))
    gamma: dict = field(default_factory=dict)
    rms: float = float("nan")
    n: int = 0
    excluded: list = field(default_factory=list)


def _block(out: np.ndarray, vecs: list, s: int, e: int, rows_of=None, done=None) -> np.ndarray:
    """Rows ``vecs[j][s:e]`` of out (a tuple of vectors: their product), in place. ``rows_of[j] >= 0``: the
    vector is ``done``'s row of that index (the same vector, formed already in this block): copied from it."""
    for j, v in enumerate(vecs):
        if rows_of is not None and rows_of[j] >= 0:
            out[j] = done[rows_of[j]]
        elif isinstance(v, tuple):
            np.multiply(v[0][s:e], v[1][s:e], out=out[j])
            for x in v[2:]:
                out[j] *= x[s:e]
        elif isinstance(v, Gathered):   # read from its table into the row (:mod:`.gathered`)
            v.fill(out[j], s, e)
        else:
            out[j] = v[s:e]
    return out


#: Samples per block of the streamed sums of products (:meth:`Context.fold_products`): 32 kB per column,
#: so a block's columns stay in the second-level cache between their copy and their product (blocks of
#: 65 k samples, 4 MB per 8 columns, made the copies and the product go through memory twice).
BLOCK_ROWS = 1 << 14



def load_variable(S: Samples, ext: str, nl: dict) -> np.ndarray:
    """The variable of a load term: the payload, or the torque the transmission carries besides friction
    (``load_torque``: ``|J a + G|``; ``load_gravity``: ``|G|``) with the model's own corrections of the
    fit's rigid body, ``dPx cos q + dPy sin q`` (its gravity term) and ``dJ a`` (its inertia term), from the
    settings (:func:`frictid.diagnose.causes.propose`): the friction the fit took out with a biased gravity
    is the torque the corrected model puts back (a load that raises the friction with ``|G|`` biases the
    fit's gravity, and ``|G|`` of the fit then crosses zero at the wrong angles)."""
    if ext == "load_payload":
        return S.payload
    # the last variables are kept, one per training set and one for all samples: each fold's proposal scales
    # its own (the current model's gravity and inertia corrections differ by fold), and the candidate's
    # columns, formed after the proposals, are the same variables
    key = (ext,) + tuple(float(nl.get(k, 0.0)) for k in ("dPx", "dPy", "dJ"))
    last = S.cached("load_variable_last", lambda: {})
    if key in last:
        last[key] = last.pop(key)   # the most recent last
        return last[key]
    corr = 0.0
    if S.q is not None and (nl.get("dPx", 0.0) or nl.get("dPy", 0.0)):
        cq = S.cached("cos_q", lambda: np.cos(S.q))
        sq = S.cached("sin_q", lambda: np.sin(S.q))
        corr = nl.get("dPx", 0.0) * cq + nl.get("dPy", 0.0) * sq
    if ext == "load_gravity":
        out = np.abs(S.G + corr)
    else:
        if nl.get("dJ", 0.0):
            corr = corr + nl["dJ"] * S.a
        out = np.abs(S.cached("rigid_torque", lambda: S.tau - S.F) + corr)
    while len(last) > S.n_folds:
        del last[next(iter(last))]
    last[key] = out
    return out

def _abs_max(x: np.ndarray) -> float:
    """``max(|x|)`` of a finite array without the array of ``|x|`` (a joint-hour's 29 MB of fresh pages):
    the larger of its maximum and its minimum's negative, the same number."""
    return abs(max(float(np.max(x)), -float(np.min(x))))


class Context:
    """Column cache for one :class:`Samples` (columns of the base map and of each term)."""

    def __init__(self, S: Samples, use_normal_equations: bool = True):
        self.S = S
        self._cache: dict = {}
        #: solve linear fits on whole folds from the cached normal equations (False: dense least squares on
        #: the samples, as before; kept for benchmarks/diagnosis_scorecard.py --bench, which compares both)
        self.use_normal_equations = use_normal_equations
        self.sgn = np.sign(S.w)
        self.pos = S.w >= 0
        self._fold_memo: dict = {}
        self.v = np.abs(S.w)
        # the largest speed and acceleration of the logs (not only of the sliding samples)
        self.w_top = max(_abs_max(S.log_w(i)) for i in range(len(S.logs)))
        self.a_top = max(_abs_max(S.log_a(i)) for i in range(len(S.logs)))
        #: (the context of all samples, the indices of S's samples in them) when S is a stride of them
        #: (:class:`frictid.diagnose.search.StrideSearch`): the thermal states, a recursion over the whole
        #: logs, are then that context's at these samples (one recursion per time constant, shared)
        self.full: tuple | None = None

    @staticmethod
    def base_key(slot: int, shapes, term_nl=None) -> tuple:
        return ("base", slot, tuple(np.round(np.asarray(shapes, float)[[2, 3, 5]], 12)), term_nl)

    # normal equations ---------------------------------------------------------------------------------
    def fold_of(self, idx) -> int | None | bool:
        """None when idx holds every sample, f when it holds exactly the samples outside fold f (a training
        set), False otherwise."""
        S = self.S
        if "fold_counts" not in self._cache:
            self._cache["fold_counts"] = np.bincount(S.fold, minlength=S.n_folds)
        full = self._cache["fold_counts"]
        if idx.size == S.n:
            return None
        # the chain passes the same training arrays again and again: remembered while they live
        memo = self._fold_memo.get(id(idx))
        if memo is not None and memo[0]() is idx:
            return memo[1]
        cnt = np.bincount(S.fold[idx], minlength=S.n_folds)
        miss = np.flatnonzero(cnt == 0)
        out = False
        if miss.size == 1 and np.array_equal(np.delete(cnt, miss), np.delete(full, miss)):
            out = int(miss[0])
        self._fold_memo[id(idx)] = (weakref.ref(idx), out)
        return out

    def _set_pair(self, ka, kb, v: np.ndarray) -> None:
        """Cache the per-fold sums of a pair. A pair summed again (with a list of columns whose other pairs
        were missing: other blocks, another rounding) replaces the old sums, as before, and the systems
        assembled from them (:meth:`_stacked`) are assembled again."""
        if ("pair", ka, kb) in self._cache or ("pair", kb, ka) in self._cache:
            self._cache.pop("stacked", None)
        self._cache[("pair", ka, kb)] = v

    def _cached_pair(self, ka, kb):
        out = self._cache.get(("pair", ka, kb))
        return self._cache.get(("pair", kb, ka)) if out is None else out

    def _fold_bounds(self) -> np.ndarray:
        """Each fold's bounds in the samples' order (the samples are in folds, :func:`.samples._fold_major`)."""
        if "fold_bounds" not in self._cache:
            fold = self.S.fold
            if fold.size and np.any(np.diff(fold) < 0):
                raise ValueError("the diagnosis' samples must be ordered by fold")
            counts = np.bincount(fold, minlength=self.S.n_folds)
            self._cache["fold_bounds"] = np.concatenate([[0], np.cumsum(counts)])
        return self._cache["fold_bounds"]

    def fold_products(self, vecs: list, others: list | None = None) -> np.ndarray:
        """Per-fold sums of the products of every vector with every other, ``out[f, i, j] = sum_f v_i o_j``
        (others default: vecs; a tuple of vectors stands for their product): streamed over blocks of :data:`BLOCK_ROWS` consecutive samples of one fold
        (the block's columns copied side by side, one matrix product per block), so the memory is one block
        whatever the log's length."""
        bounds = self._fold_bounds()
        same = others is None
        others = vecs if same else others
        m, k = len(vecs), len(others)
        out = np.zeros((self.S.n_folds, m, k))
        rows = min(BLOCK_ROWS, max(self.S.n, 1))
        V, W = np.empty((m, rows)), (None if same else np.empty((k, rows)))
        # a vector among both lists (a bordered system's rows and its new columns) is formed once per block and
        # copied (its product, a gather from its table): B stays its own array, so the product is the same call
        ids = {id(v): i for i, v in enumerate(vecs)}
        rows_of = None if same else [ids.get(id(o), -1) for o in others]
        for f in range(self.S.n_folds):
            for s in range(bounds[f], bounds[f + 1], BLOCK_ROWS):
                e = min(s + BLOCK_ROWS, bounds[f + 1])
                A = _block(V[:, :e - s], vecs, s, e)
                B = A if same else _block(W[:, :e - s], others, s, e, rows_of, A)
                out[f] += A @ B.T
        return out

    def prefetch(self, structures: list) -> None:
        """Cache the per-fold sums that fits of several structures will ask for (the settings of one
        candidate's grid: Stribeck velocities, time constants, rest scales, periods, each on top of the same
        current model) in one pass over the samples: the current model's columns, which every setting's
        border meets, are read once for all of them (:meth:`_border_products`), not once per setting. The
        sums are those :meth:`_fill_pairs` would accumulate setting by setting."""
        if not self.use_normal_equations:
            return
        groups = {}   # the same setting in several folds (an offset, a load term) is one list
        for st in structures:
            for g in Evaluator(st, self)._sum_groups():
                groups.setdefault(tuple(k for k, _ in g), g + [(("y",), self.S.F)])
        self._prefetch_groups(list(groups.values()))

    def _prefetch_groups(self, groups: list) -> None:
        """:meth:`prefetch` of lists of (key, vector), each list's pairs wanted; one list is summed as a fit
        would sum it (:meth:`_fill_pairs`, the same numbers)."""
        if len(groups) == 1:
            return self._fill_pairs(groups[0])
        vec, missing = {}, []
        for items in groups:
            for i in range(len(items)):
                for j in range(i, len(items)):
                    ka, kb = items[i][0], items[j][0]
                    if self._cached_pair(ka, kb) is None:
                        missing.append((ka, kb))
                        vec[ka], vec[kb] = items[i][1], items[j][1]
        if not missing:
            return
        new = {a for a, b in missing if a == b}   # a column whose own sum is missing has none cached
        seen: dict = {}
        for items in groups:
            for k in dict.fromkeys(x[0] for x in items):
                seen[k] = seen.get(k, 0) + (k in new)
        shared = [k for k, c in seen.items() if c > 1]
        if shared:   # new columns that several lists share (no current model summed yet): theirs first
            self._fill_pairs([(k, vec[k]) for k in shared])
            return self._prefetch_groups(groups)
        if any(a not in new and b not in new for a, b in missing):   # two old columns never met
            for items in groups:
                self._fill_pairs(items)
            return
        old = [k for k in vec if k not in new]
        order, spans = [], []   # the new columns list by list (a list's rows one slice of the block)
        for items in groups:
            mine = [k for k in dict.fromkeys(x[0] for x in items) if k in new]
            spans.append((len(order), len(order) + len(mine)))
            order += mine
        P, Q = self._border_products([vec[k] for k in old], [vec[k] for k in order], spans)
        for a, ka in enumerate(old):
            for b, kb in enumerate(order):
                self._set_pair(ka, kb, P[:, a, b].copy())
        for (s0, s1), q in zip(spans, Q):
            for a in range(s1 - s0):
                for b in range(a, s1 - s0):
                    self._set_pair(order[s0 + a], order[s0 + b], q[:, a, b].copy())

    def _border_products(self, olds: list, news: list, spans: list) -> tuple[np.ndarray, list]:
        """Per-fold sums of the products of every old vector with every new one, and of the new ones of each
        span with each other (:meth:`fold_products`' blocks)."""
        bounds = self._fold_bounds()
        nf, m, k = self.S.n_folds, len(olds), len(news)
        P = np.zeros((nf, m, k))
        Q = [np.zeros((nf, s1 - s0, s1 - s0)) for s0, s1 in spans]
        rows = min(BLOCK_ROWS, max(self.S.n, 1))
        V, W = np.empty((m, rows)), np.empty((k, rows))
        for f in range(nf):
            for s in range(bounds[f], bounds[f + 1], BLOCK_ROWS):
                e = min(s + BLOCK_ROWS, bounds[f + 1])
                A = _block(V[:, :e - s], olds, s, e)
                B = _block(W[:, :e - s], news, s, e)
                P[f] += A @ B.T
                for (s0, s1), q in zip(spans, Q):
                    if s1 > s0:
                        q[f] += B[s0:s1] @ B[s0:s1].T
        return P, Q

    def _fill_pairs(self, items) -> None:
        """Cache the per-fold sums of every pair of items (list of (key, vector or callable)) not cached yet.
        A candidate's system is the current one bordered by new columns: only the border is accumulated
        (the products of the items of missing pairs with the new ones, :meth:`fold_products`)."""
        p = len(items)
        missing = [(i, j) for i in range(p) for j in range(i, p)
                   if self._cached_pair(items[i][0], items[j][0]) is None]
        if not missing:
            return
        rows = sorted({x for ij in missing for x in ij})
        new = [i for i in rows if (i, i) in missing]
        # every missing pair has a new item, or (a pair of old columns never met) all of them are new
        cols = new if new and all(i in new or j in new for i, j in missing) else rows
        vec = {i: items[i][1] for i in rows}
        P = self.fold_products([vec[i] for i in rows], [vec[j] for j in cols])
        for a, i in enumerate(rows):
            for b, j in enumerate(cols):
                self._set_pair(items[i][0], items[j][0], P[:, a, b].copy())

    def normal_equations(self, items, fold: int | None):
        """:class:`frictid.identify.regression.NormalEquations` of the columns ``items`` (list of (key, vector))
        against the friction torque, over all samples (fold None) or outside fold ``fold``. A vector may be
        given as a tuple of vectors (their product, formed block by block only when a sum is not cached).

        Accumulated once per fold and column pair and cached: a candidate's system is the current one
        bordered by its own columns, and only the border is new."""
        S = self.S
        T = self._stacked(items)
        p = len(items)
        A = T.sum(axis=0) if fold is None else T.sum(axis=0) - T[fold]
        # contiguous copies, as the pair-by-pair assembly gave: BLAS may round a strided matrix's products apart
        XtX, Xty, yty = np.ascontiguousarray(A[:p, :p]), A[:p, p].copy(), float(A[p, p])
        full = self._cache.get("fold_counts")
        if full is None:
            full = self._cache["fold_counts"] = np.bincount(S.fold, minlength=S.n_folds)
        n = int(full.sum() - (0 if fold is None else full[fold]))
        return NormalEquations(p, XtX, Xty, yty, n)

    def _stacked(self, items) -> np.ndarray:
        """Every fold's sums of the products of the columns ``items`` and the friction torque (its last row
        and column), ``T[f, i, j]``, assembled from the cached pairs once per list of keys: the folds' fits of
        one structure (a candidate's five training sets, a grid setting's) ask for the same list, and
        assembling it pair by pair was most of a fit's own time. ``T.sum(0) - T[f]`` adds the folds in the
        order a pair's ``v.sum() - v[f]`` did, the same numbers."""
        keys = tuple(k for k, _ in items)
        memo = self._cache.setdefault("stacked", {})
        T = memo.get(keys)
        if T is not None:
            return T
        allk = list(items) + [(("y",), self.S.F)]
        self._fill_pairs(allk)
        p = len(allk)
        T = np.empty((self.S.n_folds, p, p))
        for i in range(p):
            ka = allk[i][0]
            for j in range(i, p):
                T[:, i, j] = T[:, j, i] = self._cached_pair(ka, allk[j][0])
        memo[keys] = T
        return T

    def position_bins(self, idx: np.ndarray, p_min: float) -> tuple:
        """The bins of :func:`frictid.diagnose.causes.best_period` over the positions of the samples idx with a
        level of one (the position torque's periodogram): the lowest position, the range, each sample's bin of
        ``p_min / 32`` and the samples per bin (floats), the same numbers as it computes. A sample's bin
        depends on the lowest position and the range only: for all samples or a training set it is read off
        the bins of every sample for that lowest position and range (an encoder's extremes recur: one array
        serves every training set and every step of the chain), and the samples per bin are kept."""
        S, fold = self.S, self.fold_of(idx)
        h2 = p_min / 32.0
        if fold is False:
            q = np.asarray(S.q[idx], float)
            q0, rng = float(q.min()), float(np.ptp(q))
            nb2 = int(rng / h2) + 1
            j2 = np.minimum(((q - q0) / h2).astype(np.int64), nb2 - 1)
            return q0, rng, j2, np.bincount(j2, minlength=nb2).astype(float)
        b = self._fold_bounds()
        parts = [slice(b[g], b[g + 1]) for g in range(S.n_folds) if g != fold and b[g + 1] > b[g]]
        key = ("position_bins", fold, float(p_min))
        got = self._cache.get(key)
        if got is None:
            q0 = min(float(S.q[p].min()) for p in parts)
            rng = float(np.float64(max(float(S.q[p].max()) for p in parts)) - np.float64(q0))   # np.ptp's
            nb2 = int(rng / h2) + 1
            every = ("position_bins_all", q0, nb2, h2)
            if every not in self._cache:
                self._cache[every] = np.minimum(((np.asarray(S.q, float) - q0) / h2).astype(np.int64), nb2 - 1)
            got = (q0, rng, every, None)
        q0, rng, every, B2 = got
        j2 = self._cache[every]
        j2 = j2 if fold is None else np.concatenate([j2[p] for p in parts])
        if B2 is None:
            B2 = np.bincount(j2, minlength=int(rng / h2) + 1).astype(float)
            self._cache[key] = (q0, rng, every, B2)
        return q0, rng, j2, B2

    def extremes(self, term: Term, cols=None) -> np.ndarray:
        """Rows of the term's columns (``cols`` of them, default all) among which every linear function of
        them reaches its largest and smallest value over the samples: the smallest and largest value of
        one column (cached); all rows for more columns (the hull of points along a curve, as sin and cos
        of the position or q and q^2 are, holds nearly all of them)."""
        key = ("extremes", term.ext, term.nl, cols)
        if key not in self._cache:
            if term.ext == "thermal6" and cols is not None and len(cols) == 1:   # one product, not all four
                X = _product(self.term_vectors(term)[cols[0]])[:, None]
            elif cols is None and _periodic(term) and self._cache.get("q2pi", (None, None))[1] is not None:
                X = sin_cos(self._cache, None, term.settings["period"])   # one row per distinct position
            elif self.position_table(term) is not None:   # the same values, one row per distinct position
                X = self.position_table(term)
                X = X if cols is None else X[:, list(cols)]
            else:
                X = self.term_columns(term)
                X = X if cols is None else X[:, list(cols)]
            self._cache[key] = np.vstack([X.min(axis=0), X.max(axis=0)]) if X.shape[1] == 1 and X.size else X
        return self._cache[key]

    def spread(self, term: Term, g: np.ndarray) -> float:
        """The standard deviation over the samples of the term's correction ``term_columns(term) @ g`` (0 when
        g does not match its columns). A periodic position term whose positions repeat (:func:`sin_cos`)
        is evaluated once per distinct position, weighted by how many samples hold it: the same mean and
        spread without forming its columns over every sample (a confound check reads the five folds'
        corrections after the trial released their columns)."""
        q2pi = self._cache.get("q2pi", (None, None))
        if _periodic(term) and q2pi[1] is not None and ("term", term.ext, term.nl) not in self._cache:
            X = sin_cos(self._cache, None, term.settings["period"])
            if g.size != X.shape[1]:
                return 0.0
            if "q2pi_counts" not in self._cache:
                self._cache["q2pi_counts"] = np.bincount(q2pi[1], minlength=X.shape[0]).astype(float)
            cnt = self._cache["q2pi_counts"]
            v = X @ g
            n = float(cnt.sum())
            mean = float(cnt @ v) / n
            return float(np.sqrt(max(float(cnt @ (v - mean) ** 2) / n, 0.0)))
        cols = self.term_columns(term)
        return float(np.std(cols @ g)) if g.size == cols.shape[1] else 0.0

    def release(self, st: Structure) -> None:
        """Drop the cached columns that no term of st uses: those of a candidate's settings (time constants,
        Stribeck velocities, periods) once it is judged. Their sums of products stay cached (small); a
        column needed again is computed again. Keeps the diagnosis' memory to the current model's columns
        plus one candidate's (on a one-hour log, 1.1 GB above the fit without it before).

        The thermal states stay while st has no thermal term: the grid's states serve the time-constant
        check (:func:`frictid.diagnose.causes.tau_grid`), both thermal candidates and the chosen one's
        proposal on all samples (each a recursion over the whole logs, computed up to four times before;
        12 states, 110 MB on the one-hour bench log, where thermal6 no longer stores its four columns per
        state: :meth:`_thermal6_vectors`; the diagnosis' measured peak did not rise)."""
        terms = {(t.ext, t.nl) for t in st.terms}
        strib = {(t.settings["vs"], t.settings["delta"]) for t in st.terms if t.role == "stribeck"}
        thermal = {(round(float(t.settings["tau_c"]), 9), t.settings.get("source", "heat_balance"),
                    float(t.settings.get("K", 1.0))) for t in st.terms if t.ext in ("thermal4", "thermal6")}
        keep_states = not thermal

        def stale(k) -> bool:
            kind = k[0]
            if kind in ("term", "term_vectors", "extremes", "table"):
                return (k[1], k[2]) not in terms
            if kind == "base":
                return k[3] is not None and k[3] not in strib
            if kind == "signed":
                return stale(k[1])
            if kind == "thermal":
                return not keep_states and (k[1], k[2], k[3]) not in thermal
            return False

        for k in [k for k in self._cache if isinstance(k, tuple) and k and stale(k)]:
            del self._cache[k]

    def y_scale(self, idx, fold) -> float:
        """The largest |F| [F] on samples idx (cached for a fold's training set or all samples)."""
        def compute():
            y = self.S.F[idx]
            return float(np.max(np.abs(y))) if y.size else 1.0
        if fold is False:
            return compute()
        key = ("y_scale", fold)
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

    def abs_max(self, key, col, idx, fold) -> float:
        """The largest |col| on samples idx; for all samples or a fold's training set (``fold`` from
        :meth:`fold_of`) from the per-fold maxima of the column, cached under its key (no gather)."""
        if fold is False:
            return float(np.max(np.abs(col[idx])))
        k = ("abs_max", key)
        if k not in self._cache:
            b = self._fold_bounds()
            self._cache[k] = np.array([float(np.max(np.abs(col[b[f]:b[f + 1]]))) if b[f + 1] > b[f] else -np.inf
                                       for f in range(self.S.n_folds)])
        per = self._cache[k]
        return float(np.max(per if fold is None else np.delete(per, fold)))

    def signed(self, key, col, positive: bool) -> np.ndarray:
        """col on the samples of one velocity sign (w >= 0 or w < 0), zero elsewhere (cached)."""
        k = ("signed", key, positive)
        if k not in self._cache:
            m = self.S.w >= 0
            self._cache[k] = col * (m if positive else ~m)
        return self._cache[k]

    def base_column(self, slot: int, shapes, term_nl=None) -> np.ndarray:
        key = self.base_key(slot, shapes, term_nl)
        if key not in self._cache:
            w, v, s = self.S.w, self.v, self.sgn
            if slot == 0:
                c = s
            elif slot == 1:   # s exp(-(v / vs)^d), in place (a Stribeck grid makes 16 of them)
                vs, d = (shapes[2], shapes[3]) if term_nl is None else term_nl
                c = np.divide(v, vs)
                np.power(c, d, out=c)
                np.negative(c, out=c)
                np.exp(c, out=c)
                np.multiply(s, c, out=c)
            elif slot == 4:   # s (1 - exp(-v / vs2)), in place
                c = np.negative(v)
                np.divide(c, shapes[5], out=c)
                np.exp(c, out=c)
                np.subtract(1.0, c, out=c)
                np.multiply(s, c, out=c)
            elif slot == 6:
                c = w
            elif slot == 7:
                c = w * v
            else:
                c = w ** 3
            self._cache[key] = c
        return self._cache[key]

    def term_columns(self, term: Term) -> np.ndarray:
        key = ("term", term.ext, term.nl)
        if key in self._cache:
            return self._cache[key]
        S, nl = self.S, term.settings
        if term.ext == "position_periodic":
            c = sin_cos(self._cache, S.q, nl["period"])
        elif term.ext == "position_smooth":
            d = (S.q - nl["q0"]) / nl["qs"]
            c = np.empty((2, d.size))
            c[0] = d
            np.multiply(d, d, out=c[1])
            c = c.T
        elif term.ext.startswith("load_"):
            c = (load_variable(S, term.ext, nl) / nl["scale"])[:, None]
        elif term.ext == "drift":
            c = S.th[:, None]
        elif term.ext in ("asym_scale", "asym_level"):
            c = (S.w < 0).astype(float)[:, None]
        elif term.ext in ("thermal4", "thermal6"):
            x = self.thermal(nl["tau_c"], nl.get("source", "heat_balance"), nl.get("K", 1.0))
            if term.ext == "thermal4":
                c = x[:, None]
            else:
                w, v = S.w, self.v
                c = np.empty((4, S.n))      # rows filled in place: the columns of the F-ordered c.T
                np.multiply(self.sgn, x, out=c[0])
                np.multiply(w, x, out=c[1])
                np.multiply(c[1], v, out=c[2])
                np.multiply(c[1], w * w, out=c[3])
                c = c.T
        elif term.ext == "offset":
            c = np.ones((S.n, 1))
        elif term.ext == "inertia":
            c = S.a[:, None]
        elif term.ext == "gravity":
            c = np.array([np.cos(S.q), np.sin(S.q)]).T
        elif term.ext == "position_torque" and nl["period"] == 0:   # smooth over the travel
            d = (S.q - nl["q0"]) / nl["qs"]
            c = np.empty((3, d.size))
            c[0] = 1.0
            c[1] = d
            np.multiply(d, d, out=c[2])
            c = c.T
        elif term.ext == "position_torque":
            c = sin_cos(self._cache, S.q, nl["period"])
        elif term.ext == "delay":
            c = delay_column(S, nl.get("shift", 0.0), nl.get("beta", ()))[:, None]
        elif term.ext == "dwell" and nl.get("source") == "previous":   # a competitor only, never exported
            c = previous_columns(S, nl["s_c"])
        elif term.ext == "dwell":
            c = dwell_state(S, nl["t0"], nl["s_c"])[:, None]
        else:
            raise KeyError(term.ext)
        # columns stored contiguously (Fortran order, np.array(...).T): the fits use them one by one
        self._cache[key] = c if c.shape[1] == 1 else np.asfortranarray(c)
        return self._cache[key]

    def term_vectors(self, term: Term) -> list:
        """The columns of :meth:`term_columns` as contiguous vectors (cached); thermal6's as the products that
        form them (:meth:`_thermal6_vectors`)."""
        key = ("term_vectors", term.ext, term.nl)
        if key not in self._cache:
            if term.ext == "thermal6":
                self._cache[key] = self._thermal6_vectors(term)
            elif self.position_table(term) is not None:   # read from the table where used (:mod:`.gathered`)
                inv = self._cache["q2pi"][1]
                self._cache[key] = [Gathered(x, inv) for x in self.position_table(term).T]
            else:   # views when F-ordered
                self._cache[key] = [np.ascontiguousarray(x) for x in self.term_columns(term).T]
        return self._cache[key]

    #: Extensions whose columns are read from a table of the distinct positions (:meth:`position_table`).
    TABLE_EXTS = ("position_torque", "position_periodic")

    def position_table(self, term: Term) -> np.ndarray | None:
        """The columns of a position term (:data:`TABLE_EXTS`) at the distinct positions of the samples, one row
        each, F-ordered (cached with the term's columns), or None: another term, or positions of which more
        than half are distinct (:func:`sin_cos`). Each value is the one :meth:`term_columns` holds at every
        sample of that position (the same operations on the same number): sin and cos of the period, or the
        smooth form ``1, d, d^2``, ``d = (q - q0) / qs``."""
        if term.ext not in self.TABLE_EXTS or self.S.q is None:
            return None
        key = ("table", term.ext, term.nl)
        if key not in self._cache:
            if _distinct(self._cache, self.S.q)[1] is None:
                return None
            nl = term.settings
            if _periodic(term):
                self._cache[key] = sin_cos(self._cache, None, nl["period"])
            else:
                d = (self._cache["q_distinct"] - nl["q0"]) / nl["qs"]
                c = np.empty((3, d.size))
                c[0] = 1.0
                c[1] = d
                np.multiply(d, d, out=c[2])
                self._cache[key] = c.T
        return self._cache[key]

    def term_matrix(self, term: Term) -> np.ndarray:
        """The term's columns (:meth:`term_columns`), or, for one read from a table (:meth:`position_table`), an
        empty array of their width: a fit reads only the width, its sums and predictions the vectors
        (:meth:`term_vectors`)."""
        tab = self.position_table(term)
        return self.term_columns(term) if tab is None else np.empty((0, tab.shape[1]))

    def _thermal6_vectors(self, term: Term) -> list:
        """thermal6's columns ``x sgn w, x w, x w |w|, x w^3`` as tuples of the vectors whose product they
        are (the same factors in the same order as :meth:`term_columns`), multiplied where they are used:
        block by block in the sums (:meth:`fold_products`), on the samples of a prediction (:class:`_At`).
        Four columns per time constant tried are never stored (12 time constants on a one-hour log: 0.45 GB
        and a third of the thermal6 candidate's time)."""
        nl = term.settings
        x = self.thermal(nl["tau_c"], nl.get("source", "heat_balance"), nl.get("K", 1.0))
        if "w2" not in self._cache:
            self._cache["w2"] = self.S.w * self.S.w
        w, w2 = self.S.w, self._cache["w2"]
        return [(self.sgn, x), (w, x), (w, x, self.v), (w, x, w2)]

    def thermal(self, tau_c: float, source: str = "heat_balance", K: float = 1.0) -> np.ndarray:
        """The thermal state of time constant ``tau_c`` [s] from ``source`` (``heat_balance``: the measured
        friction power with the conductance ``K`` [W/K], :meth:`Samples.conductances`; ``temp_joint``; ``work``)."""
        key = ("thermal", round(float(tau_c), 9), source, float(K))
        if key not in self._cache:
            if self.full is not None:   # the same recursion, its values at these samples
                self._cache[key] = self.full[0].thermal(tau_c, source, K)[self.full[1]]
            elif source == "work":   # a competitor's state only (chain.Chain._not_from_the_work), never exported
                self._cache[key] = self.S.thermal_state(tau_c, power=self.work_power(), K=K)
            else:
                self._cache[key] = self.S.thermal_state(tau_c, measured=(source == "temp_joint"), K=K)
        return self._cache[key]

    #: Equal-count bins of the signed velocity of :meth:`work_power`'s friction of the speed alone.
    WORK_BINS = 200

    def work_power(self) -> list:
        """Per log, the power ``F(w) w`` [W] of every sample with the friction the speed alone predicts: the
        mean friction torque of all logs' samples in equal-count bins of the signed velocity. The heat the
        motion delivers, without the friction's own changes (which the measured power ``F w`` carries)."""
        if "work_power" not in self._cache:
            S = self.S
            w = np.concatenate([S.log_w(i) for i in range(len(S.logs))])
            F = np.concatenate([np.nan_to_num(np.asarray(lg.F, float)) for lg in S.logs])
            b, nb = equal_count_bins(w, self.WORK_BINS, side="left")
            mean = np.bincount(b, weights=F, minlength=nb) / np.maximum(np.bincount(b, minlength=nb), 1)
            at = np.cumsum([S.log_w(i).size for i in range(len(S.logs))])[:-1]
            self._cache["work_power"] = [mean[bi] * S.log_w(i) for i, bi in enumerate(np.split(b, at))]
        return self._cache["work_power"]


def _periodic(term: Term) -> bool:
    """Whether the term's columns are sin and cos of a position period (:func:`sin_cos`)."""
    return term.ext == "position_periodic" or (term.ext == "position_torque" and term.settings["period"] != 0)


def _distinct(cache: dict, q: np.ndarray) -> tuple:
    """``(2 pi u, inv)`` of the distinct positions u of q and each sample's row among them, or ``(2 pi q, None)``
    when more than half of them are distinct (kept in ``cache``, with u: :meth:`Context.position_table`)."""
    if "q2pi" not in cache:
        u, inv = np.unique(q, return_inverse=True)
        cache["q2pi"] = (2 * np.pi * u, inv) if 2 * u.size <= q.size else (2 * np.pi * q, None)
        cache["q_distinct"] = u
    return cache["q2pi"]


def sin_cos(cache: dict, q: np.ndarray | None, period: float) -> np.ndarray:
    """``sin`` and ``cos`` of ``2 pi q / period`` as the columns of an F-ordered array (filled in place).
    An encoder's positions repeat (208 000 distinct among 1.16 M sliding samples on the one-hour bench
    log): where at most half of them are distinct, the two functions are evaluated once per distinct
    position and read back per sample, the same numbers (``2 pi q`` and the distinct positions kept in
    ``cache``, a :class:`Context`'s: every period tried shares them). q None (after a first call that kept
    the distinct positions): one row per distinct position, the rows the samples read back
    (:meth:`Context.extremes`: every linear function of the columns takes its extremes among them)."""
    q2pi, inv = _distinct(cache, q)
    ph = q2pi / period
    if q is None:
        c = np.empty((2, ph.size))
        c[0] = np.sin(ph)   # as the samples' read-back forms them
        c[1] = np.cos(ph)
        return c.T
    c = np.empty((2, q.size))
    if inv is None:
        np.sin(ph, out=c[0])
        np.cos(ph, out=c[1])
    else:   # mode "wrap": the indices are in range, and the default "raise" copies out through a buffer
        np.take(np.sin(ph), inv, out=c[0], mode="wrap")
        np.take(np.cos(ph), inv, out=c[1], mode="wrap")
    return c.T


def _lstsq(cols: list, y: np.ndarray) -> np.ndarray:
    """Least-squares coefficients of y on the columns ``cols`` (1-D arrays of y's length).

    Normal equations of the columns scaled to unit RMS, solved by a rank-revealing pseudo-inverse. Their
    sums are einsum dot products of contiguous vectors: no n x p matrix, and no threaded BLAS for these
    thin products."""
    p = len(cols)
    if p == 0:
        return np.zeros(0)
    XtX = np.empty((p, p))
    Xty = np.empty(p)
    for i, a in enumerate(cols):
        Xty[i] = np.einsum("i,i->", a, y)
        for j in range(i, p):
            XtX[i, j] = XtX[j, i] = np.einsum("i,i->", a, cols[j])
    d = np.sqrt(XtX.diagonal() / y.shape[0])
    d[~(d > 0)] = 1.0
    b = np.linalg.pinv(XtX / np.outer(d, d), rcond=1e-10, hermitian=True) @ (Xty / d)
    return b / d


#: A linear term may reach at most this many times the largest training friction at any speed the joint
#: reaches ...
BOUND = 10.0
#: A Stribeck column whose largest value on the training samples is below this is not excited.
EXCITE = 0.2
#: ... and a factor term at most this much (1 + phi gamma between -1 and 3); the dwell's at most this much
#: per unit of its column (:func:`_factor_bound`).
FACTOR_BOUND = 2.0


def _factor_bound(t: "Term", x_top: float) -> float:
    """The largest |phi gamma| a factor term may reach on the samples: FACTOR_BOUND, and for the dwell's own
    term (not the previous move's competitor, which shares its extension) FACTOR_BOUND times its column's
    largest |value| x_top when above one. The dwell's column ``ln(1 + t_rest / t0)`` grows with the logs'
    longest rest (7 for 60 s over 50 ms), and a plant whose level grows by 0.46 per unit of it is 4x after
    such a rest (foreign seed 322537): a fixed bound on the factor held it at zero in 3 of 5 folds. Per unit
    of the column the bound stays (a coefficient of 2 doubles the level per e-fold of the rest), which still
    catches the blow-up the bound is for: a coefficient resting on a column the samples hardly excite."""
    if t.ext == "dwell" and t.settings.get("source") != "previous":
        return FACTOR_BOUND * max(1.0, x_top)
    return FACTOR_BOUND


def _combination(cols, coef) -> np.ndarray:
    """``sum_j coef_j cols_j`` (cols: 1-D arrays), summed in column order: each product formed in one work
    array and added in place (the same numbers as ``out + x * g``, two arrays in all instead of two fresh
    ones per column: fresh pages cost kernel time, issue 20)."""
    out = cols[0] * coef[0]
    if len(cols) > 1:
        tmp = np.empty_like(out)
        for x, g in zip(cols[1:], coef[1:]):
            np.multiply(x, g, out=tmp)
            out += tmp
    return out


def _product(vecs) -> np.ndarray:
    """The product of a tuple of vectors, left to right (as :func:`_block` forms it); a vector itself."""
    if not isinstance(vecs, tuple):
        return vecs
    out = np.multiply(vecs[0], vecs[1])
    for x in vecs[2:]:
        out *= x
    return out


class _At:
    """The columns of an :class:`Evaluator` at samples idx (all samples when idx is None), gathered once
    for a whole fit or prediction. base : {slot: column}; vec : {term index: columns}; pos : w >= 0."""

    def __init__(self, ev: "Evaluator", idx):
        if isinstance(idx, slice):   # a run of samples, given as one
            pass
        elif idx is not None and idx.size and idx[-1] - idx[0] + 1 == idx.size and np.all(np.diff(idx) == 1):
            idx = slice(int(idx[0]), int(idx[-1]) + 1)   # a fold's samples are consecutive: views, no gather
        def pick(x):
            if isinstance(x, Gathered):   # a column read from its table (:mod:`.gathered`), a new array
                return x.at(idx)
            return x if idx is None else x[idx]

        def take(x):
            return _product(tuple(pick(v) for v in x)) if isinstance(x, tuple) else pick(x)
        self.n = ev.ctx.S.n if idx is None else (idx.stop - idx.start if isinstance(idx, slice) else int(idx.size))
        self.pos = take(ev.pos)
        self.base = {sl: take(col) for sl, col in ev.base_cols.items()}
        self.vec = {i: [take(x) for x in cols] for i, cols in ev.vec.items()}


class Evaluator:
    """Design pieces of one structure on one :class:`Context`, with :meth:`fit` and :meth:`predict`."""

    def __init__(self, st: Structure, ctx: Context):
        self.st, self.ctx = st, ctx
        self._excl: set = set()
        self._held: set = set()
        strib = next((t for t in st.terms if t.role == "stribeck"), None)
        self.slots = st.slots()
        cols, bkeys = {}, {}
        for sl in self.slots:
            nl = (strib.settings["vs"], strib.settings["delta"]) if (strib and sl == 1 and
                                                                     1 not in MAP_SLOTS[st.map]) else None
            cols[sl] = ctx.base_column(sl, st.shapes, nl)
            bkeys[sl] = ctx.base_key(sl, st.shapes, nl)
        self.base_cols = cols
        self.base_keys = bkeys
        self.pos = ctx.pos
        self.lf = [(i, t, ctx.term_matrix(t)) for i, t in enumerate(st.terms) if t.role == "level_factor"]
        self.af = [(i, t, ctx.term_matrix(t)) for i, t in enumerate(st.terms) if t.role == "whole_factor"]
        self.add = [(i, t, ctx.term_matrix(t)) for i, t in enumerate(st.terms) if t.role == "additive"]
        # thermal6's columns are products formed where they are used (Context.term_vectors): none stored here
        self.t6 = next(((i, t, None) for i, t in enumerate(st.terms) if t.role == "thermal6"), None)
        #: each term's columns as contiguous vectors, by term index
        self.vec = {i: ctx.term_vectors(t)
                    for i, t, _ in self.lf + self.af + self.add + ([self.t6] if self.t6 is not None else [])}

    def _sum_groups(self) -> list:
        """The lists of (key, vector) whose sums of products a fit of this structure asks for (nothing
        excluded yet): its linear items (the first, linear solve) and, with factor terms, the monomials of
        its Gauss-Newton (:meth:`Context.prefetch`)."""
        self._excl, self._held = set(), set()
        items, held = self._linear_items()
        out = [[(k, v) for k, v, _ in items] + [(k, v) for k, v, _ in held]]
        if self.lf or self.af:
            out.append(list(self._moment_layout()[1]))
        return out

    # pieces -----------------------------------------------------------------------------------------
    def _gf(self, c: Coef, a: _At):
        """Level part g (signed, incl. thermal6 dc0) and viscous part f at the samples of a."""
        g = np.zeros(a.n)
        f = np.zeros(a.n)
        for sl, col in a.base.items():
            ap, an = c.base_pos.get(sl, 0.0), c.base_neg.get(sl, 0.0)
            amp = ap if ap == an else np.where(a.pos, ap, an)  # per sign only when they differ
            if sl in LEVEL_SLOTS:
                g += amp * col
            else:
                f += amp * col
        if self.t6 is not None:
            X = a.vec[self.t6[0]]
            g += X[0] * c.dc[0]
            f += _combination(X[1:], c.dc[1:])
        return g, f

    def _factor(self, group, c: Coef, a: _At, skip=None):
        m = np.ones(a.n)
        for i, t, X in group:
            if i == skip:
                continue
            m *= 1.0 + _combination(a.vec[i], np.atleast_1d(c.gamma.get(i, np.zeros(X.shape[1]))))
        return m

    def _additive(self, c: Coef, a: _At):
        out = np.zeros(a.n)
        for i, t, X in self.add:
            out += _combination(a.vec[i], np.atleast_1d(c.gamma.get(i, np.zeros(X.shape[1]))))
        return out

    def level(self, c: Coef, idx) -> np.ndarray:
        """The signed friction level ``mA mL g`` [F] at samples idx (what level factors multiply)."""
        a = _At(self, idx)
        g, f = self._gf(c, a)
        return self._factor(self.af, c, a) * self._factor(self.lf, c, a) * g

    def predict(self, c: Coef, idx=None) -> np.ndarray:
        return self._predict(c, _At(self, idx))

    def _predict(self, c: Coef, a: _At) -> np.ndarray:
        g, f = self._gf(c, a)
        return self._factor(self.af, c, a) * (self._factor(self.lf, c, a) * g + f) + self._additive(c, a)

    # fit ----------------------------------------------------------------------------------------------
    def _linear_columns(self, c: Coef, a: _At, mL, mA):
        """Columns of the coefficients that enter linearly (base amplitudes, thermal6 slopes, additive
        terms) at the samples of a, with their keys, the excluded ones left out."""
        pos = a.pos
        cols, keys = [], []
        for sl, col in a.base.items():
            if sl in self._held:
                continue
            x = col * (mA * mL if sl in LEVEL_SLOTS else mA)
            if self.st.asym:
                cols += [x * pos, x * ~pos]
                keys += [("p", sl, 0), ("n", sl, 0)]
            else:
                cols.append(x)
                keys.append(("b", sl, 0))
        if self.t6 is not None:
            X = a.vec[self.t6[0]]
            cols.append(X[0] * mA * mL)
            keys.append(("dc", 0, 0))
            for j in range(1, 4):
                cols.append(X[j] * mA)
                keys.append(("dc", j, 0))
        for i, t, X in self.add:
            for j, x in enumerate(a.vec[i]):
                cols.append(x)
                keys.append(("g", i, j))
        keep = [k not in self._excl for k in keys]
        return [x for x, o in zip(cols, keep) if o], [k for k, o in zip(keys, keep) if o]

    def _linear_block(self, c: Coef, a: _At, y):
        mL = self._factor(self.lf, c, a)
        mA = self._factor(self.af, c, a)
        cols, keys = self._linear_columns(c, a, mL, mA)
        c.base_pos, c.base_neg, c.dc = {}, {}, np.zeros(4)
        for i, t, X in self.add:
            c.gamma[i] = np.zeros(X.shape[1])
        # base amplitudes held at the base fit's values (slots the samples do not excite)
        for sl in self._held:
            c.base_pos[sl] = c.base_neg[sl] = float(self.st.shapes[sl])
        if self._held:
            g, f = self._gf(c, a)
            y = y - mA * (mL * g + f)
        if cols:
            self._apply(c, keys, _lstsq(cols, y))

    def _linear_items(self):
        """The linear columns with every factor at one, on all samples: [(key, vector, coefficient key)],
        the excluded ones left out, and the held base columns [(key, vector, value)]."""
        items, held = [], []
        for sl, col in self.base_cols.items():
            k = self.base_keys[sl]
            if sl in self._held:
                held.append((k, col, float(self.st.shapes[sl])))
                continue
            if self.st.asym:
                items += [(k + ("p",), self.ctx.signed(k, col, True), ("p", sl, 0)),
                          (k + ("n",), self.ctx.signed(k, col, False), ("n", sl, 0))]
            else:
                items.append((k, col, ("b", sl, 0)))
        for i, t, X in ([self.t6] if self.t6 is not None else []) + self.add:
            for j, x in enumerate(self.vec[i]):
                items.append((("term", t.ext, t.nl, j), x, ("dc", j, 0) if t.role == "thermal6" else ("g", i, j)))
        return [x for x in items if x[2] not in self._excl], held

    def _linear_block_ne(self, c: Coef, fold):
        """:meth:`_linear_block` with the factors at one, from the cached per-fold normal equations; returns
        the residual sum of squares and the sample count."""
        items, held = self._linear_items()
        c.base_pos, c.base_neg, c.dc = {}, {}, np.zeros(4)
        for i, t, X in self.add:
            c.gamma[i] = np.zeros(X.shape[1])
        ne = self.ctx.normal_equations([(k, v) for k, v, _ in items] + [(k, v) for k, v, _ in held], fold)
        p = len(items)
        h = np.array([v for _, _, v in held])
        for k, _, v in held:
            sl = k[1]
            c.base_pos[sl] = c.base_neg[sl] = v
        XtX, Xty, yty = ne.XtX[:p, :p], ne.Xty[:p].copy(), ne.yty
        if held:
            Xty -= ne.XtX[:p, p:] @ h
            yty = yty - 2 * h @ ne.Xty[p:] + h @ ne.XtX[p:, p:] @ h
        b = np.zeros(0)
        if p:
            b = solve(NormalEquations(p, XtX, Xty, yty, ne.n), tuple(str(x[2]) for x in items)).coef
            self._apply(c, [x[2] for x in items], b)
        rss = float(yty - 2 * b @ Xty + b @ XtX @ b) if p else float(yty)
        return max(rss, 0.0), ne.n

    def _jacobian(self, c: Coef, a: _At):
        """Prediction and the columns of its derivative in every coefficient, with their keys."""
        g, f = self._gf(c, a)
        mL = self._factor(self.lf, c, a)
        mA = self._factor(self.af, c, a)
        cols, keys = self._linear_columns(c, a, mL, mA)
        for i, t, X in self.lf:
            d = mA * self._factor(self.lf, c, a, skip=i) * g
            for j, x in enumerate(a.vec[i]):
                if ("g", i, j) not in self._excl:
                    cols.append(d * x)
                    keys.append(("g", i, j))
        inner = mL * g + f
        for i, t, X in self.af:
            d = self._factor(self.af, c, a, skip=i) * inner
            for j, x in enumerate(a.vec[i]):
                if ("g", i, j) not in self._excl:
                    cols.append(d * x)
                    keys.append(("g", i, j))
        pred = mA * inner + self._additive(c, a)
        return pred, cols, keys

    def _unsupported(self, c: Coef, y_scale: float) -> list:
        """Coefficients whose term would exceed the data anywhere on the samples (inputs only, never the
        held-out targets): a linear term above BOUND times the largest training friction, a factor term
        beyond +-FACTOR_BOUND (the dwell's per unit of its column, :func:`_factor_bound`). Such a coefficient
        rests on a column the training samples hardly excite (a Stribeck term without low speeds) and would
        blow up a held-out prediction."""
        bad = []
        wt = self.ctx.w_top
        for sl, col in self.base_cols.items():
            if sl in self._held:
                continue
            # the largest the column can be over the joint's speeds: 1 for the level slots, w^k for f
            m = 1.0 if sl in LEVEL_SLOTS else {6: wt, 7: wt * wt, 8: wt ** 3}[sl]
            for key, amp in ((("b", sl, 0), c.base_pos.get(sl, 0.0)),) if not self.st.asym else (
                    (("p", sl, 0), c.base_pos.get(sl, 0.0)), (("n", sl, 0), c.base_neg.get(sl, 0.0))):
                if key not in self._excl and abs(amp) * m > BOUND * y_scale:
                    bad.append(key)
        if self.t6 is not None:
            x_top = float(np.max(np.abs(self.ctx.extremes(self.t6[1], (0,)))))
            for j in range(4):
                m = x_top * (1.0 if j == 0 else wt ** j)
                if ("dc", j, 0) not in self._excl and abs(c.dc[j]) * m > BOUND * y_scale:
                    bad.append(("dc", j, 0))
        for i, t, X in self.add:
            for j in range(X.shape[1]):
                m = self.ctx.a_top if t.ext == "inertia" else float(np.max(np.abs(self.ctx.extremes(t, (j,)))))
                if ("g", i, j) not in self._excl and abs(c.gamma[i][j]) * m > BOUND * y_scale:
                    bad.append(("g", i, j))
        for i, t, X in self.lf + self.af:
            ext = self.ctx.extremes(t)
            if np.max(np.abs(ext @ np.atleast_1d(c.gamma[i]))) > _factor_bound(t, float(np.max(np.abs(ext)))):
                bad += [("g", i, j) for j in range(X.shape[1]) if ("g", i, j) not in self._excl]
        return bad

    def _apply(self, c: Coef, keys, delta):
        for (kind, a, b), v in zip(keys, delta):
            v = float(v)
            if kind == "b":
                c.base_pos[a] = c.base_pos.get(a, 0.0) + v
                c.base_neg[a] = c.base_neg.get(a, 0.0) + v
            elif kind == "p":
                c.base_pos[a] = c.base_pos.get(a, 0.0) + v
            elif kind == "n":
                c.base_neg[a] = c.base_neg.get(a, 0.0) + v
            elif kind == "dc":
                c.dc[a] += v
            else:
                c.gamma[a][b] += v

    def _moment_layout(self):
        """The monomials of this structure (:mod:`.moments`), each with its key and the vectors whose
        product it is, the entries (linear items, then held base columns), the factors, the free items and
        factor coefficients, and the keys of the free coefficients (in the order of the Jacobian's columns).
        It does not depend on the coefficients: built once per Gauss-Newton run (:meth:`_moment_values`
        reads the coefficients at each iteration)."""
        items, held = self._linear_items()
        factors = self.lf + self.af
        n_lf = len(self.lf)
        entries = [(k, v, ck) for k, v, ck in items] + [(k, v, None) for k, v, _ in held]
        applies = []
        for k, v, ck in entries:
            if ck is None:                       # a held base column: its value is fixed
                level = k[1] in LEVEL_SLOTS
            elif ck[0] in ("b", "p", "n"):
                level = ck[1] in LEVEL_SLOTS
            elif ck[0] == "dc":
                level = ck[1] == 0
            else:                                # additive: no factor multiplies it
                applies.append(())
                continue
            applies.append(tuple(range(len(factors))) if level else tuple(range(n_lf, len(factors))))
        sizes = [X.shape[1] for _, _, X in factors]
        monos = mo.monomials(len(entries), applies, sizes)
        fkeys = [("term", t.ext, t.nl) for _, t, _ in factors]

        def column(m):
            # the monomial as the tuple of vectors whose product it is (multiplied block by block when its
            # sums are accumulated: Context.fold_products)
            head = entries[m.item][1]   # a product itself (thermal6's columns): its factors first
            vecs = (head if isinstance(head, tuple) else (head,)) + tuple(
                self.vec[factors[f][0]][j] for f, j in zip(m.factors, m.choice) if j >= 0)
            key = (entries[m.item][0], tuple(sorted((fkeys[f], j) for f, j in zip(m.factors, m.choice) if j >= 0)))
            return key, (vecs[0] if len(vecs) == 1 else vecs)

        free_items = [n for n, e in enumerate(entries) if e[2] is not None]
        free_gamma = [(f, j) for f, (i, _, X) in enumerate(factors) for j in range(X.shape[1])
                      if ("g", i, j) not in self._excl]
        keys = [entries[n][2] for n in free_items] + [("g", factors[f][0], j) for f, j in free_gamma]
        return monos, [column(m) for m in monos], entries, factors, free_items, free_gamma, keys

    def _moment_values(self, c: Coef, layout) -> tuple[np.ndarray, np.ndarray]:
        """The monomials' coefficients c and the Jacobian's C (:func:`.moments.coefficients`) at the
        coefficients c of :meth:`_moment_layout`'s entries and factors."""
        monos, _, entries, factors, free_items, free_gamma, _ = layout
        amp = []
        for k, v, ck in entries:
            if ck is None:
                amp.append(float(self.st.shapes[k[1]]))
            elif ck[0] in ("b", "p", "n"):
                amp.append((c.base_neg if ck[0] == "n" else c.base_pos).get(ck[1], 0.0))
            elif ck[0] == "dc":
                amp.append(float(c.dc[ck[1]]))
            else:
                amp.append(float(np.atleast_1d(c.gamma[ck[1]])[ck[2]]))
        gam = [np.atleast_1d(c.gamma[i]).astype(float) for i, _, _ in factors]
        return mo.coefficients(monos, np.array(amp), gam, free_items, free_gamma)

    def _gauss_newton_moments(self, c: Coef, fold, max_iter: int, tol: float) -> tuple[float, int]:
        """Gauss-Newton of the factor terms from the per-fold moments (:mod:`.moments`), from c (updated in
        place); the same iterates as :meth:`_gauss_newton` on the samples. Returns (RSS at the end, n)."""
        layout = self._moment_layout()
        ne = self.ctx.normal_equations(layout[1], fold)
        G, b, yty, n = ne.XtX, ne.Xty, ne.yty, ne.n
        keys = layout[6]
        prev = np.inf
        for _ in range(max_iter):
            cv, C = self._moment_values(c, layout)
            step, cost = mo.gauss_newton_step(G, b, yty, n, cv, C)
            self._apply(c, keys, step)
            if abs(prev - cost) <= tol * max(cost, 1e-300):
                break
            prev = cost
        return mo.rss(G, b, yty, self._moment_values(c, layout)[0]), n

    def _gauss_newton(self, c: Coef, rows: _At, y: np.ndarray, max_iter: int, tol: float) -> None:
        """Gauss-Newton of the factor terms on the samples of rows, from c (updated in place)."""
        prev = np.inf
        for _ in range(max_iter):
            pred, cols, keys = self._jacobian(c, rows)
            r = y - pred
            cost = float(np.einsum("i,i->", r, r))
            self._apply(c, keys, _lstsq(cols, r))
            if abs(prev - cost) <= tol * max(cost, 1e-300):
                break
            prev = cost

    def fit(self, idx=None, start: Coef | None = None, max_iter: int = 12, tol: float = 1e-9) -> Coef:
        """Least-squares coefficients on samples idx (default all).

        The model is linear in the amplitudes and additive terms and, given them, in each factor; the
        coupled problem is solved by Gauss-Newton from the exact linear solution with all factors at one
        (it is bilinear, so the iterations converge in a few steps).
        """
        S = self.ctx.S
        idx = np.arange(S.n) if idx is None else np.asarray(idx)
        fold = self.ctx.fold_of(idx) if self.ctx.use_normal_equations else False
        y = S.F[idx] if fold is False else None   # fits from the normal equations and moments never need it
        y_scale = self.ctx.y_scale(idx, fold)
        self._excl = set()
        # a Stribeck term the training samples do not reach (all far above its velocity) keeps the base
        # fit's amplitude: refitted there it would rest on nothing and blow up at low speed
        self._held = set()
        if 1 in self.base_cols and 1 in MAP_SLOTS[self.st.map] and idx.size:
            if self.ctx.abs_max(self.base_keys[1], self.base_cols[1], idx, fold) < EXCITE:
                self._held.add(1)
        linear = not (self.lf or self.af)
        # the columns at idx, gathered once (not needed by fits from the normal equations and moments)
        rows = _At(self, idx) if fold is False else None
        rss = None
        for _ in range(4):
            c = Coef({}, {}, np.zeros(4), {})
            for i, t, X in self.lf + self.af + self.add:
                c.gamma[i] = np.zeros(X.shape[1])
            if fold is not False:
                rss, n_ne = self._linear_block_ne(c, fold)
                if not linear:
                    rss, n_ne = self._gauss_newton_moments(c, fold, max_iter, tol)
            else:
                self._linear_block(c, rows, y)
                if not linear:
                    self._gauss_newton(c, rows, y, max_iter, tol)
            bad = self._unsupported(c, y_scale)
            if not bad:
                break
            self._excl.update(bad)
        if bad:  # still unsupported after the refits: hold those at zero
            self._apply(c, bad, [0.0] * len(bad))
            for kind, a, b in bad:
                if kind in ("b", "p"):
                    c.base_pos[a] = 0.0
                if kind in ("b", "n"):
                    c.base_neg[a] = 0.0
                if kind == "dc":
                    c.dc[a] = 0.0
                if kind == "g":
                    c.gamma[a][b] = 0.0
        c.excluded = sorted(self._excl)
        if fold is not False and not bad and rss is not None:
            c.rms = float(np.sqrt(rss / n_ne)) if n_ne else float("nan")
        else:
            r = y - self._predict(c, rows if rows is not None else _At(self, idx))
            c.rms = float(np.sqrt(np.mean(r * r))) if r.size else float("nan")
        c.n = int(idx.size)
        return c


# ---------------------------------------------------------------------------------------------------
# Conversion to parameter-file values


def canonical_vectors(st: Structure, c: Coef) -> tuple[np.ndarray, np.ndarray]:
    """Canonical 9-vectors (w >= 0, w < 0) of a fitted structure (thermal and factors excluded)."""
    out = []
    strib = next((t for t in st.terms if t.role == "stribeck"), None)
    # the asym_scale factor (1 + gamma on w < 0) folds into the w < 0 amplitudes
    neg, neg_level = 1.0, 1.0   # asym_level (1 + gamma on the w < 0 level) folds into its level amplitudes
    for i, t in enumerate(st.terms):
        if t.ext == "asym_scale":
            neg = 1.0 + float(np.atleast_1d(c.gamma.get(i, [0.0]))[0])
        if t.ext == "asym_level":
            neg_level = 1.0 + float(np.atleast_1d(c.gamma.get(i, [0.0]))[0])
    for amps, fac, lev in ((c.base_pos, 1.0, 1.0), (c.base_neg, neg, neg_level)):
        v = np.array(st.shapes, dtype=float).copy()
        for sl in (0, 1, 4, 6, 7, 8):
            v[sl] = amps.get(sl, 0.0) * fac * (lev if sl in LEVEL_SLOTS else 1.0)
        if strib is not None and 1 not in MAP_SLOTS[st.map]:
            v[2], v[3] = strib.settings["vs"], strib.settings["delta"]
        out.append(v)
    return out[0], out[1]


def low_speed_amps(st: Structure, c: Coef) -> list[float] | None:
    """The amplitudes of the low-speed term the ``stribeck`` extension adds (canonical slot 1 of a map that has
    none), as the parameter file stores them (``str_amp``; and ``str_amp_neg`` on a per-sign model), or None
    without that term."""
    if not any(t.role == "stribeck" for t in st.terms) or 1 in MAP_SLOTS[st.map]:
        return None
    cp, cn = canonical_vectors(st, c)
    return [float(cp[1]), float(cn[1])] if st.per_sign else [float(cp[1])]


def term_name(st: Structure, c: Coef, ext: str) -> str:
    """The name an extension of a fitted structure is reported by: ``ext`` itself, except the ``stribeck``
    candidate, a low-speed term of either sign, named by its fitted amplitudes
    (:func:`frictid.models.static.low_speed_name`: ``low_speed_rise`` where the friction at low speed lies
    below the sliding level; a ``stribeck`` term is a drop, ``Fs >= Fc``)."""
    amps = low_speed_amps(st, c) if ext == "stribeck" else None
    return ext if amps is None else low_speed_name(amps)


def model_name(st: Structure, c: Coef) -> str:
    """The parameter file's name of a fitted structure: :attr:`Structure.name` with its low-speed term named by
    its amplitudes (:func:`term_name`)."""
    head, *exts = st.name.split("+")
    return "+".join([head] + [term_name(st, c, e) for e in exts])


def named_static(mapname: str, cvec: np.ndarray) -> dict:
    """Named parameters of a base map from its canonical vector (inverse of static.py's conversions)."""
    a0, a1, vs1, d1, a2, vs2, b1, b2, b3 = (float(x) for x in cvec)
    if mapname == "coulomb_viscous":
        return {"Fc": a0, "sigma2": b1}
    if mapname == "stribeck":
        return {"Fc": a0, "Fs": a0 + a1, "vs": vs1, "delta": d1, "sigma2": b1}
    if mapname == "stribeck_2exp":
        return {"alpha0": a0, "alpha1": a1, "alpha2": a2, "alpha3": b1, "alpha4": b2, "ws1": vs1, "ws2": vs2}
    if mapname == "polynomial":
        return {"c0": a0, "c1": b1, "c2": b2, "c3": b3}
    raise KeyError(mapname)


def model_values(st: Structure, c: Coef, S: Samples, rigid: dict) -> tuple[str, dict]:
    """(map name, {param: value}) of a fitted structure, in the parameter-file names that
    :func:`frictid.replay.joint_model` reads. rigid : the fit's J, Px, Py (corrected by inertia/gravity)."""
    cp, cn = canonical_vectors(st, c)
    vals: dict = {}
    mapname = st.map + ("_asym" if st.per_sign else "")
    if st.per_sign:
        for suf, cv in (("_pos", cp), ("_neg", cn)):
            vals.update({k + suf: v for k, v in named_static(st.map, cv).items()})
    else:
        vals.update(named_static(st.map, cp))
    for i, t in enumerate(st.terms):
        g = np.atleast_1d(c.gamma.get(i, np.zeros(0)))
        nl = t.settings
        if t.ext == "position_periodic":
            a, b = float(g[0]), float(g[1])
            vals.update(pos_amp=float(np.hypot(a, b)), pos_period=nl["period"], pos_phase=float(np.arctan2(b, a)))
        elif t.ext == "position_smooth":
            vals.update(pos_q0=nl["q0"], pos_lin=float(g[0]) / nl["qs"], pos_quad=float(g[1]) / nl["qs"] ** 2)
        elif t.ext.startswith("load_"):
            vals[t.ext] = float(g[0]) / nl["scale"]
        elif t.ext == "drift":
            vals["drift_per_hour"] = float(g[0])
            vals["drift_t0"] = float(S.clock_t0) if S.clock_real else 0.0
        elif t.ext == "thermal4":
            K = float(nl.get("K", 1.0))   # C dT/dt = P - K (T - Tenv): the time constant is C / K
            vals.update(alpha=float(g[0]), beta=1.0, C=K * float(nl["tau_c"]), K=K, T0=float(S.T0))
        elif t.ext == "thermal6":
            vals.update({f"dc{j}": float(c.dc[j]) for j in range(4)})
            K = float(nl.get("K", 1.0))
            vals.update(C=K * float(nl["tau_c"]), K=K, T0=float(S.T0))
        elif t.ext == "offset":
            vals["tau_offset"] = float(g[0])
        elif t.ext == "inertia":
            vals["J"] = rigid.get("J", 0.0) + float(g[0])
        elif t.ext == "gravity":
            vals["Px"] = rigid.get("Px", 0.0) + float(g[0])
            vals["Py"] = rigid.get("Py", 0.0) + float(g[1])
        elif t.ext == "stribeck":
            vals.update(str_amp=float(cp[1]), str_vs=float(nl["vs"]), str_delta=float(nl["delta"]))
            if st.per_sign:   # each branch its own amplitude (their mean replayed 0.708 N m where the fit gave 0.646)
                vals["str_amp_neg"] = float(cn[1])
    if any(t.ext in ("thermal4", "thermal6") for t in st.terms):
        th = next(t for t in st.terms if t.ext in ("thermal4", "thermal6"))
        if th.settings.get("source") == "temp_joint":
            vals.pop("C", None)
            vals.pop("K", None)
    return mapname, vals
