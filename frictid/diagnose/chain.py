"""The diagnosis chain: test every candidate cause on held-out segments, extend the model with the
best significant one, repeat; then write the findings and the extended models.

Judging a candidate (:func:`evaluate`). In each of the ``n_folds`` folds the current model and the
extended one are both refitted on the other folds (the extension's period, time constant or variable
chosen there too) and predict the held-out fold; every sliding sample is predicted exactly once by fits
that never saw its segment. Then, per held-out group ``g`` (a segment or a chunk of one),
``d_g = sum (r_before^2 - r_after^2)``; the candidate is *significant* when the mean of ``d_g`` is
positive with a one-sided Student t statistic over the groups above the ``1 - ALPHA / m`` quantile
(``m`` candidates tested at this step: Bonferroni). Samples within a group are never treated as
independent. The gain is ``1 - rms_after / rms_before`` over all held-out samples.

Worth it (:func:`worth_it`). A significant extension enters the model when the RMS it explains,
``sqrt(rms_before^2 - rms_after^2)``, is at least :data:`EXPLAINED_MIN` of the friction RMS: very large
logs make tiny, real but useless corrections significant (a 1 % inertia error), and a model term must pay
for itself. The relative gain is not a criterion: measurement noise stays in both RMS, so a real effect
in noisy data has a small gain. A delay may instead pay for itself on every moving sample, where it shows
(transients included), when it takes a material share of the sliding samples' residual too.

Choice among the worthy candidates (:func:`choose`): the lowest held-out RMS, except that a candidate
with fewer coefficients wins when the best is not significantly better than it (the same paired test
between the two). This keeps a torque offset from being named an asymmetry (per-sign amplitudes can
absorb an offset, with more coefficients). A cause is *named* only when it beats every competing
explanation of another cause that makes the same correction on the held-out residual (:meth:`Chain.same_correction`:
the same column space on these data, as an offset and a level-only asymmetry on a Coulomb + viscous map); otherwise
its term enters the model (the residual the next steps search stays clean) but no cause is named: the
step is recorded as ambiguous between the causes (``Trial.unresolved``). Explanations that are not
candidates compete too (:data:`COMPETITORS`: a per-direction level for an offset).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import ndtri, stdtr

from .binned import equal_count_bins, fold_parts, heldout_binned
from .causes import EXTENSIONS, X_NOISE, candidates, n_coef, propose, torque_noise
from ..models.static import canonical_level
from .model import VISCOUS_SLOTS, Coef, Context, Evaluator, Structure, canonical_vectors
from .samples import Samples
from .screen import explained_bound, gap_allowance, screen_record
from .search import StrideSearch
from .signals import REST_MIN, delay_heldout, delay_mirror, rest_scales, rests, share_delay_terms

#: Family-wise false-finding level of one step of the chain (split over its candidates).
ALPHA = 0.01
#: Smallest held-out gain of a presliding finding (judged by the fit's ramps, without an explained RMS).
GAIN_MIN = 0.05
#: Smallest RMS a term must explain, as a fraction of the friction RMS.
EXPLAINED_MIN = 0.02
#: Competing explanations that are not candidates (their models are not exported) but must be beaten before
#: the candidate is named: a torque offset is, on sliding data of a map without a Stribeck part, the same
#: column space as a per-direction Coulomb level (``asym_level``); where the map has a Stribeck part the
#: two differ at low speed, where the level asymmetry scales the hump and the offset does not. Where they
#: make the same correction the step is ambiguous (offset or asymmetry): the data cannot tell a torque
#: sensor's bias from a Coulomb level that differs by direction, and the rest torque after a move does not
#: either (the bristles hold the sliding level; foreign seed 300017, docs/scorecards.md).
COMPETITORS = {"offset": ("asym_level",)}


def beyond_rms(e: np.ndarray, part: np.ndarray) -> float:
    """The RMS [F] that a correction's ``part`` removes from a residual ``e`` (e's least-squares projection on
    it, per sample of e): what the part explains of e."""
    pp = float(part @ part)
    return abs(float(e @ part)) / math.sqrt(pp * e.size) if pp > 0 and e.size else 0.0


def _competing_causes(tr: Trial) -> set:
    """The causes of a candidate's competing explanations (:data:`COMPETITORS`)."""
    return {EXTENSIONS[x][0] for x in COMPETITORS.get(tr.ext, ())}


#: Repairs of the fit's rigid body: their torque is no friction (:meth:`Chain._friction_rms`).
RIGID_REPAIRS = ("inertia", "gravity")
#: Terms of the model that the moving samples' judgement of a delay carries (its per-sign velocity map
#: holds an offset, a level or branch by direction and a Stribeck part; its acceleration and cos q, sin q
#: columns the inertia and gravity).
MOVING_MAP_EXTS = ("offset", "asym", "asym_level", "asym_scale", "stribeck", "inertia", "gravity")

#: Longest chain.
MAX_STEPS = 6
#: Two candidates make the same correction when their held-out corrections differ by at most this share of
#: the RMS the chosen one explains (rounding and the iterations of a factor's fit, not the data, part them).
SAME_CORRECTION = 1e-3


@dataclass
class Trial:
    """One candidate extension judged on held-out folds."""

    ext: str
    cause: str
    pred_before: np.ndarray
    pred_after: np.ndarray
    fold_terms: list
    fold_coefs: list
    rms_before: float
    rms_after: float
    gain: float
    t: float
    p: float
    groups: int
    explained: float
    k: int
    d: np.ndarray = field(repr=False, default=None)
    rivals: list = field(default_factory=list)
    #: other causes this one does not beat on held-out data (one-sided paired t, p >= ALPHA): it is then not
    #: named, its term kept (:func:`frictid.diagnose.joint`: ``selection.diagnosis.ambiguous``)
    unresolved: list = field(default_factory=list)
    #: a delay judged on every moving sample too (:func:`delay_moving`): held-out RMS before and after, the
    #: per-group differences, t, p and the RMS it explains there; computed only where it decides (None
    #: otherwise, and for other candidates)
    moving: dict | None = None
    #: the candidate's term index in the extended structure (its coefficients' key in ``Coef.gamma``)
    index: int = -1

    def record(self) -> dict:
        return {"extension": self.ext, "rms_before": self.rms_before, "rms_after": self.rms_after,
                "gain": self.gain, "t": self.t, "p": self.p}


def group_d(S: Samples, rb: np.ndarray, ra: np.ndarray) -> np.ndarray:
    """Per held-out group: sum of (r_before^2 - r_after^2)."""
    return S.group_sums(rb * rb - ra * ra)


def paired_t(d: np.ndarray) -> tuple[float, float]:
    """One-sided t statistic and p-value that the mean of d is positive (groups as the units)."""
    d = d[np.isfinite(d)]
    G = d.size
    if G < 3:
        return 0.0, 1.0
    sd = float(np.std(d, ddof=1))
    if sd == 0:
        return (math.inf, 0.0) if d.mean() > 0 else (0.0, 1.0)
    t = float(d.mean() / (sd / math.sqrt(G)))
    return t, float(stdtr(G - 1, -t))  # the survival function of Student's t (scipy.stats.t.sf's own)


def supported(S: Samples) -> np.ndarray:
    """Per sample: whether its held-out fold is scored there, i.e. the training folds (all but the sample's
    own) hold samples of the same velocity sign at speeds on both sides of it. Outside that range every
    model's velocity map is extrapolated (a polynomial's w|w| and w^3 most), and an extension that shifts the
    map's amplitudes changes the extrapolation by more than all it explains elsewhere: one group at the top
    speed of a sweep, alone in its fold, gave a load term a held-out gain of -1.7 where it explained half of
    the residual of every other fold (foreign seed 302012). What the data cannot test is not scored: the
    candidate's prediction there is the current model's (no difference), and the RMS are over the rest."""
    def compute():
        # each fold's smallest and largest velocity of each sign (exact), then each training set's from them
        sgn = np.sign(S.w)
        lo = np.full((S.n_folds, 2), np.inf)
        hi = np.full((S.n_folds, 2), -np.inf)
        parts = fold_parts(S)   # a slice per fold (the samples are in folds)
        for f, part in enumerate(parts):
            w, s = S.w[part], sgn[part]
            for j, sg in enumerate((1.0, -1.0)):
                x = w[s == sg]
                if x.size:
                    lo[f, j], hi[f, j] = x.min(), x.max()
        inside = np.zeros(S.n, bool)
        for f, part in enumerate(parts):
            w, s = S.w[part], sgn[part]
            out = inside[part] if isinstance(part, slice) else np.zeros(w.size, bool)
            for j, sg in enumerate((1.0, -1.0)):
                a, b = np.delete(lo[:, j], f).min(), np.delete(hi[:, j], f).max()
                if a <= b:   # the training folds hold samples of this sign
                    sel = s == sg
                    out[sel] = (w[sel] >= a) & (w[sel] <= b)
            if not isinstance(part, slice):
                inside[part] = out
        return inside
    return S.cached("supported", compute)


def _on_training(fn, c, tr: np.ndarray, te: np.ndarray) -> np.ndarray:
    """``fn(c, tr)`` (a prediction or a level on a training set ``tr``, the samples outside the held-out fold
    ``te``, both in increasing order), on the runs of samples before and after the held-out fold when it is
    one run (the samples are in folds): views of the columns, not a gather of them, the same numbers."""
    n = tr.size + te.size
    if not te.size or te[-1] - te[0] + 1 != te.size:
        return fn(c, tr)
    parts = [fn(c, slice(a, b)) for a, b in ((0, int(te[0])), (int(te[-1]) + 1, n)) if b > a]
    return np.concatenate(parts) if parts else np.zeros(0)


def _rows(te: np.ndarray):
    """The held-out fold's samples ``te`` (increasing) as a slice when they are one run (the samples are in
    folds): a prediction there reads views of the columns, not a gather of them, the same numbers."""
    return slice(int(te[0]), int(te[-1]) + 1) if te.size and te[-1] - te[0] + 1 == te.size else te


