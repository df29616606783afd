"""Score detected segments against the plant's truth labels (tests and the scorecard only).

A truth segment is a run of samples with the same ``truth["segment"]`` kind and ``truth["cycle"]`` index
(the index of a duty cycle, presliding ramp or torque step): the plant writes its labels in the segment
conventions of docs/segments.md, so they are scored as written.
A detected segment is a true positive when a truth segment of the same kind overlaps it with
intersection-over-union >= ``IOU`` (0.8; above 0.5 a match is necessarily one-to-one).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

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


def session_recipe(duty_cycle_time: float = 40.0) -> dict:
    """Every experiment in one log, with rests and the plant's repositioning moves in between."""
    return {
        "name": "session",
        "description": "all experiments concatenated, rests and repositioning moves between them",
        "default_plant": "direct_drive",
        "start_rest": 2.0,
        "experiments": [
            {"kind": "constant_velocity", "velocities": {"min": 0.02, "max": 0.9, "count": 6},
             "plateau": 2.0, "rest": 2.0},
            {"kind": "ramp_presliding", "peaks": [0.5], "ramp_up": 3.0, "hold": 1.0, "ramp_down": 3.0,
             "rest": 1.5},
            {"kind": "torque_steps", "levels": [0.4], "rest": 1.5},
            {"kind": "multisine", "duration": 20.0, "f0": 0.1, "rest": 2.0},
            {"kind": "duty_cycle", "duty": 0.5, "cycles": 4, "cycle_time": duty_cycle_time, "slots": 4,
             "rest": 2.0},
            {"kind": "rest", "duration": 2.0, "rest": 0.0},
        ],
    }


def random_ptp_logs(plant, seed: int = 0, moves: int = 40):
    """The shipped ``random_ptp`` recipe (random point-to-point moves and dwells, no experiment) on every
    joint of ``plant``, its moves drawn with ``seed`` (the sensor noise too)."""
    from frictid.plant import load_recipe, simulate_recipe

    rec, _ = load_recipe("random_ptp")
    d = rec.model_dump()
    d["experiments"][0].update(seed=seed, moves=moves)
    return simulate_recipe(type(rec).model_validate(d), plant, seed=seed)


def slow_logger(recipe, plant_name: str, k: int, seed: int = 0, drive_rate: float = 1000.0):
    """Logs of ``recipe`` on ``plant_name`` driven at ``drive_rate`` [Hz] and logged every ``k``-th sample
    (a logger recording slower than the drive controls), with their rests labelled at the log's rate.

    The plant labels its rests by docs/segments.md's definition on the samples it logs: a 0.1 s mean of
    the torque and its standard errors at ``drive_rate``. The log kept at ``drive_rate / k`` holds k times
    fewer samples per 0.1 s: a torque change the drive's log shows at 5 standard errors is at about
    5 / sqrt(k) on the kept samples, within the noise. The closed-loop rests are therefore labelled again
    on the kept samples (``frictid.plant.recipe.closed_loop_rests``), from the drive torque: the same
    run without torque-sensor noise (that noise is drawn last and the loop never sees it, so the motion and
    the drive torque are the same)."""
    from frictid.plant import simulate_recipe
    from frictid.plant.config import load_recipe
    from frictid.plant.recipe import (L, closed_loop, closed_loop_rests, compile_recipe, encoder_step,
                                      still_to_sensors)

    plant = plant_variant(plant_name, 1.0, drive_rate)
    logs = simulate_recipe(recipe, plant, seed=seed)
    quiet = plant.model_copy(update={"sensors": plant.sensors.model_copy(update={"tau_noise": 0.0})})
    drive = simulate_recipe(recipe, quiet, seed=seed)
    rec, _ = load_recipe(recipe)
    kinds = np.asarray(SEGMENT_KINDS, dtype=object)
    out = []
    for lg, dr in zip(logs, drive):
        pr = compile_recipe(rec, plant, plant.joint(lg.joint), 1.0)
        d = decimated(lg, k)
        label = np.array([L[x] for x in np.asarray(d.truth["segment"]).astype(str)], dtype=np.int64)
        w = np.asarray(d.truth["velocity"], dtype=float)
        moving = ~still_to_sensors(np.asarray(d.truth["position"], dtype=float), drive_rate / k, d.q,
                                   encoder_step(plant.sensors, plant.axis))
        label = closed_loop_rests(label, moving, dr.tau[::k], closed_loop(pr)[::k], drive_rate / k,
                                  plant.sensors.tau_noise)
        out.append(replace(d, truth=dict(d.truth, segment=kinds[label])))
    return out


def decimated(log, k: int):
    """Every ``k``-th sample of a log (a logger recording slower than the drive controls), truth included."""
    from dataclasses import replace

    def cut(x):
        return x[::k] if isinstance(x, np.ndarray) and x.shape[:1] == (log.n,) else x

    return replace(log, t=log.t[::k], q=cut(log.q), qd=cut(log.qd), tau=cut(log.tau),
                   channels={c: cut(v) for c, v in log.channels.items()},
                   truth={c: cut(v) for c, v in log.truth.items()})
