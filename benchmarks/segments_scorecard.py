"""Scorecard of ``frictid segments`` against the plant's truth labels.

    python benchmarks/segments_scorecard.py            # the full card (a few minutes on one core)
    python benchmarks/segments_scorecard.py --quick    # a smaller set (what the tests assert)
    python benchmarks/segments_scorecard.py --timing-only  # section 5 alone (on a quiet machine)

Prints, per segment kind, precision / recall / F1 where a detected segment is a true positive when a truth
segment of the same kind overlaps it with intersection-over-union >= 0.8:

1. every shipped recipe with an experiment x every shipped plant x three sensor-noise levels (0.3x, 1x,
   3x the plant's tau/q/qd noise), against the plant's truth labels as written (the plant labels in the
   segment conventions of docs/segments.md: one ramp per monotonic piece, a step until the next input);
2. sessions that concatenate every experiment with rests and repositioning moves (every plant x noise);
3. logs without any experiment (the ``random_ptp`` recipe: random point-to-point moves and dwells): the
   number of ramp_presliding and step segments found, which must be zero, and the rest F1;
4. sample rate and velocity channel: 100 Hz and 10 kHz, qd logged or not (a subset of recipes);
5. timing of ``find_segments`` on logs of 1 million and 10 million samples.

The plant's truth labels are read here and in the tests only, never by ``frictid.segments``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from segscore import (PLANTS, Tally, plant_variant, random_ptp_logs, session_recipe, slow_logger,  # noqa: E402
                      truth_segments)

from frictid.data import SEGMENT_KINDS  # noqa: E402
from frictid.plant import simulate_recipe  # noqa: E402
from frictid.segments import find_segments  # noqa: E402

RECIPES = ("constant_velocity_sweep", "ramp_presliding", "torque_steps", "multisine", "duty_cycle",
           "validation_ptp")
#: Kinds whose F1 is held to the target (``other`` is the complement: the plant labels fragments of a
#: few samples between segments, e.g. the last samples of a deceleration, as ``other``).
GATED = ("constant_velocity", "ramp_presliding", "step", "duty_cycle", "rest")
TARGET = 0.95


def tally_logs(logs, tally: Tally) -> float:
    """Segment each log, score it against the plant's truth labels; returns the seconds spent segmenting."""
    seconds = 0.0
    for lg in logs:
        t0 = time.perf_counter()
        segs = find_segments(lg)
        seconds += time.perf_counter() - t0
        tally.add(truth_segments(lg), segs)
    return seconds


