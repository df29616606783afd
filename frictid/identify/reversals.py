"""LuGre's bristle stiffness from the stops and reversals of moving data, for joints without presliding ramps.

Where no ramp identifies sigma0 (:mod:`.dynamics`), the stops and reversals of ordinary motion still show
the bristles: the friction crosses from one level to the other over a travel of about ``L = g(0) / sigma0``
(the bristle length), where the static map jumps at the velocity's sign change. :func:`reversal_lugre`
fits that length on the moving samples *including* the stops (the static maps keep them out by design):

- for each length on a grid, from a few encoder steps (the position's quantisation, else its noise) up
  to a tenth of the median stroke between reversals, the chosen map with bristles of stiffness
  ``sigma0 = g(0) / L`` (and a damping, below) is replayed along the measured velocity as
  :func:`frictid.replay.replay` does (at rest the
  bristles carry what the applied torque loads them with where the joint stands), and the inertia, free
  gravity terms and offset are fitted again with it by least squares (the rigid body and the friction
  through the stops trade off: both act where the acceleration is largest); the map stays as fitted
  (refitting its amplitudes with the bristles cost the selected Fc's and sigma2's coverage on the foreign
  fit card where the map came from plateaus, and gained nothing on the UR10e);
- the length is chosen by the held-out error of the fit's time blocks (each fold fitted without its
  blocks), and compared with the static map under the same refit, block by block.

Where the map has no low-speed (Stribeck) part of its own, a low-speed term ``amp exp(-(|w| / vs)^2)``
under the bristles is chosen alike (:func:`_low_speed`: amplitudes a share of the level at rest, speeds from
twice the stick threshold to half the median speed; kept when its speed is inside that grid and it beats the
bristles alone by two paired errors of the held-out blocks): the maps are fitted away from the stops, where
a Stribeck drop acts, and the bristles carry the friction through them. It is the model's ``str_amp``,
``str_vs`` (``str_delta`` held at 2), the Stribeck slot of its canonical vectors.

With the bristles chosen, two more terms of the refit are judged on the same held-out blocks (session 23):
the free gravity terms are kept only when they beat the refit with the gravity held at zero by two paired
errors (:func:`_gravity_guard`: on an oscillation J and the gravity trade off, and a gravity the data cannot
tell from none moves J); and on logs that declare their positions absolute a torque ripple that follows the
position (:mod:`.ripple`, :func:`_ripple`: a motor's cogging, a gear's teeth) is added when, its period
searched on each fold's training blocks, it beats the model without it by two paired errors.

sigma0 is identifiable when the chosen length lies inside the grid (not at the encoder's end, where the
bristles are the static map's jump, nor at the stroke's end), beats the static map on the held-out blocks
by more than two standard errors of the paired block differences, and the lengths within one such error
of the best stay inside the grid; its standard error is the spread of sigma0 over those lengths. The damping
is chosen with the length (:func:`_damped`): a damping ratio ``zeta`` of :data:`ZETAS` sets ``sigma1 = 2 zeta
sqrt(sigma0 J) - sigma2`` at each length, the pair with the least held-out error wins, and the lengths of
every ratio within one paired error widen sigma0's error; sigma1 is reported as chosen, not identifiable
(the reversals do not resolve it apart from the length). The refitted terms'
errors are the block jackknife's over the folds. Arrays in, result objects out; truth is never read.
"""
from __future__ import annotations

import math

import numpy as np

from frictid.models.params import unit_of
from frictid.models.replay_kernel import replay_friction
from frictid.replay import STICK_NOISE, stands
from frictid.result import ModelFit, ParamEstimate

from . import presliding as pre
from . import ripple as rp
from . import samples as smp
from .prepare import JointData

#: The shortest bristle length tried: this many encoder steps (or position noise levels).
LENGTH_MIN_STEPS = 2.0
#: The longest: this share of the median stroke between reversals.
LENGTH_MAX_STROKE = 0.1
#: Lengths per decade on the grid.
PER_DECADE = 4
#: Paired standard errors by which the bristles must beat the static map on the held-out blocks.
GAIN_Z = 2.0
#: Reversals and stops needed in the moving samples.
MIN_REVERSALS = 6
#: Bristle damping ratios tried with each length (``sigma1 = 2 zeta sqrt(sigma0 J) - sigma2``, at least 0).
ZETAS = (0.0, 0.25, 0.5, 0.75, 1.0)
#: The damped best length is kept only within this factor of the undamped best (else the undamped, its error
#: spanning both).
SPAN_MAX = 2.0
#: Segment kinds kept out (ramps and steps identify sigma0 themselves).
EXCLUDE = ("ramp_presliding", "step")
RIGID = ("J", "Px", "Py", "offset")
#: The gravity terms, kept in the refit only when they predict the held-out blocks better (:func:`_gravity_guard`).
GRAVITY = ("Px", "Py")
#: The low-speed (Stribeck) term under the bristles, for a map without one: amplitudes [share of the map's
#: level at rest] and speeds from this many stick thresholds ...
STR_AMPS = (0.1, 0.2, 0.3, 0.5)
STR_MIN_STICK = 2.0
#: ... to this share of the used samples' median speed (PER_DECADE speeds per decade).
STR_MAX_SPEED = 0.5


