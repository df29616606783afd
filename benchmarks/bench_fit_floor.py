"""The fit against its floor: what any identification of these logs has to do at least.

The floor of one joint log is: read it (``frictid.io.logs.read_logs``), differentiate it
(``frictid.segments.derivatives``, the Savitzky-Golay velocity and acceleration) and solve one linear
least-squares problem over every sample (Coulomb, viscous, inertia, gravity and offset columns,
``np.linalg.lstsq``). The fit (``frictid.fit``, one joint at a time, ``jobs=1``) is timed without and
with the diagnosis; runs alternate with the floor's, and the ratios are of medians in the same run.

    python benchmarks/bench_fit_floor.py                  # 2 joints x 15 min at 1 kHz, 3 rounds
    python benchmarks/bench_fit_floor.py --minutes 5 --joints 1 --rounds 2
    python benchmarks/bench_fit_floor.py --stages         # and the CPU time of each step of one fit
    python benchmarks/bench_fit_floor.py --optimiser      # and the CPU time inside least_squares, by purpose
    python benchmarks/bench_fit_floor.py --against main   # the fit's CPU time, this tree against a revision

``--stages`` times one more fit with the diagnosis with every step of :data:`STAGES` wrapped (CPU time,
steps nest: "diagnosis" holds "samples", "chain" and the rest); :func:`stage_times` is shared with
``bench_diagnose_whole.py``.

``--against REV`` times the fit without the diagnosis of this tree and of git revision ``REV`` (exported by
``git archive``), each in a fresh process (a warm fit, then ``--repeat`` timed ones, CPU time), the two
alternating in every round (the order reversed every other round): the ratio of medians of a speed change
measured under one load.
"""
from __future__ import annotations

import argparse
import collections
import functools
import importlib
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import frictid  # noqa: E402
from bench_fit import build_log  # noqa: E402
from frictid.io.logs import read_logs  # noqa: E402
from frictid.segments import derivatives  # noqa: E402

#: The issue's target: the fit within this multiple of the floor.
TARGET = 3.0

#: (label, module, attribute) of the steps ``--stages`` times; "Class.method" for methods.
STAGES = [("read", "frictid.api", "read_logs"), ("derivatives", "frictid.segments", "derivatives"),
          ("scales", "frictid.segments", "estimate_scales"), ("segments", "frictid.segments", "find_segments"),
          ("regression (rigid body)", "frictid.identify.mechanics", "regress"),
          ("bandwidth check", "frictid.identify.mechanics", "_bandwidth_check"),
          ("stage-2 map", "frictid.identify.mechanics", "_stage2_map"),
          ("static maps", "frictid.identify.maps", "static_maps"), ("choice", "frictid.identify.maps", "choose_base"),
          ("LuGre", "frictid.identify.dynamics", "fit_lugre"),
          ("thermal", "frictid.identify.thermal_fit", "fit_thermal_models"),
          ("diagnosis", "frictid.api", "diagnose_fit"),
          ("diagnosis: samples", "frictid.diagnose.joint", "build_samples"),
          ("diagnosis: candidates", "frictid.diagnose.chain", "candidates"),
          ("diagnosis: chain", "frictid.diagnose.chain", "Chain.run"),
          ("diagnosis: proposals", "frictid.diagnose.chain", "propose"),
          ("diagnosis check", "frictid.api", "check_diagnosis"), ("finish", "frictid.api", "finish")]


def resolve(mod_name: str, attr: str):
    """The object that holds ``attr`` (a dotted name within the module ``mod_name``), the last name of it and
    the function it names: what a timing wrapper replaces for one call."""
    owner = importlib.import_module(mod_name)
    *path, name = attr.split(".")
    for part in path:
        owner = getattr(owner, part)
    return owner, name, getattr(owner, name)


