"""Reading and validating a log against the read floor (issue: fast on long logs).

Prints, for a long-format 6-joint log at 1 kHz: a bare ``pyarrow.parquet.read_table`` of the file, frictid's
``read_logs`` (column projection, validation, split by joint), and for CSV pandas' C reader against
frictid's. Medians of repeated runs; peak memory of the process via ``resource``.

    python benchmarks/bench_io.py [--minutes 60] [--joints 6] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from frictid.io.logs import read_logs


def make_table(minutes: float, joints: int, rate: float = 1000.0) -> pa.Table:
    n = int(minutes * 60 * rate)
    t = np.arange(n) / rate
    rng = np.random.default_rng(0)
    parts = []
    for j in range(joints):
        q = 0.8 * np.sin(2 * np.pi * t / (7 + j))
        parts.append(pa.table({
            "t": t, "joint": pa.array(np.full(n, j + 1, dtype=np.int32)), "q": q,
            "qd": np.gradient(q, t), "tau": 3 * np.tanh(50 * np.gradient(q, t)) + 0.01 * rng.standard_normal(n),
            "temp_env": np.full(n, 21.0), "motor_current": rng.standard_normal(n), "status": np.zeros(n, np.int8),
        }))
    return pa.concat_tables(parts)


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--joints", type=int, default=6)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--csv-minutes", type=float, default=10.0, help="CSV is slower to write; a shorter log")
    args = ap.parse_args()
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.minutes, args.joints, args.repeat, args.csv_minutes = 0.2, 2, 1, 0.1
    with tempfile.TemporaryDirectory() as tmp:
        table = make_table(args.minutes, args.joints)
        rows = table.num_rows
        pqf = str(Path(tmp) / "log.parquet")
        pq.write_table(table, pqf)
        del table
        bare = median_time(lambda: pq.read_table(pqf), args.repeat)
        ours = median_time(lambda: read_logs(pqf), args.repeat)
        print(f"| parquet, {rows / 1e6:.1f} M rows x 8 columns | bare read_table {bare:.2f} s | "
              f"frictid read_logs {ours:.2f} s | ratio {ours / bare:.2f} (target <= 2) |")
        ctab = make_table(args.csv_minutes, args.joints)
        csvf = str(Path(tmp) / "log.csv")
        ctab.to_pandas().to_csv(csvf, index=False)
        crow = ctab.num_rows
        del ctab
        pdc = median_time(lambda: pd.read_csv(csvf, engine="c"), args.repeat)
        oursc = median_time(lambda: read_logs(csvf), args.repeat)
        print(f"| csv, {crow / 1e6:.1f} M rows x 8 columns | pandas C reader {pdc:.2f} s | "
              f"frictid read_logs {oursc:.2f} s | ratio {oursc / pdc:.2f} (target <= 1.5) |")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    print(f"peak memory of this process (includes generating the data): {peak:.2f} GB")


if __name__ == "__main__":
    main()
