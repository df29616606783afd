"""Scorecard of ``frictid.fit`` on identification logs of an independent simulator (issue 19).

    python benchmarks/foreign/fit_scorecard.py                          # 300 draws, seeds 200000..200299
    python benchmarks/foreign/fit_scorecard.py --draws 1 --seed-base 200017    # reproduce one draw

Each draw (``scenarios.make_log`` with the identification families ``scenarios.FIT_FAMILIES``: sweeps, the
issue-19 sweep, sweep + ramps + steps + point-to-point, sweep + the issue-19 creeping ramps, and a
point-to-point excitation without plateaus) is written as a joint log and fitted with the public API
``frictid.fit([path], diagnose=False)``. Against the simulator's truth (its sidecar; frictid never reads
it), per parameter:

- Fc, Fs, sigma2 within 3 %, vs within 15 % (the symmetric ``stribeck`` model, and the selected model
  where it names the same parameters, per sign for an asymmetric one), J within 5 %
  (``res[joint].inertia``), sigma0 within 25 % (the ``lugre`` model);
- on target: identifiable and within the tolerance; not identifiable: frictid says so (honest);
  wrong but identifiable: frictid trusts a value outside the tolerance (the dangerous case); absent: the
  model or parameter was not reported at all;
- coverage: of the identifiable values with a standard error, the share whose truth lies within 2 stderr.

Seeds: scorecards use seeds >= 100000 (this card 200000 on by default); the tests use seeds < 1000.
"""
from __future__ import annotations

import argparse
import json
import os
import math
import statistics
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import scenarios  # noqa: E402

import frictid  # noqa: E402

#: (row name, model or "inertia" or "selected", parameter, tolerance [1]).
TARGETS = (
    ("Fc", "stribeck", "Fc", 0.03), ("Fs", "stribeck", "Fs", 0.03), ("sigma2", "stribeck", "sigma2", 0.03),
    ("vs", "stribeck", "vs", 0.15), ("J", "inertia", "J", 0.05), ("sigma0", "lugre", "sigma0", 0.25),
    ("Fc (selected)", "selected", "Fc", 0.03), ("Fs (selected)", "selected", "Fs", 0.03),
    ("sigma2 (selected)", "selected", "sigma2", 0.03), ("vs (selected)", "selected", "vs", 0.15),
)
OUTCOMES = ("on_target", "not_identifiable", "wrong_identifiable", "absent", "unresolved")


def unresolved(value: float, stderr, truth: float, tol: float) -> bool:
    """The scoring convention of both fit cards (this one and ``benchmarks/fit_scorecard.py``): a value
    outside its tolerance is *honest-unresolved*, not wrong, when its own error says the data do not
    resolve it to the tolerance (2 stderr >= tol |value|) and covers the truth (|value - truth| <= 2
    stderr)."""
    if stderr is None or not math.isfinite(stderr) or stderr <= 0:
        return False
    return 2.0 * stderr >= tol * abs(value) and abs(value - truth) <= 2.0 * stderr


def estimates(jf, model: str, name: str) -> list:
    """The ParamEstimates that stand for ``name``: one, two (an asymmetric model's _pos and _neg), or none
    (the model is missing or names its parameters otherwise)."""
    if model == "inertia":
        return [jf.inertia] if jf.inertia is not None else []
    fit = jf.selected_fit if model == "selected" else jf.models.get(model)
    if fit is None:
        return []
    if name in fit.params:
        return [fit.params[name]]
    pair = [fit.params.get(name + "_pos"), fit.params.get(name + "_neg")]
    return pair if all(p is not None for p in pair) else []


def raw(ests: list) -> list:
    """The estimates as (value, stderr, identifiable) triples (what :func:`judge` reads; kept per draw so
    that ``--rescore`` can judge a saved run again)."""
    return [(e.value, e.stderr, bool(e.identifiable)) for e in ests]


def judge(ests: list, truth: float, tol: float) -> tuple[str, float, list[bool]]:
    """Outcome, worst relative error and, per estimate with a standard error, whether the truth lies
    within 2 of them. ``ests``: (value, stderr, identifiable) triples. Outside the tolerance, the outcome
    is "unresolved" when every estimate outside it is (:func:`unresolved`), else "wrong_identifiable"."""
    if not ests:
        return "absent", math.nan, []
    if not all(ok for _, _, ok in ests):
        return "not_identifiable", math.nan, []
    if any(v is None for v, _, _ in ests):
        return "absent", math.nan, []
    err = max(abs(v - truth) / abs(truth) for v, _, _ in ests)
    cover = [abs(v - truth) <= 2.0 * se for v, se, _ in ests
             if se is not None and math.isfinite(se) and se > 0]
    if err <= tol:
        return "on_target", err, cover
    off = [(v, se) for v, se, _ in ests if abs(v - truth) > tol * abs(truth)]
    return ("unresolved" if all(unresolved(v, se, truth, tol) for v, se in off) else "wrong_identifiable"), \
        err, cover


