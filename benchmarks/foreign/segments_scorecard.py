"""Scorecard of ``frictid.segments.find_segments`` on logs of an independent simulator (issue 19).

    python benchmarks/foreign/segments_scorecard.py                     # 300 draws, seeds 100000..100299
    python benchmarks/foreign/segments_scorecard.py --draws 1 --seed-base 100042   # reproduce one draw
    python benchmarks/foreign/segments_scorecard.py --draws 150 --out a.jsonl   # save each draw as it ends
    python benchmarks/foreign/segments_scorecard.py --draws 150 --seed-base 100150 --out b.jsonl
    python benchmarks/foreign/segments_scorecard.py --rescore a.jsonl b.jsonl   # one card of both

``--out`` appends one JSON line per finished draw (a draw already in the file is not run again, so an
interrupted run resumes where it stopped); ``--rescore`` prints the card of saved draws without running
anything, so disjoint seed ranges run in separate processes make one card.

Each draw (``scenarios.make_log``: plant, controller, sensors and layout from one seed) is written as a
joint log, read back with ``frictid.io.logs.read_logs`` and segmented. A found segment is a true positive
when a truth segment of the same kind (from the simulator's sidecar, which frictid never reads) overlaps
it with intersection-over-union >= 0.8. Prints per kind precision / recall / F1, overall and per layout
family, the ramp / step / duty-cycle segments reported on pure random point-to-point draws (must be 0),
and the draws behind each failure class with the command that reproduces them.

Seeds: scorecards use seeds >= 100000; the tests use seeds < 1000, so nothing here was seen by a test.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[1] / "tests"))

import scenarios  # noqa: E402
import sim  # noqa: E402
from segscore import _iou_best as best_iou  # noqa: E402 (the plant scorecard's matching rule)

from frictid.io.logs import read_logs  # noqa: E402
from frictid.segments import find_segments  # noqa: E402

IOU = 0.8
KINDS = sim.KINDS
#: Kinds an experiment-free log must never show.
EXPERIMENT_KINDS = ("ramp_presliding", "step", "duty_cycle")


class Tally:
    """Per kind: truth segments, found segments, matched truth and matched found (IoU >= 0.8)."""

    def __init__(self):
        self.c = {k: np.zeros(4, dtype=np.int64) for k in KINDS}

    def add(self, truth, found) -> dict:
        """Add one log; ``truth`` and ``found`` are lists of (kind, i0, i1). Returns this log's counts."""
        one = {}
        for k in KINDS:
            tr = [(a, b) for kk, a, b in truth if kk == k]
            fo = [(a, b) for kk, a, b in found if kk == k]
            row = np.array([len(tr), len(fo), int(np.sum(best_iou(tr, fo) >= IOU)),
                            int(np.sum(best_iou(fo, tr) >= IOU))])
            self.c[k] += row
            one[k] = row
        return one

    def prf(self, k):
        """Precision, recall, F1 of kind k (nan where undefined)."""
        n_t, n_f, tp_t, tp_f = self.c[k]
        p = tp_f / n_f if n_f else float("nan")
        r = tp_t / n_t if n_t else float("nan")
        f1 = 2 * p * r / (p + r) if n_f and n_t and (p + r) > 0 else (0.0 if n_f or n_t else float("nan"))
        return p, r, f1

    def table(self, indent="") -> str:
        lines = [f"{indent}{'kind':<18} {'truth':>6} {'found':>6} {'precision':>9} {'recall':>7} {'F1':>6}"]
        for k in KINDS:
            p, r, f1 = self.prf(k)
            lines.append(f"{indent}{k:<18} {self.c[k][0]:>6d} {self.c[k][1]:>6d} {p:>9.3f} {r:>7.3f} {f1:>6.3f}")
        return "\n".join(lines)


