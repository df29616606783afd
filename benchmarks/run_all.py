"""Every figure of "fast on long logs" in one table: frictid against naive baselines and the read floor.

    python benchmarks/run_all.py                   # full sizes (about half an hour on a 2-core box)
    python benchmarks/run_all.py --quick           # small sizes, a few minutes
    python benchmarks/run_all.py --only replay,plant
    python benchmarks/run_all.py --write-docs      # also replace the table in docs/benchmarks.md

Figures (each a ratio measured in one run, with the absolute value; the baseline runs in the same run):

- replay: friction along a measured velocity (LuGre bristle state and thermal6 joint temperature) by
  :func:`frictid.models.replay_kernel.replay_friction`, against a straightforward ``solve_ivp`` (LSODA)
  of the same model on the same measured log, and its error against a tight reference (Radau,
  rtol 1e-10, interval by interval with the velocity linear between samples);
- plant: the closed-loop plant kernel (:func:`frictid.plant.kernel.simulate_joint`) on the one-hour
  ``validation_ptp`` recipe of each shipped plant, against the Radau reference of
  :mod:`frictid.plant.reference` (speed and friction error over a window centred on a velocity reversal,
  ``benchmarks/bench_plant.py``);
- read: :func:`frictid.io.logs.read_logs` against a bare ``pyarrow.parquet.read_table`` of the same file
  (and the columns it asks Parquet for), and against pandas' C reader for CSV (``benchmarks/bench_io.py``);
- normal equations: :func:`frictid.identify.regression.accumulate` (chunked) against ``np.linalg.lstsq`` on
  the stacked matrix, 7 regressors;
- fit: ``frictid fit`` in a fresh process on a 6-joint, 1 kHz, 1-hour log (8 passes of every
  experiment kind, simulated by the plant), against the bare read of the same file; its peak memory
  (proportional set size of the process tree, sampled); the same on one pass (1/8 of the data) for the
  scaling; its CPU time over wall time (parallel joints);
- report: ``frictid report`` of that fit and log, time and size.

Times are medians of repeated runs (``--repeat``); every figure carries the CPU time of the process
(``time.process_time`` or the child's rusage) and the 1-minute load average when it was measured,
because the development machine is shared and wall-clock rates suffer from the load.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

DOCS = ROOT / "docs" / "benchmarks.md"
MARK_START = "<!-- run-all:start -->"
MARK_END = "<!-- run-all:end -->"


# ---------------------------------------------------------------------------------------------------
# measuring


def load() -> float:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


@dataclass
class Timing:
    wall: float      # median wall time [s]
    cpu: float       # median CPU time of this process [s]
    load: float      # load average after the runs
    runs: int
    result: object = None


#: FRICTID_SMOKE=1 (the docs test, tests/test_docs_commands.py): every figure on a tiny case, one run
#: each, the same code path; nothing written into docs.
SMOKE = os.environ.get("FRICTID_SMOKE") == "1"


def size(quick: bool, full, small, smoke):
    """A figure's size: ``full``, ``small`` with --quick, ``smoke`` under FRICTID_SMOKE=1."""
    return smoke if SMOKE else small if quick else full


def timed(fn, repeat: int, warm: bool = False) -> Timing:
    """Median wall and CPU time of ``fn()`` over ``repeat`` runs (one extra unmeasured run if warm)."""
    out = fn() if warm else None
    walls, cpus = [], []
    for _ in range(repeat):
        # the previous run's result is freed first, as a caller's would be: held, it made every run map
        # fresh pages for its outputs, which this VM charges for (the kernel's rate then measured the
        # memory system: 18 M/s in one run, 40-44 M/s in the others)
        out = None
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return Timing(statistics.median(walls), statistics.median(cpus), load(), repeat, out)


def timed_pair(fa, fb, repeat: int) -> tuple[Timing, Timing]:
    """:func:`timed` of two functions, alternating their runs so that both see the same load."""
    wa, ca, wb, cb = [], [], [], []
    for _ in range(repeat):
        for fn, w, c in ((fa, wa, ca), (fb, wb, cb)):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            w.append(time.perf_counter() - t0)
            c.append(time.process_time() - c0)
    la = load()
    return (Timing(statistics.median(wa), statistics.median(ca), la, repeat),
            Timing(statistics.median(wb), statistics.median(cb), la, repeat))