def verdict(t: Tally, kinds=GATED) -> str:
    bad = []
    for k in kinds:
        p, r, f1 = t.prf(k)
        if t.n_true[k] and not f1 >= TARGET:
            bad.append(f"{k} F1 {f1:.3f}")
    return "PASS (F1 >= 0.95 for " + ", ".join(kinds) + ")" if not bad else "BELOW TARGET: " + "; ".join(bad)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the smaller set the tests assert")
    ap.add_argument("--duty-scale", type=float, default=0.25,
                    help="duration scale of the duty-cycle recipes (1 = 002's 4-minute cycles)")
    ap.add_argument("--noise", default="0.3,1,3", help="sensor-noise multipliers")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-timing", action="store_true")
    ap.add_argument("--timing-only", action="store_true", help="only the timing (section 5)")
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.quick, args.noise, args.duty_scale = True, "1", 0.02
    if args.timing_only:
        timing(args.seed, args.quick, print)
        return 0
    noises = [float(x) for x in args.noise.split(",")]
    plants = PLANTS
    recipes = RECIPES
    duty_scale = args.duty_scale
    if args.quick:
        noises = [1.0]
        duty_scale = min(duty_scale, 0.25)
    out = []

    def say(s=""):
        print(s, flush=True)
        out.append(s)

    say(f"frictid segments scorecard ({'quick' if args.quick else 'full'}; IoU >= 0.8; target F1 >= {TARGET})")
    say(f"noise levels x{', x'.join(f'{x:g}' for x in noises)}; duty-cycle recipes at duration scale "
        f"{duty_scale:g}; seed {args.seed}")
    say()

    # 1. recipes x plants x noise
    main_t = Tally()
    per_recipe = {r: Tally() for r in recipes}
    n_samples, seconds = 0, 0.0
    for rec in recipes:
        scale = duty_scale if rec in ("duty_cycle", "validation_ptp") else 1.0
        for pl in plants:
            for nz in noises:
                logs = simulate_recipe(rec, plant_variant(pl, nz), seed=args.seed, duration_scale=scale)
                t = Tally()
                seconds += tally_logs(logs, t)
                n_samples += sum(lg.n for lg in logs)
                main_t.merge(t)
                per_recipe[rec].merge(t)
    say(f"1. every recipe ({len(recipes)}) x every plant ({len(plants)}) x {len(noises)} noise level(s): "
        f"{n_samples / 1e6:.1f} M samples, segmented in {seconds:.1f} s")
    say(_indent(main_t.table()))
    say("   " + verdict(main_t))
    say("   per recipe (F1 of the kinds present in its truth):")
    for rec, t in per_recipe.items():
        f1s = ", ".join(f"{k} {t.prf(k)[2]:.3f}" for k in SEGMENT_KINDS if t.n_true[k] and k != "other")
        say(f"     {rec:<24} {f1s}")
    say()

    # 2. concatenated sessions
    sess_t = Tally()
    recipe = session_recipe(40.0 if not args.quick else 40.0)
    for pl in plants:
        for nz in noises:
            logs = simulate_recipe(recipe, plant_variant(pl, nz), seed=args.seed)
            tally_logs(logs, sess_t)
    say(f"2. sessions: every experiment in one log with rests and repositioning moves "
        f"({len(plants)} plants x {len(noises)} noise level(s)):")
    say(_indent(sess_t.table()))
    say("   " + verdict(sess_t))
    say()

    # 3. no experiment
    seeds = [args.seed] if args.quick else [args.seed, args.seed + 1, args.seed + 2]
    ptp_t = Tally()
    n_logs = 0
    for pl in plants:
        for nz in noises:
            for sd in seeds:
                logs = random_ptp_logs(plant_variant(pl, nz), seed=sd)
                n_logs += len(logs)
                tally_logs(logs, ptp_t)
    found = ptp_t.n_det
    say(f"3. no experiment: recipe random_ptp, {n_logs} joint logs "
        f"({len(plants)} plants x {len(noises)} noise x {len(seeds)} seeds, 40 moves each):")
    say(f"   ramp_presliding found: {found['ramp_presliding']}, step found: {found['step']}, "
        f"duty_cycle found: {found['duty_cycle']}  -> "
        + ("PASS" if found["ramp_presliding"] == 0 and found["step"] == 0 else "FAIL"))
    say(f"   (constant_velocity found on cruise phases of the moves: {found['constant_velocity']}; the "
        "plant labels moves 'other')")
    p, r, f1 = ptp_t.prf("rest")
    say(f"   rest: truth {ptp_t.n_true['rest']}, found {found['rest']}, precision {p:.3f}, recall {r:.3f}, "
        f"F1 {f1:.3f}")
    say()

    # 4. sample rate and velocity channel
    rate_t = {}
    rate_recipes = ("constant_velocity_sweep", "ramp_presliding", "torque_steps")
    rate_plants = ("direct_drive", "hydraulic") if not args.quick else ("direct_drive",)
    for fs in (100.0, 10000.0):
        for qd in (True, False):
            t = Tally()
            for rec in rate_recipes:
                for pl in rate_plants:
                    logs = rate_logs(rec, pl, fs, args.seed)
                    if not qd:
                        logs = [replace(lg, qd=None) for lg in logs]
                    tally_logs(logs, t)
            rate_t[(fs, qd)] = t
    say(f"4. sample rate and velocity channel ({', '.join(rate_recipes)} on {', '.join(rate_plants)}):")
    say(f"   {'':<22} " + " ".join(f"{k[:12]:>12}" for k in ("constant_velocity", "ramp_presliding", "step", "rest")))
    for (fs, qd), t in rate_t.items():
        cells = " ".join(f"{t.prf(k)[2]:>12.3f}" for k in ("constant_velocity", "ramp_presliding", "step", "rest"))
        say(f"   {fs:>7g} Hz, qd {'logged' if qd else 'absent':<7}  {cells}")
    say()

    # 5. timing
    if not args.no_timing:
        timing(args.seed, args.quick, say)
    return 0