class Chain:
    """Runs the diagnosis on one joint's samples from a base structure."""

    def __init__(self, S: Samples, base: Structure, J: float | None = None, ctx: Context | None = None,
                 full: Chain | None = None):
        self.S = S
        #: the fit's inertia (None: unknown), which an inertia repair corrects (:func:`unphysical`)
        self.J = J
        self.ctx = Context(S) if ctx is None else ctx
        #: the chain of all samples when this one is its screen, on a stride of them (:mod:`.screen`); a weak
        #: reference: the screen is the full chain's own (``_sub``), and a cycle between them kept the whole
        #: diagnosis (its samples, folds and caches, 0.83 GB on a joint-hour) alive through the check
        self.full = weakref.proxy(full) if full is not None else None
        #: a long log's screen (:meth:`_screen_chain`), made when first asked for
        self._sub: Chain | None = None
        self.st = base
        self.idx_all = np.arange(S.n)
        #: held-out samples at a speed the training folds cover (:func:`supported`): the only ones scored
        self.inside = supported(S)
        #: a long log's stride, on which some candidates' grids of settings are ranked (:mod:`.search`)
        self.stride = StrideSearch(S)
        self.steps: list[dict] = []
        self.history: list[tuple[Structure, Coef, np.ndarray]] = []
        self._before(base)

    # -- the current model, refitted per fold ---------------------------------------------------------
    def _before(self, st: Structure):
        S = self.S
        ev = Evaluator(st, self.ctx)
        pred = np.empty(S.n)
        self.train_info = []
        # each fold's training and held-out samples: the samples' own, formed once for every refit of the chain
        folds = S.cached("fold_rows", lambda: [(np.flatnonzero(S.fold != f), np.flatnonzero(S.fold == f))
                                               for f in range(S.n_folds)])
        for f, (tr, te) in enumerate(folds):
            c = ev.fit(tr)
            pred[te] = ev.predict(c, _rows(te))
            res = np.take(S.F, tr)   # the training residual formed in the gather's array (one fresh array)
            res -= _on_training(ev.predict, c, tr, te)
            self.train_info.append((tr, te, res, _on_training(ev.level, c, tr, te), c))
        self.pred = pred
        self.coef = ev.fit(self.idx_all)
        self.history.append((st, self.coef, pred))
        #: the friction RMS, the scale of what a term must explain: of the friction torque the logs give,
        #: ``F = tau - J a - G`` with the fit's rigid body, less the rigid-body repairs the chain adopts
        #: (:meth:`_friction_rms`), for the current model
        self.F_rms = self._friction_rms(st, self.coef)

    def _friction_rms(self, st: Structure, coef: Coef) -> float:
        """RMS of the friction torque on the sliding samples: ``F`` less the current model's corrections of the
        fit's rigid body (:data:`RIGID_REPAIRS`: the base's re-estimate of the fit's gravity and the repairs the
        chain adopted, their coefficients on all samples). A wrong rigid body of the fit leaves its torque in
        ``F``: on sweeps with a fit's inertia 16 times the plant's and a gravity the plant does not have
        (foreign seed 309207, cogging), ``F`` had an RMS of 3.25 N m against a friction of 0.29, and a cogging
        torque that the inertia repair left (held-out RMS 0.045 -> 0.010) explained 1.3 % of that RMS, under
        the 2 % a term must explain."""
        F = self.S.F
        for i, t in enumerate(st.terms):
            g = np.atleast_1d(coef.gamma.get(i, np.zeros(0)))
            if t.ext in RIGID_REPAIRS and g.size and np.any(g != 0):
                F = F - self.ctx.term_columns(t) @ g
        return float(np.sqrt(np.mean(F * F)))

    @property
    def rms_heldout(self) -> float:
        r = (self.S.F - self.pred)[self.inside]
        return float(np.sqrt(np.mean(r * r))) if r.size else 0.0

    # -- one candidate -------------------------------------------------------------------------------
    def evaluate(self, ext: str, m: int) -> Trial | None:
        S = self.S
        terms = []
        for f, (tr, te, res, lev, c0) in enumerate(self.train_info):
            term = self._propose(ext, tr, res, lev, c0, f)
            if term is None:
                self.ctx.release(self.st)
                return None
            terms.append(term)
        after, coefs = self._fold_fits(terms)
        rms_b, rms_a, d, t, p, expl = self._judged(after)
        gain = 1.0 - rms_a / rms_b if rms_b > 0 else 0.0
        # self.pred is replaced, never changed in place, when the model is extended: shared, not copied
        tr = Trial(ext, EXTENSIONS[ext][0], self.pred, after, terms, coefs, rms_b, rms_a, gain, t, p,
                   S.n_groups, expl, n_coef(ext, self.st), d, index=len(self.st.terms))
        memo = getattr(self, "_moving_memo", None)   # a screen's judgement on every moving sample, the same shifts
        if ext == "delay" and memo is not None and memo[0] == tuple(_fold_shifts(tr)):
            tr.moving = memo[1]
        return tr

    def _fold_fits(self, terms: list) -> tuple[np.ndarray, list]:
        """Each fold's fit of the current structure with its term ``terms[f]`` on its training set, predicting
        its held-out samples; the folds' own settings (a period, a shift) are summed in one pass, then each
        fold is fitted from its sums. Returns the held-out prediction and the folds' coefficients."""
        after = np.empty(self.S.n)
        coefs = []
        self.ctx.prefetch([self.st.plus(term) for term in terms])
        for (tr, te, *_), term in zip(self.train_info, terms):
            ev = Evaluator(self.st.plus(term), self.ctx)
            c = ev.fit(tr)
            after[te] = ev.predict(c, _rows(te))
            coefs.append(c)
        self.ctx.release(self.st)   # the candidate's columns (its sums of products stay cached)
        return after, coefs

    def in_sample_d(self, tr: Trial) -> np.ndarray:
        """Per group, its sum of ``r_before^2 - r_after^2`` over its scored samples on the training sets that
        hold it, averaged over them: each fold's fit of the current model (``train_info``) and of the
        extended one (``tr.fold_coefs``) on its own training set (what the trial explains in-sample;
        :func:`.screen.gap_allowance`)."""
        S = self.S
        acc = np.zeros(S.n_groups)
        for (tri, te, res, _, _), term, c in zip(self.train_info, tr.fold_terms, tr.fold_coefs):
            ra = S.F[tri] - _on_training(Evaluator(self.st.plus(term), self.ctx).predict, c, tri, te)
            x = np.zeros(S.n)
            x[tri] = np.where(self.inside[tri], res * res - ra * ra, 0.0)
            acc += S.group_sums(x)
        self.ctx.release(self.st)
        return acc / max(S.n_folds - 1, 1)

    def _judged(self, after: np.ndarray) -> tuple:
        """A held-out prediction ``after`` against the current model's: (RMS before, RMS after on the scored
        samples, per held-out group ``d`` = sum of r_before^2 - r_after^2, t, p, what it explains). Where the
        map is extrapolated ``after`` takes the current model's prediction (in place): it is not judged there."""
        rb, rms_b, out, n_in, rb2 = self._before_numbers()
        after[out] = self.pred[out]
        ra = self.S.F - after
        d = self.S.group_sums(rb2 - ra * ra)   # group_d, the step's rb * rb formed once
        t, p = paired_t(d)
        ra_in = ra[self.inside]
        rms_a = float(np.sqrt(np.dot(ra_in, ra_in) / n_in))
        return rms_b, rms_a, d, t, p, math.sqrt(max(rms_b ** 2 - rms_a ** 2, 0.0))

    def _propose(self, ext: str, tr: np.ndarray, res: np.ndarray, lev: np.ndarray, c0: Coef, f: int | None = None):
        """:func:`propose` on the training set ``tr`` (fold f's; None: all samples); on a long log, a
        candidate's grid of settings ranked on a stride of it (:mod:`.search`)."""
        if self.full is not None and ext == "delay":
            # a screen's delay: the shifts of the whole logs' moving samples, searched once for both chains
            # (a delay's proposal reads no residual); the stride's columns of the five terms then in one pass
            term = propose(ext, self.full.ctx, self.full.st,
                           self.full.idx_all if f is None else self.full.train_info[f][0], None, None, None)
            share_delay_terms(self.full.S, self.S)
            return term
        if self.full is not None and f is not None and self.full.stride.wants(ext):
            # a screen's grid search is the one the whole chain's trial makes (:meth:`StrideSearch.propose`)
            return self.full.stride.propose(ext, f, self.st, lambda: propose(ext, self.ctx, self.st, tr, res,
                                                                              lev, c0))
        if not self.stride.wants(ext):
            return propose(ext, self.ctx, self.st, tr, res, lev, c0)
        self.stride.sync(self.ctx)
        idx, res_s, lev_s = self.stride.training(f, tr, res, lev)
        if f is None:
            term = propose(ext, self.stride.ctx, self.st, idx, res_s, lev_s, c0)
        else:
            term = self.stride.propose(ext, f, self.st, lambda: propose(ext, self.stride.ctx, self.st, idx, res_s,
                                                                         lev_s, c0))
        self.stride.ctx.release(self.st)
        return term

    def _before_numbers(self) -> tuple:
        """The current model's held-out residual, its RMS over the scored samples, the samples not scored
        (indices), the number scored and the residual's square: the same for every candidate of a step (kept
        while ``self.pred`` is the step's)."""
        memo = getattr(self, "_memo_before", None)
        if memo is None or memo[0] is not self.pred:
            out = np.flatnonzero(~self.inside)
            n_in = max(self.S.n - out.size, 1)
            rb = self.S.F - self.pred
            rb_in = rb[self.inside]
            memo = self._memo_before = (self.pred, rb, float(np.sqrt(np.dot(rb_in, rb_in) / n_in)), out, n_in,
                                        rb * rb)
        return memo[1:]

    def significant(self, tr: Trial, m: int) -> bool:
        """The held-out gain on the sliding samples is significant at the step's level; for a delay, on
        every moving sample instead when not there (:func:`delay_moving`: on sweeps the fit's inertia and
        viscous terms absorb a delay's imprint on the sliding samples, foreign seed 309229, a 50 ms delay of
        20 %: t = -0.39 there, 15 on the moving samples). Such a delay still has to be worth it there
        (:meth:`worth_it`) and shown at speed (:func:`_not_at_speed`)."""
        if tr.p < ALPHA / max(m, 1):
            return True
        if tr.ext != "delay" or not self._moving_map_carries_model() or _unresolved_delay(self.S, tr) is not None:
            return False
        return bool(delay_moving(self.S, tr)["p"] < ALPHA / max(m, 1)) or self._shown_at_speed(tr, m)

    def _shown_at_speed(self, tr: Trial, m: int) -> bool:
        """Whether a delay trial is significant at the step's level and worth a term (:data:`EXPLAINED_MIN` of
        the friction RMS) on the faster half of the moving samples (:func:`_not_at_speed`'s numbers), where a
        delay of the signal shifts the torque and the friction's own memory does not act. A delay shifts the
        torque-speed relation at every change of speed; near the reversals and starts the presliding state
        and a loop's static band make the shifted torque err by more than the delay's gain in a few groups,
        and on every moving sample its paired t fails (session 22: foreign card seed 316001, a 50 ms delay,
        20 %: at speed 68.8 -> 1.15 N, t = 11.7; on every moving sample 48.6 -> 34.9 N, t = 1.08; a load was
        named instead). What it explains there must also stand above the noise of the friction torque
        (:data:`X_NOISE` times :func:`torque_noise`, the floor of a structure worth stating): at speed the
        residual can be as large as the friction RMS itself, and a shift that cuts it by 0.2 % passed the 2 %
        of the friction RMS (frictid's slide at three times its noise, an offset hidden: 0.0226 -> 0.0225 N at
        speed, 0.0014 N explained for a noise of 0.0063; ``tests/test_diagnose_plants.py``)."""
        _not_at_speed(self.S, tr, self.F_rms)   # fills tr.moving["at_speed"]
        fast = (tr.moving or {}).get("at_speed")
        floor = max(EXPLAINED_MIN * self.F_rms, X_NOISE * torque_noise(self.S))
        return bool(fast is not None and fast["p"] < ALPHA / max(m, 1) and fast["explained"] >= floor)

    def worth_it(self, tr: Trial, m: int = 1) -> bool:
        """The RMS a term explains on held-out samples is at least :data:`EXPLAINED_MIN` of the friction RMS
        on the sliding samples; or, for a delay, on every moving sample (``tr.moving``, significant there at
        the step's level too), where a delay shows most (in the transients, where the torque changes
        fastest: a 33 ms delay of which the sliding samples' small residual holds under 2 % of the friction RMS;
        on sweeps the fit's inertia and viscous terms absorb a delay's imprint on the sliding samples
        altogether: foreign seed 309229, a 50 ms delay of 20 %, gain -0.0001 there). Such a delay must show on
        the faster half of the moving samples too (:func:`_not_at_speed`, a confound check), where the
        friction's own memory does not act; a shift of a fraction of a sample that a sampled log's timing
        convention leaves is rounded to whole samples there and on every moving sample (frictid's slide: 0.5 ms
        at 1 kHz). (Until session 20 the route asked for :data:`GAIN_MIN` of the sliding samples' residual
        instead: it missed 309229 and 309704, and named a 34 ms shift on seed 309007, an asymmetry and a
        drift with no delay hidden, which the check at speed now rejects.)"""
        if tr.gain > 0 and tr.explained >= EXPLAINED_MIN * self.F_rms:
            return True
        if tr.ext != "delay" or not self._moving_map_carries_model():
            return False
        mv = delay_moving(self.S, tr)   # computed only here, where it decides (one pass over the moving samples)
        return bool(mv["p"] < ALPHA / max(m, 1) and mv["explained"] >= EXPLAINED_MIN * self.F_rms
                    ) or self._shown_at_speed(tr, m)

    def _moving_map_carries_model(self) -> bool:
        """Whether the moving samples' judgement of a delay (:func:`delay_moving`: a velocity-only map per
        sign, the acceleration, cos q and sin q) carries every term of the current model
        (:data:`MOVING_MAP_EXTS`): only then does its held-out gain stand for the model's. After a dwell,
        a load or a warm-up the shift there takes part of what those terms already explain (foreign seed
        310721: after a dwell a 10 ms ``delay`` of gain 0.012, no delay hidden); such a delay must pay for
        itself on the sliding samples, where the model carries them."""
        return all(t.ext in MOVING_MAP_EXTS for t in self.st.terms)

    def choose(self, trials: list[Trial], m: int, rejected: list | None = None) -> Trial | None:
        ok = [t for t in trials if self.significant(t, m) and self.worth_it(t, m)]
        for t in list(ok):
            why = confounded(self.S, t, m, self.ctx, self.F_rms,
                             delayed=any(x.ext == "delay" for x in self.st.terms)) or self._not_from_the_work(t, m) \
                or self._not_the_rest(t, m)
            if why is not None:
                ok.remove(t)
                if rejected is not None:
                    rejected.append({"extension": t.ext, "reason": why})
        if not ok:
            return None
        ok.sort(key=lambda t: t.rms_after)
        best = ok[0]
        # a simpler candidate wins when the best is not significantly better than it
        for t in sorted(ok[1:], key=lambda t: (t.k, t.rms_after)):
            if t.k >= best.k:
                continue
            _, p = paired_t(group_d(self.S, self.S.F - t.pred_after, self.S.F - best.pred_after))
            if p >= ALPHA / max(m, 1):
                best = t
        best = self._delay_before_dwell(_speed_only_last(best, ok, lambda a, b: self.beyond(a, b, m)), ok, m)
        # a candidate with a competing explanation of no more coefficients that explains something beyond
        # it, while it explains nothing beyond that one, yields to it (an offset to a per-direction level,
        # foreign seed 309534); a rival with more coefficients may explain beyond it by its extra freedom
        # alone (the per-branch `asym` on a position ripple's per-direction imprint, tests/test_fit_static.py)
        over = [t for t in ok if t.cause in _competing_causes(best) and t.k <= best.k
                and self.beyond(t, best, m) and not self.beyond(best, t, m)]
        best = min(over, key=lambda t: t.rms_after) if over else best
        self._rivals(best, ok + self._competitors(best, m), m)
        return best

    def _not_from_the_work(self, tr: Trial, m: int) -> str | None:
        """Why a heat-balance candidate is no warm-up, or None. Its thermal state is driven by the measured
        friction power ``F w``, which carries the friction's own changes: a level that cycles in time (or
        drifts) heats and cools the state with it, and a state of a short time constant then follows the
        residual whatever its cause (foreign seed 314026, a level cycling in time, 35 %, a work program:
        ``thermal6`` with a 37 s time constant named temperature, 0.31). A warm-up is the heat the motion
        delivers: the state driven by the power of the friction the speed alone predicts
        (:meth:`frictid.diagnose.model.Context.work_power`), with each fold's time constant, must explain the
        residual too, significantly at the step's level and at least :data:`EXPLAINED_MIN` of the friction
        RMS (the chain's own bars). A logged ``temp_joint`` is a measurement and is not judged here."""
        if tr.ext not in ("thermal4", "thermal6") or any(t.settings.get("source") != "heat_balance"
                                                         for t in tr.fold_terms):
            return None
        terms = [replace(t, nl=tuple((k, "work" if k == "source" else v) for k, v in t.nl)) for t in tr.fold_terms]
        _, _, _, t, p, expl = self._judged(self._fold_fits(terms)[0])
        if p < ALPHA / max(m, 1) and expl >= EXPLAINED_MIN * self.F_rms:
            return None
        return (f"{tr.ext} follows the friction's own change, not the heat of the work: driven by the power of the "
                f"friction the speed alone predicts, its thermal state (the same time constant) explains {expl:.3g} "
                f"RMS (t = {t:.2f}, p = {p:.2g}) of the {tr.explained:.3g} the measured power's explains; a level that "
                f"changes by itself heats the measured-power state with it")

    def _not_the_rest(self, tr: Trial, m: int) -> str | None:
        """Why a dwell candidate does not survive the move before the rest as an explanation, or None. A level
        that grows with the previous move's travel (a film a long stroke pushes aside) rises at the start of the
        next move and fades over its travel: a dwell's shape, which the dwell follows through the rests of a
        program (foreign seeds 314400 and 314403, such a level, outside the list: ``dwell`` named 0.065 and
        0.066). The competitor: the dwell's own fade (each fold's ``s_c``) from a height that is a free function
        of the previous move's travel (:func:`frictid.diagnose.previous.previous_columns`), refitted with the
        model on the same folds. The dwell is refused when the competitor predicts the held-out data
        significantly better, the one-sided paired t over held-out groups at the step's level (to be beaten,
        not merely matched: a free height per bin also takes the part of a Stribeck hump the base lacks at every
        move's start, where a true dwell then leads it by t = 2.8 only, tests/test_diagnose_outside.py)."""
        if tr.ext != "dwell":
            return None
        terms = [replace(t, nl=t.nl + (("source", "previous"),)) for t in tr.fold_terms]
        after = self._fold_fits(terms)[0]
        _, _, _, _, _, expl = self._judged(after)
        t, p = paired_t(group_d(self.S, self.S.F - tr.pred_after, self.S.F - after))
        if p >= ALPHA / max(m, 1):
            return None
        return (f"{tr.ext} is beaten by the move before the rest: the same fade over the move from a height that is a "
                f"free function of the previous move's travel explains {expl:.3g} RMS on held-out data, the dwell "
                f"{tr.explained:.3g} (t = {t:.2f}, p = {p:.2g}): the level at a move's start follows the move before "
                f"the rest, not the rest")

    def _delay_before_dwell(self, best: Trial, ok: list[Trial], m: int) -> Trial:
        """The chosen candidate, except that a dwell yields to a worthy delay that explains more torque where
        it shows, on every moving sample (:func:`delay_moving`, significant at the step's level), than the
        dwell explains on the sliding samples. A delay's residual is largest in the transients, which the
        sliding samples leave out but for the start of each move, where the dwell's variable is largest
        too: the dwell then takes the part of the delay the sliding samples see and wins on their RMS
        (foreign seed 307707: a 25 ms delay named ``dwell`` first; on the moving samples the shift cuts the
        held-out RMS from 0.96 to 0.39 N m, the dwell explains 0.17 of the sliding samples'). A load term
        (:data:`YIELD_TO_DELAY_EXTS`) yields alike, and the torque a delay explains may be read on the faster
        half of the moving samples where it is shown there (:meth:`_shown_at_speed`; session 22: foreign seed
        316001, a 50 ms delay, 20 %, named ``load_torque`` first, 10.6 N of the sliding samples' residual,
        while the shift explains 68.8 N at speed)."""
        if best.ext not in YIELD_TO_DELAY_EXTS:
            return best
        d = next((t for t in ok if t.ext == "delay"), None)
        if d is None:
            return best
        mv = delay_moving(self.S, d)
        if mv["p"] < ALPHA / max(m, 1) and mv["explained"] > best.explained:
            return d
        fast = mv.get("at_speed") if self._shown_at_speed(d, m) else None
        return d if fast is not None and fast["explained"] > best.explained else best

    def _rivals(self, best: Trial, others: list[Trial], m: int) -> None:
        """Other causes the data cannot tell from the chosen one (``best.rivals``: not significantly worse on
        held-out data, named in its sentence), and those that make its correction (``best.unresolved``: a
        competing explanation of another cause with no more coefficients whose held-out correction is the
        chosen one's, :meth:`same_correction`; for a candidate with :data:`COMPETITORS`, also one of their
        causes beyond which it explains nothing, :meth:`beyond`). Such a step names no cause. (A rival that is merely not
        significantly worse is not enough: two real effects of similar size, a warm-up and a position
        ripple, explain different parts of the residual and each is not significantly worse than the other.)"""
        best.rivals, best.unresolved = [], []
        for t in others:
            if t.cause == best.cause:
                continue
            _, p = paired_t(group_d(self.S, self.S.F - t.pred_after, self.S.F - best.pred_after))
            beaten = p < ALPHA / max(m, 1)
            if not beaten:
                best.rivals.append((t.cause, t.ext, t.rms_after))
            # a competing explanation (no more coefficients) that makes the same correction (the same column
            # space on these data, whichever wins by rounding)
            if t.k <= best.k and t.cause not in best.unresolved and self.same_correction(best, t):
                best.unresolved.append(t.cause)
            elif (t.k <= best.k and t.cause in _competing_causes(best) and t.cause not in best.unresolved
                  and not self.beyond(best, t, m)):
                best.unresolved.append(t.cause)

    def _competitors(self, best: Trial, m: int) -> list[Trial]:
        """The competing explanations of the chosen candidate that are not candidates themselves
        (:data:`COMPETITORS`), judged on the same held-out folds."""
        out = []
        for ext in COMPETITORS.get(best.ext, ()):
            tr = self.evaluate(ext, m)
            if tr is not None:
                out.append(tr)
        return out

    def beyond(self, a: Trial, b: Trial, m: int) -> bool:
        """Whether candidate ``a`` explains something beyond candidate ``b`` on held-out data: the residual
        ``b`` leaves co-varies with the part of ``a``'s correction that ``b``'s does not contain (``a``'s
        correction less its least-squares multiple of ``b``'s), the one-sided t over held-out groups of
        their products significant at the step's level. An offset and a per-direction level on a map with a
        Stribeck part differ by a hair at the lowest speeds (their corrections are not the same), yet
        neither may explain anything of what the other leaves (foreign seeds 306002, 309534: a Coulomb-level
        asymmetry named ``offset``): then the data cannot tell them apart either. What ``a`` explains beyond
        ``b`` must also be worth a term (:data:`EXPLAINED_MIN` of the friction RMS, :meth:`worth_it`'s bar):
        the RMS that ``a``'s own part removes from ``b``'s held-out residual (its projection on that part, over
        the scored samples) must be at least :data:`EXPLAINED_MIN` of what ``b`` leaves (its held-out residual's
        RMS). A model's remaining misfit is the same in every group, so on a long log any correction with a
        slight share of its shape is significant beyond another, however small: session 23, foreign seed
        322035 (a Coulomb-level asymmetry of 37 % on 288 k samples; a hump of 1.16 times the level below 2 % of
        the top speed): the offset left 0.0074058 N m, the per-direction level 0.0074061, and the offset's part
        beyond it had t = 5.2 for an RMS of 6.8e-5 N m, 0.9 % of that residual (0.03 % of the friction RMS):
        ``offset`` was named first where the data cannot tell the two apart. Where they can the bar is far below
        (frictid's plateau logs: an offset of 0.2 on a flat map with a hump of 1.3 times the level explains 0.012
        beyond the scaled w < 0 branch, 77 % of what that leaves at a noise of 0.01, 23 % at 0.05; an offset of
        0.35 on the Stribeck plant 0.034 beyond the per-direction level, 96 %)."""
        ca, cb = a.pred_after - a.pred_before, b.pred_after - b.pred_before
        ss = float(cb @ cb)
        perp = ca - (float(ca @ cb) / ss) * cb if ss > 0 else ca
        e = self.S.F - b.pred_after
        _, p = paired_t(self.S.group_sums(e * perp))
        if p >= ALPHA / max(m, 1):
            return False
        e_in = e[self.inside]
        return beyond_rms(e_in, perp[self.inside]) >= EXPLAINED_MIN * float(np.sqrt(np.mean(e_in * e_in)))

    def same_correction(self, a: Trial, b: Trial) -> bool:
        """Whether two candidates make the same held-out correction: their corrections differ by an RMS of
        at most :data:`SAME_CORRECTION` of what the first explains (the same column space on these data,
        e.g. an offset and a level-only asymmetry on a Coulomb + viscous map, up to the fits' rounding)."""
        diff = a.pred_after - b.pred_after
        return float(np.sqrt(np.mean(diff * diff))) <= SAME_CORRECTION * a.explained

    # -- the loop --------------------------------------------------------------------------------------
    def run(self, max_steps: int = MAX_STEPS) -> list[dict]:
        for _ in range(max_steps):
            exts = candidates(self.S, self.st, self.ctx)
            if not exts:
                break
            m = len(exts)
            trials, records = [], []
            for e in exts:
                rec = self._screened(e, m)   # a long log's candidate that cannot pass: not tried on all samples
                tr = None if rec is not None else self.evaluate(e, m)
                if tr is not None:
                    trials.append(tr)
                    rec = tr.record()
                if rec is not None:
                    records.append(rec)
            step = {"tested": records, "m": m}
            best, term, st_new = self._choose_sound(trials, m, step)
            if best is None:
                step["chosen"] = None
                self.steps.append(step)
                break
            step.update(chosen=best, term=term, structure=st_new, before=self.st, coef_before=self.coef)
            self.steps.append(step)
            self.st = st_new
            self._before(st_new)
            step["coef"] = self.coef
        return self.steps

    def _screen_chain(self) -> Chain:
        """The screen of a long log: a chain of the same structure on the stride's samples (:mod:`.search`,
        every ``k``-th sample of every group), refitted whenever this chain's model changes."""
        if self._sub is None or self._sub.st is not self.st:
            self.stride.sync(self.ctx)   # the current model's columns that cost a pass over the logs
        if self._sub is None:
            self._sub = Chain(self.stride.sub, self.st, self.J, ctx=self.stride.ctx, full=self)
        elif self._sub.st is not self.st:
            self._sub.st = self.st
            self._sub._before(self.st)
        return self._sub

    def _screened(self, ext: str, m: int) -> dict | None:
        """A long log's candidate judged on the stride first (:func:`.screen.explained_bound`): its record
        when even the upper bound of what it would explain on all samples is under the bar a term must pass
        (:data:`EXPLAINED_MIN` of the friction RMS) and, for a delay, it does not pay for itself on every
        moving sample or at speed either (:meth:`worth_it`'s routes); such a candidate cannot be chosen and
        its trial on all samples is skipped. None: the candidate is tried on all samples (every log of at most
        :data:`.search.STRIDE_MIN` sliding samples)."""
        if not self.stride.active or self.full is not None:
            return None
        sub = self._screen_chain()
        try:
            tr = sub.evaluate(ext, m)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            tr = None   # a trial the stride cannot make leaves the candidate to the trial on all samples
        if tr is None:
            return None
        bar = EXPLAINED_MIN * self.F_rms
        n_in, level = sub._before_numbers()[3], ALPHA / max(m, 1)
        bound = explained_bound(tr, n_in, level, self.S.n_folds)
        if bound >= bar and explained_bound(tr, n_in, level / 2, self.S.n_folds, fits=0.0) < bar:
            # the fits' share decides: the stride's own in-sample to held-out gap (:func:`.screen.gap_allowance`),
            # each of the two errors at half the step's level
            fits = gap_allowance(sub.in_sample_d(tr), tr.d, n_in, level / 2)
            bound = min(bound, explained_bound(tr, n_in, level / 2, self.S.n_folds, fits=fits))
        if bound >= bar:
            return None
        if ext == "delay" and self._moving_map_carries_model() and _unresolved_delay(self.S, tr) is None:
            mv = delay_moving(self.S, tr)   # every moving sample: the whole logs' shifts, exact
            self._moving_memo = (tuple(_fold_shifts(tr)), mv)
            if mv["p"] < ALPHA / max(m, 1) and mv["explained"] >= bar or self._shown_at_speed(tr, m):
                return None   # a delay worth a term on every moving sample or at speed (:meth:`worth_it`)
        return screen_record(tr, self.stride, bound, bar)

    def _choose_sound(self, trials: list[Trial], m: int, step: dict):
        """The chosen candidate, its term on all samples and the extended structure, skipping candidates
        whose extended model is degenerate on all samples (:func:`degenerate`; recorded in
        ``step['rejected']``). (None, None, None) when none is left."""
        left = list(trials)
        while True:
            conf: list = []   # position candidates that stand in for the speed (:func:`confounded`)
            best = self.choose(left, m, conf)
            step.setdefault("rejected", []).extend(c for c in conf if c not in step.get("rejected", []))
            if not step["rejected"]:
                del step["rejected"]
            if best is None:
                return None, None, None
            res = self.S.F - self.pred
            ev0 = Evaluator(self.st, self.ctx)
            term = self._propose(best.ext, self.idx_all, res, ev0.level(self.coef, self.idx_all), self.coef)
            st_new = self.st.plus(term)
            after = Evaluator(st_new, self.ctx).fit(self.idx_all)
            why = (degenerate(self.coef, st_new, after) or unphysical(st_new, after, self.J)
                   or level_below_zero(st_new, after, self.S))
            if why is None:
                return best, term, st_new
            step.setdefault("rejected", []).append({"extension": best.ext, "reason": why})
            left = [t for t in left if t is not best]


