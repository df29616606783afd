"""Scorecard of the fleet trend on a simulated fleet (docs/fleet.md).

Simulates ROBOTS x JOINTS x DAYS daily logs from the plant (tests/fleet_synth.py: planted wear on about
10 % of the joints, a re-lubrication step on about 5 %, day-to-day ambient swings of +-8 K on about 35 %,
noise only on the rest), fits them on a distributed.LocalCluster (``frictid fit DATASET --engine dask``)
and runs ``frictid trend``. Scores: every planted wear and step found as such with its date within two
runs; false alarms (a temperature-only or noise-only joint called wear or step) as a share of all joints
(target <= 2 %). Seeds from 9000 up: the tests use others.

    python benchmarks/fleet_scorecard.py                       # the full size: 20 x 6 x 30
    python benchmarks/fleet_scorecard.py --robots 2 --joints 2 --days 10   # a quick look
"""
from __future__ import annotations

import argparse
import os
import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from fleet_synth import plan_fleet, write_fleet  # noqa: E402
from frictid.cli import main  # noqa: E402
from frictid.fleet.trend import trend_fleet  # noqa: E402


def run_cli(*args) -> int:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
        except SystemExit as exc:
            if exc.code:
                print(err.getvalue()[-3000:], file=sys.stderr)
            return exc.code if isinstance(exc.code, int) else 1
    return 0


def score(plan, ft, days: int) -> dict:
    got = {j.joint: j for j in ft.joints if j.level is not None and len(j.level.dates) == days}
    plan = [p for p in plan if f"robot={p.robot}/joint={p.joint}" in got]  # joints with every day fitted
    rows, found, planted, alarms = [], 0, 0, 0
    for p in plan:
        jt = got.get(f"robot={p.robot}/joint={p.joint}")
        kind = jt.kind if jt else "missing"
        date_ix = jt.level.dates.index(jt.level.date) if jt and jt.level.date else None
        if p.kind in ("wear", "step"):
            planted += 1
            ok = kind == p.kind and date_ix is not None and abs(date_ix - p.day) <= 2
            found += ok
            rows.append(f"  {p.robot}/{p.joint}: planted {p.kind} {p.size:+.0%} at run {p.day}; found {kind}"
                        f"{f' at run {date_ix}' if date_ix is not None else ''} {'ok' if ok else 'MISSED'}")
        elif kind not in ("steady",):
            alarms += 1
            rows.append(f"  {p.robot}/{p.joint}: planted {p.kind}; FALSE ALARM {kind} at run {date_ix}")
    return {"rows": rows, "found": found, "planted": planted, "alarms": alarms, "joints": len(plan)}


def main_(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=20)
    ap.add_argument("--joints", type=int, default=6)
    ap.add_argument("--days", type=int, default=30)
    ap.add_argument("--seed", type=int, default=9000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--keep", help="folder to keep the fleet and the store in")
    ap.add_argument("--score-only", action="store_true",
                    help="score the store kept in --keep as it is (a run stopped early: the joints with every day fitted)")
    a = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        a.robots, a.joints, a.days = 1, 2, 8
    if a.score_only and not (a.keep and (Path(a.keep) / "store").is_dir()):
        ap.error("--score-only needs --keep FOLDER holding the store of an earlier run")
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
        ft = trend_fleet(str(root / "store"))
        s = score(plan, ft, a.days)
    n = a.robots * a.joints * a.days
    kinds = {k: sum(p.kind == k for p in plan) for k in ("wear", "step", "temperature", "noise")}
    print(f"fleet scorecard: {a.robots} robots x {a.joints} joints x {a.days} days = {n} partitions, seed {a.seed}; "
          f"planted {kinds}")
    print(f"simulate {t1 - t0:.0f} s, fit on {a.workers} workers {t2 - t1:.0f} s (exit code {code}); "
          f"scored: {s['joints']} joints with all {a.days} days fitted")
    print("\n".join(s["rows"]))
    share = s["alarms"] / max(s["joints"], 1)
    print(f"wear and steps found with their date within 2 runs: {s['found']}/{s['planted']}")
    print(f"false alarms: {s['alarms']}/{s['joints']} joints = {share:.1%} (target <= 2 %)")
    return 0 if s["found"] == s["planted"] and share <= 0.02 else 1


if __name__ == "__main__":
    sys.exit(main_())