def run_draw(seed: int, family: str | None, tmp: Path) -> dict:
    """Make, read and segment one draw. Returns family, per-kind counts, found experiment kinds, timing."""
    t0 = time.perf_counter()
    path, truth = scenarios.make_log(seed, family, tmp)
    t1 = time.perf_counter()
    log = read_logs(str(path))[0]
    segs = find_segments(log)
    t2 = time.perf_counter()
    tr = [(k, a, b) for k, a, b, _ in truth["segments"]]
    found = [(s.kind, s.i0, s.i1) for s in segs]
    for p in tmp.glob(path.name + "*"):
        p.unlink()
    return {"seed": seed, "family": truth["family"], "truth": tr, "found": found, "n": truth["n"],
            "sim_s": t1 - t0, "seg_s": t2 - t1, "sensors": truth["sensors"], "controller": truth["controller"]}


def describe(d: dict, row: dict) -> str:
    """One line about a draw: seed, family, sensors and per-kind misses."""
    s = d["sensors"]
    bad = []
    for k in KINDS:
        n_t, n_f, tp_t, tp_f = row[k]
        if n_t - tp_t or n_f - tp_f:
            bad.append(f"{k}: {tp_t}/{n_t} found, {n_f - tp_f} spurious of {n_f}")
    return (f"seed {d['seed']} {d['family']} fs {s['fs']:.0f} Hz, {s['bits']} bits, qd {s['qd_mode']}, "
            f"{d['controller']['kind']}: " + ("; ".join(bad) or "all matched"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--seed-base", type=int, default=100000)
    ap.add_argument("--family", choices=scenarios.FAMILIES, default=None, help="only this layout family")
    ap.add_argument("--examples", type=int, default=4, help="draws listed per failure class")
    ap.add_argument("--minutes", type=float, default=None, help="stop starting draws after this many minutes")
    ap.add_argument("--out", default=None, help="append each finished draw to this JSON-lines file "
                    "(draws already in it are not run again)")
    ap.add_argument("--rescore", nargs="+", default=None, metavar="FILE",
                    help="print the card of the draws saved in these files (no draw is run)")
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.draws, args.minutes = 1, None
    if args.rescore:
        return rescore(args)
    if args.seed_base < 100000 and args.draws > 1:
        print("note: seeds below 100000 may be seeds the tests use", file=sys.stderr)
    done = {d["seed"]: d for d in load(args.out)} if args.out and Path(args.out).exists() else {}
    draws, t_start = [], time.time()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.draws):
            if args.minutes is not None and time.time() - t_start > 60 * args.minutes:
                print(f"stopped after {i} draws ({args.minutes} min)", file=sys.stderr)
                break
            seed = args.seed_base + i
            if seed in done:
                draws.append(done[seed])
                continue
            try:
                d = run_draw(seed, args.family, Path(tmp))
            except Exception as exc:  # a crash is a finding, not the end of the card
                d = {"seed": seed, "error": f"{type(exc).__name__}: {exc}".splitlines()[0][:200]}
                traceback.print_exc(limit=2, file=sys.stderr)
            draws.append(d)
            if args.out:
                with open(args.out, "a") as f:
                    f.write(json.dumps(d) + "\n")
    total, fams, rows, errors, ptp_fp = score(draws, verbose=args.draws <= 5)
    report(args, total, fams, rows, errors, ptp_fp, time.time() - t_start)
    return 0


def load(path) -> list[dict]:
    """The draws saved by ``--out`` (JSON lines; a line cut by an interrupted write is skipped)."""
    out = []
    for line in Path(path).read_text().splitlines():
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            continue
        d["truth"] = [tuple(x) for x in d.get("truth", [])]
        d["found"] = [tuple(x) for x in d.get("found", [])]
        out.append(d)
    return out


def score(draws, verbose=False):
    """Tally draws: overall and per family, the rows, the errors and the ptp false positives."""
    total, fams, rows, errors, ptp_fp = Tally(), {}, [], [], 0
    for d in draws:
        if "error" in d:
            errors.append((d["seed"], d["error"]))
            continue
        row = total.add(d["truth"], d["found"])
        fams.setdefault(d["family"], Tally()).add(d["truth"], d["found"])
        if d["family"] == "ptp":
            ptp_fp += sum(1 for k, _, _ in d["found"] if k in EXPERIMENT_KINDS)
        rows.append((d, row))
        if verbose:
            print(describe(d, row))
            print(f"  sim {d['sim_s']:.1f} s, segments {d['seg_s']:.1f} s, {d['n']} samples")
    return total, fams, rows, errors, ptp_fp


def rescore(args) -> int:
    """The card of saved draws: each seed once (the last saved), in seed order; wall = summed draw time."""
    by_seed = {}
    for path in args.rescore:
        if not Path(path).exists():
            print(f"error: {path}: no such file", file=sys.stderr)
            return 2
        for d in load(path):
            by_seed[d["seed"]] = d
    draws = [by_seed[s] for s in sorted(by_seed)]
    if args.family:
        draws = [d for d in draws if d.get("family") == args.family]
    if not draws:
        print("error: no saved draws", file=sys.stderr)
        return 2
    args.seed_base = draws[0]["seed"]
    total, fams, rows, errors, ptp_fp = score(draws)
    wall = sum(d.get("sim_s", 0) + d.get("seg_s", 0) for d in draws)
    report(args, total, fams, rows, errors, ptp_fp, wall, seeds=[d["seed"] for d in draws])
    return 0


def report(args, total, fams, rows, errors, ptp_fp, wall, seeds=None):
    """Print the card: overall, per family, ptp false positives, failure classes, errors."""
    n = len(rows) + len(errors)
    span = (f"seeds {args.seed_base}..{args.seed_base + n - 1}" if seeds is None else
            f"seeds {min(seeds)}..{max(seeds)}, {len(seeds)} saved")
    clock = "s wall" if seeds is None else "s of draw time summed"
    print(f"\nforeign segments scorecard: {len(rows)} draws ({span}"
          f"{', family ' + args.family if args.family else ''}), IoU >= {IOU}, {wall:.0f} {clock}")
    print(total.table())
    print("(other is the complement, not a target: moves, transitions and the fragments between segments;"
          " docs/segments.md)")
    n_ptp = sum(1 for d, _ in rows if d["family"] == "ptp")
    print(f"\nramp/step/duty-cycle segments reported on {n_ptp} pure point-to-point draws: {ptp_fp} (must be 0)")
    print("\nper layout family (F1 per kind; truth/found counts in brackets)")
    print(f"{'family':<16} {'draws':>5}  " + "  ".join(f"{k[:12]:>18}" for k in KINDS))
    for fam in scenarios.FAMILIES:
        if fam not in fams:
            continue
        t = fams[fam]
        nd = sum(1 for d, _ in rows if d["family"] == fam)
        cells = []
        for k in KINDS:
            f1 = t.prf(k)[2]
            cells.append(f"{'-' if np.isnan(f1) else f'{f1:.2f}':>5} ({t.c[k][0]:>4}/{t.c[k][1]:>4})")
        print(f"{fam:<16} {nd:>5}  " + "  ".join(f"{c:>18}" for c in cells))
    failure_classes(args, rows)
    if errors:
        print(f"\nerrors ({len(errors)} draws):")
        for seed, msg in errors:
            print(f"  seed {seed}: {msg}")


def failure_classes(args, rows):
    """Per (family, kind): draws with a missed or spurious segment, the worst listed with a command."""
    print("\nfailure classes: (family, kind) -> draws with a miss or a spurious segment; worst first")
    classes = {}
    for d, row in rows:
        for k in KINDS:
            n_t, n_f, tp_t, tp_f = row[k]
            miss = (n_t - tp_t) + (n_f - tp_f)
            if miss:
                classes.setdefault((d["family"], k), []).append((miss / max(n_t + n_f, 1), d, row))
    for (fam, k), items in sorted(classes.items(), key=lambda kv: -len(kv[1])):
        n_fam = sum(1 for d, _ in rows if d["family"] == fam)
        print(f"- {fam} / {k}: {len(items)} of {n_fam} draws")
        for _, d, row in sorted(items, key=lambda x: -x[0])[:args.examples]:
            print(f"    {describe(d, {k: row[k] for k in KINDS})}")
            print(f"    python benchmarks/foreign/segments_scorecard.py --draws 1 --seed-base {d['seed']}")


if __name__ == "__main__":
    sys.exit(main())