#: Extensions whose variable is the position: a finding must show itself at one speed within a segment.
POSITION_EXTS = ("position_periodic", "position_smooth", "position_torque")
#: Speed bins (equal count, per velocity sign) that cut the segments into cells of nearly one speed.
SPEED_BINS = 20


def _within(cell: np.ndarray, x: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """x less its mean in each cell, and (w given) less its least-squares line in w within the cell: what
    varies with the speed inside a cell (an accelerating stretch) is taken out with the mean. What depends
    on the cells and w only is formed once while they live (:func:`_cell_line`)."""
    if w is None:
        cnt = np.maximum(np.bincount(cell), 1)
        return x - (np.bincount(cell, weights=x) / cnt)[cell]
    cnt, wc, sww = _cell_line(cell, w)
    xc = x - (np.bincount(cell, weights=x) / cnt)[cell]
    beta = np.bincount(cell, weights=wc * xc) / np.where(sww > 0, sww, np.inf)
    return xc - beta[cell] * wc


#: :func:`_cell_line` of the cells and velocities alive: (id of the cells, id of w) -> (weak references to
#: both, the counts, w less its cell means, the sums of its squares).
_CELL_LINES: dict = {}


def _cell_line(cell: np.ndarray, w: np.ndarray) -> tuple:
    """(samples per cell, at least 1; w less its mean in each cell; the sum of its squares per cell): the part
    of :func:`_within` that its x does not change, the same for every candidate judged (and both the
    residual and the correction of one) on the same cells, formed once while the cells and w live."""
    key = (id(cell), id(w))
    got = _CELL_LINES.get(key)
    if got is not None and got[0]() is cell and got[1]() is w:
        return got[2]
    cnt = np.maximum(np.bincount(cell), 1)
    wc = w - (np.bincount(cell, weights=w) / cnt)[cell]
    out = (cnt, wc, np.bincount(cell, weights=wc * wc))
    _CELL_LINES[key] = (weakref.ref(cell), weakref.ref(w), out)
    for a in (cell, w):
        weakref.finalize(a, _CELL_LINES.pop, key, None)
    return out


def _within_t(S: Samples, cell: np.ndarray, tr: Trial) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The residual before the candidate (``rw``) and its held-out correction (``dw``), each less its mean
    and its line in the velocity in every cell (:func:`_within`), and the one-sided t (and p) over held-out
    groups that they vary together there: ``sum(rw dw)`` per group."""
    rw = _within(cell, S.F - tr.pred_before, S.w)
    dw = _within(cell, tr.pred_after - tr.pred_before, S.w)
    t, p = paired_t(np.bincount(S.group, weights=rw * dw, minlength=S.n_groups))
    return rw, dw, t, p


def speed_cells(S: Samples) -> np.ndarray:
    """Cell index per sample: its group (a segment or a chunk of one) and its speed bin (:data:`SPEED_BINS`
    equal-count bins of the signed velocity): within a cell the speed, the plateau and the time hardly
    change, so what varies there with the position is not a stand-in for any of them."""
    def compute():
        b = speed_bins(S)
        _, cell = np.unique(S.group.astype(np.int64) * (int(b.max()) + 1) + b, return_inverse=True)
        return cell
    return S.cached("speed_cells", compute)


def confounded(S: Samples, tr: Trial, m: int, ctx: Context, F_rms: float, delayed: bool = False) -> str | None:
    """Why a candidate is not named (its confound checks, :func:`_stand_in`), or None; a candidate that
    passes them and could follow the rests (:data:`REST_COURSE_EXTS`) must also explain something beyond a
    free function of the travel since a rest (:func:`_not_beyond_rests`), and so must a dwell once the model
    carries a delay (``delayed``): what the delay's column leaves of its transients at the start of every
    move follows the travel since the move began, whatever the rest before it, and a dwell is told from it
    only by growing with the rest (foreign seed 307707: after the delay, a dwell named second)."""
    why = _stand_in(S, tr, m, ctx, F_rms)
    if why is None and (tr.ext in REST_COURSE_EXTS or (delayed and tr.ext in AT_ONE_SPEED_EXTS)):
        why = _not_beyond_rests(S, tr, m)
    return why


def _stand_in(S: Samples, tr: Trial, m: int, ctx: Context, F_rms: float) -> str | None:
    """Why a position candidate is a stand-in for the speed or the order of the plateaus (EMPS: each plateau
    speed in one stretch of travel, so any function of the speed is a function of the position), or None.
    Its held-out correction and the residual, each less its mean and its line in the velocity in every cell
    of one segment and one speed bin (:func:`speed_cells`), must vary together within the cells: the one-sided t over held-out groups of
    ``sum(rw dw)`` significant at the step's level. (A covariance, not the gain of subtracting ``dw``: in a
    closed loop the residual's variation within a plateau is an attenuated copy of the effect's, the
    controller's lag and the estimated acceleration share it.)"""
    if tr.ext == "delay":
        return _unresolved_delay(S, tr) or _a_friction_lag(S, tr, m) or _not_at_speed(S, tr, F_rms)
    if tr.ext in AT_ONE_SPEED_EXTS:
        why = _not_at_one_speed(S, tr, m)
        if why is not None:
            return why
    if tr.ext in TIME_COURSE_EXTS and tr.ext != "position_torque":
        why = _not_its_time_course(S, tr, m)
        if why is not None or tr.ext not in POSITION_EXTS:
            return why
    if tr.ext not in POSITION_EXTS:
        return None
    if tr.ext == "position_torque":
        why = _a_constant(ctx, tr, F_rms, torque_noise(S))
        if why is not None:
            return why
    rw, dw, t, p = _within_t(S, speed_cells(S), tr)
    if p >= ALPHA / max(m, 1):
        return (f"{tr.ext} does not show within segments at one speed (held-out within-cell t = {t:.2f}, "
                f"p = {p:.2g}): the position stands in for the speed or the order of the plateaus")
    why = _grows_with_speed(S, tr, rw, dw, m)
    # a torque of the position faces the time's course last (session 21): its own checks name a vibration
    # or a constant first
    return why if why is not None or tr.ext != "position_torque" else _not_its_time_course(S, tr, m)


def _a_constant(ctx: Context, tr: Trial, F_rms: float, noise: float) -> str | None:
    """Why a position torque is a constant, not a torque of the position, or None. The smooth form carries
    its mean over the travel (1, q, q^2): its correction can be a torque offset's, or a per-direction
    level's, with a slight shape that makes it significantly better on a long log (foreign seed 302048, a
    Coulomb asymmetry: a constant -0.60 N m and 0.008 N m from end to end of the travel, named
    ``position_torque``). What varies with the position, the spread of the term over the samples (its
    columns, :meth:`Context.term_columns`, times each training fold's coefficients; their mean), must be
    structure: worth a term by itself (at least :data:`EXPLAINED_MIN` of the friction RMS ``F_rms``) or
    beyond what the noise makes (at least :data:`frictid.diagnose.causes.X_NOISE` times the noise of the
    friction torque ``noise``, :func:`frictid.diagnose.causes.torque_noise`: the floor of a structure worth
    stating). The term as a whole pays for itself by the chain's rule (:meth:`Chain.worth_it`), and the
    chain's choice makes it beat an offset significantly (a candidate with fewer coefficients wins
    otherwise). (Session 20: with the friction RMS alone, the varying part of a gravity harmonic on a short
    travel could not pass however clear it was: foreign seed 309711, a 10 % harmonic on a linear axis, a
    mean of 7.2 N over the travel and 1.1 N RMS of shape, 1.6 % of the friction RMS and five times the
    noise; held-out RMS 7.35 -> 0.98 with the position torque, 1.51 with an offset. It was rejected and the
    step left ambiguous, offset or asymmetry.)"""
    var = [ctx.spread(term, np.atleast_1d(c.gamma.get(tr.index, np.zeros(0))))
           for term, c in zip(tr.fold_terms, tr.fold_coefs)]
    v = float(np.mean(var)) if var else 0.0
    if v < EXPLAINED_MIN * F_rms and v <= X_NOISE * noise:
        return (f"{tr.ext} hardly varies with the position: what varies over the travel has an RMS of {v:.3g}, "
                f"under {100 * EXPLAINED_MIN:g} % of the friction RMS ({F_rms:.3g}) and {X_NOISE:g}x the noise of "
                f"the friction torque ({noise:.3g}); its correction is a constant, another cause's (an offset, a "
                f"level by direction)")
    return None


#: Extensions that are functions of the speed alone: a repair of the base map, which the fit should carry.
SPEED_ONLY_EXTS = ("stribeck",)
#: Extensions whose variable changes at one speed from move to move (the rest before it): they must show
#: there, where a function of the speed cannot follow them.
AT_ONE_SPEED_EXTS = ("dwell",)
#: Extensions that yield to a worthy delay explaining more torque where it shows (:meth:`Chain._delay_before_dwell`):
#: their variables are largest where a delay's residual is, at the start of a move (the rest before it) and
#: in the transients (the torque the transmission carries, ``|J a + G|``); tested again on the delay's model.
#: Since session 24 the position terms too: on sweeps the accelerations sit at the ends of the travel, so a
#: delay's transients are a smooth function of the position there (foreign seed 330303, a 35.9 ms delay of
#: 18 %: ``position_smooth`` named first while the shift explained 7.2 N m of every moving sample).
YIELD_TO_DELAY_EXTS = AT_ONE_SPEED_EXTS + ("load_torque", "load_gravity") + POSITION_EXTS


def speed_bins(S: Samples) -> np.ndarray:
    """Bin index per sample: :data:`SPEED_BINS` equal-count bins of the signed velocity per sign, all
    segments pooled (cached). Within a bin a function of the speed hardly changes; a dwell variable changes
    from a move after a short rest to one after a long rest."""
    return S.cached("speed_bins", lambda: equal_count_bins(S.w, 2 * SPEED_BINS)[0])


def _not_at_one_speed(S: Samples, tr: Trial, m: int) -> str | None:
    """Why a dwell candidate is a stand-in for a function of the speed (a Stribeck hump the base map lacks:
    the moves start slowly), or None. Where the two differ is at one speed, between moves after short and
    after long rests: the candidate's held-out correction and the residual, each less its mean and its line
    in the velocity in every speed bin (:func:`speed_bins`, segments pooled), must vary together there, the
    one-sided t over held-out groups of ``sum(rw dw)`` significant at the step's level."""
    _, _, t, p = _within_t(S, speed_bins(S), tr)
    if p >= ALPHA / max(m, 1):
        return (f"{tr.ext} does not show at one speed between moves after short and long rests (held-out "
                f"within-speed-bin t = {t:.2f}, p = {p:.2g}): a function of the speed stands in for it")
    return None


#: Extensions whose variable changes slowly over the recording or from move to move (a warm-up, the rests
#: of a program): a free function of the time competes with them for the same residual.
TIME_COURSE_EXTS = ("thermal4", "thermal6", "dwell", "position_smooth", "position_periodic", "position_torque",
                    "load_gravity", "load_torque")
#: What each such extension's variable describes, for the sentence of a rejection.
TIME_COURSE_SHAPES = {"dwell": "a dwell effect", "position_smooth": "a function of the position",
                      "position_periodic": "a function of the position",
                      "position_torque": "a torque of the position", "load_gravity": "a load-dependent level",
                      "load_torque": "a load-dependent level"}


def _not_its_time_course(S: Samples, tr: Trial, m: int) -> str | None:
    """Why a temperature or dwell candidate follows only part of a slow change of another shape (a level
    cycling in time), or None. Its best competing explanation is a free function of the time times the velocity's
    sign (the training folds' mean of ``r sgn w`` in bins of the time,
    :func:`frictid.diagnose.binned.heldout_binned`): after the
    candidate's correction, that function must not explain, on held-out data and significantly at the
    step's level, at least as much of what is left as the candidate explained. A warm-up the thermal state
    describes leaves little of its course behind, nor does a dwell effect; a cycle that a thermal state or
    the rests of a program follow in part leaves the rest of it. Where a plateau runs, the position, the
    gravity torque and the transmitted torque advance with the time too: a position torque and a
    load-dependent level face the same competitor (session 21: foreign seeds 313620 and 314016, a level
    cycling in time on sweeps, named ``position_torque`` 0.06 and ``load_gravity`` 0.05)."""
    ra = S.F - tr.pred_after
    sg = np.sign(S.w)   # a slow change of the friction changes its level, whose sign is the velocity's
    rest = ra - sg * heldout_binned(S, ra * sg, S.th * 3600.0)
    t, p = paired_t(group_d(S, ra, rest))
    left = math.sqrt(max(float(np.mean(ra * ra) - np.mean(rest * rest)), 0.0))
    if p < ALPHA / max(m, 1) and left >= tr.explained:
        return (f"{tr.ext} follows only part of the residual's course in time: it explains {tr.explained:.3g} "
                f"RMS, and a free function of the time explains {left:.3g} more of what it leaves on held-out data "
                f"(t = {t:.2f}, p = {p:.2g}): a slow change that is not the shape of "
                f"{TIME_COURSE_SHAPES.get(tr.ext, 'a warm-up')}")
    return None


#: Fading travels (the longest tried, :func:`frictid.diagnose.signals.rest_scales`) after which a dwell has
#: faded (e^-3 = 5 % of it left).
DWELL_FADES = 3.0


def after_rest_travel(S: Samples) -> np.ndarray | None:
    """Per sample: the travel [q] since the current move started when a rest (slower than ``v_min`` for at
    least :data:`frictid.diagnose.signals.REST_MIN`) came before it and the travel is within
    :data:`DWELL_FADES` of the longest fading travel tried, and -1 elsewhere (a move after no rest, the rest
    of a long move): the variable of a dwell effect's fade, which neither a log without rests nor a long
    sweep turns into a clock. None when the logs hold no rests to tell a dwell by
    (:func:`frictid.diagnose.signals.rest_scales`)."""
    def compute():
        t_rest, s = rests(S)
        scales = rest_scales(S)
        if scales is None:
            return None
        # a dwell has faded after a few of the longest fading travels tried: beyond, the travel of a long
        # move would be a clock (a warm-up in a sweep's first move)
        return np.where((t_rest >= REST_MIN) & (s <= DWELL_FADES * float(np.max(scales[1]))), s, -1.0)
    return S.cached("after_rest_travel", compute)


#: Extensions a free function of the travel since a rest competes with: a heat balance with a time constant
#: of seconds cools in every rest and a torque of the position shows where the moves start, so both can
#: follow what the rests do (a dwell effect: static friction that grows with the rest and fades over the
#: move).
REST_COURSE_EXTS = ("thermal4", "thermal6", "position_torque")


def _not_beyond_rests(S: Samples, tr: Trial, m: int) -> str | None:
    """Why a candidate explains nothing beyond a free function of the travel since a rest, or None. The
    competitor: the training folds' mean of ``r sgn w`` in bins of :func:`after_rest_travel` (moves after
    no rest share one bin), predicting the held-out fold times ``sgn w`` (a level that changes over the
    moves that follow rests, as a dwell effect's does). The candidate's held-out correction must still
    explain part of what that leaves, significantly at the step's level (the one-sided paired t over
    held-out groups, the candidate's own test): a warm-up, slow against the moves, and a torque of the
    position at every position do; a thermal state of a few seconds that follows the rests does not
    (foreign seed 302046, a dwell: thermal4 with a 12 s time constant named first)."""
    x = after_rest_travel(S)
    if x is None:   # no rests of two lengths: no dwell to follow
        return None
    rb = S.F - tr.pred_before
    sg = np.sign(S.w)
    e = rb - sg * heldout_binned(S, rb * sg, x)
    t, p = paired_t(group_d(S, e, e - (tr.pred_after - tr.pred_before)))
    if p < ALPHA / max(m, 1):
        return None
    return (f"{tr.ext} explains nothing beyond a free function of the travel since a rest (held-out t = "
            f"{t:.2f}, p = {p:.2g} on what that function leaves): "
            + ("it does not grow with the rest before the move; a transient at every move's start (a delay's) "
               "follows the travel alone" if tr.ext == "dwell" else
               f"the rests, not {'the position' if tr.ext == 'position_torque' else 'a warm-up'}, shape what "
               f"it follows"))


def _speed_only_last(best: Trial, ok: list[Trial], beyond=None) -> Trial:
    """The chosen candidate, except that a function of the speed alone (:data:`SPEED_ONLY_EXTS`, a repair of
    the base map) yields to a worthy candidate shown at one speed (:data:`AT_ONE_SPEED_EXTS`, past
    :func:`_not_at_one_speed`): the speed-only term cannot explain what the other shows where the speed
    does not change, while the other's correction can take part of the speed-only one's (the moves after
    rests start slowly); the speed-only term is tested again at the next step, on the residual without it.
    It yields only when the other explains something beyond it on held-out data (``beyond(a, b)``,
    :meth:`Chain.beyond`): a candidate that explains nothing of what the speed-only term leaves follows
    part of its correction, whatever its own at-one-speed test says (session 20: foreign seed 309205, a
    gravity harmonic on a linear axis beside a Stribeck hump the base lacked: the dwell, held-out RMS 28.4
    -> 27.1 N against the Stribeck term's 18.1, nothing beyond it, went first and was named)."""
    if best.ext not in SPEED_ONLY_EXTS:
        return best
    shown = [t for t in ok if t.ext in AT_ONE_SPEED_EXTS]
    if not shown:
        return best
    pick = min(shown, key=lambda t: t.rms_after)
    return pick if beyond is None or beyond(pick, best) else best


#: Equal-count bands of the speed |w| in which a position candidate's share of the residual is compared.
SPEED_BANDS = 4
#: Most a closed loop can raise a torque of the position in the measured torque at a higher speed, by the
#: resonance peak of its complementary sensitivity (1 / (2 zeta sqrt(1 - zeta^2)): 2 at a damping of 0.25).
LOOP_PEAK_MAX = 2.0


def _band_shares(S: Samples, rw: np.ndarray, dw: np.ndarray) -> list[tuple[float, float, float, float]]:
    """Per speed band (:data:`SPEED_BANDS` equal-count bands of |w|): the share of the candidate's
    correction in the residual, ``beta = sum(rw dw) / sum(dw^2)`` over the band's samples (both within
    cells), its standard error with the held-out groups as the independent units (a ratio estimator), and
    the band's speeds [lowest, highest]. The bands, their speeds and each sample's (band, group) cell are the
    samples' own (cached); the sums per band and group come from one ``bincount`` over the cells (the same
    samples added in the same order as band by band)."""
    def bands():
        speed = np.abs(S.w)
        band, nb = equal_count_bins(speed, SPEED_BANDS)
        lims = [(float(speed[band == k].min()), float(speed[band == k].max())) if np.any(band == k) else None
                for k in range(nb)]
        return band * S.n_groups + S.group, nb, lims
    cell, nb, lims = S.cached("speed_bands", bands)
    G = S.n_groups
    sums = np.bincount(cell, weights=rw * dw, minlength=nb * G).reshape(nb, G)
    dsq = np.bincount(cell, weights=dw * dw, minlength=nb * G).reshape(nb, G)
    out = []
    for k in range(nb):
        s, d = sums[k], dsq[k]
        if d.sum() <= 0:
            continue
        beta = float(s.sum() / d.sum())
        out.append((beta, float(np.sqrt(np.sum((s - beta * d) ** 2)) / d.sum())) + lims[k])
    return out


def speed_growth(S: Samples, rw: np.ndarray, dw: np.ndarray, m: int) -> dict | None:
    """Where a correction ``dw`` of the position lives at some speeds only, or None: its share of the residual
    ``rw`` (both within cells, :func:`_band_shares`) in a faster band exceeds :data:`LOOP_PEAK_MAX` times the
    largest share of the slower bands by more than the one-sided quantile of ``ALPHA / (m (bands - 1))``
    (the held-out groups' standard errors). The numbers of the first such band: ``share``, ``lo``, ``hi``,
    the slower band's ``share_slow``, ``lo_slow``, ``hi_slow``, and ``z``."""
    bands = _band_shares(S, rw, dw)
    if len(bands) < 2:
        return None
    z = float(ndtri(1.0 - ALPHA / (max(m, 1) * (len(bands) - 1))))
    for k in range(1, len(bands)):
        j = max(range(k), key=lambda i: bands[i][0])
        (bj, sj, lo_j, hi_j), (bk, sk, lo_k, hi_k) = bands[j], bands[k]
        excess = bk - LOOP_PEAK_MAX * bj
        se = math.hypot(sk, LOOP_PEAK_MAX * sj)
        if excess > z * se:
            return {"share": bk, "lo": lo_k, "hi": hi_k, "share_slow": bj, "lo_slow": lo_j, "hi_slow": hi_j,
                    "z": excess / se}
    return None


def _grows_with_speed(S: Samples, tr: Trial, rw: np.ndarray, dw: np.ndarray, m: int) -> str | None:
    """Why a position candidate is a vibration of the speed, not a torque of the position, or None. A torque
    that depends on the position reaches the measured torque at every speed: a closed loop attenuates it
    where ``v / P`` lies above its bandwidth and raises it at most by its resonance peak
    (:data:`LOOP_PEAK_MAX`). A correction whose share of the residual (:func:`_band_shares`) is
    significantly more than that many times larger in a faster band than in every slower one (the largest
    of them, :func:`speed_growth`) lives at some speeds only: a vibration at the time frequency ``v / P`` (a
    resonance the motion passes through), which the position stands in for on a repeated program."""
    g = speed_growth(S, rw, dw, m)
    if g is None:
        return None
    return (f"{tr.ext} grows with the speed: it carries {g['share']:.2f} of its correction at {g['lo']:.3g}-{g['hi']:.3g} "
            f"against {g['share_slow']:.2f} at {g['lo_slow']:.3g}-{g['hi_slow']:.3g} (speed units; held-out groups, "
            f"z = {g['z']:.1f}): a closed loop passes a torque of the position at every speed, at most "
            f"{LOOP_PEAK_MAX:g}x more at a higher one; a vibration at the time frequency v / P is not one")


#: A delay is resolved by the log's rate when it is at least this many sample periods (the sampling places
#: the torque and the motion within half a period of each other).
DELAY_MIN_SAMPLES = 0.5


def _unresolved_delay(S: Samples, tr: Trial) -> str | None:
    """Why a delay candidate cannot be named (its shift, estimated on the training folds' moving samples,
    is shorter than :data:`DELAY_MIN_SAMPLES` sample periods in any fold, or at the end of the range
    searched), or None."""
    from .signals import delay_limit
    shifts = [float(t.settings.get("shift", 0.0)) for t in tr.fold_terms]
    dt = min(S.dt(i) for i in range(len(S.logs)))
    own = velocity_lag(S)
    lo = min(abs(x - own) for x in shifts)   # a late torque is a negative shift
    if lo < DELAY_MIN_SAMPLES * dt and not _late_beyond_mirror(S, tr):
        late = f" and the velocity's own {1e3 * own:.3g} ms (a difference of the position)" if own else ""
        return (f"delay: the shift fitted on the moving samples{late}, {1e3 * lo:.3g} ms in one fold, is shorter "
                f"than {DELAY_MIN_SAMPLES:g} of the sample period ({1e3 * dt:.3g} ms): the log's rate does not "
                f"resolve it")
    if max(abs(x) for x in shifts) >= delay_limit(S) - S.dt(0):
        return (f"delay: the shift reaches the longest searched ({1e3 * delay_limit(S):.3g} ms): not a delay of "
                f"the torque against the same motion")
    return None


def sub_sample(S: Samples, tr: Trial) -> bool:
    """Whether a delay trial's shift, less the velocity's own lag (:func:`velocity_lag`), is under
    :data:`DELAY_MIN_SAMPLES` of the sample period in some fold: a fraction of a sample, judged against its
    mirror image (:func:`delay_moving`)."""
    dt = min(S.dt(i) for i in range(len(S.logs)))
    own = velocity_lag(S)
    return min(abs(x - own) for x in _fold_shifts(tr)) < DELAY_MIN_SAMPLES * dt


def _late_beyond_mirror(S: Samples, tr: Trial) -> bool:
    """Whether a delay of under :data:`DELAY_MIN_SAMPLES` of a period is resolved all the same: the torque late
    against the motion in every fold (each shift less the velocity's own lag negative) and the shift
    significantly better than its mirror image on every moving sample (:func:`delay_moving`, at
    :data:`ALPHA`). A held command logged at the start of the period it acts over leads the motion by half a
    period (frictid's slide: 0.5 ms at 1 kHz), so a leading fraction of a period stays unresolved; a torque
    interpolated between two samples averages their noise, which the mirror does alike. Foreign card seeds
    340000 and 340544 (work programs at 131 and 190 Hz, delays of 0.45 and 0.44 of a period, 27 % and 11 % of
    the friction RMS): fitted as 0.49 and 0.47 of a period in every fold, called unresolved."""
    own = velocity_lag(S)
    if not all(x - own < 0 for x in _fold_shifts(tr)):
        return False
    return bool(delay_moving(S, tr)["p"] < ALPHA)


def velocity_lag(S: Samples) -> float:
    """How late [s] the logs' velocity is against their position, when every log's velocity is the position's
    difference over one sample period (:func:`frictid.segments.scales.difference_lag`; a backward difference
    is the velocity half a period before the sample), else 0. The delay's shift is fitted against that
    velocity: the torque's delay against the motion is the delay against the velocity plus this lag (a late
    torque's shift is negative: the shift less this lag; foreign seed 343800: a
    3.76 ms delay at 177 Hz fitted as 1.62 ms against a backward difference, called unresolved)."""
    from ..segments.scales import difference_lag

    def compute():
        lags = [difference_lag(lg.q, lg.w, lg.t) if lg.q is not None else 0.0 for lg in S.logs]
        if not lags or any(x != lags[0] for x in lags):
            return 0.0
        return lags[0] * min(S.dt(i) for i in range(len(S.logs)))
    return S.cached(("velocity_lag",), compute)


def _fold_shifts(tr: Trial) -> list[float]:
    """A delay trial's shift [s] per fold (each chosen on its training folds)."""
    return [float(t.settings.get("shift", 0.0)) for t in tr.fold_terms]


def delay_moving(S: Samples, tr: Trial) -> dict:
    """A delay trial judged on every moving sample (:func:`frictid.diagnose.signals.delay_heldout`, each
    fold's shift from its training folds), where a delay shows most: in the transients, which the sliding
    samples leave out (the inertial torque there is large). Computed once and kept on the trial
    (``tr.moving``): the moving-sample route of :meth:`Chain.worth_it`, the dwell's yield to a delay and the
    friction-lag competitor read the same pass."""
    if tr.moving is None and sub_sample(S, tr):
        # a fraction of a period: against its mirror image about the velocity's own lag, both interpolated;
        # against no delay the shift explains a quarter of what it gains over its mirror (for small shifts the
        # residual is linear in the shift), so the numbers are stated as against no delay
        rm, ra, d = delay_mirror(S, _fold_shifts(tr), velocity_lag(S))
        t, p = paired_t(d)
        gain = (rm * rm - ra * ra) / 4.0 if math.isfinite(rm) else 0.0
        tr.moving = {"rms_before": math.sqrt(ra * ra + max(gain, 0.0)) if math.isfinite(ra) else math.nan,
                     "rms_after": ra, "d": d / 4.0, "t": t, "p": p, "explained": math.sqrt(max(gain, 0.0)),
                     "mirror": rm}
    if tr.moving is None:
        rb, ra, d = delay_heldout(S, _fold_shifts(tr))
        t, p = paired_t(d)
        tr.moving = {"rms_before": rb, "rms_after": ra, "d": d, "t": t, "p": p,
                     "explained": math.sqrt(max(rb * rb - ra * ra, 0.0)) if math.isfinite(rb) else 0.0}
    return tr.moving


def _a_friction_lag(S: Samples, tr: Trial, m: int) -> str | None:
    """Why a delay candidate is not a delay of the torque but a lag of the friction behind the velocity, or
    None. A delay of the signal shifts the whole measured torque (the inertial and gravity torques too), a
    lag of the friction (the bristles' presliding dynamics, frictional memory) only the friction: on every
    moving sample the delay's held-out correction (:func:`frictid.diagnose.signals.delay_heldout`) must beat
    the velocity map taken a few samples earlier (:func:`frictid.diagnose.lag.friction_lag_heldout`, the lag
    chosen on the training folds), the one-sided paired t over held-out groups significant at the step's
    level. (Foreign seed 307721, a clean work program at 131 Hz: a 1.8-sample torque shift cut the moving
    samples' held-out RMS from 2.59 to 2.10 N m, the map one sample earlier to 2.03.) A lag whose own
    held-out gain is not significant at that level explains nothing and is no competitor (session 20: seed
    311500, a 24 ms delay on sweeps, gain 0.84 on the sliding samples, the lag 0.90 -> 0.92 N m on the
    moving samples, where the delay's gain sits in a few groups, t = 1.7: it was rejected as the lag)."""
    from .lag import friction_lag_heldout
    lag = friction_lag_heldout(S, float(np.mean(_fold_shifts(tr))))
    if lag is None:
        return None
    mv = delay_moving(S, tr)
    rb, ra = mv["rms_before"], mv["rms_after"]
    if paired_t(lag["ss0"] - lag["ss1"])[1] >= ALPHA / max(m, 1):
        return None   # the lag explains nothing significant itself: no competing explanation
    t, p = paired_t(mv["d"] - (lag["ss0"] - lag["ss1"]))
    if p < ALPHA / max(m, 1):
        return None
    ms = sorted({round(1e3 * x, 3) for x in lag["lags"]})
    return (f"delay: shifting the whole torque explains the moving samples no better than the friction lagging "
            f"the velocity by {', '.join(f'{x:.3g}' for x in ms)} ms (the velocity map taken earlier, the inertial "
            f"and gravity torques not: held-out RMS {rb:.3g} -> {ra:.3g} with the delay, -> {lag['rms_after']:.3g} "
            f"with the lag; t = {t:.2f}, p = {p:.2g}): a lag of the friction, not of the signal")


def _not_at_speed(S: Samples, tr: Trial, F_rms: float) -> str | None:
    """Why a delay candidate is not a delay of the signal but the friction's memory at the lowest speeds of
    each move, or None. A delay shifts the measured torque at every speed: in the accelerations and
    decelerations at speed as much as at a move's start. The friction's own memory lives at the starts and
    reversals (presliding; a velocity loop whose integrator builds up the torque while the friction holds
    the joint in its static band, the torque ramping at nearly no speed): a shift of the torque by the
    ramp's time aligns it with the velocity there. On the faster half of the moving samples
    (:func:`frictid.diagnose.lag.delay_at_speed`, judged as on every moving sample) the delay must be
    significant at :data:`ALPHA` and explain at least :data:`EXPLAINED_MIN` of the friction RMS. The level is
    not split over the step's candidates: the delay already passed the step's test (on the sliding or every
    moving sample); this second test of the one candidate asks whether its gain also holds at speed, and a
    gain of the friction's memory, nothing at speed, passes it at rate ALPHA. (Session 21: foreign seed
    313601, a 50 ms delay at 442 Hz, 17 %: at speed 2.34 -> 0.26 N m, 5 % of the friction RMS, in 123 of the
    135 groups that hold fast samples, none worse by much; t = 2.99 because five groups hold 73 % of the
    gain, under the step's level 7.7e-4: rejected, nothing named.) (Foreign
    seeds 309007 and 309247, PI velocity loops, an asymmetry hidden and no delay: a 34 ms and a 43 ms shift
    cut the moving samples' held-out RMS by half, 90-99 % of that gain in the slowest eighth of their speeds; at
    speed 0.0158 -> 0.0151 N m (1.2 % of the friction RMS) and 1.26 -> 1.67 N m. True delays of 21 and 50 ms,
    309704 and 309229: 10.9 -> 2.1 and 22.9 -> 2.1 N m, 14 % and 18 % of it.)"""
    from .lag import delay_at_speed
    mv = delay_moving(S, tr)
    if "at_speed" not in mv:   # kept on the trial (scalars: the record's ``moving_samples.at_speed``)
        mirror = "mirror" in mv
        fast = delay_at_speed(S, _fold_shifts(tr), velocity_lag(S) if mirror else None)
        if fast is not None and mirror:   # stated as against no delay, as on every moving sample
            rm, ra = fast["rms_before"], fast["rms_after"]
            fast = dict(fast, rms_before=math.sqrt(ra * ra + max((rm * rm - ra * ra) / 4.0, 0.0)), mirror=rm)
        if fast is not None:
            rb, ra = fast["rms_before"], fast["rms_after"]
            t, p = paired_t(fast["d"])
            fast = {"rms_before": rb, "rms_after": ra, "t": t, "p": p,
                    "explained": math.sqrt(max(rb * rb - ra * ra, 0.0)), "samples": fast["n"]}
        mv["at_speed"] = fast
    fast = mv["at_speed"]
    if fast is None:
        return None
    rb, ra, t, expl = fast["rms_before"], fast["rms_after"], fast["t"], fast["explained"]
    if fast["p"] < ALPHA and expl >= EXPLAINED_MIN * F_rms:
        return None
    return (f"delay: on the faster half of the moving samples the shift explains {expl:.3g} "
            f"({100 * expl / F_rms:.2g} % of the friction RMS; held-out RMS {rb:.3g} -> {ra:.3g}, t = {t:.2f}): "
            f"its gain lies at the lowest speeds of the moves, where the friction's own memory acts (presliding, "
            f"the static band at starts and reversals), not in a torque shifted at every speed")


def unphysical(st: Structure, after: Coef, J: float | None) -> str | None:
    """Why the extended model (its last term new, coefficients ``after`` on all samples) is no physical
    repair of the fit, or None: an inertia repair that leaves the fit's inertia ``J`` at zero or below (no
    rigid body has one; the acceleration's share of the residual then belongs to something else, a torque
    that leads the motion most often: a delay biases the fit's inertia, even to a negative value); or a dwell
    term whose level falls with the rest before a move (contacts that age at rest hold more, never less: the
    foreign card's seed 304500, a 50 ms torque delay on a joint whose fit's inertia is negative, named a dwell
    of -146 % after a 58 s rest)."""
    i = len(st.terms) - 1
    if st.terms[i].ext == "dwell":
        k = float(np.atleast_1d(after.gamma.get(i, np.zeros(1)))[0])
        return (f"dwell: the level falls with the rest before a move (coefficient {k:.3g} per unit of "
                f"ln(1 + t_rest / t0)): contacts that age at rest hold more, not less") if k < 0 else None
    if st.terms[i].ext != "inertia" or J is None:
        return None
    new = J + float(np.atleast_1d(after.gamma.get(i, np.zeros(1)))[0])
    if new <= 0:
        return (f"inertia {J:.3g} -> {new:.3g}: not a rigid body's (at most zero); the acceleration's share of "
                f"the residual is another cause's")
    return None


def level_below_zero(st: Structure, after: Coef, S: Samples) -> str | None:
    """Why the extended model, as a parameter file runs it, is not the formula its gain was measured with,
    or None: its map's level goes below zero at the speeds of the sliding samples, where the model runs it
    held at zero (a friction level cannot push the motion, :func:`frictid.models.static.evaluate`), as the
    fit refuses such a map (docs/fit.md step 5). (Franka joint 3: `stribeck_2exp+asym_scale`, amplitudes of
    +207, -237 and -224 N m, its level -17 N m at the slowest sliding speeds of w > 0; 7.49 -> 4.44 N m held out by
    its formula, 10.8 N m as run on the same samples.)"""
    cp, cn = canonical_vectors(st, after)
    pos = S.w >= 0
    low = [(float(np.min(canonical_level(S.w[m], c))), name) for m, c, name in
           ((pos, cp, "w > 0"), (~pos, cn, "w < 0")) if np.any(m)]
    worst = min(low, default=(0.0, ""))
    if worst[0] >= 0:
        return None
    return (f"{st.terms[-1].ext}: the extended map's level goes below zero on the sliding samples ({worst[0]:.3g} "
            f"at {worst[1]}): a model file runs it held at zero, not as the formula its gain was measured with")


#: The parts of a base map (canonical slots): a part collapses when none of its amplitudes is left. A
#: polynomial's cubic term held at zero beside its linear and quadratic ones leaves a viscous part (foreign
#: seed 309218: a gravity harmonic rejected as degenerate because the refit with it held w^3 as unsupported,
#: while w and w|w| stayed). The Coulomb level is a part of its own: a two-exponential base whose Coulomb and
#: first Stribeck amplitudes cancel (+108 and -108 N m, foreign seed 311801) loses both with a gravity
#: harmonic, and a thermal6 then rebuilds them (named temperature 0.81, nothing thermal hidden).
MAP_PARTS = (("level amplitude", (0,)), ("Stribeck amplitude", (1, 4)), ("viscous part", VISCOUS_SLOTS))


def degenerate(before: Coef, st: Structure, after: Coef) -> str | None:
    """Why the extended model (structure st, its last term new, coefficients ``after`` on all samples) is
    degenerate, or None: the new term collapses to zero (its coefficients held at zero as unsupported, or
    zero), or a part of the base map that the model before it had (:data:`MAP_PARTS`) collapses to zero (a
    level with no viscous part). Such a model is never reported: its gain compares against a model it no longer contains."""
    i = len(st.terms) - 1
    t = st.terms[i]
    if t.role == "thermal6":
        vals = after.dc
    elif t.role == "stribeck":
        vals = np.array([after.base_pos.get(1, 0.0), after.base_neg.get(1, 0.0)])
    elif t.role == "asym":
        vals = None
    else:
        vals = np.atleast_1d(after.gamma.get(i, np.zeros(0)))
    if vals is not None and vals.size and not np.any(vals != 0):
        return f"{t.ext} collapses to zero on all samples"
    def amp(c: Coef, sl: int) -> bool:
        return c.base_pos.get(sl, 0.0) != 0 or c.base_neg.get(sl, 0.0) != 0
    for part, slots in MAP_PARTS:
        had = [sl for sl in slots if amp(before, sl)]
        if had and not any(amp(after, sl) for sl in slots):
            return (f"with {t.ext} the base map's {part} (canonical slot{'s' if len(had) > 1 else ''} "
                    f"{', '.join(str(sl) for sl in had)}) collapses to zero")
    return None