def _data(jd: JointData):
    """Per log with a position: (t, w, F, columns of the free rigid terms, used mask, w_stick, standing
    mask, q), the reversal count and the median stroke between them, and the encoder's (or noise's) position step."""
    from frictid.segments import estimate_scales

    from .mechanics import regressors
    free = [n for n in regressors(jd).free if n in RIGID]
    out, strokes, steps, n_rev = [], [], [], 0
    for p in jd.preps:
        if p.log.q is None or p.F is None:
            continue
        sc = p.scales or estimate_scales(p.log)
        q = np.asarray(p.log.q, float)
        w_stick = STICK_NOISE * sc.sigma_w
        use = np.isfinite(p.F) & np.isfinite(p.w) & np.isfinite(p.a) & (np.abs(p.w) > w_stick)
        for s in p.segments:
            if s.kind in EXCLUDE:
                use[s.i0:s.i1] = False
        cols = {"J": p.a, "Px": np.cos(q), "Py": np.sin(q), "offset": np.ones_like(q)}
        X = np.column_stack([np.nan_to_num(cols[n]) for n in free]) if free else np.zeros((q.size, 0))
        # a stop or reversal: the velocity leaves the moving band (enters the stick zone or changes sign)
        sgn = np.where(np.abs(p.w) > w_stick, np.sign(p.w), 0.0)
        moving = np.flatnonzero(sgn != 0)
        if moving.size > 1:
            ends = moving[np.flatnonzero(np.diff(sgn[moving]) != 0) + 1]
            gaps = moving[np.flatnonzero(np.diff(moving) > 1) + 1]
            n_rev += np.unique(np.concatenate([ends, gaps])).size
            if ends.size > 1:  # the travel between reversals
                strokes.extend(np.abs(np.diff(q[ends])).tolist())
        steps.append(sc.q_step or pre.encoder_resolution(q) or sc.sigma_q)
        hold = stands(np.nan_to_num(p.w), sc)
        out.append((np.asarray(p.log.t, float), np.asarray(p.w, float), np.asarray(p.F, float), X, use, w_stick,
                    hold, q))
    stroke = float(np.median(strokes)) if strokes else 0.0
    return free, out, n_rev, stroke, max(steps, default=0.0)


def _speeds(data) -> tuple[float, float]:
    """The largest stick threshold and the median speed of the used samples."""
    w = np.concatenate([np.abs(d[1][d[4]]) for d in data]) if data else np.zeros(0)
    return max((d[5] for d in data), default=0.0), float(np.median(w)) if w.size else 0.0


def _block_equations(data, F_of, n_folds: int):
    """Per time block: (X'X, X'y, y'y, n) on the used samples of the friction with the fit's rigid terms less
    the model's (``F_of(t, w, F, w_stick, hold)``) against the free rigid terms' columns."""
    return _equations(data, [d[2] - F_of(d[0], d[1], d[2], d[5], d[6]) for d in data], [d[3] for d in data],
                      n_folds)


def _equations(data, ys, Xs, n_folds: int, extra=None):
    """:func:`_block_equations` of residuals ``ys`` against columns ``Xs`` (per log), with the columns
    ``extra(q)`` of the position appended when given (the ripple's)."""
    ranges = smp.block_ranges([d[0] for d in data], n_folds)
    n_blocks = smp.BLOCKS_PER_FOLD * n_folds
    k = (Xs[0].shape[1] if data else 0) + (2 if extra is not None else 0)
    XX, Xy = np.zeros((n_blocks, k, k)), np.zeros((n_blocks, k))
    yy, nn = np.zeros(n_blocks), np.zeros(n_blocks)
    for d, y, X, rr in zip(data, ys, Xs, ranges):
        use, q = d[4], d[7]
        for i0, i1, b in rr:
            m = use[i0:i1]
            Xb, yb = X[i0:i1][m], y[i0:i1][m]
            if extra is not None:
                Xb = np.column_stack([Xb, extra(q[i0:i1][m])])
            XX[b] += Xb.T @ Xb
            Xy[b] += Xb.T @ yb
            yy[b] += float(yb @ yb)
            nn[b] += m.sum()
    return XX, Xy, yy, nn


def _solve(XX, Xy):
    k = XX.shape[0]
    if k == 0:
        return np.zeros(0)
    sc = np.sqrt(np.maximum(np.diag(XX), 1e-300))
    b, *_ = np.linalg.lstsq(XX / np.outer(sc, sc), Xy / sc, rcond=1e-10)
    return b / sc


def _heldout(eq, n_folds: int):
    """Per block its held-out squared error (the fold's fit without its blocks), the fit on all blocks and
    the per-fold fits (for the jackknife)."""
    XX, Xy, yy, nn = eq
    fold = np.arange(nn.size) % n_folds
    sse = np.zeros(nn.size)
    fits = []
    for f in range(n_folds):
        tr = fold != f
        b = _solve(XX[tr].sum(0), Xy[tr].sum(0))
        fits.append(b)
        for i in np.flatnonzero(~tr):
            sse[i] = yy[i] - 2.0 * b @ Xy[i] + b @ XX[i] @ b
    return sse, _solve(XX.sum(0), Xy.sum(0)), fits


def _grid(n_rev: int, stroke: float, step: float) -> tuple[np.ndarray | None, str]:
    """The bristle lengths [q] tried, or None with the reason."""
    if n_rev < MIN_REVERSALS:
        return None, f"{n_rev} stops and reversals in the moving samples (at least {MIN_REVERSALS} needed)"
    lo, hi = LENGTH_MIN_STEPS * step, LENGTH_MAX_STROKE * stroke
    if not (lo > 0 and hi > 10.0 * lo):
        return None, (f"the strokes between reversals (median {stroke:.3g}) are too short against the "
                      f"position's step ({step:.3g}) to resolve a bristle length")
    n = int(math.ceil(PER_DECADE * math.log10(hi / lo))) + 1
    return np.geomspace(lo, hi, n), ""


def _paired(sse_a, sse_b, nn) -> tuple[float, float]:
    """Mean-square gain of b over a on the held-out blocks and its standard error (blocks paired)."""
    m = nn > 0
    e = sse_a[m] - sse_b[m]
    N = float(nn[m].sum())
    return float(e.sum() / N), float(math.sqrt(e.size) * np.std(e, ddof=1) / N) if e.size > 1 else math.inf