def stage_times(run) -> tuple[float, dict]:
    """CPU time of ``run()`` and of each step of :data:`STAGES` within it [s] (wrapped for the call only)."""
    spent: dict = collections.defaultdict(float)
    undo = []
    for label, mod_name, attr in STAGES:
        owner, name, fn = resolve(mod_name, attr)

        @functools.wraps(fn)
        def timed(*a, _fn=fn, _label=label, **kw):
            t0 = time.process_time()
            try:
                return _fn(*a, **kw)
            finally:
                spent[_label] += time.process_time() - t0
        setattr(owner, name, timed)
        undo.append((owner, name, fn))
    try:
        t0 = time.process_time()
        run()
        total = time.process_time() - t0
    finally:
        for owner, name, fn in reversed(undo):
            setattr(owner, name, fn)
    return total, dict(spent)


#: Modules of the fit that call ``scipy.optimize.least_squares`` (imported by name: wrapped there).
LSQ_MODULES = ("frictid.identify.thermal", "frictid.identify.presliding")
#: What a least-squares run is for: the innermost of these functions on the call stack names it.
LSQ_PURPOSES = (("_shift_profile", "static maps: rigid-body error refits"),
                ("_delta_profile", "static maps: Stribeck exponent profile"),
                ("heldout_static", "static maps: held-out folds"),
                ("_stage2_map", "stage-2 map (per-sign, on stage 1's plateaus)"),
                ("static_maps", "static maps: full-data fits"),
                ("_presliding_rms", "LuGre: sigma0 held-out ramps"), ("_sigma1", "LuGre: sigma1 steps"),
                ("fit_lugre", "LuGre: sigma0"), ("fit_thermal_models", "thermal models"))


def _purpose(frame) -> str:
    names = []
    while frame is not None:
        names.append(frame.f_code.co_name)
        frame = frame.f_back
    return next((label for fn, label in LSQ_PURPOSES if fn in names), "other")


def optimiser_times(run) -> tuple[float, dict]:
    """CPU time of ``run()`` and, per purpose of a ``least_squares`` run (:data:`LSQ_PURPOSES`), the runs,
    residual and Jacobian evaluations, the CPU time inside ``least_squares`` and, of it, inside the
    residual and Jacobian callbacks (the rest is the optimiser's own loop: trust-region steps, SVDs, scaling
    and bound handling, finite differences' bookkeeping); and the row :data:`SOLVES`, every static map's
    solve as a whole (``identify.static._Branch.search``)."""
    rows: dict = collections.defaultdict(lambda: {"runs": 0, "nfev": 0, "njev": 0, "cpu": 0.0, "callbacks": 0.0})
    undo = []

    def clocked(fn, row):
        def inner(*a, **kw):
            t0 = time.process_time()
            try:
                return fn(*a, **kw)
            finally:
                row["callbacks"] += time.process_time() - t0
        return inner

    for mod_name in LSQ_MODULES:
        mod = importlib.import_module(mod_name)
        lsq = mod.least_squares

        def timed(fun, x0, *a, _lsq=lsq, **kw):
            caller = sys._getframe(1)
            own = caller.f_locals.get("self")  # a static map's branch (its projection's): its name too
            smap = getattr(own, "smap", None) or getattr(getattr(own, "pb", None), "smap", None)
            row = rows[_purpose(caller) + (f", {smap.name}" if smap is not None else "")]
            if callable(kw.get("jac")):
                kw["jac"] = clocked(kw["jac"], row)
            t0 = time.process_time()
            try:
                res = _lsq(clocked(fun, row), x0, *a, **kw)
            finally:
                row["cpu"] += time.process_time() - t0
            row["runs"] += 1
            row["nfev"] += int(res.nfev)
            row["njev"] += int(res.njev or 0)
            return res
        mod.least_squares = timed
        undo.append((mod, "least_squares", lsq))
    # every static map's solve as a whole (frictid.identify.varpro: the scan, the refinements, the linear
    # solves), whatever runs inside it; a row of its own, not summed with the least_squares rows
    from frictid.identify.static import _Branch
    search, solves = _Branch.search, rows[SOLVES]

    def timed_search(self, *a, **kw):
        t0 = time.process_time()
        try:
            return search(self, *a, **kw)
        finally:
            solves["cpu"] += time.process_time() - t0
            solves["runs"] += 1
    _Branch.search = timed_search
    undo.append((_Branch, "search", search))
    try:
        t0 = time.process_time()
        run()
        total = time.process_time() - t0
    finally:
        for mod, attr, fn in undo:
            setattr(mod, attr, fn)
    return total, dict(rows)


