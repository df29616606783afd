"""End-to-end benchmark of frictid fit on a 6-joint, 1 kHz, 1-hour log (21.6 M rows), with peak memory.

    python benchmarks/bench_fit.py [--hours 1.0] [--joints 6] [--keep FILE.parquet]

Builds the log by simulating the geared industrial plant's recipes (sweep, multi-sine, ramps, steps,
duty cycles) and repeating them to the requested length for each joint, writes it as Parquet, then times
``frictid fit LOG -o PARAMS.yaml`` in a fresh process (read, segment, fit, write) and reports its peak
resident memory (``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``). Not run in CI: it takes minutes.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
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
    ap.add_argument("--keep", default=None, help="keep (or reuse) the generated log at this path")
    args = ap.parse_args(argv)
    tmp = tempfile.mkdtemp(prefix="frictid-bench-")
    log = args.keep or os.path.join(tmp, "bench.parquet")
    if not os.path.exists(log):
        t0 = time.time()
        rows = build_log(log, args.hours, args.joints)
        print(f"built {rows:,} rows in {time.time() - t0:.0f} s -> {log} ({os.path.getsize(log) / 1e6:.0f} MB)")
    out = os.path.join(tmp, "params.yaml")
    t0 = time.time()
    r = subprocess.run([sys.executable, "-m", "frictid", "fit", log, "-o", out], capture_output=True, text=True)
    wall = time.time() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(r.stderr[-2000:])
    print(f"frictid fit: exit {r.returncode}, wall {wall:.1f} s, peak RSS {peak_mb:.0f} MB "
          f"({args.joints} joints x {args.hours:g} h at 1 kHz)")
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