def _verdict(sse: list, sse0, nn, L) -> tuple[int, float, str]:
    """The chosen length's index, sigma0's relative error and the reason it is not identifiable ('' when it
    is): interior, better than the static map by GAIN_Z paired errors, the lengths within one paired error
    of it inside the grid."""
    tot = np.array([s.sum() for s in sse])
    i = int(np.argmin(tot))
    gain, se = _paired(sse0, sse[i], nn)
    near = [j for j in range(len(sse)) if (tot[j] - tot[i]) / nn.sum() <= _paired(sse[j], sse[i], nn)[1]]
    span = (L[max(near)], L[min(near)])
    rel = max(L[i] / span[1] - 1.0, 1.0 - L[i] / span[0], 0.5 * (L[1] / L[0] - 1.0))
    if i == 0:
        why = (f"the best bristle length is the shortest tried ({L[0]:.3g}, {LENGTH_MIN_STEPS:g} position "
               "steps): the reversals show no transition longer than the encoder resolves")
    elif i == len(L) - 1:
        why = (f"the best bristle length is the longest tried ({L[-1]:.3g}, {100 * LENGTH_MAX_STROKE:.0f} % of "
               "the median stroke): no presliding transition")
    elif not gain > GAIN_Z * se:
        why = (f"bristles of length {L[i]:.3g} predict the held-out blocks no better than the static map "
               f"(mean-square gain {gain:.3g} +- {se:.3g})")
    elif 0 in near or len(L) - 1 in near:
        why = (f"the held-out error is flat over bristle lengths {min(span):.3g} to {max(span):.3g} (within "
               "one paired standard error), reaching the end of the lengths tried")
    else:
        why = ""
    return i, rel, why


def _low_speed(data, c_pos, c_neg, sigma0, held_ref, nn, n_folds: int, sigma1=0.0):
    """A low-speed (Stribeck) term under the bristles, ``amp exp(-(|w| / vs)^2)`` added to the level of a map
    that has none (the static maps are fitted away from the stops, where it acts): each (amplitude, speed) of
    the grid replayed with the chosen bristles and the rigid terms refitted, chosen by the held-out error of
    the time blocks; kept when the speed is inside its grid and it beats the bristles without it by GAIN_Z
    paired errors. Returns ((amp, vs, rel. error of vs), (its block equations, held-out result)) or (None, why)."""
    if c_pos[1] or c_neg[1]:
        return None, "the map has a low-speed part of its own"
    w_stick, w_med = _speeds(data)
    lo, hi = STR_MIN_STICK * w_stick, STR_MAX_SPEED * w_med
    if not (lo > 0 and hi > 3.0 * lo):
        return None, f"the moving samples' speeds (median {w_med:.3g}) leave no room above the stick zone"
    vs = np.geomspace(lo, hi, int(math.ceil(PER_DECADE * math.log10(hi / lo))) + 1)
    g_rest = 0.5 * float(c_pos[0] + c_neg[0])
    best = None
    for share in STR_AMPS:
        amp = share * g_rest
        eqs = [_block_equations(data, _lugre_of(_with_low_speed(c_pos, amp, v), _with_low_speed(c_neg, amp, v),
                                                sigma0, sigma1), n_folds) for v in vs]
        runs = [(e, _heldout(e, n_folds)) for e in eqs]
        j = int(np.argmin([r[1][0].sum() for r in runs]))
        if best is None or runs[j][1][0].sum() < best[2][1][0].sum():
            best = (amp, j, runs[j])
    amp, j, run = best
    gain, se = _paired(held_ref[0], run[1][0], nn)
    if j in (0, vs.size - 1):
        return None, f"the best low-speed term's speed is at the end of those tried ({vs[j]:.3g})"
    if not gain > GAIN_Z * se:
        return None, f"a low-speed term predicts the held-out blocks no better (mean-square gain {gain:.3g} +- {se:.3g})"
    return (amp, float(vs[j]), 0.5 * (vs[1] / vs[0] - 1.0)), run


def _with_low_speed(c, amp: float, vs: float) -> np.ndarray:
    """A canonical vector with its Stribeck slot holding the low-speed term (the model's ``str_*``)."""
    c = np.array(c, dtype=float)
    c[1], c[2], c[3] = amp, vs, 2.0
    return c


def _lugre_of(c_pos, c_neg, sigma0, sigma1=0.0):
    """``F_of`` of :func:`_block_equations`: the map with bristles of stiffness ``sigma0`` and damping ``sigma1``
    (pairs), replayed along the measured velocity with the stick zone's torque and the standing rule, from the
    steady start."""
    return lambda t, w, F, ws, hold: replay_friction(t, w, c_pos, c_neg, u_stick=F, w_stick=ws, hold=hold,
                                                     sigma0=sigma0, sigma1=sigma1, z0="steady")[0]


def _damping(sigma0, zeta: float, J, c_pos, c_neg) -> tuple[float, float]:
    """The bristle damping (pair) of damping ratio ``zeta``: ``sigma1 = 2 zeta sqrt(sigma0 J) - sigma2``, at least
    0 (``sigma2`` the map's viscous slope at rest, canonical ``b1``)."""
    if not zeta or J is None or not J > 0:
        return 0.0, 0.0
    return tuple(max(2.0 * zeta * math.sqrt(s * J) - float(c[6]), 0.0) for s, c in zip(sigma0, (c_pos, c_neg)))