def run_draw(seed: int, family: str | None, tmp: Path, diagnose: bool) -> dict:
    """Make and fit one draw; per target its outcome, relative error and coverage."""
    t0 = time.perf_counter()
    path, truth = scenarios.make_log(seed, family, tmp, families=scenarios.FIT_FAMILIES)
    t1 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = frictid.fit([str(path)], diagnose=diagnose)
    t2 = time.perf_counter()
    for p in tmp.glob(path.name + "*"):
        p.unlink()
    jf = next(iter(res.joints.values()))
    ests = {row: raw(estimates(jf, model, name)) for row, model, name, _ in TARGETS}
    d = {"seed": seed, "family": truth["family"], "ests": ests, "selected": jf.selected,
            "basis": jf.selection.get("basis"), "sensors": truth["sensors"], "n": truth["n"],
            "sim_s": t1 - t0, "fit_s": t2 - t1, "plant": truth["plant"]}
    return scored(d)


def scored(d: dict) -> dict:
    """The draw with its per-target outcomes (``rows``) judged from its saved estimates."""
    d["rows"] = {row: judge(d["ests"][row], float(d["plant"][name]), tol) for row, _, name, tol in TARGETS}
    return d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--seed-base", type=int, default=200000)
    ap.add_argument("--family", choices=scenarios.FIT_FAMILIES, default=None)
    ap.add_argument("--diagnose", action="store_true", help="run frictid's diagnosis too (slower)")
    ap.add_argument("--minutes", type=float, default=None, help="stop starting draws after this many minutes")
    ap.add_argument("--examples", type=int, default=4, help="draws listed per failure class")
    ap.add_argument("--out", default=None, help="write each draw's estimates and truth here (JSON lines)")
    ap.add_argument("--rescore", default=None, help="judge the draws of a saved --out file again, fit nothing")
    args = ap.parse_args(argv)
    if args.rescore:
        rows = [scored(json.loads(line)) for line in Path(args.rescore).read_text().splitlines() if line.strip()]
        args.seed_base = min((d["seed"] for d in rows), default=args.seed_base)
        report(args, rows, [], 0.0)
        return 0
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.draws, args.minutes = 1, None
    rows, errors, t_start = [], [], time.time()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.draws):
            if args.minutes is not None and time.time() - t_start > 60 * args.minutes:
                print(f"stopped after {i} draws ({args.minutes} min)", file=sys.stderr)
                break
            seed = args.seed_base + i
            try:
                d = run_draw(seed, args.family, Path(tmp), args.diagnose)
            except Exception as exc:  # a crash is a finding
                errors.append((seed, f"{type(exc).__name__}: {exc}".splitlines()[0][:200]))
                traceback.print_exc(limit=3, file=sys.stderr)
                continue
            rows.append(d)
            if args.out:
                with open(args.out, "a") as fh:
                    fh.write(json.dumps({k: v for k, v in d.items() if k != "rows"}, default=float) + "\n")
            if args.draws <= 5:
                print(describe(d))
    report(args, rows, errors, time.time() - t_start)
    return 0


def describe(d: dict) -> str:
    """The draw's outcomes in one block."""
    s, p = d["sensors"], d["plant"]
    head = (f"seed {d['seed']} {d['family']} ({p['axis']}, J {p['J']:.3g}, Fc {p['Fc']:.3g}, Fs/Fc "
            f"{p['Fs'] / p['Fc']:.2f}, vs {p['vs']:.3g}, delta {p['delta']:.2f}; fs {s['fs']:.0f} Hz, "
            f"{s['bits']} bits, qd {s['qd_mode']}): selected {d['selected']}, basis {d['basis']}, "
            f"sim {d['sim_s']:.1f} s, fit {d['fit_s']:.1f} s")
    parts = [f"{r} {o}" + ("" if math.isnan(e) else f" {100 * e:.1f}%") for r, (o, e, _) in d["rows"].items()]
    return head + "\n  " + "; ".join(parts)


