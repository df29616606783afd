"""What the best model leaves: residual structure tests on held-out data, and "unexplained" as an answer.

After the chain (:mod:`.chain`) the held-out residual of its last model, ``r = F - F_model`` (every sliding
sample predicted by fits that never saw its segment), is tested for structure against the variables a
user would plot it against: the velocity, the time since the last rest, the time, the position, the
acceleration, the measured torque, its rate and the previous move's travel. Per variable ``x``, and per
fold, the training folds' residual is averaged in bins of ``x`` (equal-count bins over all samples; for the
previous move's travel the cells of :func:`.previous.previous_cells`: its bins by the current move's
direction and the travel since the move started) and that step function predicts the held-out fold; the
structure is *significant* when it lowers the held-out residual with the chain's test (one-sided paired t
over held-out groups, ``ALPHA`` split over the variables), and *large enough to state* when the RMS it
explains is at least the larger of :data:`frictid.diagnose.chain.EXPLAINED_MIN` of the friction RMS and
:data:`X_NOISE` times the noise the logs show on the friction torque (its robust white-noise level,
:func:`frictid.segments.noise_sigma`): both scales come from the data. A slow, segment-to-segment wander that no
variable carries (autocorrelation) is measured by the scatter of the held-out groups' mean residuals against
what the noise alone gives them (``sigma / sqrt(samples)``).

The strongest significant structure becomes one sentence with its numbers ("residual varies with position
(period 0.31 rad), 12 % of the friction RMS, 8x the sensor noise; no candidate explains it"), stored in
``selection.diagnosis.unexplained`` and the joint's warnings (stderr, ``--json``, the parameter file, the
report's summary); every test's numbers are in ``selection.diagnosis.structure``.
"""
from __future__ import annotations

import math

import numpy as np

from .binned import fold_parts, heldout_binned, heldout_cells
from scipy.special import ndtri

from .causes import INERTIA_EXCITATION_MIN, X_NOISE, acceleration_share, torque_noise
from .chain import ALPHA, EXPLAINED_MIN, _within, group_d, paired_t, speed_cells, speed_growth
from .previous import previous_cells
from .samples import Samples
from .signals import torque_rate

#: The variables tested, with their label and unit key.
VARIABLES = (("speed", "velocity", "w"), ("dwell", "time since the last rest", "s"), ("time", "time", "s"),
             ("position", "position", "q"), ("acceleration", "acceleration", "a"),
             ("torque", "measured torque", "F"), ("torque_rate", "rate of the measured torque", "F/s"),
             ("previous", "the previous move's travel (by direction and travel since the move started)", "q"))


def since_rest(S: Samples) -> np.ndarray:
    """Time [s] since the joint last rested (moved slower than ``v_min``), per sample; since the start of
    its log when it never rested before. The last sample at rest at or before a sample is the sample itself
    when it rests, else the last sample of the latest run of rest before it (found among the runs' ends, not
    by a running maximum over the whole log: the same indices)."""
    def compute():
        out = np.empty(S.n)
        for i, lg in enumerate(S.logs):
            sel = S.li == i
            if not sel.any():
                continue
            rest = np.abs(S.log_w(i)) <= S.v_min
            k = S.k[sel]
            ends = np.flatnonzero(rest[:-1] & ~rest[1:])   # the last sample of each run of rest with one after it
            if ends.size:
                last = ends[np.maximum(np.searchsorted(ends, k, side="right") - 1, 0)]
                last[k < ends[0]] = 0
            else:
                last = np.zeros(k.size, np.int64)
            last = np.where(rest[k], k, last)
            out[sel] = lg.t[k] - lg.t[last]
        return out
    return S.cached("since_rest", compute)


def variable(S: Samples, name: str) -> np.ndarray | None:
    """The samples of a tested variable (None when the logs do not have it)."""
    if name == "speed":
        return S.w
    if name == "dwell":
        return since_rest(S)
    if name == "time":
        return S.th * 3600.0
    if name == "position":
        return None if S.q is None or np.ptp(S.q) <= 0 else S.q
    if name == "acceleration":
        return S.a
    if name == "torque":
        return S.tau
    if name == "torque_rate":   # a delay between torque and motion leaves d dtau/dt
        return torque_rate(S)
    if name == "previous":
        return previous_cells(S)
    raise KeyError(name)