def _damped(data, c_pos, c_neg, g0, L, J, sse0, nn, n_folds: int, step: float = 0.0):
    """The bristle length and the damping ratio chosen together by the held-out error of the time blocks: a damped
    bristle turns the friction faster at a reversal (``sigma1 dz/dt`` acts at once), which stiffer undamped bristles
    imitate (sigma0 5-9x high where the damping ratio is 0.8-0.9). The undamped row is tried at every length; each
    further ratio of :data:`ZETAS` (none without a positive inertia) walks downhill from the previous ratio's best
    length and then out to the lengths within one paired error of its best (:func:`_row_walk`); where the undamped
    row's best is the shortest length (no transition longer than the encoder resolves) no damping is tried: a damped
    bristle turns faster still, and a damping there would only take up what the map misses near zero speed. The best
    cell's row gives the length and the verdict (:func:`_verdict` on that row's contiguous lengths), and the cells
    of every ratio within one paired error of the best widen sigma0's error (the length and the damping trade off
    along a ridge), such a cell at the grid's end making it not identifiable; where a damped cell is best, the
    undamped row's best length joins them (the damping is a nuisance the reversals may not resolve: on foreign logs
    whose bristles span few encoder steps a damped, longer bristle won at 0.2-0.4x the truth's stiffness, trusted),
    and where the two lie more than :data:`SPAN_MAX` apart the undamped cell is kept (the model as without the
    damping; UR10e joints 5 and 6, whose held-out tail it predicts as before) with the error spanning the damped
    one. Returns (zeta, {length index: block equations}, {length index: held-out run} of the chosen row, the
    length's index, sigma0's relative error, the reason it is not identifiable or '', the cells (block equations,
    held-out run) :func:`_with_undamped` widens the rigid terms by: the undamped row's best where a damped cell is
    chosen, and the best of the damping ratios either side of the chosen, and the lengths with the chosen one
    between the grid's (:func:`_interpolated`))."""
    zetas = ZETAS if J is not None and J > 0 else ZETAS[:1]

    def cell_at(z, length):
        s0 = (g0[0] / length, g0[1] / length)
        e = _block_equations(data, _lugre_of(c_pos, c_neg, s0, _damping(s0, z, J, c_pos, c_neg)), n_folds)
        return e, _heldout(e, n_folds)

    def cell(z, j):
        return cell_at(z, L[j])

    rows = [{j: cell(zetas[0], j) for j in range(len(L))}]
    if min(rows[0], key=lambda j: rows[0][j][1][0].sum()) == 0:
        zetas = zetas[:1]  # no transition longer than the encoder resolves: none for a damping to shorten
    for z in zetas[1:]:
        prev = rows[-1]
        rows.append(_row_walk(lambda j, z=z: cell(z, j), min(prev, key=lambda j: prev[j][1][0].sum()), len(L), nn))
    k, i = min(((r, j) for r, row in enumerate(rows) for j in row), key=lambda rj: rows[rj[0]][rj[1]][1][0].sum())
    i0 = min(rows[0], key=lambda j: rows[0][j][1][0].sum())
    N = float(nn.sum())
    cells = [(r, j) for r, row in enumerate(rows) for j in row
             if (row[j][1][0].sum() - rows[k][i][1][0].sum()) / N <= _paired(row[j][1][0], rows[k][i][1][0], nn)[1]]
    if k > 0:  # the damping is a nuisance the error carries: the undamped bristles' best length is in the span
        cells.append((0, i0))
    near = [j for _, j in cells]
    if k > 0:
        if max(L[i] / L[i0], L[i0] / L[i]) > SPAN_MAX:  # the damping not pinned: the undamped bristles, as before
            k, i = 0, i0
    row = rows[k]
    js = sorted(row)
    i_sub, rel, why = _verdict([row[j][1][0] for j in js], sse0, nn, L[js])
    rel = max(rel, L[i] / L[min(near)] - 1.0, 1.0 - L[i] / L[max(near)])
    if not why and (0 in near or len(L) - 1 in near):
        why = (f"the held-out error is flat over bristle lengths {L[min(near)]:.3g} to {L[max(near)]:.3g} and "
               f"damping ratios {min(zetas):g}-{max(zetas):g} (within one paired standard error), reaching the end "
               "of the lengths tried")
    eqs, held = {j: row[j][0] for j in js}, {j: row[j][1] for j in js}
    L = np.array(L, dtype=float)
    if not why:
        i = js[i_sub]
        ridge = [math.log(L[j] / L[i]) for r, j in cells if r != k]
        ridge += [_row_vertex(rows[r], L) - math.log(L[i]) for r in (k - 1, k + 1) if 0 <= r < len(rows)]
        found = _interpolated(row, i, L, nn, ridge, lambda length: cell_at(zetas[k], length), step,
                              lambda length: _time_resolution(data, length))
        if found is not None:
            L[i], rel, (eqs[i], held[i]) = found
    alts = [rows[0][i0]] if k > 0 else []
    alts += [rows[r][min(rows[r], key=lambda j: rows[r][j][1][0].sum())] for r in (k - 1, k + 1) if 0 < r < len(rows)]
    return float(zetas[k]), eqs, held, js[i_sub], rel, why, alts, L


