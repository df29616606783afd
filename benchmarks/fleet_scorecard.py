"""Scorecard of the fleet trend on a simulated fleet (docs/fleet.md).

Simulates ROBOTS x JOINTS x DAYS daily logs from the plant (tests/fleet_synth.py; per joint, drawn:
wear 8 %, a re-lubrication step 5 %, wear then a repair 4 %, two steps 4 %, a fault then its repair 4 %,
day-to-day ambient swings of +-8 K 30 %, noise only 45 %), fits them on a distributed.LocalCluster
(``frictid fit DATASET --engine dask``) and runs the trend. Scores: every planted change found with its
kind and its date within two runs (and the dating error), extra changes on changed joints, false alarms
(a temperature-only or noise-only joint with any change) as a share of all joints (target <= 2 %).
Seeds from 100000 up (the tests use seeds below 1000). With FRICTID_SMOKE=1: 1 joint x 6 days.

    python benchmarks/fleet_scorecard.py                       # 6 robots x 6 joints x 30 days
    python benchmarks/fleet_scorecard.py --robots 1 --joints 2 --days 10   # a quick look
"""
from __future__ import annotations

import argparse
import os
import contextlib
import io
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fleet_synth import KINDS, plan_fleet, write_fleet  # noqa: E402
from frictid.cli import main  # noqa: E402
from frictid.fleet.trend import trend_fleet  # noqa: E402


def run_cli(*args) -> int:
    """``frictid ARGS`` in this process; its stderr is shown only when it fails."""
    err, code = io.StringIO(), 0
    with contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    if code:
        print(err.getvalue()[-3000:], file=sys.stderr)
    return code


def found_changes(jt) -> list[tuple[str, int]]:
    """(kind, run index) of every change the trend found in a joint's level."""
    return [(c["kind"], c["index"]) for c in jt.level.changes] if jt.level is not None else []


def match(planted, found) -> list[tuple[int, int | None]]:
    """Each planted change (kind, day, size) paired with a found one of its kind within 2 runs (each found
    change used once, nearest first): (planted index, found index or None)."""
    free, out = list(found), []
    for kind, day, _ in planted:
        near = [f for f in free if f[0] == kind and abs(f[1] - day) <= 2]
        best = min(near, key=lambda f: abs(f[1] - day)) if near else None
        if best is not None:
            free.remove(best)
        out.append((day, best[1] if best else None))
    return out


def score(plan, ft, days: int) -> dict:
    got = {j.joint: j for j in ft.joints if j.level is not None and len(j.level.dates) == days}
    plan = [p for p in plan if f"robot={p.robot}/joint={p.joint}" in got]  # joints with every day fitted
    s = {"rows": [], "changes": 0, "found": 0, "joints_changed": 0, "joints_found": 0, "errors": [],
         "extra": 0, "alarms": {"temperature": 0, "noise": 0}, "quiet": {"temperature": 0, "noise": 0},
         "joints": len(plan)}
    for p in plan:
        jt = got[f"robot={p.robot}/joint={p.joint}"]
        found = found_changes(jt)
        text = ", ".join(f"{k} at run {i}" for k, i in found) or "steady"
        if not p.changes:
            s["quiet"][p.kind] += 1
            if found:
                s["alarms"][p.kind] += 1
                s["rows"].append(f"  {p.robot}/{p.joint}: planted {p.kind}; FALSE ALARM {text}")
            continue
        pairs = match(p.changes, found)
        hits = [f for _, f in pairs if f is not None]
        s["changes"] += len(pairs)
        s["found"] += len(hits)
        s["errors"] += [abs(f - d) for d, f in pairs if f is not None]
        s["extra"] += len(found) - len(hits)
        s["joints_changed"] += 1
        s["joints_found"] += len(hits) == len(pairs)
        planted = ", ".join(f"{k} {x:+.0%} at run {d}" for k, d, x in p.changes)
        verdict = "ok" if len(hits) == len(pairs) and len(found) == len(hits) else \
            "MISSED" if len(hits) < len(pairs) else "EXTRA CHANGE"
        s["rows"].append(f"  {p.robot}/{p.joint} ({p.kind}): planted {planted}; found {text}: {verdict}")
    return s


def report(a, plan, s: dict, t_sim: float, t_fit: float, code: int) -> bool:
    """Print the scores; True when every change was found and false alarms are <= 2 % of the joints."""
    n = a.robots * a.joints * a.days
    kinds = {k: sum(p.kind == k for p in plan) for k in KINDS}
    print(f"fleet scorecard: {a.robots} robots x {a.joints} joints x {a.days} days = {n} partitions, seed {a.seed}; "
          f"planted {kinds}")
    print(f"simulate {t_sim:.0f} s, fit on {a.workers} workers {t_fit:.0f} s (exit code {code}); "
          f"scored: {s['joints']} joints with all {a.days} days fitted")
    print("\n".join(s["rows"]))
    err = s["errors"]
    alarms = sum(s["alarms"].values())
    share = alarms / max(s["joints"], 1)
    print(f"changes found with their kind and date within 2 runs: {s['found']}/{s['changes']} "
          f"(joints with every change found: {s['joints_found']}/{s['joints_changed']}); extra changes on "
          f"changed joints: {s['extra']}")
    print("dating error [runs]: " + (f"mean {sum(err) / len(err):.2f}, max {max(err)}, exact {err.count(0)}/{len(err)}"
                                     if err else "none matched"))
    print("false alarms: " + ", ".join(f"{s['alarms'][k]}/{s['quiet'][k]} {k}-only" for k in ("temperature", "noise"))
          + f"; {alarms}/{s['joints']} joints = {share:.1%} (target <= 2 %)")
    return s["found"] == s["changes"] and share <= 0.02


def arguments(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=6)
    ap.add_argument("--joints", type=int, default=6)
    ap.add_argument("--days", type=int, default=30)
    ap.add_argument("--seed", type=int, default=100000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--keep", help="folder to keep the fleet and the store in")
    ap.add_argument("--score-only", action="store_true",
                    help="score the store kept in --keep as it is (a run stopped early: the joints with every day fitted)")
    a = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        a.robots, a.joints, a.days = 1, 2, 8
    if a.score_only and not (a.keep and (Path(a.keep) / "store").is_dir()):
        ap.error("--score-only needs --keep FOLDER holding the store of an earlier run")
    if a.seed < 100000:
        ap.error("--seed: scorecard seeds are 100000 and up (the tests use seeds below 1000)")
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same path on a tiny fleet
        a.robots, a.joints, a.days = 1, 1, 6
    return a


def main_(argv=None) -> int:
    a = arguments(argv)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(a.keep or tmp)
        plan = plan_fleet(a.robots, a.joints, a.days, seed=a.seed)
        t0 = time.perf_counter()
        if not a.score_only:
            write_fleet(root / "fleet", plan, a.days, seed=a.seed)
        t1 = time.perf_counter()
        code = 0 if a.score_only else run_cli("fit", root / "fleet", "--engine", "dask", "--jobs", a.workers,
                                              "--models", "stribeck", "--no-diagnose", "-o", root / "store", "--quiet")
        t2 = time.perf_counter()
        s = score(plan, trend_fleet(str(root / "store")), a.days)
    return 0 if report(a, plan, s, t1 - t0, t2 - t1, code) else 1


if __name__ == "__main__":
    sys.exit(main_())