#: The row of :func:`optimiser_times` that times every static map's solve as a whole.
SOLVES = "static-map solves as a whole (scan, refinements, linear solves)"


def print_optimiser(total: float, rows: dict) -> None:
    rows = dict(rows)
    whole = rows.pop(SOLVES, None)
    cpu = sum(r["cpu"] for r in rows.values())
    cb = sum(r["callbacks"] for r in rows.values())
    print(f"least_squares (CPU time of one fit without the diagnosis, {total:.2f} s): {cpu:.2f} s "
          f"({100 * cpu / total:.0f} %), of it the residuals and Jacobians {cb:.2f} s and the optimiser's own "
          f"loop {cpu - cb:.2f} s ({100 * (cpu - cb) / total:.0f} % of the fit)")
    for name, r in sorted(rows.items(), key=lambda kv: -kv[1]["cpu"]):
        print(f"  {name:<62} {r['runs']:4d} runs  {r['nfev']:6d} residuals  {r['njev']:6d} Jacobians  "
              f"{r['cpu']:6.2f} s  (callbacks {r['callbacks']:5.2f} s, loop {r['cpu'] - r['callbacks']:5.2f} s)")
    if whole:
        print(f"{SOLVES}: {whole['runs']} solves, {whole['cpu']:.2f} s ({100 * whole['cpu'] / total:.0f} % of the fit, "
              "the static rows above included)")


def print_stages(total: float, spent: dict) -> None:
    print(f"steps (CPU time of one fit with the diagnosis, {total:.2f} s; steps nest):")
    for label, _, _ in STAGES:
        if label in spent:
            print(f"  {label:<24} {spent[label]:6.2f} s  {100 * spent[label] / total:4.0f} %")


def floor(path: str) -> float:
    """Seconds for the floor of every joint of the file (see the module docstring)."""
    c0 = time.process_time()
    t0 = time.perf_counter()
    for lg in read_logs(path):
        w, a = derivatives(lg)
        ok = np.isfinite(w) & np.isfinite(a)
        X = np.column_stack([np.sign(w[ok]), w[ok], a[ok], np.cos(lg.q[ok]), np.sin(lg.q[ok]), np.ones(ok.sum())])
        np.linalg.lstsq(X, lg.tau[ok], rcond=None)
    CPU.append(time.process_time() - c0)
    return time.perf_counter() - t0


#: CPU seconds of the last timed call of floor() or fit() (the load moves them less than the wall times)
CPU: list = []


def fit(path: str, diagnose: bool) -> float:
    c0 = time.process_time()
    t0 = time.perf_counter()
    frictid.fit(path, jobs=1, diagnose=diagnose)
    CPU.append(time.process_time() - c0)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=15.0, help="minutes of log per joint (1 kHz)")
    ap.add_argument("--joints", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--stages", action="store_true", help="also the CPU time of each step of one fit")
    ap.add_argument("--optimiser", action="store_true",
                    help="also the CPU time of one fit without the diagnosis inside least_squares, by purpose")
    ap.add_argument("--against", metavar="REV", help="time the fit of this tree against git revision REV")
    ap.add_argument("--repeat", type=int, default=3, help="timed fits per process with --against")
    a = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        a.minutes, a.joints, a.rounds, a.repeat = 1.0, 1, 1, 1
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "long.parquet")
        rows = build_log(path, a.minutes / 60.0, a.joints)
        if a.against:
            return against(a, path, rows, tmp)
        fit(path, False)  # warm: compilation caches and imports are not the fit's
        times = {"floor": [], "fit": [], "fit+diagnosis": []}
        cpu = {k: [] for k in times}
        for _ in range(a.rounds):
            for k, run in (("floor", floor), ("fit", lambda p: fit(p, False)), ("floor", floor),
                           ("fit+diagnosis", lambda p: fit(p, True))):
                times[k].append(run(path))
                cpu[k].append(CPU[-1])
        print_ratios(a, rows, times, cpu)
        stages = stage_times(lambda: fit(path, True)) if a.stages else None
        optim = optimiser_times(lambda: fit(path, False)) if a.optimiser else None
    if stages is not None:
        print_stages(*stages)
    if optim is not None:
        print_optimiser(*optim)
    return 0


