"""Throughput of the fleet fit (docs/fleet.md): N partitions of ~1-minute logs fitted serially
(``--engine serial``) and on a distributed.LocalCluster with 1 and 2 worker processes.

Prints per run the wall time, the speed-up over serial, the overhead per partition of the Dask path
against the serial one (1 worker: (T_dask - T_serial) / N, as a share of a partition's mean fit time;
target < 10 %), and each worker's peak resident memory against the memory of one partition's log.

    python benchmarks/bench_fleet.py                 # 8 partitions of ~60 s at 500 Hz
    python benchmarks/bench_fleet.py --partitions 4 --seconds 15

With FRICTID_SMOKE=1 (the test of the documented commands) it runs 2 partitions of ~10 s on 1 worker.
"""
from __future__ import annotations

import argparse
import logging
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from distributed import Client, LocalCluster  # noqa: E402

from fleet_synth import plan_fleet, write_fleet  # noqa: E402
from frictid.fleet.dataset import Partition  # noqa: E402
from frictid.fleet.run import FitOptions, fit_partition, run_fleet  # noqa: E402
from frictid.fleet.store import TrendStore  # noqa: E402
from frictid.io.logs import read_logs  # noqa: E402

OPTIONS = FitOptions(models="stribeck", diagnose=False)


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def warm(path: str) -> None:
    """A worker's first fit loads frictid and its compiled kernels (numba cache): once per worker."""
    fit_partition(Partition((("file", path),), (path,)), "warm-up", OPTIONS)


def busy_seconds(store: Path) -> float:
    """The time the partitions' fits took inside their tasks (read and fit) [s]."""
    return float(TrendStore(store).latest().drop_duplicates("partition")["fit_seconds"].sum())


def run_dask(data: Path, store: Path, workers: int, first: str) -> tuple[float, float, list[float]]:
    """(start-up and warm-up time, fit time, each worker's peak RSS [MB])."""
    t0 = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cluster:  # (as frictid.fleet.run's cluster)
        with Client(cluster) as client:
            client.run(warm, first)
        t1 = time.perf_counter()
        run = run_fleet([str(data)], str(store), engine="dask", scheduler=cluster.scheduler_address, options=OPTIONS)
        t2 = time.perf_counter()
        with Client(cluster) as client:
            rss = list(client.run(peak_rss_mb).values())
    assert not run.failed, run.failed
    return t1 - t0, t2 - t1, rss


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--partitions", type=int, default=8)
    ap.add_argument("--seconds", type=float, default=60.0, help="approximate log length [s]")
    ap.add_argument("--seed", type=int, default=100001)
    a = ap.parse_args(argv)
    smoke = os.environ.get("FRICTID_SMOKE") == "1"  # the docs test: the same path, 2 short partitions, 1 worker
    if smoke:
        a.partitions, a.seconds = 2, 10.0
    # 5 speeds x 2 signs, 0.6 s plateaus: ~15 s; the plateau length scales the log
    plateau = max(0.6 * a.seconds / 15.0, 0.4)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        plan = plan_fleet(1, 1, a.partitions, seed=a.seed, kinds=["noise"])
        files = write_fleet(tmp / "data", plan, a.partitions, seed=a.seed, plateau=plateau,
                            velocities=5 if a.seconds < 30 else 10)
        log = read_logs(str(files[0]))[0]
        log_mb = sum(x.nbytes for x in (log.t, log.q, log.qd, log.tau, *log.channels.values())) / 2**20
        warm(str(files[0]))  # the serial run's process warmed up as the workers are
        t0 = time.perf_counter()
        serial = run_fleet([str(tmp / "data")], str(tmp / "s0"), engine="serial", options=OPTIONS)
        t_serial = time.perf_counter() - t0
        per = t_serial / a.partitions
        fit_mean = busy_seconds(tmp / "s0") / a.partitions
        print(f"{a.partitions} partitions of {log.t[-1]:.0f} s at {1 / log.dt:.0f} Hz ({log.n} samples, "
              f"{log_mb:.1f} MB in memory); mean fit {fit_mean:.2f} s")
        print(f"serial: {t_serial:.1f} s ({per:.2f} s per partition, store writes included; outside the fits "
              f"{(t_serial - busy_seconds(tmp / 's0')) / a.partitions:.3f} s per partition); failed {len(serial.failed)}")
        for w in (1,) if smoke else (1, 2):
            start, t, rss = run_dask(tmp / "data", tmp / f"d{w}", w, str(files[0]))
            over = (t - t_serial) / a.partitions
            busy = busy_seconds(tmp / f"d{w}")
            inside = (t * w - busy) / a.partitions  # worker time not spent fitting, per partition
            print(f"dask {w} worker{'s' if w > 1 else ''}: start-up and warm-up {start:.1f} s, fit {t:.1f} s, speed-up "
                  f"{t_serial / t:.2f}x; against serial {over:+.3f} s per partition = {over / fit_mean:+.1%} of a "
                  f"fit; worker time outside the fits {inside:.3f} s per partition = {inside / (busy / a.partitions):.1%}"
                  f" of a fit{' (target < 10 %)' if w == 1 else ''}; worker peak RSS "
                  + ", ".join(f"{r:.0f} MB" for r in rss))
    return 0


if __name__ == "__main__":
    sys.exit(main())