def _interpolated(row, i: int, L: np.ndarray, nn, ridge: list, cell_at, step: float = 0.0, resolution=None):
    """The bristle length between the grid's (session 24), and sigma0's relative error from the data instead of the
    grid's spacing (half a step, +39 % at 4 lengths per decade, was its floor, and a neighbour within one paired
    error put it at +78 %: median |z| 0.32 on the foreign card, honest 0.67). The lengths half a step either side of
    the row's best ``L[i]`` are tried too; through the best of the five (spacing ``h`` in ``ln L``) and its two
    neighbours the held-out error's parabola ``T(u) = T* + (c / 2) (u - d)^2`` (``u`` in steps of ``h``, ``c`` the
    second difference of the mean-square held-out errors) gives the vertex, whose cell is kept where it predicts the
    held-out blocks better (else the best of the five, a quarter step from the tip at most: ``h / sqrt(12)`` joins
    the error). The noise of the paired block differences, ``s`` per step (the mean of the two neighbours' paired
    standard errors), moves the slope ``T'`` by about ``s`` and so the vertex by ``s / c`` steps: its standard
    error. The ``ridge`` also holds the adjacent damping ratios' lengths (their rows' vertices,
    :func:`_row_vertex`): the reversals do not resolve the damping apart from the length, so the ratio is taken as
    known to one step of :data:`ZETAS` and the length as moving along the ridge with it (the hydraulic multisine:
    ratio 0 chosen, the plant's about 0.8, sigma0 13 % high where the noise's term is 4 %). The position's step (the
    encoder's, else its noise) bounds how finely a travel is read: ``step / sqrt(6)`` (two quantised positions)
    against the length joins it in quadrature (the UR-like wrist of tests/test_fit_reversals.py, bristles of 4
    encoder steps, gives sigma0 1.3x the truth on four seeds, the noise's term 10 %), and so does the log's time
    resolution of the transition (``resolution(length)``, :func:`_time_resolution`). The ``ridge`` (log-length
    offsets from ``L[i]`` of the other damping ratios' cells within one paired error, a nuisance the reversals do
    not pin) adds in quadrature, on each side (sigma0's error is its larger side: shorter lengths raise sigma0 by
    ``e^x - 1``, longer lower it by ``1 - e^-x``, as the grid's span did). Returns (the length, sigma0's relative
    error, the cell's (block equations, held-out run)), or None where a neighbour is missing or the errors are not
    convex (the grid's length and error are then kept)."""
    if i - 1 not in row or i + 1 not in row:
        return None
    H = math.log(L[i + 1] / L[i])
    cells = {-2: row[i - 1], 0: row[i], 2: row[i + 1]}  # in half steps
    for u in (-1, 1):
        cells[u] = cell_at(float(L[i] * math.exp(0.5 * u * H)))
    tot = {u: c[1][0].sum() / float(nn.sum()) for u, c in cells.items()}
    b = min(tot, key=tot.get)
    t = [tot[b - 1], tot[b], tot[b + 1]]
    d, c = _vertex(*t)
    if not c > 0:
        return None
    h = 0.5 * H
    s = 0.5 * (_paired(cells[b - 1][1][0], cells[b][1][0], nn)[1] + _paired(cells[b + 1][1][0], cells[b][1][0], nn)[1])
    x = (b + d) * h  # the vertex's ln L - ln L[i]
    got = cell_at(float(L[i] * math.exp(x)))
    sd = s / c * h
    if got[1][0].sum() > cells[b][1][0].sum():
        x, got, sd = b * h, cells[b], math.hypot(sd, h / math.sqrt(12.0))
    length = float(L[i] * math.exp(x))
    sd = math.hypot(sd, step / math.sqrt(6.0) / length, resolution(length) if resolution else 0.0)
    up = max([x - r for r in ridge] + [0.0])  # shorter bristles: a stiffer sigma0
    down = max([r - x for r in ridge] + [0.0])
    return float(L[i] * math.exp(x)), max(math.expm1(math.hypot(sd, up)), -math.expm1(-math.hypot(sd, down))), got


def _row_vertex(row, L: np.ndarray) -> float:
    """``ln L`` of a damping ratio's row at the vertex of its held-out error's parabola through its best length and
    that length's neighbours (the best's own ``ln L`` where a neighbour is missing or the three are not convex)."""
    j = min(row, key=lambda m: row[m][1][0].sum())
    if j - 1 not in row or j + 1 not in row:
        return math.log(L[j])
    d, _ = _vertex(*(row[m][1][0].sum() for m in (j - 1, j, j + 1)))
    return math.log(L[j]) + d * math.log(L[j + 1] / L[j])


def _vertex(t0: float, t1: float, t2: float) -> tuple[float, float]:
    """The parabola through ``(-1, t0), (0, t1), (1, t2)``: its vertex's abscissa (0 where the three are not
    convex) and its curvature ``t0 - 2 t1 + t2``."""
    c = t0 - 2.0 * t1 + t2
    return (0.5 * (t0 - t2) / c if c > 0 else 0.0), c


def _time_resolution(data, length: float) -> float:
    """How finely the log's samples place a bristle transition of travel ``length``, relative to it: after a
    reversal at acceleration ``a`` the joint covers ``length`` at the speed ``sqrt(2 a length)``, so one sample
    period there is ``sqrt(2 a / length) dt`` of the length; uniform within it, ``/ sqrt(12)``. ``a`` from the
    speeds of the moving samples either side of each sign change (beyond the stick threshold, so not the
    velocity's noise) over the time between them; the median over the reversals."""
    out = []
    for t, w, _, _, _, w_stick, *_ in data:
        m = np.flatnonzero(np.abs(w) > w_stick)
        k = np.flatnonzero(np.sign(w[m[1:]]) != np.sign(w[m[:-1]])) if m.size > 1 else m[:0]
        if k.size == 0 or not length > 0:
            continue
        i0, i1 = m[k], m[k + 1]
        a = (np.abs(w[i0]) + np.abs(w[i1])) / (t[i1] - t[i0])
        out.extend((np.sqrt(2.0 * a / length) * float(np.median(np.diff(t))) / math.sqrt(12.0)).tolist())
    return float(np.median(out)) if out else 0.0


def _with_undamped(se: np.ndarray, b: np.ndarray, alts: list, free0, free, jd: JointData, n_folds: int) -> np.ndarray:
    """The refitted rigid terms' errors ``se`` (values ``b``, names ``free``) widened by their largest change to
    the refits of ``alts`` (cells (block equations over ``free0``, held-out run), the gravity held at zero as in
    ``free``): the undamped bristles' best length where a damped one is chosen, and (session 24) the best
    lengths of the damping ratios either side of the chosen one. ``sigma1 dz/dt`` acts with the acceleration at
    each reversal, so J and the damping trade off, and the damping is a nuisance the reversals do not pin apart
    from the length (:func:`_damped`): it is taken as known to one step of :data:`ZETAS`. Hydraulic sample
    sweep: J 7.63 undamped, 9.31 at damping ratio 1 with an error of 0.045, truth 8; the sample's sweep with
    steps, J 8.84 +- 0.13 at ratio 0.25 where only the undamped cell widened it."""
    change = np.zeros_like(se)
    for alt in alts:
        eq = alt[0]
        if list(free) != list(free0):
            eq = _without_gravity(eq, free0, _gravity_now(jd, [n for n in free0 if n in GRAVITY]))
        change = np.maximum(change, np.abs(b - _heldout(eq, n_folds)[1][:len(free)]))
    return np.hypot(se, change)