def report(args, rows, errors, wall):
    """Print the card: per parameter, per family, coverage, failure classes, errors."""
    n = len(rows)
    last = args.seed_base + n + len(errors) - 1
    print(f"\nforeign fit scorecard: {n} draws (seeds {args.seed_base}..{last}"
          f"{', family ' + args.family if args.family else ''}), diagnose={args.diagnose}, {wall:.0f} s wall")
    print(f"{'parameter':<19} {'tol':>4} {'on target':>9} {'not ident.':>10} {'WRONG+ident.':>12} "
          f"{'absent':>6} {'unresolved':>10} {'coverage (2 se)':>16}")
    strict = []
    for row, _, _, tol in TARGETS:
        cnt = {o: sum(1 for d in rows if d["rows"][row][0] == o) for o in OUTCOMES}
        cov = [c for d in rows for c in d["rows"][row][2]]
        covs = f"{sum(cov)}/{len(cov)} ({100 * sum(cov) / len(cov):.0f}%)" if cov else "-"
        print(f"{row:<19} {100 * tol:>3.0f}% " + " ".join(
            f"{100 * cnt[o] / max(n, 1):>{w}.1f}%" for o, w in zip(OUTCOMES, (8, 9, 11, 5, 9))) + f" {covs:>16}")
        strict.append(f"{row} {100 * (cnt['wrong_identifiable'] + cnt['unresolved']) / max(n, 1):.1f}%")
    print("strict WRONG+ident. (identifiable and outside the tolerance, whatever its error): " + ", ".join(strict))
    print(error_sizes(rows))
    print("\nper family: on target / not identifiable / WRONG but identifiable, % of the family's draws")
    fams = [f for f in scenarios.FIT_FAMILIES if any(d["family"] == f for d in rows)]
    print(f"{'parameter':<19} " + " ".join(f"{f[:19]:>20}" for f in fams))
    for row, _, _, _ in TARGETS:
        cells = []
        for f in fams:
            ds = [d for d in rows if d["family"] == f]
            c = [100 * sum(1 for d in ds if d["rows"][row][0] == o) / len(ds) for o in OUTCOMES[:3]]
            cells.append(f"{c[0]:>5.0f} /{c[1]:>4.0f} /{c[2]:>4.0f}")
        print(f"{row:<19} " + " ".join(f"{c:>20}" for c in cells))
    print("draws per family: " + ", ".join(f"{f} {sum(1 for d in rows if d['family'] == f)}" for f in fams))
    failure_classes(args, rows)
    if errors:
        print(f"\nerrors ({len(errors)} draws):")
        for seed, msg in errors:
            print(f"  seed {seed}: {msg}")


def error_sizes(rows) -> str:
    """Whether the errors are right-sized: per parameter, the median of |value - truth| / stderr over the
    identifiable values with an error (an honest normal error gives 0.67; far below, the errors are too
    large for the typical draw even where the 2-stderr coverage looks right)."""
    out = []
    for row, _, name, _ in TARGETS:
        z = [abs(v - float(d["plant"][name])) / se for d in rows for v, se, ok in d["ests"][row]
             if ok and v is not None and se is not None and math.isfinite(se) and se > 0]
        out.append(f"{row} {statistics.median(z):.2f}" if z else f"{row} -")
    return "error size, median |value - truth| / stderr of the identifiable values (honest: 0.67): " + ", ".join(out)


def failure_classes(args, rows):
    """Wrong-but-identifiable values per (family, parameter), largest errors first, with commands."""
    print("\nwrong but identifiable, per (family, parameter); largest errors first")
    classes = {}
    for d in rows:
        for row, (o, e, _) in d["rows"].items():
            if o == "wrong_identifiable":
                classes.setdefault((d["family"], row), []).append((e, d))
    for (fam, row), items in sorted(classes.items(), key=lambda kv: -len(kv[1])):
        n_fam = sum(1 for d in rows if d["family"] == fam)
        print(f"- {fam} / {row}: {len(items)} of {n_fam} draws")
        for e, d in sorted(items, key=lambda x: -x[0])[:args.examples]:
            s = d["sensors"]
            print(f"    seed {d['seed']}: error {100 * e:.1f}%, selected {d['selected']}, fs {s['fs']:.0f} Hz, "
                  f"{s['bits']} bits, qd {s['qd_mode']}; "
                  f"python benchmarks/foreign/fit_scorecard.py --draws 1 --seed-base {d['seed']}")


if __name__ == "__main__":
    sys.exit(main())
