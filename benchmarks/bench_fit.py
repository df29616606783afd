"""End-to-end benchmark of frictid fit on a 6-joint, 1 kHz, 1-hour log (21.6 M rows), with peak memory.

    python benchmarks/bench_fit.py [--hours 1.0] [--joints 6] [--jobs 0] [--keep FILE.parquet] [--report]

Builds the log by simulating the geared industrial plant's recipes (sweep, multi-sine, ramps, steps,
duty cycles) and repeating them to the requested length for each joint, writes it as Parquet, then times
``frictid fit LOG -o PARAMS.yaml --jobs N`` in a fresh process (read, segment, fit, write) against a bare
``pyarrow.parquet.read_table`` of the same file, with its CPU time and peak memory (``run_all.run_child``:
the process's high-water resident set, or its process tree's summed Pss with worker processes); with
``--report``, ``frictid report`` of that fit and log too. Not run in CI: it takes minutes.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def build_log(path: str, hours: float, joints: int, seed: int = 0) -> int:
    """Write a long-format log of ``joints`` joints x ``hours`` at 1 kHz; returns the row count."""
    from frictid.data import JointLog
    from frictid.io.logs import write_logs
    from frictid.plant import simulate_recipe

    plant = str(ROOT / "recipes/plants/geared_industrial.yaml")
    base = []
    for i, r in enumerate(("constant_velocity_sweep", "multisine", "ramp_presliding", "torque_steps")):
        base += simulate_recipe(str(ROOT / f"recipes/{r}.yaml"), plant=plant, seed=seed + i)
    base += simulate_recipe(str(ROOT / "recipes/duty_cycle.yaml"), plant=plant, seed=seed + 9, duration_scale=0.1)
    n_target = int(hours * 3600 * 1000)
    logs = []
    for j in range(joints):
        parts = {k: [] for k in ("tau", "q", "qd", "temp_env")}
        n, t_off = 0, 0.0
        k = 0
        while n < n_target:
            lg = base[k % len(base)]
            take = min(lg.n, n_target - n)
            parts["tau"].append(lg.tau[:take])
            parts["q"].append(lg.q[:take])
            parts["qd"].append(lg.qd[:take] if lg.qd is not None else np.gradient(lg.q[:take], lg.t[:take]))
            parts["temp_env"].append(lg.channels.get("temp_env", np.full(lg.n, 25.0))[:take])
            n += take
            k += 1
        t = np.arange(n_target) * 1e-3
        logs.append(JointLog(joint=f"j{j + 1}", t=t, tau=np.concatenate(parts["tau"]),
                             q=np.concatenate(parts["q"]), qd=np.concatenate(parts["qd"]),
                             channels={"temp_env": np.concatenate(parts["temp_env"])}, meta={"sample_rate": 1000.0}))
    write_logs(logs, path, "parquet")
    return n_target * joints


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--joints", type=int, default=6)
    ap.add_argument("--jobs", type=int, default=0, help="frictid fit --jobs (0: one per core)")
    ap.add_argument("--keep", default=None, help="keep (or reuse) the generated log at this path")
    ap.add_argument("--report", action="store_true", help="also time frictid report on the fit and the log")
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.hours, args.joints = 0.02, 1
    import pyarrow.parquet as pq

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from run_all import load, run_child, timed

    tmp = tempfile.mkdtemp(prefix="frictid-bench-")
    log = args.keep or os.path.join(tmp, "bench.parquet")
    if not os.path.exists(log):
        t0 = time.time()
        rows = build_log(log, args.hours, args.joints)
        print(f"built {rows:,} rows in {time.time() - t0:.0f} s -> {log} ({os.path.getsize(log) / 1e6:.0f} MB)")
    rows = pq.ParquetFile(log).metadata.num_rows
    read = timed(lambda: pq.read_table(log), 1)
    out = os.path.join(tmp, "params.yaml")
    r = run_child(["frictid", "fit", log, "-o", out, "--jobs", str(args.jobs)])
    if r.returncode:
        print(r.stderr[-2000:])
    print(f"frictid fit --jobs {args.jobs}: exit {r.returncode}, wall {r.wall:.1f} s, CPU {r.cpu:.1f} s "
          f"(CPU / wall {r.cpu / r.wall:.2f}), peak {r.peak / 1e9:.2f} GB; bare read_table {read.wall:.2f} s "
          f"(CPU {read.cpu:.2f} s): {r.wall / read.wall:.0f}x the read ({rows / 1e6:.1f} M rows, load {load():.1f})")
    if args.report and r.returncode == 0:
        html = os.path.join(tmp, "report.html")
        rr = run_child(["frictid", "report", out, log, "-o", html])
        size = os.path.getsize(html) if os.path.exists(html) else 0
        print(f"frictid report: exit {rr.returncode}, wall {rr.wall:.1f} s, CPU {rr.cpu:.1f} s, "
              f"{size / 1e6:.2f} MB, peak {rr.peak / 1e9:.2f} GB (load {rr.load:.1f})")
        if rr.returncode:
            print(rr.stderr[-2000:])
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