def _row_walk(cell, start: int, n: int, nn) -> dict:
    """One damping ratio's row of (block equations, held-out run) by length index, evaluated lazily: downhill
    from ``start`` (both neighbours of the minimum evaluated), then outwards while a length stays within one
    paired error of the row's best; the evaluated indices are contiguous, and an end of them that is not the
    grid's is outside that band."""
    row = {}

    def get(j):
        if j not in row:
            row[j] = cell(j)
        return row[j][1][0].sum()

    j = start
    while True:
        nb = [m for m in (j - 1, j + 1) if 0 <= m < n]
        m = min(nb, key=get)
        if get(m) >= get(j):
            break
        j = m
    N = float(nn.sum())
    for step in (-1, 1):
        m = j + step
        while 0 <= m < n and (get(m) - get(j)) / N <= _paired(row[m][1][0], row[j][1][0], nn)[1]:
            m += step
    return row


def _low_speed_params(low, axis: str, source: str) -> dict[str, ParamEstimate]:
    amp, vs, rel = low
    return {"str_amp": ParamEstimate("str_amp", amp, amp * STR_AMPS[0] / max(STR_AMPS), unit_of("F", axis),
                                     source=source),
            "str_vs": ParamEstimate("str_vs", vs, rel * vs, unit_of("W", axis), source=source),
            "str_delta": ParamEstimate("str_delta", 2.0, None, "1", False, "held at 2 (Gaussian)", fixed=True,
                                       source=source)}


def _without_gravity(eq, free, g0: np.ndarray):
    """Block equations of the refit with the gravity held at zero: its columns dropped and the joint's gravity
    ``g0`` (Px, Py as the fit left them) put back into the friction residual (``y + G g0``)."""
    XX, Xy, yy, nn = eq
    gi = [j for j, n in enumerate(free) if n in GRAVITY]
    ri = [j for j, n in enumerate(free) if n not in GRAVITY]
    XXg = XX[:, ri][:, :, gi]
    return (XX[:, ri][:, :, ri], Xy[:, ri] + XXg @ g0, yy + 2.0 * Xy[:, gi] @ g0
            + np.einsum("i,bij,j->b", g0, XX[:, gi][:, :, gi], g0), nn)


def _gravity_now(jd: JointData, names) -> np.ndarray:
    """The joint's gravity terms ``names`` as the fit left them (0 where it has none)."""
    return np.array([float(jd.jf.gravity[n].value) if jd.jf.gravity.get(n) is not None and
                     jd.jf.gravity[n].value is not None else 0.0 for n in names])


def _chosen_residuals(data, jd: JointData, free0, free, c_pos, c_neg, low, sigma0, sigma1):
    """Per log the friction residual the chosen bristles (stiffness ``sigma0``, damping ``sigma1``; with the
    low-speed term when kept) leave, and the rigid columns of the terms kept (the gravity put back where
    :func:`_gravity_guard` held it at zero)."""
    if low is not None:
        c_pos, c_neg = _with_low_speed(c_pos, low[0], low[1]), _with_low_speed(c_neg, low[0], low[1])
    F_of = _lugre_of(c_pos, c_neg, sigma0, sigma1)
    keep = [j for j, n in enumerate(free0) if n in free]
    gi = [j for j, n in enumerate(free0) if n not in free]
    g0 = _gravity_now(jd, [free0[j] for j in gi])
    ys = [d[2] - F_of(d[0], d[1], d[2], d[5], d[6]) + (d[3][:, gi] @ g0 if gi else 0.0) for d in data]
    return ys, [d[3][:, keep] for d in data]


def _gravity_guard(jd: JointData, free, eq, held, n_folds: int):
    """Whether the free gravity terms earn their place in the refit with the bristles: on an oscillation the
    acceleration follows the angle, so J and ``Px cos q + Py sin q`` trade off and take up the friction's
    misfit together (docs/realdata.md, UR10e joint 6), and a gravity the data cannot tell from none moves J.
    The refit with the gravity held at zero is compared on the same held-out blocks; the gravity is kept when
    it beats it by GAIN_Z paired errors. Returns None (kept, or no free gravity) or (the reduced terms, their
    block equations, held-out result, the reason)."""
    if not any(n in GRAVITY for n in free):
        return None
    red = _without_gravity(eq, free, _gravity_now(jd, [n for n in free if n in GRAVITY]))
    held_red = _heldout(red, n_folds)
    gain, se = _paired(held_red[0], held[0], eq[3])
    if gain > GAIN_Z * se:
        return None
    why = (f"held at 0: the gravity terms predict the held-out blocks no better than none (mean-square gain "
           f"{gain:.3g} +- {se:.3g}; J and the gravity trade off where the acceleration follows the angle)")
    return [n for n in free if n not in GRAVITY], red, held_red, why


#: Why no ripple is tried on logs whose positions are not declared absolute.
NOT_ABSOLUTE = ("not tried: the logs do not declare their positions absolute (`meta: {position_absolute: true}`); "
                "an incremental encoder zeroed where a recording starts moves a ripple's phase from one "
                "recording to the next")


def _absolute(jd: JointData) -> bool:
    """Whether every log with a position declares it absolute (the same zero in every recording), so that a
    ripple's phase carries from the fitted recordings to others."""
    logs = [p.log for p in jd.preps if p.log.q is not None]
    return bool(logs) and all(bool((lg.meta or {}).get("position_absolute")) for lg in logs)