def _children(pid: int) -> list[int]:
    """pid and its descendants (from /proc)."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as fh:
                ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        kids.setdefault(ppid, []).append(int(d))
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(kids.get(p, []))
    return out


def _pss(pid: int) -> int:
    """Proportional set size [B] of a process: its resident pages, each shared page divided among the
    processes that map it (a forked worker's copy-on-write view of its parent counts once over the tree);
    0 when it is gone."""
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            for line in fh:
                if line.startswith("Pss:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _status(pid: int) -> tuple[int, int]:
    """(VmRSS, VmHWM) [B] of a process; (0, 0) when it is gone."""
    rss = hwm = 0
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    rss = int(line.split()[1]) * 1024
                elif line.startswith("VmHWM:"):
                    hwm = int(line.split()[1]) * 1024
    except OSError:
        pass
    return rss, hwm


#: Prefix of the child's code: at exit, write the process's own high-water resident set (VmHWM, per
#: address space: unlike ru_maxrss it does not inherit the parent's peak at exec) to argv[1].
_HWM = """
import atexit, runpy, sys
_out = sys.argv[1]
def _hwm():
    with open("/proc/self/status") as fh:
        v = next(line.split()[1] for line in fh if line.startswith("VmHWM:"))
    with open(_out, "w") as fh:
        fh.write(v)
atexit.register(_hwm)
"""


@dataclass
class ChildRun:
    returncode: int
    wall: float
    cpu: float            # user + system time of the child and its waited-for descendants [s]
    peak: int             # peak memory [B]: the largest of the root's high-water resident set, the
                          # sampled sum of proportional set sizes over the process tree (forked workers
                          # share their parent's pages: resident sets would count them once per process),
                          # and each process's sampled high-water mark
    load: float
    stderr: str = ""


def run_child(args: list[str], interval: float | None = 0.1) -> ChildRun:
    """Run ``python -m MODULE ARGS`` (args = [MODULE, ...]) or ``python -c CODE`` (args = ["-c", CODE])
    in a fresh process; wall time, CPU time and peak memory of its process tree, sampled every
    ``interval`` seconds (None: not sampled, the peak is the root's own high-water mark). Sampling costs
    the measured processes time: reading a worker's ``smaps_rollup`` walks its page tables under its
    memory-map lock (the report measured 1-2.5 s slower with 0.1 s sampling than without), so timings
    that matter are taken without it."""
    with tempfile.TemporaryDirectory() as tmp:
        hwm_file = str(Path(tmp) / "hwm")
        if args[0] == "-c":
            cmd = [sys.executable, "-c", _HWM + args[1], hwm_file]
        else:  # python -m MODULE ARGS
            run = 'sys.argv = sys.argv[2:]\nrunpy.run_module(sys.argv[0], run_name="__main__", alter_sys=True)\n'
            cmd = [sys.executable, "-c", _HWM + run, hwm_file] + list(args)
        with tempfile.TemporaryFile() as err:
            t0 = time.perf_counter()
            p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err, cwd=ROOT)
            peak = [0]
            stop = threading.Event()

            def sample():
                while not stop.is_set():
                    kids = _children(p.pid)[1:]  # descendants; the root's own peak: its VmHWM, below
                    tree = [_status(c) for c in kids]
                    if kids:  # several processes: physical memory of the tree, shared pages once
                        total = _pss(p.pid) + sum(_pss(c) for c in kids)
                    else:
                        total = _status(p.pid)[0]
                    peak[0] = max(peak[0], total, *(h for _, h in tree))
                    stop.wait(interval)

            th = threading.Thread(target=sample, daemon=True)
            if interval is not None:
                th.start()
            _, status, ru = os.wait4(p.pid, 0)
            wall = time.perf_counter() - t0
            stop.set()
            if interval is not None:
                th.join()
            p.returncode = os.waitstatus_to_exitcode(status)
            err.seek(0)
            text = err.read().decode("utf-8", "replace")
        try:
            root_hwm = int(Path(hwm_file).read_text()) * 1024
        except (OSError, ValueError):
            root_hwm = 0
    return ChildRun(p.returncode, wall, ru.ru_utime + ru.ru_stime, max(peak[0], root_hwm), load(), text)


def timed_child(setup: str, stmt: str, repeat: int) -> Timing:
    """Median wall and CPU time of ``stmt`` run in a fresh python after ``setup`` (untimed), over ``repeat``
    processes: a baseline for a command that runs in a fresh process (its allocators start empty; in one
    process a repeated read reuses the pages of the previous one)."""
    code = ("import json, time\n{setup}\nt0, c0 = time.perf_counter(), time.process_time()\n{stmt}\n"
            "print(json.dumps([time.perf_counter() - t0, time.process_time() - c0]))\n")
    walls, cpus = [], []
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", code.format(setup=setup, stmt=stmt)], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout
        wall, cpu = json.loads(out.strip().splitlines()[-1])
        walls.append(wall)
        cpus.append(cpu)
    return Timing(statistics.median(walls), statistics.median(cpus), load(), repeat)


def child_peak(code: str) -> int:
    """Peak resident set [B] of a fresh python running ``code`` (includes the interpreter and imports)."""
    r = run_child(["-c", code], interval=0.05)
    if r.returncode:
        raise RuntimeError(r.stderr[-2000:])
    return r.peak


# ---------------------------------------------------------------------------------------------------
# the table


@dataclass
class Row:
    figure: str
    measured: str
    baseline: str = "-"
    ratio: str = "-"
    target: str = "-"
    met: bool | None = None
    load: float = float("nan")
    note: str = ""


def fmt_rate(x: float) -> str:
    if x >= 1e6:
        return f"{x / 1e6:.1f} M/s"
    if x >= 1e3:
        return f"{x / 1e3:.1f} k/s"
    return f"{x:.0f} /s"


def gb(x: float) -> str:
    return f"{x / 1e9:.2f} GB"


def table(rows: list[Row]) -> str:
    """Markdown table. "met?" is judged on CPU time for absolute rates and single-threaded comparisons (the
    machine is shared: wall clock suffers from the load) and on wall time for ratios of runs that alternate
    or follow each other (readers, least squares, fit against the read)."""
    out = ["| figure | measured | baseline | ratio | target | met? | load |",
           "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        met = {True: "yes", False: "**no**", None: "-"}[r.met]
        out.append(f"| {r.figure} | {r.measured} | {r.baseline} | {r.ratio} | {r.target} | {met} | "
                   f"{r.load:.1f} |")
    notes = [f"- {r.figure}: {r.note}" for r in rows if r.note]
    return "\n".join(out + ([""] + notes if notes else []))


def machine() -> dict:
    model = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo") as fh:
            model = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    mem = float("nan")
    try:
        with open("/proc/meminfo") as fh:
            mem = int(next(line for line in fh if line.startswith("MemTotal")).split()[1]) * 1024
    except (OSError, StopIteration):
        pass
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True).stdout.strip()
    except OSError:
        commit = "?"
    import numba
    import pyarrow

    return {"date": _dt.datetime.now().strftime("%Y-%m-%d %H:%M"), "nproc": os.cpu_count(),
            "memory": mem, "cpu": model, "load": os.getloadavg() if hasattr(os, "getloadavg") else None,
            "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
            "pyarrow": pyarrow.__version__, "commit": commit}


# ---------------------------------------------------------------------------------------------------
# replay


def _plant_log(recipe: str, scale: float, plant_name: str = "geared_industrial", seed: int = 0):
    """A simulated log (measured signals) and the plant's true model numbers for the replay kernel."""
    from frictid.plant import load_plant, simulate_recipe
    from frictid.plant.kernel import P_C, P_K, P_S0N, P_S0P, P_S1N, P_S1P
    from frictid.plant.simulate import kernel_inputs

    plant = load_plant(plant_name)
    joint = plant.joints[0]
    lg = simulate_recipe(recipe, plant=plant, seed=seed, joints=[joint.name], duration_scale=scale)[0]
    p, c_pos, c_neg, dc9, code, theta, _, _ = kernel_inputs(plant, joint)
    model = dict(c_pos=c_pos, c_neg=c_neg, sigma0=(p[P_S0P], p[P_S0N]), sigma1=(p[P_S1P], p[P_S1N]),
                 code=code, theta=theta, dc=dc9, C=p[P_C], K=p[P_K])
    return lg, model


def _thermal(model: dict, Tenv, T_init=None) -> dict:
    th = dict(code=model["code"], theta=model["theta"], dc_pos=model["dc"], dc_neg=model["dc"],
              C=model["C"], K=model["K"], Tenv=Tenv)
    if T_init is not None:
        th["T_init"] = T_init
    return th


def ivp_replay(t, w, Tenv, model: dict, z0: float = 0.0, T0: float | None = None, method: str = "LSODA",
               rtol: float = 1e-6, atol=(1e-10, 1e-6), per_interval: bool = False) -> np.ndarray:
    """The replay model as users write it: ``solve_ivp`` on (z, T) with the velocity interpolated.

    dz/dt = w - sigma0 |w| z / g(w, T), F = sigma0 z + sigma1 dz/dt + f(w, T), C dT/dt = F w - K (T - Tenv),
    w(t) and Tenv(t) linear between samples. ``per_interval`` integrates sample interval by sample
    interval (the tight reference: no step crosses a kink of w); otherwise one call over the whole span.
    Returns the friction [F] at the samples.
    """
    from scipy.integrate import solve_ivp

    from frictid.models.static import canonical_level, canonical_viscous
    from frictid.models.thermal import canonical_at

    c_pos, c_neg = model["c_pos"], model["c_neg"]
    (s0p, s0n), (s1p, s1n) = model["sigma0"], model["sigma1"]
    code, theta, dc, C, K = model["code"], model["theta"], model["dc"], model["C"], model["K"]

    def friction(z, T, ww):
        c = canonical_at(c_pos if ww >= 0 else c_neg, T, code, theta, dc)
        g = float(canonical_level(ww, c))
        s0, s1 = (s0p, s1p) if z >= 0 else (s0n, s1n)
        zd = ww - s0 * abs(ww) / g * z
        return s0 * z + s1 * zd + float(canonical_viscous(ww, c)), zd

    def rhs(tt, x):
        z, T = x
        ww = float(np.interp(tt, t, w))
        F, zd = friction(z, T, ww)
        return [zd, (F * ww - K * (T - float(np.interp(tt, t, Tenv)))) / C]

    x0 = [z0, float(Tenv[0]) if T0 is None else T0]
    if per_interval:
        X = np.empty((len(t), 2))
        X[0] = x0
        x = np.array(x0, dtype=float)
        for k in range(len(t) - 1):
            sol = solve_ivp(rhs, (t[k], t[k + 1]), x, method=method, rtol=rtol, atol=list(atol))
            x = sol.y[:, -1]
            X[k + 1] = x
    else:
        sol = solve_ivp(rhs, (t[0], t[-1]), x0, method=method, t_eval=t, rtol=rtol, atol=list(atol))
        X = sol.y.T
    return np.array([friction(X[k, 0], X[k, 1], float(w[k]))[0] for k in range(len(t))])


def fig_replay(quick: bool, repeat: int) -> list[Row]:
    from frictid.models.replay_kernel import replay_friction

    lg, model = _plant_log("validation_ptp", size(quick, 1.0, 0.1, 0.005))
    h = lg.dt
    w_meas = np.asarray(lg.qd, dtype=float)
    Tenv_log = np.asarray(lg.channels["temp_env"], dtype=float)
    n = size(quick, 10_000_000, 1_000_000, 20_000)
    t = np.arange(n) * h
    w = np.resize(w_meas, n)            # the measured log repeated to n samples
    Tenv = np.resize(Tenv_log, n)

    def kernel(a=t, b=w, c=Tenv):
        return replay_friction(a, b, model["c_pos"], model["c_neg"], sigma0=model["sigma0"],
                               sigma1=model["sigma1"], thermal=_thermal(model, c))

    kernel(t[:1000], w[:1000], Tenv[:1000])  # compile / load the cache
    # one unmeasured full-size run first: a process's first 240 MB of fresh output pages cost about 0.8 s
    # of system time on this VM (huge-page faults; 78 000 small-page faults without them), which is the
    # memory system's price of a first allocation, not the kernel's rate (measured: 10 M/s on the first
    # call, 43 M/s on every later one; docs/benchmarks.md)
    tk = timed(kernel, repeat, warm=True)
    # the straightforward solve_ivp on stretches spread evenly over the same log (its mix of motion and
    # rest: at rest the measured velocity is noise and the bristle equation is not stiff, in motion it is)
    n_str, per = size(quick, (10, 2000), (6, 500), (2, 50))
    nb = n_str * per
    starts = np.linspace(0, len(w_meas) - per, n_str).astype(int)

    def baseline():
        for i0 in starts:
            sl = slice(i0, i0 + per)
            ivp_replay(t[sl] - t[i0], w_meas[sl], Tenv_log[sl], model)

    tb = timed(baseline, 1)
    rate_k, rate_kc = n / tk.wall, n / tk.cpu
    rate_b, rate_bc = nb / tb.wall, nb / tb.cpu
    rows = [Row("replay: LuGre + thermal6 friction along a measured velocity [samples/s]",
                f"{fmt_rate(rate_k)} (CPU {fmt_rate(rate_kc)}), {n / 1e6:.0f} M samples",
                f"solve_ivp LSODA {fmt_rate(rate_b)} (CPU {fmt_rate(rate_bc)}), {n_str} x {per} samples",
                f"{rate_kc / rate_bc:,.0f}x (wall {rate_k / rate_b:,.0f}x)", ">= 1000x and >= 20 M/s",
                rate_kc / rate_bc >= 1000 and rate_kc >= 20e6, tk.load,
                "geared_industrial (polynomial, sigma0 1.5e5, thermal6), its measured (noisy) velocity from "
                "the one-hour validation_ptp run, repeated to length; median of runs after one unmeasured run (first-touch "
                "page faults of the outputs excluded); baseline rtol 1e-6, "
                "atol 1e-10 (z) / 1e-6 (T), t_eval at the samples, velocity and ambient by np.interp, on stretches "
                "spread evenly over the log")]
    # the replay owner's benchmark input (benchmarks/bench_replay.py): a noisy multi-sine, always moving
    try:
        import bench_replay as br
    except ImportError:
        br = None
    if br is not None:
        t2, w2 = br.velocity(n, 1e-3)

        def kernel2():
            return replay_friction(t2, w2, br.C_POS, br.C_NEG, sigma0=br.SIGMA0, sigma1=br.SIGMA1,
                                   thermal=br.thermal())

        kernel2()
        tk2 = timed(kernel2, repeat)
        secs = size(quick, 10.0, 2.0, 0.2)
        tb2 = timed(lambda: br.ivp_friction(t2, w2, secs), 1)
        m2 = tb2.result[2]
        rk2, rb2 = n / tk2.cpu, m2 / tb2.cpu
        rows.append(Row("replay, bench_replay.py input (noisy multi-sine, always moving) [samples/s]",
                        f"{fmt_rate(n / tk2.wall)} (CPU {fmt_rate(rk2)}), {n / 1e6:.0f} M samples",
                        f"solve_ivp LSODA {fmt_rate(m2 / tb2.wall)} (CPU {fmt_rate(rb2)}), first {secs:g} s",
                        f"{rk2 / rb2:,.0f}x (wall {(n / tk2.wall) / (m2 / tb2.wall):,.0f}x)",
                        ">= 1000x and >= 20 M/s", rk2 / rb2 >= 1000 and rk2 >= 20e6, tk2.load,
                        "bench_replay's velocity, model and baseline (rtol 1e-6, max_step one sample)"))
    # accuracy against the tight reference on a window centred on a velocity reversal at speed
    nr = size(quick, 3000, 400, 40)
    fast = np.convolve(np.abs(w_meas) > 0.1 * np.abs(w_meas).max(), np.ones(201), mode="same") > 0
    rev = np.flatnonzero((np.sign(w_meas[:-1]) * np.sign(w_meas[1:]) < 0) & fast[:-1])
    j0 = int(np.clip(rev[len(rev) // 2] - nr // 2, 0, len(w_meas) - nr)) if rev.size else 0
    ws = slice(j0, j0 + nr)
    tw = t[:nr]
    t0 = time.perf_counter()
    F_ref = ivp_replay(tw, w_meas[ws], Tenv_log[ws], model, method="Radau", rtol=1e-10,
                       atol=(1e-14, 1e-10), per_interval=True)
    t_ref = time.perf_counter() - t0
    F_k = replay_friction(tw, w_meas[ws], model["c_pos"], model["c_neg"], sigma0=model["sigma0"],
                          sigma1=model["sigma1"], thermal=_thermal(model, Tenv_log[ws]))[0]
    F_b = ivp_replay(tw, w_meas[ws], Tenv_log[ws], model)
    err = float(np.sqrt(np.mean((F_k - F_ref) ** 2)) / np.sqrt(np.mean(F_ref ** 2)))
    err_b = float(np.sqrt(np.mean((F_b - F_ref) ** 2)) / np.sqrt(np.mean(F_ref ** 2)))
    rows.append(Row("replay: friction error vs tight reference [RMS / RMS]",
                    f"{100 * err:.2g} %", f"solve_ivp LSODA {100 * err_b:.2g} %", "-", "<= 1 %", err <= 0.01,
                    load(), f"{nr} samples around a velocity reversal at speed; reference Radau rtol 1e-10 "
                            f"interval by interval ({t_ref:.0f} s)"))
    return rows


def fig_replay_e2e(quick: bool, repeat: int) -> list[Row]:
    """frictid.replay.replay on a whole log: derivatives, multipliers, kernel, torque."""
    try:
        from frictid.replay import ReplayModel, replay
    except ImportError as exc:  # pragma: no cover
        return [Row("replay(): whole log", f"n/a ({exc})")]
    lg, model = _plant_log("validation_ptp", size(quick, 1.0, 0.1, 0.005))
    tp = lg.truth["params"]
    rm = ReplayModel(name="lugre", map=tp["map"], c_pos=np.asarray(model["c_pos"]),
                     c_neg=np.asarray(model["c_neg"]), sigma0=model["sigma0"], sigma1=model["sigma1"],
                     J=tp["J"], Px=tp["gravity"]["Px"], Py=tp["gravity"]["Py"],
                     offset=tp["gravity"].get("offset", 0.0),
                     thermal={"law": tp["thermal"]["law"], "alpha": tp["thermal"].get("alpha", 0.0),
                              "beta": tp["thermal"].get("beta", 1.0), "lam": tp["thermal"].get("lam", 0.0),
                              "T0": tp["thermal"]["T0"],
                              "dc": [tp["thermal"].get(k, 0.0) for k in ("dc0", "dc1", "dc2", "dc3")],
                              "C": tp["thermal"]["C"], "K": tp["thermal"]["K"]})
    try:
        replay(lg, rm)
        tr = timed(lambda: replay(lg, rm), repeat)
    except Exception as exc:  # the replay module is being changed by others; say so, do not fail
        return [Row("replay(): whole log", f"n/a ({type(exc).__name__}: {exc})")]
    n = lg.n
    return [Row("replay(): whole log incl. derivatives and torque [samples/s]",
                f"{fmt_rate(n / tr.wall)} (CPU {fmt_rate(n / tr.cpu)}), {n / 1e6:.1f} M samples", "-", "-",
                "-", None, tr.load, "frictid.replay.replay with the plant's true model: Savitzky-Golay "
                                     "derivatives, gravity, multipliers and the kernel")]


# ---------------------------------------------------------------------------------------------------
# plant


def fig_plant(quick: bool, repeat: int) -> list[Row]:
    from bench_plant import PLANTS, accuracy

    from frictid.plant import load_plant
    from frictid.plant.config import load_recipe
    from frictid.plant.kernel import simulate_joint
    from frictid.plant.simulate import prepare_joint

    rec, _ = load_recipe("validation_ptp")
    scale = size(quick, 1.0, 0.1, 0.005)
    nwin = size(quick, 2000, 400, 40)
    rows = []
    for name in PLANTS:
        plant = load_plant(name)
        _, args, _ = prepare_joint(plant, plant.joints[0], rec, 0, scale)
        n = len(args["mode"])
        simulate_joint(**args)
        tk = timed(lambda: simulate_joint(**args), repeat)
        err, t_ref, _, _ = accuracy(name, "multisine", nwin, 0.5, substeps=(1,))
        rate, rate_c, rate_ref = n / tk.wall, n / tk.cpu, nwin / t_ref
        ok = rate_c >= 10e6 and err[1] <= 0.01
        rows.append(Row(f"plant: {name}, closed loop [steps/s]; friction error",
                        f"{fmt_rate(rate)} (CPU {fmt_rate(rate_c)}), {n / 1e6:.1f} M steps; "
                        f"error {100 * err[1]:.3f} %",
                        f"Radau rtol 1e-10 {fmt_rate(rate_ref)} (wall)", f"{rate / rate_ref:,.0f}x (wall)",
                        ">= 10 M/s, <= 1 %", ok, tk.load,
                        f"validation_ptp (1 h) at {plant.sensors.sample_rate:g} Hz" if not quick else ""))
    return rows


# ---------------------------------------------------------------------------------------------------
# reading


def fig_read(quick: bool, repeat: int) -> list[Row]:
    import pandas as pd
    import pyarrow.parquet as pq
    from bench_io import make_table

    from frictid.io.logs import read_logs

    minutes, csv_minutes = size(quick, (60.0, 10.0), (10.0, 2.0), (0.2, 0.1))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        table = make_table(minutes, 6)
        nrows = table.num_rows
        files = {"snappy": str(Path(tmp) / "log.parquet")}
        pq.write_table(table, files["snappy"])
        if not quick:
            files["zstd"] = str(Path(tmp) / "log-zstd.parquet")
            pq.write_table(table, files["zstd"], compression="zstd")
        del table
        for comp, f in files.items():
            read_logs(f)
            tb, tf = timed_pair(lambda: pq.read_table(f), lambda: read_logs(f), repeat)
            pk_b = child_peak(f"import pyarrow.parquet as pq; pq.read_table({f!r})")
            pk_f = child_peak(f"from frictid.io.logs import read_logs; read_logs({f!r})")
            r = tf.wall / tb.wall
            rows.append(Row(f"read: Parquet ({comp}), {nrows / 1e6:.1f} M rows x 8 columns, read and validate",
                            f"{tf.wall:.2f} s (CPU {tf.cpu:.2f} s), peak {gb(pk_f)}",
                            f"read_table {tb.wall:.2f} s (CPU {tb.cpu:.2f} s), peak {gb(pk_b)}",
                            f"{r:.2f}x (CPU {tf.cpu / tb.cpu:.2f}x)", "<= 2x", r <= 2.0, tf.load,
                            "6 joints (long format), 2 of the 8 columns unused by frictid; peaks are whole "
                            "fresh processes (interpreter and imports included)" if comp == "snappy" else ""))
        # which columns does read_logs ask Parquet for?
        asked: set = set()
        origs = {m: getattr(pq.ParquetFile, m) for m in ("read", "read_row_group", "read_row_groups",
                                                          "iter_batches")}

        def spy(method):
            def f(self, *a, **kw):
                cols_ = kw.get("columns")
                if cols_ is None and method == "read" and a:
                    cols_ = a[0]
                if cols_ is None and method != "read" and len(a) > 1:
                    cols_ = a[1]
                asked.update(cols_ if cols_ is not None else ["<every column>"])
                return origs[method](self, *a, **kw)
            return f

        for m in origs:
            setattr(pq.ParquetFile, m, spy(m))
        try:
            read_logs(files["snappy"])
        finally:
            for m, fn in origs.items():
                setattr(pq.ParquetFile, m, fn)
        cols = sorted(asked)
        skipped = sorted({"motor_current", "status"} - asked)
        rows.append(Row("read: columns not needed are not read", f"asked Parquet for {', '.join(cols)}", "-",
                        "-", "motor_current, status not read", skipped == ["motor_current", "status"], load()))
        ctab = make_table(csv_minutes, 6)
        csvf = str(Path(tmp) / "log.csv")
        ctab.to_pandas().to_csv(csvf, index=False)
        crow = ctab.num_rows
        del ctab
        read_logs(csvf)
        tpd, tfc = timed_pair(lambda: pd.read_csv(csvf, engine="c"), lambda: read_logs(csvf), repeat)
        r = tfc.wall / tpd.wall
        rows.append(Row(f"read: CSV, {crow / 1e6:.1f} M rows x 8 columns, read and validate",
                        f"{tfc.wall:.2f} s (CPU {tfc.cpu:.2f} s)", f"pandas C reader {tpd.wall:.2f} s "
                        f"(CPU {tpd.cpu:.2f} s)", f"{r:.2f}x (CPU {tfc.cpu / tpd.cpu:.2f}x)", "<= 1.5x",
                        r <= 1.5, tfc.load))
    return rows


# ---------------------------------------------------------------------------------------------------
# normal equations


def fig_normal_equations(quick: bool, repeat: int) -> list[Row]:
    from frictid.identify.regression import accumulate, column, solve

    n = size(quick, 10_000_000, 1_000_000, 20_000)
    names = ("J", "c0", "c1", "c2", "c3", "Px", "Py")
    rng = np.random.default_rng(0)
    t = np.arange(n) * 1e-3
    q = 0.8 * np.sin(2 * np.pi * t / 7.0)
    w = np.gradient(q, t)
    a = np.gradient(w, t)
    true = np.array([12.0, 45.0, 30.0, -4.0, 1.5, 350.0, 40.0])
    tau = sum(c * column(nm, q, w, a, None) for c, nm in zip(true, names)) + rng.normal(0, 1.0, n)

    def chunked():
        ne = accumulate([(0, n)], names, q, w, a, tau)[0]
        return solve(ne, names).coef

    def dense():
        X = np.column_stack([column(nm, q, w, a, None) for nm in names])
        return np.linalg.lstsq(X, tau, rcond=None)[0]

    def peak(fn):
        tracemalloc.start()
        fn()
        p = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return p

    tc, td = timed_pair(chunked, dense, repeat)
    tc.result, td.result = chunked(), dense()
    pc, pd_ = peak(chunked), peak(dense)
    agree = float(np.max(np.abs(tc.result - td.result) / np.abs(td.result)))
    return [Row(f"least squares: {n / 1e6:.0f} M samples x 7 regressors",
                f"chunked normal equations {tc.wall:.2f} s (CPU {tc.cpu:.2f} s), {gb(pc)}",
                f"np.linalg.lstsq {td.wall:.2f} s (CPU {td.cpu:.2f} s), {gb(pd_)}",
                f"{td.wall / tc.wall:.1f}x faster (CPU {td.cpu / tc.cpu:.1f}x), {pd_ / max(pc, 1):.0f}x less memory",
                "faster and smaller than lstsq", tc.wall < td.wall and pc < pd_, tc.load,
                f"frictid.identify.regression.accumulate + solve; coefficients agree with lstsq to {agree:.1e} "
                "(relative); memory by tracemalloc (numpy allocations)")]


# ---------------------------------------------------------------------------------------------------
# fit and report on a long log

#: One pass of every experiment kind on the geared industrial joint: about 8 minutes at 1 kHz, cut to
#: 7.5 minutes (so that 8 passes are one hour).
PASS = [
    {"kind": "multisine", "duration": 60.0, "f0": 0.1, "harmonics": 5, "velocity": 0.7, "rest": 1.0},
    {"kind": "constant_velocity", "velocities": {"min": 0.01, "max": 0.95, "count": 10, "spacing": "log"},
     "relative": True, "signs": "both", "plateau": 3.0, "min_plateau": 0.5, "accel": 0.5, "gap": 0.3,
     "rest": 1.0},
    {"kind": "ramp_presliding", "peaks": [0.3, 0.6], "relative": True, "signs": "both", "ramp_up": 3.0,
     "hold": 1.0, "ramp_down": 3.0, "settle": 1.0, "rest": 1.0},
    {"kind": "torque_steps", "levels": [0.3, 0.6], "relative": True, "signs": "both", "hold": 0.5,
     "release": 0.3, "settle": 0.5, "rest": 1.0},
    {"kind": "duty_cycle", "duty": 0.5, "cycles": 5, "cycle_time": 60.0, "slots": 4, "rest": 2.0},
]
PASS_MINUTES = 7.5


def pass_recipe(passes: int) -> dict:
    return {"name": f"bench_passes_{passes}", "description": f"{passes} pass(es) of every experiment kind",
            "default_plant": "geared_industrial", "temp_env": 25.0, "start_rest": 1.0,
            "experiments": PASS * passes}


def build_log(path: str, passes: int, joints: int, scale: float = 1.0) -> int:
    """Long-format Parquet log: ``joints`` joints (plant runs with seeds 0..), each ``passes`` passes of
    every experiment kind at 1 kHz cut to ``passes * PASS_MINUTES * scale`` minutes, as a drive records
    them (t, q, qd, tau, references, ambient; no truth). Returns the row count."""
    import yaml

    from frictid.data import JointLog
    from frictid.io.logs import write_logs
    from frictid.plant import simulate_recipe

    with tempfile.TemporaryDirectory() as tmp:
        rp = Path(tmp) / "recipe.yaml"
        rp.write_text(yaml.safe_dump(pass_recipe(passes)))
        logs = []
        for i in range(joints):
            lg = simulate_recipe(str(rp), seed=i, duration_scale=scale)[0]
            n = int(round(passes * PASS_MINUTES * scale * 60.0 / lg.dt))
            if lg.n < n:
                raise RuntimeError(f"the recipe runs {lg.n * lg.dt / 60:.2f} min, less than {n * lg.dt / 60:.2f}")
            logs.append(JointLog(joint=f"j{i + 1}", t=lg.t[:n], tau=lg.tau[:n], q=lg.q[:n], qd=lg.qd[:n],
                                 channels={k: v[:n] for k, v in lg.channels.items()}, axis=lg.axis,
                                 meta=dict(lg.meta)))
            del lg
    write_logs(logs, path, "parquet")
    return sum(lg.n for lg in logs)


def fig_fit_report(quick: bool, repeat: int, keep: str | None = None) -> list[Row]:
    import pyarrow.parquet as pq

    joints, scale = size(quick, (6, 1.0), (2, 0.25), (1, 0.02))
    work = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="frictid-runall-"))
    work.mkdir(parents=True, exist_ok=True)
    logs = {}
    for passes in (1, 8):
        f = work / f"fit_{joints}j_{passes}p_{scale:g}_v2.parquet"
        if not f.exists():
            rows_ = build_log(str(f), passes, joints, scale)
            print(f"  built {f.name}: {rows_:,} rows, {f.stat().st_size / 1e6:.0f} MB", file=sys.stderr)
        logs[passes] = f
    big, small = logs[8], logs[1]
    nbig = pq.ParquetFile(big).metadata.num_rows
    nsmall = pq.ParquetFile(small).metadata.num_rows
    hours = nbig / joints / 1000 / 3600
    # the bare read twice: repeated in this process (the first run cold; the earlier rounds' baseline), and
    # in fresh processes as the fit runs (imports untimed), the stricter of the two judging the ratio. The
    # fresh reads alternate with the fits: on this VM both are dominated at times by the system time of
    # first-touched memory (a fresh read_table of this file took 0.7-4.7 s within one hour), and
    # alternating lets both see the same state of the machine
    tread_in = timed(lambda: pq.read_table(big), repeat)
    reads, big_fits = [], []
    for _ in range(max(1, repeat)):
        reads.append(timed_child("import pyarrow.parquet as pq", f"pq.read_table({str(big)!r})", 1))
        big_fits.append(run_child(["frictid", "fit", str(big), "-o", str(work / "params_8.yaml")], interval=1.0))
        if big_fits[-1].returncode:
            print(big_fits[-1].stderr[-3000:], file=sys.stderr)
    tread = sorted(reads, key=lambda x: x.wall)[len(reads) // 2]
    fb = sorted(big_fits, key=lambda x: x.wall)[len(big_fits) // 2]
    fb.peak = max(x.peak for x in big_fits)
    fb.returncode = max(x.returncode for x in big_fits)
    if tread_in.wall < tread.wall:
        tread, tread_in = tread_in, tread
    fs = run_child(["frictid", "fit", str(small), "-o", str(work / "params_1.yaml")], interval=1.0)
    if fs.returncode:
        print(fs.stderr[-3000:], file=sys.stderr)
    r = fb.wall / tread.wall
    rows = [
        Row(f"fit end to end: {joints} joints x {hours:.2f} h at 1 kHz ({nbig / 1e6:.1f} M rows)",
            f"{fb.wall:.0f} s (CPU {fb.cpu:.0f} s), exit {fb.returncode}",
            f"read_table {tread.wall:.2f} s (CPU {tread.cpu:.2f} s); the other way {tread_in.wall:.2f} s",
            f"{r:.0f}x (CPU {fb.cpu / tread.cpu:.0f}x; {fb.wall / tread_in.wall:.0f}x the other)",
            "<= 20x",
            r <= 20 and fb.returncode == 0, fb.load,
            "every experiment kind, 8 passes of 7.5 min per joint (geared_industrial, thermal6, "
            "seeds per joint); `frictid fit LOG -o PARAMS` in a fresh process (segments, all models, "
            f"diagnosis), median of {len(big_fits)} runs (" + ", ".join(f"{x.wall:.1f}" for x in big_fits)
            + " s), against a bare read_table of the same file timed two ways, median of "
            f"{repeat} each: in fresh processes (imports untimed) alternating with the fits ("
            + ", ".join(f"{x.wall:.2f}" for x in reads) + " s), and repeated in one process (the first read "
            "cold); the ratio is judged against the faster of the two"),
        Row("fit peak memory", gb(fb.peak), "-", "-", "<= 3 GB", fb.peak <= 3e9, fb.load,
            "the largest over the fit's runs of the process's high-water resident set (VmHWM), or, with "
            "worker processes, the sum of their proportional set sizes (Pss: pages shared copy-on-write with "
            "the parent counted once) sampled every 1 s (every 0.1 s slowed the measured processes), when "
            "larger"),
        Row("fit scaling: 8x the data", f"{fb.wall:.0f} s vs {fs.wall:.0f} s (CPU {fb.cpu:.0f} vs {fs.cpu:.0f} s)",
            f"1 pass, {nsmall / 1e6:.2f} M rows", f"{fb.cpu / fs.cpu:.1f}x CPU (wall {fb.wall / fs.wall:.1f}x) "
            f"for {nbig / nsmall:.1f}x rows", "<= 9x", fb.cpu / fs.cpu <= 9 * (nbig / nsmall) / 8, fs.load,
            "the small run's time is mostly fixed costs (imports, compilation caches, optimiser starts) when "
            "the ratio is far below 8"),
        Row("fit: joints in parallel (CPU time / wall time)", f"{fb.cpu / fb.wall:.2f}", "-", "-",
            f"about {os.cpu_count()} on an idle machine", None, fb.load,
            "CPU / wall <= 1 means one core; under a load above the core count this ratio is also "
            "capped by the share the process gets"),
    ]
    if fb.returncode == 0:
        html = work / "report.html"
        cmd = ["frictid", "report", str(work / "params_8.yaml"), str(big), "-o", str(html)]
        runs = [run_child(cmd, interval=None) for _ in range(max(1, repeat))]  # timed without sampling
        rr = sorted(runs, key=lambda x: x.wall)[len(runs) // 2]  # the median run by wall time
        rr.peak = run_child(cmd).peak  # the peak memory from one more run, sampled every 0.1 s
        html_bytes = html.stat().st_size if html.exists() else 0
        ok = all(x.returncode == 0 for x in runs)
        rows.append(Row(f"report: {joints} joints x {hours:.2f} h", f"{rr.wall:.1f} s (CPU {rr.cpu:.0f} s), "
                        f"{html_bytes / 1e6:.2f} MB, peak {gb(rr.peak)}, exit {rr.returncode}", "-", "-",
                        "< 10 s, < 5 MB", ok and rr.wall < 10 and html_bytes < 5e6, rr.load,
                        "`frictid report PARAMS LOG -o REPORT.html` in a fresh process, joints built in "
                        "parallel (one worker per core): judged on the median wall time of "
                        f"{len(runs)} runs (" + ", ".join(f"{x.wall:.1f}" for x in runs) + " s) timed without "
                        "memory sampling, CPU time summed over the workers; the peak from one more run "
                        "sampled every 0.1 s"))
        for x in runs:
            if x.returncode:
                print(x.stderr[-3000:], file=sys.stderr)
    return rows


# ---------------------------------------------------------------------------------------------------

FIGURES = {
    "replay": fig_replay,
    "replay_e2e": fig_replay_e2e,
    "plant": fig_plant,
    "read": fig_read,
    "normal_equations": fig_normal_equations,
    "fit": fig_fit_report,
}


def header(m: dict, quick: bool, seconds: float) -> str:
    la = m["load"]
    return (f"{'quick run (small sizes)' if quick else 'full run'}, {m['date']}, commit {m['commit']}, "
            f"{seconds / 60:.0f} min\n\n"
            f"machine: {m['nproc']} CPUs ({m['cpu']}), {m['memory'] / 2**30:.0f} GiB, load average at the end "
            f"{la[0]:.1f} / {la[1]:.1f} / {la[2]:.1f} (1 / 5 / 15 min); python {m['python']}, numpy "
            f"{m['numpy']}, numba {m['numba']}, pyarrow {m['pyarrow']}")


def write_docs(text: str) -> None:
    doc = DOCS.read_text() if DOCS.exists() else f"# Benchmarks\n\n{MARK_START}\n{MARK_END}\n"
    a, b = doc.index(MARK_START), doc.index(MARK_END)
    DOCS.write_text(doc[:a + len(MARK_START)] + "\n" + text + "\n" + doc[b:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (a few minutes)")
    ap.add_argument("--only", help=f"comma list of figures: {', '.join(FIGURES)}")
    ap.add_argument("--repeat", type=int, default=None, help="runs per timing (default 3, quick 3)")
    ap.add_argument("--keep", help="folder for the generated logs (reused when present), fit and report")
    ap.add_argument("--write-docs", action="store_true", help=f"replace the table in {DOCS.relative_to(ROOT)}")
    ap.add_argument("--json", help="also write the rows as JSON to this file")
    a = ap.parse_args(argv)
    repeat = 1 if SMOKE else a.repeat or 3
    a.keep = os.path.abspath(a.keep) if a.keep else None  # the timed children run in the repository's root
    names = [s.strip() for s in a.only.split(",")] if a.only else list(FIGURES)
    unknown = set(names) - set(FIGURES)
    if unknown:
        ap.error(f"unknown figure(s) {', '.join(sorted(unknown))}; known: {', '.join(FIGURES)}")
    t0 = time.perf_counter()
    rows: list[Row] = []
    for nm in names:
        print(f"== {nm} (load {load():.1f})", file=sys.stderr, flush=True)
        t1 = time.perf_counter()
        fn = FIGURES[nm]
        got = fn(a.quick, repeat, a.keep) if nm == "fit" else fn(a.quick, repeat)
        rows.extend(got)
        print(table(got), file=sys.stderr)
        print(f"   ({time.perf_counter() - t1:.0f} s)", file=sys.stderr, flush=True)
    text = header(machine(), a.quick, time.perf_counter() - t0) + "\n\n" + table(rows)
    print(text)
    if a.write_docs and SMOKE:
        print(f"(FRICTID_SMOKE=1: {DOCS.relative_to(ROOT)} left as it is)", file=sys.stderr)
    elif a.write_docs:
        write_docs(text)
    if a.json:
        Path(a.json).write_text(json.dumps([r.__dict__ for r in rows], indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