#: Variables whose test must also clear :data:`X_NOISE` times the friction torque's noise to be stated: those
#: that carry the residual's own noise (the measured torque and its rate carry the torque sensor's, the
#: estimated acceleration the noise ``J a`` puts in ``F``), so that bins of them sort the noise and a held-out
#: step function of them predicts part of it (an errors-in-variables regression: the shipped direct-drive
#: sample, nothing hidden, 6 % of the friction RMS against the measured torque at 0.75x the noise, t = 11.8);
#: the velocity, whose structure is the base map's own misfit (the fit's, which the ``stribeck`` repair
#: tests; 3 % and 0.4x on the same sample); and the wander, whose test holds the noise to be white. The
#: others (the time since a rest, the time, the position, the previous move) are measured apart from the
#: torque: their held-out cells cannot predict the noise, their significance is the test that the structure
#: is not noise, and the bar is the one a term must pass (:data:`EXPLAINED_MIN` of the friction RMS).
NOISE_BAR = ("speed", "acceleration", "torque", "torque_rate", "wander")


def structure_tests(S: Samples, r: np.ndarray, F_rms: float) -> list[dict]:
    """Every variable's test on the held-out residual r: explained RMS [F], its share of the friction RMS,
    its ratio to the sensor noise, t, p, significant, large (worth stating: at least :data:`EXPLAINED_MIN`
    of the friction RMS, and for :data:`NOISE_BAR` also :data:`X_NOISE` times the noise)."""
    sig = torque_noise(S)
    rms = float(np.sqrt(np.mean(r * r)))
    out = []
    names = [(n, lab, u) for n, lab, u in VARIABLES if variable(S, n) is not None]
    m = len(names) + 1
    floors = {True: max(EXPLAINED_MIN * F_rms, X_NOISE * sig), False: EXPLAINED_MIN * F_rms}
    for name, label, unit in names:
        x = variable(S, name)
        ra = r - (heldout_cells(S, r, x) if name == "previous" else heldout_binned(S, r, x))
        t, p = paired_t(group_d(S, r, ra))
        expl = math.sqrt(max(rms ** 2 - float(np.mean(ra * ra)), 0.0))
        out.append(_entry(name, label, expl, t, p, m, floors[name in NOISE_BAR], F_rms, sig))
    out.append(_wander(S, r, F_rms, sig, m, floors[True]))
    return out


def _entry(name, label, expl, t, p, m, floor, F_rms, sig) -> dict:
    sigf = bool(p < ALPHA / m)
    return {"variable": name, "label": label, "explained_rms": expl,
            "of_friction_rms": expl / F_rms if F_rms > 0 else math.nan,
            "x_noise": expl / sig if sig > 0 else math.inf, "t": t, "p": p,
            "significant": sigf, "large": bool(sigf and expl >= floor)}


def _wander(S: Samples, r: np.ndarray, F_rms: float, sig: float, m: int, floor: float) -> dict:
    """The slow wander of the residual from segment to segment (autocorrelation no variable carries): the
    RMS of the held-out groups' mean residuals beyond what the noise gives them (``sig / sqrt(n_g)``), with a
    one-sided t of ``n_g mean_g^2 / sig^2 - 1`` over the groups (zero mean for white noise)."""
    n_g = np.bincount(S.group, minlength=S.n_groups).astype(float)
    mean_g = np.bincount(S.group, weights=r, minlength=S.n_groups) / np.maximum(n_g, 1)
    if sig > 0:
        z = n_g * mean_g ** 2 / sig ** 2 - 1.0
        t, p = paired_t(z)
    else:
        t, p = 0.0, 1.0
    excess = float(np.sum(n_g * mean_g ** 2) - sig ** 2 * S.n_groups) / max(S.n, 1)
    expl = math.sqrt(max(excess, 0.0))
    e = _entry("wander", "segment to segment (autocorrelated)", expl, t, p, m, floor, F_rms, sig)
    return e