def _ripple_equations(data, ys, Xs, period: float, n_folds: int):
    """Block equations of the refit with the ripple's two columns at ``period`` added (residuals ``ys`` and
    rigid columns ``Xs`` per log, as the chosen model leaves them)."""
    return _equations(data, ys, Xs, n_folds, lambda q: rp.columns(q, period))


def _ripple(data, ys, Xs, held_ref, stroke: float, step: float, n_folds: int):
    """A torque ripple that follows the position (:mod:`.ripple`) under the chosen model: its period searched
    on each fold's training blocks (the residual of the fold's refit), the held-out blocks scored with it;
    kept when the period is not at its band's end and the ripple beats the model without it by GAIN_Z paired
    errors. Returns ((period, its grid's relative spacing), (block equations, held-out result)) or (None, why)."""
    ranges = smp.block_ranges([d[0] for d in data], n_folds)
    blk = []
    for d, rr in zip(data, ranges):
        b = np.full(d[0].size, -1)
        for i0, i1, k in rr:
            b[i0:i1] = k
        blk.append(np.where(d[4], b, -1))
    q_used = np.concatenate([d[7][m >= 0] for d, m in zip(data, blk)])
    band, why = rp.period_band(q_used, step, stroke)
    if band is None:
        return None, why

    def period_without(fit, fold):
        tr = [(m >= 0) & (m % n_folds != fold) for m in blk]
        r = np.concatenate([(y - X @ fit)[t] for y, X, t in zip(ys, Xs, tr)])
        return rp.best_period(np.concatenate([d[7][t] for d, t in zip(data, tr)]), r, band)

    sse = np.zeros(held_ref[0].size)
    fold = np.arange(sse.size) % n_folds
    for f, fit in enumerate(held_ref[2]):
        XX, Xy, yy, _ = _ripple_equations(data, ys, Xs, period_without(fit, f)[0], n_folds)
        b = _solve(XX[fold != f].sum(0), Xy[fold != f].sum(0))
        for i in np.flatnonzero(fold == f):
            sse[i] = yy[i] - 2.0 * b @ Xy[i] + b @ XX[i] @ b
    P, rel, edge = period_without(held_ref[1], -1)
    eq = _ripple_equations(data, ys, Xs, P, n_folds)
    gain, se = _paired(held_ref[0], sse, eq[3])
    if edge:
        return None, f"the best ripple period is at the end of those tried ({P:.4g})"
    if not gain > GAIN_Z * se:
        return None, (f"a ripple of period {P:.4g} predicts the held-out blocks no better (mean-square gain "
                      f"{gain:.3g} +- {se:.3g})")
    _, full, fits = _heldout(eq, n_folds)
    return (P, rel), (eq, (sse, full, fits))


def _ripple_params(rip, b, se, axis: str, source: str) -> dict[str, ParamEstimate]:
    P, rel = rip
    unit = unit_of("F", axis)
    out = {"rip_period": ParamEstimate("rip_period", P, rel * P, "rad" if axis == "rotary" else "m",
                                       source=source)}
    for j, n in enumerate(("rip_sin", "rip_cos")):
        v, e = float(b[j]), float(se[j])
        ok = bool(np.isfinite(e) and e < abs(v))
        out[n] = ParamEstimate(n, v, e, unit, ok, "" if ok else "relative error above 100 % (block jackknife)",
                               source=source)
    return out


def _jackknife(fits) -> np.ndarray:
    """Block jackknife standard errors over the folds' fits (:func:`.samples.jackknife_se`; NaN from one fold)."""
    return smp.jackknife_se(fits) if len(fits) > 1 else np.full(np.shape(fits)[1], np.nan)


def _rigid_params(jd: JointData, free, full, se, held_at_zero: str = "") -> dict[str, ParamEstimate]:
    """The inertia, gravity and offset fitted with the bristles: the joint's values plus the refit's change
    (the offset's change as ``tau_offset``), standard errors by the block jackknife over the folds; with
    ``held_at_zero`` (the reason) the gravity terms held at zero (:func:`_gravity_guard`)."""
    jf, axis = jd.jf, jd.axis
    cur = {"J": jf.inertia.value if jf.inertia else None, "offset": 0.0,
           **{g: (jf.gravity[g].value if jf.gravity.get(g) else None) for g in ("Px", "Py")}}
    units = {"J": "kg m^2" if axis == "rotary" else "kg", "Px": unit_of("F", axis), "Py": unit_of("F", axis),
             "offset": unit_of("F", axis)}
    out = {}
    for j, n in enumerate(free):
        v = (cur[n] or 0.0) + float(full[j])
        name = "tau_offset" if n == "offset" else n
        ok = bool(np.isfinite(se[j]) and se[j] < abs(v))
        out[name] = ParamEstimate(name, v, float(se[j]), units[n], ok,
                                  "" if ok else "relative error above 100 % (block jackknife)",
                                  source="refitted with the bristles on the moving samples including the stops")
    for n in GRAVITY if held_at_zero else ():
        out[n] = ParamEstimate(n, 0.0, None, units[n], False, held_at_zero, fixed=True,
                               source="refitted with the bristles on the moving samples including the stops")
    return out


def _bristle_params(g0, L, i: int, rel: float, why: str, source: str, s1: ParamEstimate, s1_neg, axis) -> dict:
    """sigma0 (and sigma0_neg where the map's zero-speed levels differ by sign) of bristle length ``L[i]``
    with relative error ``rel``, sigma1 ``s1`` (and sigma1_neg of value ``s1_neg`` when it is one, not
    False)."""
    params = {"sigma0": ParamEstimate("sigma0", g0[0] / L[i], rel * g0[0] / L[i], unit_of("K", axis),
                                      not why, why, source=source, bounds=(g0[0] / L[-1], g0[0] / L[0])),
              "sigma1": s1}
    if g0[1] != g0[0]:
        params["sigma0_neg"] = ParamEstimate("sigma0_neg", g0[1] / L[i], rel * g0[1] / L[i],
                                             unit_of("K", axis), not why, why, source=source,
                                             bounds=(g0[1] / L[-1], g0[1] / L[0]))
        if s1_neg is not False:
            params["sigma1_neg"] = ParamEstimate(**{**vars(s1), "name": "sigma1_neg", "value": s1_neg})
    return params


