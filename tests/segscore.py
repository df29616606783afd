"""Score detected segments against the plant's truth labels (tests and the scorecard only).

A truth segment is a run of samples with the same ``truth["segment"]`` kind and ``truth["cycle"]`` index.
A detected segment is a true positive when a truth segment of the same kind overlaps it with
intersection-over-union >= ``IOU`` (0.8; above 0.5 a match is necessarily one-to-one).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from frictid.data import SEGMENT_KINDS

IOU = 0.8


def truth_segments(log) -> list[tuple[str, int, int]]:
    """(kind, i0, i1) runs of equal (segment, cycle) truth labels."""
    lab = np.asarray(log.truth["segment"]).astype(str)
    cyc = np.asarray(log.truth.get("cycle", np.full(lab.size, -1)))
    change = np.flatnonzero((lab[1:] != lab[:-1]) | (cyc[1:] != cyc[:-1])) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [lab.size]))
    return [(str(lab[s]), int(s), int(e)) for s, e in zip(starts, ends)]


def adapted_truth_segments(log) -> list[tuple[str, int, int]]:
    """Truth segments under the issue's definitions, derived from the plant's labels and references.

    The plant labels a presliding experiment's ramp up, hold and ramp down as one ``ramp_presliding``
    run, and a torque step's hold and the labelled 0.3 s "release" after the step back as one ``step``
    run. The segment definitions (docs/segments.md) are one row per monotonic torque ramp and one row per
    torque step lasting until the next input, so here:

    - a ``ramp_presliding`` run is cut where the reference torque ``tau_ref`` stops changing or turns:
      its rising and falling pieces are ramps, its flat pieces (the hold) are ``rest``;
    - a ``step`` run is cut at each jump of ``tau_ref``; the piece after the last jump (the release)
      extends through the ``rest`` run that follows it (the joint sits still at the same torque) until
      the next input: a change of the control mode when ``truth["mode"]`` is known (see
      :func:`simulate_with_modes`).

    - a velocity plateau of a constant-velocity experiment (``truth["plateaus"]``) is constant_velocity
      from where the true velocity, averaged over ``T_AVERAGE`` (the time scale at which a plateau is
      averaged), has settled within 2 % of the reference plus 0.1 % of the velocity limit for the rest
      of the plateau. The plant applies the same band to a 10 ms average, which the controller's jitter
      leaves on slow plateaus once the sensors are noisy: those plateaus it labels ``other`` although
      their mean velocity is the reference.

    Everything else is the plant's labels as written. Without a ``tau_ref`` channel and plateaus this
    equals :func:`truth_segments`.
    """
    segs = truth_segments(log)
    if log.truth.get("plateaus"):
        segs = _plateau_truth(log)
    ref = log.channels.get("tau_ref")
    if ref is None:
        return segs
    ref = np.asarray(ref, dtype=float)
    scale = max(float(np.ptp(ref)), 1e-300)
    out: list[tuple[str, int, int]] = []
    k = 0
    while k < len(segs):
        kind, a, b = segs[k]
        if kind == "ramp_presliding":
            d = np.diff(ref[a - 1 if a > 0 else a:b])
            if a == 0:
                d = np.concatenate(([0.0], d))
            sgn = np.where(np.abs(d) <= 1e-9 * scale, 0, np.sign(d)).astype(int)
            change = np.flatnonzero(sgn[1:] != sgn[:-1]) + 1
            starts = np.concatenate(([0], change))
            ends = np.concatenate((change, [sgn.size]))
            for s0, e0 in zip(starts, ends):
                out.append(("ramp_presliding" if sgn[s0] != 0 else "rest", a + int(s0), a + int(e0)))
        elif kind == "step":
            jumps = [a] + [a + int(i) + 1 for i in np.flatnonzero(np.abs(np.diff(ref[a:b])) > 1e-9 * scale)]
            jumps = sorted(set(jumps))
            bounds = jumps + [b]
            for s0, e0 in zip(bounds[:-1], bounds[1:]):
                out.append(("step", s0, e0))
            if k + 1 < len(segs) and segs[k + 1][0] == "rest":
                last = out.pop()
                end = segs[k + 1][2]
                mode = log.truth.get("mode")
                if mode is not None:  # the input changes when a controller takes over
                    sw = np.flatnonzero(np.asarray(mode[last[1]:end]) != mode[last[1]])
                    end = last[1] + int(sw[0]) if sw.size else end
                out.append(("step", last[1], end))
                if end < segs[k + 1][2]:
                    out.append(("rest", end, segs[k + 1][2]))
                k += 1
        else:
            out.append((kind, a, b))
        k += 1
    # merge touching rests created by the split
    merged: list[tuple[str, int, int]] = []
    for seg in out:
        if merged and merged[-1][0] == seg[0] == "rest" and merged[-1][2] == seg[1]:
            merged[-1] = ("rest", merged[-1][1], seg[2])
        else:
            merged.append(seg)
    return merged


T_AVERAGE = 0.1


def _plateau_truth(log) -> list[tuple[str, int, int]]:
    """Truth runs with the plateaus relabelled as described in :func:`adapted_truth_segments`."""
    lab = np.asarray(log.truth["segment"]).astype(object).copy()
    w = np.asarray(log.truth["velocity"], dtype=float)
    vmax = float(log.truth.get("vmax", np.max(np.abs(w))))
    m = max(1, int(round(T_AVERAGE / log.dt)))
    for i0, i1, v in log.truth["plateaus"]:
        seg = w[i0:i1]
        if seg.size < 2 * m:
            continue
        c = np.concatenate(([0.0], np.cumsum(seg - v)))
        k = np.arange(seg.size)
        lo, hi = np.maximum(k - m // 2, 0), np.minimum(k + m - m // 2, seg.size)
        dev = np.abs((c[hi] - c[lo]) / (hi - lo))
        bad = np.flatnonzero(dev > 0.02 * abs(v) + 1e-3 * vmax)
        start = 0 if bad.size == 0 else int(bad[-1]) + 1
        if seg.size - start >= 0.3 * seg.size:
            lab[i0:i0 + start] = "other"
            lab[i0 + start:i1] = "constant_velocity"
    cyc = np.asarray(log.truth.get("cycle", np.full(lab.size, -1)))
    change = np.flatnonzero((lab[1:] != lab[:-1]) | (cyc[1:] != cyc[:-1])) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [lab.size]))
    return [(str(lab[a]), int(a), int(b)) for a, b in zip(starts, ends)]


def simulate_with_modes(recipe, plant=None, seed=0, duration_scale=1.0, **kw):
    """``frictid.plant.simulate_recipe`` plus, from the compiled recipe program, the control mode of every
    sample in ``truth["mode"]`` (open-loop torque, position PID, velocity PI) and the velocity plateaus of
    the constant-velocity experiments in ``truth["plateaus"]`` ((i0, i1, reference velocity) rows)."""
    from frictid.plant import simulate_recipe
    from frictid.plant.config import load_plant, load_recipe, resolve_plant_path
    from frictid.plant.recipe import compile_recipe

    logs = simulate_recipe(recipe, plant, seed=seed, duration_scale=duration_scale, **kw)
    rec, base = load_recipe(recipe)
    pl = load_plant(plant if plant is not None else resolve_plant_path(rec.default_plant, base))
    for lg in logs:
        pr = compile_recipe(rec, pl, pl.joint(lg.joint), duration_scale)
        prog = pr.finish()
        if prog["mode"].size == lg.n:
            lg.truth["mode"] = prog["mode"]
            lg.truth["plateaus"] = list(pr.plateaus)
            lg.truth["vmax"] = float(pl.joint(lg.joint).limits.velocity)
    return logs


def _iou_best(segs: list[tuple[int, int]], others: list[tuple[int, int]]) -> np.ndarray:
    """Best IoU of each (i0, i1) in ``segs`` against the non-overlapping, sorted ``others``."""
    if not segs:
        return np.zeros(0)
    if not others:
        return np.zeros(len(segs))
    o = np.array(sorted(others), dtype=np.int64)
    best = np.zeros(len(segs))
    for k, (a0, a1) in enumerate(segs):
        j0 = max(0, int(np.searchsorted(o[:, 1], a0, side="right")))
        j1 = int(np.searchsorted(o[:, 0], a1, side="left"))
        for b0, b1 in o[j0:j1]:
            inter = min(a1, b1) - max(a0, b0)
            if inter > 0:
                best[k] = max(best[k], inter / (max(a1, b1) - min(a0, b0)))
    return best


@dataclass
class Tally:
    """Per-kind counts: true positives (detected side), detected, true positives (truth side), truth."""

    tp_det: dict = field(default_factory=lambda: {k: 0 for k in SEGMENT_KINDS})
    n_det: dict = field(default_factory=lambda: {k: 0 for k in SEGMENT_KINDS})
    tp_true: dict = field(default_factory=lambda: {k: 0 for k in SEGMENT_KINDS})
    n_true: dict = field(default_factory=lambda: {k: 0 for k in SEGMENT_KINDS})

    def add(self, truth: list[tuple[str, int, int]], detected) -> "Tally":
        for kind in SEGMENT_KINDS:
            tr = [(a, b) for k, a, b in truth if k == kind]
            de = [(s.i0, s.i1) for s in detected if s.kind == kind]
            self.tp_det[kind] += int(np.sum(_iou_best(de, tr) >= IOU))
            self.n_det[kind] += len(de)
            self.tp_true[kind] += int(np.sum(_iou_best(tr, de) >= IOU))
            self.n_true[kind] += len(tr)
        return self

    def merge(self, other: "Tally") -> "Tally":
        for d in ("tp_det", "n_det", "tp_true", "n_true"):
            for k in SEGMENT_KINDS:
                getattr(self, d)[k] += getattr(other, d)[k]
        return self

    def prf(self, kind: str) -> tuple[float, float, float]:
        """Precision, recall, F1 of one kind (nan where undefined)."""
        p = self.tp_det[kind] / self.n_det[kind] if self.n_det[kind] else float("nan")
        r = self.tp_true[kind] / self.n_true[kind] if self.n_true[kind] else float("nan")
        if self.n_det[kind] == 0 and self.n_true[kind] == 0:
            return p, r, float("nan")
        if not (p > 0 or r > 0) or np.isnan(p) or np.isnan(r):
            return p, r, 0.0
        return p, r, 2 * p * r / (p + r)

    def table(self) -> str:
        lines = [f"{'kind':<18} {'truth':>6} {'found':>6} {'precision':>9} {'recall':>7} {'F1':>6}"]
        for k in SEGMENT_KINDS:
            p, r, f1 = self.prf(k)
            lines.append(f"{k:<18} {self.n_true[k]:>6d} {self.n_det[k]:>6d} {p:>9.3f} {r:>7.3f} {f1:>6.3f}")
        return "\n".join(lines)


# ---------------------------------------------------------------------------------------------------
# Plant variants and logs the shipped recipes do not make

PLANTS = ("direct_drive", "geared_industrial", "hydraulic", "linear_slide")


def plant_variant(name: str, noise: float = 1.0, sample_rate: float | None = None):
    """A shipped plant with its sensor noise (tau, q, qd) multiplied by ``noise`` and optionally another
    sample rate [Hz]. The encoder quantum is kept."""
    from frictid.plant.config import load_plant, resolve_plant_path

    import yaml

    with open(resolve_plant_path(name)) as fh:
        d = yaml.safe_load(fh)
    s = d.setdefault("sensors", {})
    for k in ("tau_noise", "q_noise", "qd_noise"):
        s[k] = float(s.get(k, 0.0)) * noise
    if sample_rate is not None:
        s["sample_rate"] = float(sample_rate)
    return load_plant(d, where=f"{name} (noise x{noise:g})")


def random_ptp_logs(plant, seed: int = 0, moves: int = 40, joints=None):
    """Random point-to-point motion (no experiment): closed-loop moves to random targets at random speeds
    and accelerations, with random dwells, on every joint of ``plant``. Truth labels are ``other`` for
    moves and ``rest`` for dwells (refined like the plant's closed-loop rests).

    Built from the plant's own program pieces (:class:`frictid.plant.recipe.Program`): the recipe
    compiler is replaced by this program for the duration of the call.
    """
    import frictid.plant.simulate as sim
    from frictid.plant.config import Recipe
    from frictid.plant.recipe import Program, travel

    rng = np.random.default_rng(seed)
    recipe = Recipe.model_validate({"name": "random_ptp", "default_plant": plant.name,
                                    "experiments": [{"kind": "rest", "duration": 1.0}]})

    def program(rec, pl, joint, scale=1.0):
        lo, hi = travel(joint, pl.axis)
        if not np.isfinite(lo):
            lo, hi = -2.0 * joint.limits.velocity, 2.0 * joint.limits.velocity
        pr = Program(plant=pl, joint=joint, scale=scale, q=0.5 * (lo + hi), temp_env=25.0)
        pr.hold(pr.ns(1.0))
        for _ in range(moves):
            target = float(rng.uniform(lo, hi))
            v = float(rng.uniform(0.05, 1.0)) * joint.limits.velocity
            a = float(rng.uniform(0.2, 1.0)) * joint.limits.acceleration
            pr.ptp(target, v, a)
            pr.hold(pr.ns(float(rng.uniform(0.05, 3.0))))
        return pr

    saved = sim.compile_recipe
    sim.compile_recipe = program
    try:
        names = joints or [j.name for j in plant.joints]
        seeds = np.random.SeedSequence(seed).spawn(len(names))
        return [sim.simulate_joint_program(plant, plant.joint(nm), recipe, ss, 1.0) for nm, ss in zip(names, seeds)]
    finally:
        sim.compile_recipe = saved


def decimated(log, k: int):
    """Every ``k``-th sample of a log (a logger recording slower than the drive controls), truth included."""
    from dataclasses import replace

    def cut(x):
        return x[::k] if isinstance(x, np.ndarray) and x.shape[:1] == (log.n,) else x

    return replace(log, t=log.t[::k], q=cut(log.q), qd=cut(log.qd), tau=cut(log.tau),
                   channels={c: cut(v) for c, v in log.channels.items()},
                   truth={c: cut(v) for c, v in log.truth.items()})
