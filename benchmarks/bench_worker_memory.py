"""What each joint costs its worker in fresh memory: ``frictid fit`` or ``frictid report`` on run_all's log,
with the stages of every joint measured inside the worker that builds it.

    python benchmarks/bench_worker_memory.py report [--log FILE] [--params FILE] [--runs 3]
    python benchmarks/bench_worker_memory.py fit [--log FILE] [--runs 3]

The log is run_all's hour (6 joints x 8 passes of every experiment kind at 1 kHz; built once, about 4 min,
unless ``--log`` names it, e.g. ``/tmp/ra_keep/fit_6j_8p_1_v2.parquet`` after ``run_all.py --keep
/tmp/ra_keep``); the report's parameter file is fitted first unless ``--params`` names it. Each run is the
command in a fresh process. Printed per joint: the worker, wall time, user and system time, minor page
faults (of the function that builds the joint: the fit's read comes before it), and the worker's private
dirty memory (``Private_Dirty`` of ``/proc/self/smaps_rollup``) before and after the joint; then, for the
first joint of each worker
(the one that touches the worker's memory first), the stages that added private memory.

On this VM the system time of a worker's first joint is mostly the first touch of that memory (the kernel
zeroing it, the host backing it): it moves with the host's state from one minute to the next, so compare
runs that alternate, and the private memory more than the time.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

#: (module, function) of each command's stages, measured on every call in the workers.
STAGES = {
    "report": [("frictid.cli.report", "_read_report_log"), ("frictid.report.content", "prepare_log"),
               ("frictid.report.content", "ramp_curves"), ("frictid.report.content", "thermal_cycles"),
               ("frictid.report.content", "replay_log"), ("frictid.report.content", "diagnosis_residuals"),
               *(("frictid.report.figures", n) for n in ("timeline", "friction_map", "presliding", "thermal",
                                                          "replay", "diagnosis"))],
    "fit": [("frictid.io.logs", "read_logs"), ("frictid.segments", "estimate_scales"),
            ("frictid.segments", "derivatives"), ("frictid.segments", "find_segments"),
            ("frictid.identify.mechanics", "regress"), ("frictid.identify.mechanics", "plateaus"),
            ("frictid.identify.mechanics", "_stage2_map"), ("frictid.identify.dynamics", "fit_lugre"),
            ("frictid.identify.thermal_fit", "fit_thermal_models"), ("frictid.api", "diagnose_fit"),
            ("frictid.api", "check_diagnosis")],
}
#: The function that builds one joint in a worker, per command.
JOINT = {"report": ("frictid.report.build", "_joint_part"), "fit": ("frictid.api", "fit_joint")}


def private_memory() -> int:
    """Private dirty memory of this process [MB]."""
    got = {}
    with open("/proc/self/smaps_rollup") as fh:
        for line in fh:
            parts = line.split()
            if len(parts) >= 3 and parts[2] == "kB":
                got[parts[0].rstrip(":")] = int(parts[1]) // 1024
    return got.get("Private_Dirty", 0)


def _usage() -> tuple[float, float, int]:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime, r.ru_stime, r.ru_minflt


def instrument(command: str, out_path: str) -> None:
    """Wrap the command's stages and its per-joint function (in this process: the forked workers inherit
    the wrappers); every joint appends one JSON line to ``out_path``."""
    import functools
    import importlib

    stages: dict[str, list[float]] = {}  # name -> [+private MB, system s]; nested calls count in both

    def wrap(mod_name: str, name: str, per_joint: bool = False) -> None:
        mod = importlib.import_module(mod_name)
        fn = getattr(mod, name)

        @functools.wraps(fn)
        def wrapper(*a, **kw):
            m0, u0, t0 = private_memory(), _usage(), time.perf_counter()
            try:
                return fn(*a, **kw)
            finally:
                m1, u1 = private_memory(), _usage()
                if per_joint:
                    joint = a[0] if command == "report" else (a[0][0].joint if a[0] else "")
                    rec = {"joint": str(joint), "pid": os.getpid(),
                           "wall": time.perf_counter() - t0, "user": u1[0] - u0[0], "sys": u1[1] - u0[1],
                           "faults": u1[2] - u0[2], "private": [m0, m1],
                           "stages": dict(stages)}
                    with open(out_path, "a") as fh:
                        fh.write(json.dumps(rec) + "\n")
                    stages.clear()  # the next joint's stages start here (the fit reads a joint before fit_joint)
                else:
                    s = stages.setdefault(name, [0.0, 0.0])
                    s[0] += m1 - m0
                    s[1] += u1[1] - u0[1]
        setattr(mod, name, wrapper)

    for mod_name, name in STAGES[command]:
        wrap(mod_name, name)
    wrap(*JOINT[command], per_joint=True)


def child(command: str, args: list[str], out_path: str) -> None:
    """The measured process: the command as the CLI runs it, instrumented."""
    instrument(command, out_path)
    from frictid.cli import main

    sys.argv = ["frictid", command, *args, "-q"]
    main()


def report_rows(lines: list[dict]) -> list[str]:
    out = []
    seen: set[int] = set()
    for r in lines:
        first = r["pid"] not in seen
        seen.add(r["pid"])
        out.append(f"  {r['joint'] or '-':6s} pid {r['pid']:>7d} {'first' if first else '     '} "
                   f"wall {r['wall']:5.2f} s  user {r['user']:5.2f} s  sys {r['sys']:5.2f} s  "
                   f"faults {r['faults'] // 1000:4d} k  private {r['private'][0]:5d} -> {r['private'][1]:5d} MB")
        if first:
            grow = [(n, s) for n, s in r["stages"].items() if s[0] >= 5 or s[1] >= 0.05]
            out.append("         first joint's stages (+private MB / system s): " + ", ".join(
                f"{n} +{s[0]:.0f}/{s[1]:.2f}" for n, s in grow))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("command", choices=("report", "fit"))
    ap.add_argument("--log", help="run_all's 6-joint hour (default: build it)")
    ap.add_argument("--params", help="the report's parameter file (default: fit the log first)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a, rest = ap.parse_known_args(argv)
    smoke = os.environ.get("FRICTID_SMOKE") == "1"  # the docs test: the same code path on a tiny case
    if smoke:
        a.runs = 1
    if a.child:
        child(a.command, rest, a.child)
        return 0
    work = Path(tempfile.mkdtemp(prefix="frictid-wmem-"))
    log = a.log
    if log is None:
        from run_all import build_log

        log = str(work / "fit_6j_8p_1_v2.parquet")
        build_log(log, *((1, 1, 0.02) if smoke else (8, 6)))
    params = a.params
    if a.command == "report" and params is None:
        params = str(work / "params.yaml")
        subprocess.run([sys.executable, "-m", "frictid", "fit", log, "-o", params, "-q"], check=True)
    args = [log, "-o", str(work / "out.yaml")] if a.command == "fit" else [params, log, "-o",
                                                                               str(work / "out.html")]
    print(f"frictid {a.command}: per joint in its worker ({log})")
    for k in range(max(1, a.runs)):
        rec_path = work / f"run{k}.jsonl"
        t0 = time.perf_counter()
        subprocess.run([sys.executable, __file__, a.command, "--child", str(rec_path), *args], check=True)
        wall = time.perf_counter() - t0
        lines = [json.loads(x) for x in rec_path.read_text().splitlines()]
        print(f"run {k + 1}: {wall:.1f} s")
        print("\n".join(report_rows(lines)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