def position_period(S: Samples, r: np.ndarray) -> float | None:
    """The period [q] of the sinusoid in position that best explains r (additive), or None."""
    from .causes import _period_range, best_period
    pr = _period_range(S)
    return None if pr is None else best_period(S.q, r, np.ones_like(r), pr)


def vibration(S: Samples, r: np.ndarray, m: int, period: float | None) -> dict | None:
    """Where the residual's structure in the position lives at some speeds only (:func:`.chain.speed_growth`,
    the test that rejects a position candidate as a vibration), or None: the held-out correction of the
    structure stated (the sinusoid of ``period`` in the position, fitted on the training folds; without a
    period, the held-out bin means of r in the position) and r, each less its mean and its line in the
    velocity in every cell of one segment and one speed bin (:func:`.chain.speed_cells`), their shares in
    bands of the speed. A torque of the position reaches the measured torque at every speed through a
    closed loop; a resonance the motion passes through at some speeds, on a repeated program, falls at the
    same positions every cycle (frictid's geared joint in a pick-and-place program,
    ``benchmarks/bench_diagnose_whole.py``)."""
    if period is None:
        d = heldout_binned(S, r, S.q)
    else:
        x = 2.0 * math.pi * S.q / period
        X = np.column_stack([np.sin(x), np.cos(x), np.ones(S.n)])
        d = np.empty(S.n)
        for te in fold_parts(S):
            train = np.ones(S.n, dtype=bool)
            train[te] = False
            d[te] = X[te] @ np.linalg.lstsq(X[train], r[train], rcond=None)[0]
    cell = speed_cells(S)
    return speed_growth(S, _within(cell, r, S.w), _within(cell, d, S.w), m)


def acceleration_noise(S: Samples, r: np.ndarray, J: float | None, J_err: float | None, m: int) -> dict | None:
    """Where the residual's structure against the acceleration is the estimated acceleration's own noise, not
    motion the torque follows, or None. ``F = tau - J a - G`` with the fit's inertia ``J``: where the sliding
    samples' estimated acceleration ``a`` is mostly noise (an encoder's step through the derivative), the
    measured torque does not follow it and the residual is ``-J`` times that noise, a function of ``a``
    itself (errors in the variable; the noise of ``J a`` is smooth, so the torque's white-noise level, the
    :data:`X_NOISE` bar, misses it). The competing explanation is the fit's inertia: the residual's slope on
    ``a`` (within cells of one segment and one speed, :func:`.chain._within`), ``beta``, says the torque
    follows ``a`` at the inertia ``J + beta``. Only where the sliding samples hold under
    :data:`INERTIA_EXCITATION_MIN` of the acceleration excitation (the ``inertia`` repair is then not tried:
    the fit's ``J`` rests on the rest of it) and the fit's ``J`` has a standard error; the structure is the
    estimate's noise when ``J + beta`` is below the fit's ``J`` by more than both errors (``beta``'s over the
    groups, the one-sided normal quantile at the step's level) and not below zero by more than its own error
    (noise attenuates the slope toward zero, never past it). Foreign card seeds 340025 and 340504 (clean
    sweeps, 14-bit encoders): the torque follows 6 % and 4 % of the sliding samples' acceleration at the
    fit's inertia (10.2 and 0.041, 3 % and 1 % from the plant's), stated before as "residual varies with
    acceleration", 21-28 % of the friction RMS."""
    if J is None or J_err is None or not J > 0 or not math.isfinite(J_err):
        return None
    share = acceleration_share(S)
    if share >= INERTIA_EXCITATION_MIN:
        return None
    cell = speed_cells(S)
    aw, rw = _within(cell, S.a, S.w), _within(cell, r, S.w)
    sra = np.bincount(S.group, weights=rw * aw, minlength=S.n_groups)
    saa = np.bincount(S.group, weights=aw * aw, minlength=S.n_groups)
    G, total = S.n_groups, float(saa.sum())
    if G < 3 or not total > 0:
        return None
    beta = float(sra.sum()) / total
    se = math.sqrt(G / (G - 1) * float(np.sum((sra - beta * saa) ** 2))) / total
    z = float(ndtri(1.0 - ALPHA / max(m, 1)))
    follows = J + beta
    if not (-beta > z * math.hypot(se, J_err) and follows > -z * se):
        return None
    return {"slope": beta, "slope_err": se, "J": J, "J_err": J_err, "follows": follows / J, "share": share,
            "sentence": (f"the residual's structure against the acceleration is the estimated acceleration's noise: "
                         f"the measured torque follows the sliding samples' acceleration at an inertia of "
                         f"{follows:.3g} +- {se:.2g}, {100 * follows / J:.0f} % of the fit's {J:.3g} +- {J_err:.2g} "
                         f"(resting on the {100 * (1 - share):.0f} % of the acceleration excitation outside them), "
                         f"and leaves -J times the rest")}


