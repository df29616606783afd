"""Benchmark: the diagnosis on every sliding sample of a long log, against the fit without the diagnosis.

    python benchmarks/bench_diagnose_whole.py [--minutes 60] [--plant geared_industrial] [--seed 100000] [--stages]
                                             [--candidates] [--repeat N] [--passes]

Input: frictid's plant (``--plant``, its own hidden effects removed, ``tests/diag_synth.py``) run through a
pick-and-place program (``diag_synth.pick_place_recipe``: a constant-velocity sweep, ``--minutes`` of 7 s
cycles moving half of each cycle between 10 and 90 % of the travel at three speeds, the sweep again) from a
cold joint whose friction falls by 30 % over 35 K as it warms (thermal4, heated by the program's
friction power towards 35 K above the ambient), the joint temperature logged
as ``temp_joint`` (0.05 K noise, 0.1 K steps). The plant's own sample rate (1 kHz for the geared joint).

Measured in one run, on the same logs, after a warm-up fit of a short log (compiled kernels loaded):
``frictid.fit(..., diagnose=False)`` and ``frictid.fit(...)`` (with the diagnosis), CPU and wall time of each; the ratio of the two is the figure (aim: at most 3). Printed
with it: the log's samples, the sliding samples the diagnosis used (all of them: no cap), its groups, the
findings (cause, extension, held-out gain, where the temperature came from) and any warning.

``--stages``: the CPU time of each step of one more fit with the diagnosis (``bench_fit_floor.stage_times``).
``--candidates``: the CPU time of each candidate extension's trials in the chain of one more fit, and of
them its proposals' and its folds' sums; on a long log a candidate's trial on the stride (its screen,
``frictid.diagnose.screen``) is listed apart as ``ext (stride)``, and the candidates the screen skipped.
``--repeat N``: the pair of fits timed N times more in the same process (the steady cost, after the first
fit with the diagnosis has grown the heap to its peak).
``--passes``: the parts of one pass of the diagnosis' sums (current model's columns, new columns, products)
over as many random samples as the diagnosis slid, for 1-30 new columns.
``--budget``: the whole CPU budget of one more fit without and one with the diagnosis, in exclusive parts
(:data:`BUDGET_SPOTS` wrapped for the two fits only): the fit's own steps (the same with and without the
diagnosis), then the diagnosis (its samples, the chain's set-up, the candidates' lists, their trials on the
stride and on all samples, the screen's bounds besides its trials, the choice and confound rules, the chosen
term on all samples, the refits after a step, the findings and sentences, the structure tests) and the check
(its replays, sample sets, map fits and held-out refits, stored RMS); each part's CPU time, of it system
(kernel) time, and its minor page faults (``resource.getrusage``: the fresh pages its temporaries touch).

``FRICTID_SMOKE=1`` shrinks the log to one minute of cycles (a few seconds), the same code path.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import diag_synth as ds  # noqa: E402


def load() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def timed(fn):
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.process_time() - c0, time.perf_counter() - w0


def make_logs(minutes: float, plant: str, seed: int):
    """The pick-and-place logs with the warm-up hidden and the joint temperature logged."""
    return ds.warm_pick_place(minutes, plant, seed)


def candidate_times(run) -> tuple[float, dict]:
    """CPU time of ``run()`` and, per candidate extension, the CPU time of its trials in the diagnosis'
    chain (``Chain.evaluate``: its proposals and held-out refits over the folds, summed over the chain's
    steps), the number of steps it was tried in, and the parts of its trials in its proposals
    (``Chain._propose``: the settings' searches) and in the sums its folds' fits ask for (``Context.prefetch``
    outside the proposals, the candidate's columns formed for them included)."""
    from frictid.diagnose.chain import Chain
    from frictid.diagnose.model import Context

    spent: dict = {}
    cur: list = [None, False]
    fn, prop, pre = Chain.evaluate, Chain._propose, Context.prefetch

    def add(ext, i, dt):
        row = spent.setdefault(ext, [0.0, 0, 0.0, 0.0])
        row[i] += dt

    def timed(self, ext, m):
        t0 = time.process_time()
        # a long log's screen (the same trial on the stride, frictid.diagnose.screen) is listed apart
        key = ext + (" (stride)" if getattr(self, "full", None) is not None else "")
        cur[0] = key
        try:
            return fn(self, ext, m)
        finally:
            add(key, 0, time.process_time() - t0)
            spent[key][1] += 1
            cur[0] = None

    def proposing(self, ext, *a, **k):
        t0, cur[1] = time.process_time(), True
        try:
            return prop(self, ext, *a, **k)
        finally:
            add(cur[0] if cur[0] is not None else ext, 2, time.process_time() - t0)
            cur[1] = False

    def summing(self, structures):
        t0 = time.process_time()
        try:
            return pre(self, structures)
        finally:
            if cur[0] is not None and not cur[1]:
                add(cur[0], 3, time.process_time() - t0)
    Chain.evaluate, Chain._propose, Context.prefetch = timed, proposing, summing
    try:
        t0 = time.process_time()
        run()
        total = time.process_time() - t0
    finally:
        Chain.evaluate, Chain._propose, Context.prefetch = fn, prop, pre
    return total, {k: tuple(v) for k, v in spent.items()}


def print_candidates(total: float, spent: dict) -> None:
    chain = sum(v[0] for v in spent.values())
    print(f"candidates (CPU time of one fit with the diagnosis, {total:.2f} s; their trials {chain:.2f} s; "
          f"of each: proposals, sums):")
    for ext, (cpu, n, p, q) in sorted(spent.items(), key=lambda kv: -kv[1][0]):
        print(f"  {ext:<20} {cpu:6.2f} s  {100 * cpu / total:4.0f} %  ({n} steps)  {p:5.2f} s  {q:5.2f} s")


def repeat_times(logs, k: int) -> None:
    """The pair of fits (without, with the diagnosis) timed ``k`` times more in this process: after the first
    fit with the diagnosis a process has its heap at the peak, so these show the diagnosis' steady cost."""
    import frictid

    ratios, diag = [], []
    for i in range(k):
        _, c0, _ = timed(lambda: frictid.fit(logs, models=ds.FIT_MODELS, diagnose=False))
        _, c1, _ = timed(lambda: frictid.fit(logs, models=ds.FIT_MODELS))
        ratios.append(c1 / c0)
        diag.append(c1 - c0)
        print(f"again {i + 1}: without CPU {c0:.2f} s, with {c1:.2f} s, ratio {c1 / c0:.2f}x, the difference "
              f"{c1 - c0:.2f} s (load {load():.1f})")
    print(f"again, mean: ratio {sum(ratios) / k:.2f}x, the difference {sum(diag) / k:.2f} s")


def pass_times(n: int, seed: int = 0) -> None:
    """The parts of one pass of the diagnosis' sums (``Context._border_products``) over ``n`` samples: the
    current model's columns formed block by block (8 plain columns at the first step; 14 at the next, 6 of
    them products with a factor's column), the candidate's new columns, and the products; CPU time of one
    pass, mean of three, one BLAS thread as in the diagnosis."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from frictid.diagnose.model import BLOCK_ROWS, _block

    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n)
    plain = [rng.standard_normal(n) for _ in range(8)]
    print(f"one pass of the sums over {n:,} samples (CPU ms: current model's columns, new columns, products):")
    with threadpool_limits(1, "blas"):
        steps = (("first step, 8 columns", plain), ("next step, 14 columns", plain + [(v, x) for v in plain[:6]]))
        for name, olds in steps:
            for k in (1, 2, 10, 30):
                news = [rng.standard_normal(n) for _ in range(k)]
                V, W = np.empty((len(olds), BLOCK_ROWS)), np.empty((k, BLOCK_ROWS))
                P, Q = np.zeros((len(olds), k)), np.zeros((k, k))
                t = np.zeros(3)
                for _ in range(3):
                    for s in range(0, n, BLOCK_ROWS):
                        e = min(s + BLOCK_ROWS, n)
                        t0 = time.process_time()
                        A = _block(V[:, :e - s], olds, s, e)
                        t1 = time.process_time()
                        B = _block(W[:, :e - s], news, s, e)
                        t2 = time.process_time()
                        P += A @ B.T
                        Q += B @ B.T
                        t += (t1 - t0, t2 - t1, time.process_time() - t2)
                t *= 1e3 / 3
                print(f"  {name}, {k:2d} new: {t[0]:5.1f} {t[1]:5.1f} {t[2]:6.1f}")


#: (module, attribute) of what ``--budget`` times; "Class.method" for methods. Each key is timed on its outermost
#: call, and apart within the keys of :data:`BUDGET_WITHIN` it runs inside (a trial inside the screen).
BUDGET_SPOTS = [("frictid.identify.prepare", "prepare"), ("frictid.identify.mechanics", "rigid_body"),
                ("frictid.identify.maps", "static_maps"), ("frictid.identify.validity", "of_joint"),
                ("frictid.api", "diagnose_fit"), ("frictid.api", "check_diagnosis"),
                ("frictid.diagnose.joint", "build_samples"), ("frictid.diagnose.joint", "_chain"),
                ("frictid.diagnose.joint", "_findings"), ("frictid.diagnose.joint", "_structure"),
                ("frictid.diagnose.chain", "candidates"), ("frictid.diagnose.chain", "Chain._screened"),
                ("frictid.diagnose.chain", "Chain.evaluate"), ("frictid.diagnose.chain", "Chain._choose_sound"),
                ("frictid.diagnose.chain", "Chain.choose"), ("frictid.diagnose.chain", "Chain._before"),
                ("frictid.diagnose.chain", "Chain.run"), ("frictid.diagnose.check", "_static_targets"),
                ("frictid.diagnose.check", "_stored_rms"), ("frictid.identify.samples", "build"),
                ("frictid.diagnose.check", "_same_samples"), ("frictid.identify.samples", "fit_map")]
BUDGET_WITHIN = ("_screened", "run", "_choose_sound", "check_diagnosis")


def _usage():
    """CPU time [s], system (kernel) time [s] and minor page faults of this process so far (the faults count
    the fresh pages its temporaries touch: the kernel zeroes and maps each)."""
    import resource

    import numpy as np

    r = resource.getrusage(resource.RUSAGE_SELF)
    return np.array([time.process_time(), r.ru_stime, float(r.ru_minflt)])


def budget_times(run) -> dict:
    """CPU time, system time and minor page faults (:func:`_usage`) of ``run()`` (key ``total``) and of each
    :data:`BUDGET_SPOTS` function within it, on its outermost call (key: the function's name), and apart
    where it runs inside a :data:`BUDGET_WITHIN` one (key ``name@outer``). The functions are wrapped where
    they are defined and where ``frictid.api`` imported them, for the call only."""
    import collections
    import functools
    import importlib

    import numpy as np

    from bench_fit_floor import resolve

    spent, depth, undo = collections.defaultdict(lambda: np.zeros(3)), collections.Counter(), []
    api = importlib.import_module("frictid.api")
    for mod, attr in BUDGET_SPOTS:
        owner, name, fn = resolve(mod, attr)

        @functools.wraps(fn)
        def timed(*a, _fn=fn, _k=name, **kw):
            outer = [k for k in BUDGET_WITHIN if depth[k] and k != _k]
            depth[_k] += 1
            u0 = _usage()
            try:
                return _fn(*a, **kw)
            finally:
                depth[_k] -= 1
                if depth[_k] == 0:
                    du = _usage() - u0
                    spent[_k] += du
                    for k in outer:
                        spent[f"{_k}@{k}"] += du
        for where in (owner, api):
            if getattr(where, name, None) is fn:
                setattr(where, name, timed)
                undo.append((where, name, fn))
    try:
        u0 = _usage()
        run()
        spent["total"] = _usage() - u0
    finally:
        for where, name, fn in reversed(undo):
            setattr(where, name, fn)
    return dict(spent)


def print_budget(without: dict, with_: dict) -> None:
    """The budget of :func:`budget_times` of a fit without and one with the diagnosis, in exclusive parts:
    CPU, of it system time, and minor page faults (thousands) of each."""
    import numpy as np

    for label, s in (("without", without), ("with", with_)):
        g = lambda k, s=s: s.get(k, np.zeros(3))  # noqa: E731
        fit = g("prepare") + g("rigid_body") + g("static_maps") + g("of_joint")
        rest = g("total") - fit - g("diagnose_fit") - g("check_diagnosis")
        print(f"budget, fit {label} the diagnosis: CPU {g('total')[0]:.2f} s (system {g('total')[1]:.2f} s, "
              f"{g('total')[2] / 1e3:.0f} k page faults); the fit's steps {fit[0]:.2f} s (system {fit[1]:.2f} s, "
              f"{fit[2] / 1e3:.0f} k faults: prepare {g('prepare')[0]:.2f}, rigid body {g('rigid_body')[0]:.2f}, "
              f"static maps {g('static_maps')[0]:.2f}, validity {g('of_joint')[0]:.2f}), the rest {rest[0]:.2f} s")
    g = lambda k: with_.get(k, np.zeros(3))  # noqa: E731
    ev_stride = g("evaluate@_screened")
    # the fit builds sample sets and fits maps on them too (a joint's sample basis): the check's own only
    check_parts = (g("_static_targets") + g("build@check_diagnosis") + g("_same_samples")
                   + g("fit_map@check_diagnosis") + g("_stored_rms"))
    rows = [("samples (build_samples)", g("build_samples")),
            ("chain set-up: base refits, columns, stride (_chain)", g("_chain")),
            ("candidates' lists (candidates)", g("candidates")),
            ("trials on the stride (evaluate within _screened)", ev_stride),
            ("the screen besides its trials (_screened less them)", g("_screened") - ev_stride),
            ("trials on all samples (evaluate)", g("evaluate") - ev_stride - g("evaluate@_choose_sound")),
            ("choice and confound rules (choose)", g("choose")),
            ("chosen term on all samples (_choose_sound less choose)", g("_choose_sound") - g("choose")),
            ("refits after a step (_before in run)", g("_before@run") - g("_before@_screened")
             - g("_before@_choose_sound")),
            ("findings, models, sentences (_findings)", g("_findings")),
            ("structure tests (_structure)", g("_structure"))]
    rows.append(("the diagnosis' rest", g("diagnose_fit") - sum(v for _, v in rows)))
    rows += [("check: replays and targets (_static_targets)", g("_static_targets")),
             ("check: sample sets (build, _same_samples)", g("build@check_diagnosis") + g("_same_samples")),
             ("check: map fits and held-out refits (fit_map)", g("fit_map@check_diagnosis")),
             ("check: stored parameters' RMS (_stored_rms)", g("_stored_rms")),
             ("check: rest", g("check_diagnosis") - check_parts)]
    d, c = g("diagnose_fit"), g("check_diagnosis")
    print(f"  diagnosis {d[0]:.2f} s (system {d[1]:.2f} s, {d[2] / 1e3:.0f} k faults) and its check {c[0]:.2f} s "
          f"(system {c[1]:.2f} s, {c[2] / 1e3:.0f} k faults), of them (exclusive; CPU, system, k faults):")
    for k, v in rows:
        print(f"    {k:<56} {v[0]:6.3f} s  {v[1]:6.3f} s  {v[2] / 1e3:6.1f} k")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0, help="pick-and-place cycles [min]")
    ap.add_argument("--plant", default="geared_industrial")
    ap.add_argument("--seed", type=int, default=100000)
    ap.add_argument("--stages", action="store_true", help="also the CPU time of each step of one fit")
    ap.add_argument("--candidates", action="store_true",
                    help="also the CPU time of each candidate extension in the diagnosis' chain of one fit")
    ap.add_argument("--repeat", type=int, default=0,
                    help="also time the pair of fits (without, with the diagnosis) this many times more")
    ap.add_argument("--passes", action="store_true",
                    help="also the parts of one pass of the diagnosis' sums over as many samples as it slid")
    ap.add_argument("--budget", action="store_true",
                    help="also the whole CPU budget of one fit without and one with the diagnosis, in exclusive parts")
    args = ap.parse_args(argv)
    smoke = os.environ.get("FRICTID_SMOKE") == "1"
    minutes = 1.0 if smoke else args.minutes
    import frictid

    print(f"load average {load():.1f}, {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC"
          + (" (FRICTID_SMOKE=1: one minute)" if smoke else ""))
    logs, _, sim_wall = timed(lambda: make_logs(minutes, args.plant, args.seed))
    lg = logs[0]
    dur = float(lg.t[-1] - lg.t[0])
    T = lg.truth["temp_joint"]
    print(f"input: {args.plant} pick-and-place, {dur / 3600:.2f} h at {1 / (lg.t[1] - lg.t[0]):.0f} Hz, "
          f"{lg.n:,} samples (simulated in {sim_wall:.0f} s); joint {T.min():.1f} -> {T.max():.1f} degC, "
          f"friction x (1 {-0.3 / 35.0:+.4f} (T - 25)), temp_joint logged")
    # warm-up: the compiled kernels load and the imports happen once, before either timing
    frictid.fit(make_logs(0.2, args.plant, args.seed + 1), models=ds.FIT_MODELS)
    r0, c0, w0 = timed(lambda: frictid.fit(logs, models=ds.FIT_MODELS, diagnose=False))
    r1, c1, w1 = timed(lambda: frictid.fit(logs, models=ds.FIT_MODELS))
    jf = r1[lg.joint]
    rec = jf.selection.get("diagnosis", {})
    print(f"fit without the diagnosis: CPU {c0:.1f} s, wall {w0:.1f} s")
    print(f"fit with the diagnosis:    CPU {c1:.1f} s, wall {w1:.1f} s")
    print(f"ratio (with / without): CPU {c1 / c0:.2f}x, wall {w1 / w0:.2f}x (aim <= 3)")
    print(f"diagnosis: {rec.get('samples', 0):,} sliding samples (all of them), {rec.get('groups', 0):,} groups, "
          f"base {rec.get('base')}" + (f"; skipped: {rec['skipped']}" if rec.get("skipped") else ""))
    for f in jf.diagnosis:
        src = (jf.models[f["model"]].extra or {}).get("temperature", "")
        print(f"  finding: {f['cause']} ({f['extension']}{', ' + src if src else ''}), held-out gain "
              f"{f['gain']:.2f}")
    steps = [[(t["extension"], "screened" in t) for t in st.get("tested", [])] for st in rec.get("steps", [])]
    print(f"  steps: {len(steps)}; candidates' trials {sum(len(s) for s in steps)}, of them screened out on the "
          f"stride {sum(x for s in steps for _, x in s)} (" + "; ".join(
              f"step {i + 1}: " + (", ".join(e for e, x in s if not x) or "none") + " on all samples"
              for i, s in enumerate(steps)) + ")")
    for w in jf.warnings:
        print(f"  warning: {w}")
    if args.repeat:
        repeat_times(logs, args.repeat)
    if args.stages:
        from bench_fit_floor import print_stages, stage_times

        print_stages(*stage_times(lambda: frictid.fit(logs, models=ds.FIT_MODELS)))
    if args.candidates:
        print_candidates(*candidate_times(lambda: frictid.fit(logs, models=ds.FIT_MODELS)))
    if args.passes:
        pass_times(int(rec.get("samples", 0)) or lg.n)
    if args.budget:
        print_budget(budget_times(lambda: frictid.fit(logs, models=ds.FIT_MODELS, diagnose=False)),
                     budget_times(lambda: frictid.fit(logs, models=ds.FIT_MODELS)))
    print(f"load average at the end {load():.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