#: A fresh process's fits of the log argv[2] with the frictid of folder argv[1]: a warm one, then argv[3] timed
#: (CPU seconds printed).
CHILD = """import sys, time
import frictid
assert frictid.__file__.startswith(sys.argv[1]), frictid.__file__
frictid.fit(sys.argv[2], jobs=1, diagnose=False)
for _ in range(int(sys.argv[3])):
    t = time.process_time(); frictid.fit(sys.argv[2], jobs=1, diagnose=False); print(time.process_time() - t)
"""


def against(a, path: str, rows: int, tmp: str) -> int:
    """The fit (no diagnosis) of this tree and of revision ``a.against``, alternating (module docstring)."""
    other = Path(tmp) / "against"
    other.mkdir()
    rev = subprocess.run(["git", "rev-parse", "--short", a.against], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout.strip()
    tar = subprocess.run(["git", "archive", rev], cwd=ROOT, capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(other)], input=tar, check=True)
    trees = [("this tree", ROOT), (rev, other)]
    cpu: dict = {label: [] for label, _ in trees}
    for r in range(a.rounds):
        for label, src in (trees if r % 2 == 0 else trees[::-1]):
            env = dict(os.environ, PYTHONPATH=str(src))
            out = subprocess.run([sys.executable, "-c", CHILD, str(src), path, str(a.repeat)], cwd=src, env=env,
                                 capture_output=True, text=True, check=True).stdout
            cpu[label] += [float(x) for x in out.split()]
    med = {k: statistics.median(v) for k, v in cpu.items()}
    print(f"fit (no diagnosis), this tree against {rev}: {a.joints} joints x {a.minutes:g} min at 1 kHz "
          f"({rows} rows), {a.rounds} rounds x {a.repeat} fits, CPU time medians")
    for k, v in cpu.items():
        print(f"  {k:<10} {med[k]:6.3f} s  (runs {', '.join(f'{x:.2f}' for x in v)})")
    saved = med[rev] - med["this tree"]
    print(f"saved {saved:.3f} s ({100 * saved / med[rev]:.1f} %); this tree at {med['this tree'] / med[rev]:.3f}x "
          f"of {rev}", flush=True)
    return 0


def print_ratios(a, rows: int, times: dict, cpu: dict) -> None:
    med = {k: statistics.median(v) for k, v in times.items()}
    mcpu = {k: statistics.median(v) for k, v in cpu.items()}
    print(f"fit against its floor: {a.joints} joints x {a.minutes:g} min at 1 kHz ({rows} rows), "
          f"{a.rounds} rounds, medians")
    print(f"floor (read + derivatives + least squares): {med['floor']:.2f} s "
          f"({', '.join(f'{x:.2f}' for x in times['floor'])})")
    for k in ("fit", "fit+diagnosis"):
        r = med[k] / med["floor"]
        print(f"{k:<14} {med[k]:6.2f} s  = {r:4.1f}x the floor  (target <= {TARGET:g}x: "
              f"{'met' if r <= TARGET else 'not met'}; runs {', '.join(f'{x:.2f}' for x in times[k])})")
    ratio = {k: "" if k == "floor" else f" ({mcpu[k] / mcpu['floor']:.1f}x)" for k in mcpu}
    print("CPU time, medians: " + ", ".join(f"{k} {mcpu[k]:.2f} s{ratio[k]}" for k in mcpu), flush=True)
    print("CPU time, runs: " + "; ".join(f"{k} {', '.join(f'{x:.2f}' for x in cpu[k])}" for k in cpu), flush=True)


if __name__ == "__main__":
    sys.exit(main())