def reversal_lugre(jd: JointData, base: ModelFit, c_pos, c_neg, n_folds: int = 5) -> tuple[dict, dict, str]:
    """sigma0 (and sigma1 by a damping ratio chosen with it) from the stops and reversals of the moving samples,
    with the rigid terms fitted again with the bristles; the map stays as fitted. Returns (the dynamic and refitted
    rigid parameters, metrics, notes line); sigma0 says why it is not identifiable when it is not (module
    docstring)."""
    free, data, n_rev, stroke, step = _data(jd)
    axis = jd.axis
    L, why = _grid(n_rev, stroke, step) if data else (None, "no log with a position channel")
    g0 = (float(c_pos[0] + c_pos[1]), float(c_neg[0] + c_neg[1]))
    if L is not None and not min(g0) > 0:
        L, why = None, "the map's level at zero speed is not positive"
    s1 = ParamEstimate("sigma1", 0.0, None, unit_of("D", axis), False,
                       "held at 0: no bristles from the reversals to damp" if L is None else
                       "held at 0: no positive inertia to set a damping ratio against", fixed=True, source="reversals")
    if L is None:
        return {"sigma0": ParamEstimate("sigma0", None, None, unit_of("K", axis), False, why,
                                        source="reversals"), "sigma1": s1}, {}, ""

    def static(t, w, F, ws, hold):
        return replay_friction(t, w, c_pos, c_neg, u_stick=F, w_stick=ws)[0]

    eq0 = _block_equations(data, static, n_folds)
    sse0, _, _ = _heldout(eq0, n_folds)
    J = jd.jf.inertia.value if jd.jf.inertia is not None else None
    zeta, eqs, held, i, rel, why, alt, L = _damped(data, c_pos, c_neg, g0, L, J, sse0, eq0[3], n_folds, step)
    s0 = (g0[0] / L[i], g0[1] / L[i])
    s1v = _damping(s0, zeta, J, c_pos, c_neg)
    source = (f"reversals: bristle length {L[i]:.3g} and damping ratio {zeta:g} chosen by the held-out error of "
              f"{smp.BLOCKS_PER_FOLD * n_folds} time blocks ({n_rev} stops and reversals)")
    if J is not None and J > 0:
        s1 = ParamEstimate("sigma1", s1v[0], None, unit_of("D", axis), False,
                           f"damping ratio {zeta:g} (sigma1 = 2 zeta sqrt(sigma0 J) - sigma2) chosen with the bristle "
                           "length on a grid; the reversals do not resolve it apart from the length", fixed=True,
                           source="reversals")
    params = _bristle_params(g0, L, i, rel, why, source, s1, s1v[1] != s1v[0] and s1v[1], axis)
    low, got = (None, "") if why else _low_speed(data, c_pos, c_neg, s0, held[i], eq0[3], n_folds, s1v)
    if low is not None:
        eqs[i], held[i] = got
        params.update(_low_speed_params(low, axis, f"{source}; the low-speed term under them chosen alike"))
    grav = None if why else _gravity_guard(jd, free, eqs[i], held[i], n_folds)
    free0 = free
    if grav is not None:
        free, eqs[i], held[i], _ = grav
    if why or not _absolute(jd):
        rip, got_r = None, ("" if why else NOT_ABSOLUTE)
    else:
        rip, got_r = _ripple(data, *_chosen_residuals(data, jd, free0, free, c_pos, c_neg, low, s0, s1v), held[i],
                             stroke, step, n_folds)
    if rip is not None:
        eqs[i], held[i] = got_r
    if not why:
        se = _jackknife(held[i][2])
        k = len(free)
        se_k = _with_undamped(se[:k], held[i][1][:k], alt, free0, free, jd, n_folds)
        params.update(_rigid_params(jd, free, held[i][1][:k], se_k, grav[3] if grav else ""))
        if rip is not None:
            params.update(_ripple_params(rip, held[i][1][k:], se[k:], axis,
                                         f"{source}; a torque ripple that follows the position, its period "
                                         "searched on each fold's training blocks"))
    N = float(eq0[3].sum())
    XX, Xy, yy, _ = (x.sum(0) for x in eqs[i])
    b = held[i][1]
    met = {"rms": float(math.sqrt(max(yy - 2 * b @ Xy + b @ XX @ b, 0.0) / N)),
           "rms_heldout": float(math.sqrt(held[i][0].sum() / N)),
           "rms_heldout_static": float(math.sqrt(sse0.sum() / N)), "n": int(N),
           "k": int(len(base.params) + 1 + len(free) + (2 if low else 0) + (3 if rip else 0))}
    note = (f"sigma0 from {n_rev} stops and reversals: bristle lengths {L[0]:.3g}-{L[-1]:.3g} tried, held-out "
            f"RMS {met['rms_heldout']:.4g} against {met['rms_heldout_static']:.4g} for {base.name} with the "
            "same refit of the rigid terms" + (f"; a low-speed term under the bristles (amplitude {low[0]:.3g}, "
                                               f"speed {low[1]:.3g})" if low else
                                               f"; no low-speed term under them: {got}" if got else "")
            + (f"; gravity {grav[3]}" if grav else "")
            + (f"; a torque ripple of period {rip[0]:.4g} that follows the position" if rip else
               f"; no position ripple: {got_r}" if got_r else ""))
    return params, met, note