def timing(seed: int, quick: bool, say) -> None:
    """Time ``find_segments`` on a session log tiled to 1 M and 10 M samples (best of 3, resp. 2 runs)."""
    say("5. timing of find_segments (one joint; a session log tiled to length; best of 3 / 2 runs):")
    base = simulate_recipe(session_recipe(), plant_variant("direct_drive", 1.0), seed=seed)[0]
    find_segments(tiled(base, 100_000))  # compiled kernels loaded
    for n, reps in (((1_000_000, 3),) if quick else ((1_000_000, 3), (10_000_000, 2))):
        lg = tiled(base, n)
        best = np.inf
        for _ in range(reps):
            t0 = time.perf_counter()
            segs = find_segments(lg)
            best = min(best, time.perf_counter() - t0)
        say(f"   {n / 1e6:>4g} M samples: {best:6.2f} s ({best / n * 1e6:.2f} us/sample), {len(segs)} segments")
    # the duty-cycle search alone (python loops over motion onsets before they were compiled)
    from frictid.segments.detect import features, find_duty_cycles

    logs = [lg for rec in ("duty_cycle", "validation_ptp")
            for lg in simulate_recipe(rec, plant_variant("geared_industrial", 1.0), seed=seed, duration_scale=0.25)]
    feats = [features(lg) for lg in logs]
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for f in feats:
            find_duty_cycles(f)
        best = min(best, time.perf_counter() - t0)
    say(f"   duty-cycle search alone on duty_cycle + validation_ptp (geared_industrial, scale 0.25, "
        f"{sum(lg.n for lg in logs) / 1e6:.1f} M samples): {best:.3f} s")


def rate_logs(recipe: str, plant: str, fs: float, seed: int):
    """Logs at sample rate ``fs``: a 10 kHz drive simulated at 10 kHz; a 100 Hz logger as every tenth
    sample of the drive running at 1 kHz (the plant's controller runs at the log's rate, and a 100 Hz
    position loop would not hold a plateau), its rests labelled on the kept samples (``slow_logger``)."""
    if fs >= 1000.0:
        return simulate_recipe(recipe, plant_variant(plant, 1.0, sample_rate=fs), seed=seed)
    return slow_logger(recipe, plant, int(round(1000.0 / fs)), seed=seed)


def tiled(log, n: int):
    """``log`` repeated (time and position continued) to ``n`` samples."""
    reps = int(np.ceil(n / log.n))
    dt = log.dt
    span = log.t[-1] - log.t[0] + dt
    t = (log.t[None, :] + span * np.arange(reps)[:, None]).ravel()[:n]
    qoff = (log.q[-1] - log.q[0]) if log.q is not None else 0.0
    q = (log.q[None, :] + qoff * np.arange(reps)[:, None]).ravel()[:n] if log.q is not None else None
    qd = np.tile(log.qd, reps)[:n] if log.qd is not None else None
    return replace(log, t=t, q=q, qd=qd, tau=np.tile(log.tau, reps)[:n], channels={}, truth={})


def _indent(s: str) -> str:
    return "\n".join("   " + line for line in s.splitlines())


if __name__ == "__main__":
    sys.exit(main())