def unexplained(S: Samples, r: np.ndarray, F_rms: float, units: dict, model: str = "the best model",
                J: float | None = None, J_err: float | None = None) -> tuple[list[dict], str | None]:
    """(the tests, the sentence on the strongest structure worth stating or None); model : the name of the
    model whose held-out residual r is; J, J_err : the inertia ``F`` was formed with and its standard error,
    for :func:`acceleration_noise` (None: not judged)."""
    tests = structure_tests(S, r, F_rms)
    acc = next((e for e in tests if e["variable"] == "acceleration" and e["large"]), None)
    noise = None if acc is None else acceleration_noise(S, r, J, J_err,
                                                         sum(1 for x in tests if x["variable"] != "wander") + 1)
    if noise is not None:
        # a variable carries the structure (the acceleration, its estimate's noise), and the wander, which a
        # smooth noise also shows in the segments' means, is stated only when none does (below)
        acc["large"], acc["estimate_noise"] = False, noise
        for e in tests:
            if e["variable"] == "wander" and e["large"]:
                e["large"], e["carried_by"] = False, "acceleration"
    # a variable that carries the structure names it; the wander (which any slow structure also shows in
    # the segments' means) only when none does
    large = sorted((e for e in tests if e["large"]), key=lambda e: (e["variable"] == "wander", -e["explained_rms"]))
    if not large:
        return tests, None
    top = large[0]
    what, why = top["label"], ""
    if top["variable"] == "position":
        P = position_period(S, r)
        g = vibration(S, r, sum(1 for e in tests if e["variable"] != "wander") + 1, P)
        top["speed_growth"] = g
        if g is not None:
            what += " at some speeds only"
            why = (f"; its correction carries {g['share']:.2f} of the residual at {g['lo']:.3g}-{g['hi']:.3g} "
                   f"{units.get('w', 'speed units')} against {g['share_slow']:.2f} at {g['lo_slow']:.3g}-"
                   f"{g['hi_slow']:.3g} (z = {g['z']:.1f}): a vibration the motion excites at those speeds, which a "
                   f"repeated program places at the same positions, not a torque of the position")
        elif P is not None:
            what += f" (period {P:.3g} {units.get('q', 'rad')})"
    others = [e["label"] for e in large[1:] if e["variable"] != "wander"]
    xn = f"{top['x_noise']:.0f}x the sensor noise" if math.isfinite(top["x_noise"]) else "noise-free torque"
    text = (f"residual varies with {what} after {model}: {top['explained_rms']:.3g} "
            f"{units.get('F', 'N m')} RMS, {100 * top['of_friction_rms']:.0f} % of the friction RMS, {xn}"
            + (f" (also seen against {', '.join(others)})" if others else "") + why
            + "; no candidate explains it")
    if top["variable"] == "wander":
        text = (f"residual wanders from segment to segment after {model}: {top['explained_rms']:.3g} "
                f"{units.get('F', 'N m')} RMS beyond the noise, {100 * top['of_friction_rms']:.0f} % of the "
                f"friction RMS, {xn}; no candidate explains it")
    return tests, text
