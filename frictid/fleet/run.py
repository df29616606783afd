"""The fit of one partition, and the loop over a dataset's partitions: serial, or one Dask task per
partition on a ``distributed.LocalCluster`` (default) or the cluster at a scheduler address.

Both paths call :func:`fit_partition` on the same partitions with the same options, so their stores hold
the same numbers. A partition that fails to read or fit is recorded with its reason; the others go on.
"""
from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from distributed import Client, LocalCluster, as_completed

from ..api import fit as frictid_fit
from ..errors import FrictidInputError
from ..io.logs import read_logs
from ..result import FitResult
from ..version import __version__
from .dataset import KeySpec, Partition, find_partitions
from .level import covariance_from_json, covariance_json, level_with_stderr
from .store import TrendStore

#: Outcomes written to the store at a time (an interrupted run keeps what was written).
FLUSH_EVERY = 256


@dataclass(frozen=True)
class FitOptions:
    """What ``frictid fit`` is asked besides the logs; part of every partition's content hash."""

    models: str | None = None
    diagnose: bool = True
    mapping: str | None = None
    units: str | None = None

    def salt(self) -> str:
        return f"frictid {__version__}|models={self.models}|diagnose={self.diagnose}|map={self.mapping}|units={self.units}"


@dataclass
class Outcome:
    """What the fit of one partition gave: the result, or why there is none (``kind``: "input" for bad
    input, "internal" for a bug), and the logs' ranges the trend needs, per joint."""

    partition: Partition
    digest: str
    result: FitResult | None = None
    kind: str = ""
    reason: str = ""
    stats: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.result is not None


def log_stats(log) -> dict:
    """Ranges of one joint's log: samples, duration [s], the speed reached (99th percentile of |qd|
    [q/s]) and the mean, lowest and highest temperature [degC] (joint temperature if logged, else the
    ambient; NaN when neither)."""
    qd = log.qd if log.qd is not None else np.gradient(log.q, log.t)
    temp = log.channels.get("temp_joint", log.channels.get("temp_env"))
    temp = np.asarray(temp, dtype=float) if temp is not None else np.full(1, np.nan)
    temp = temp[np.isfinite(temp)] if np.isfinite(temp).any() else np.full(1, np.nan)
    return {"n_samples": int(log.n), "duration": float(log.t[-1] - log.t[0]),
            "speed_hi": float(np.percentile(np.abs(qd[np.isfinite(qd)]), 99)) if np.isfinite(qd).any() else np.nan,
            "temp_mean": float(np.mean(temp)), "temp_lo": float(np.min(temp)), "temp_hi": float(np.max(temp))}


def run_level(jf, speed_hi: float) -> dict:
    """The run's own ``F_ref`` (at half its highest speed, the thermal law's reference temperature) with its
    standard error, and the selected model's covariance, as the store keeps them (:mod:`.level`)."""
    mf = jf.models.get(jf.selected) if jf.selected else None
    out = {"F_ref": np.nan, "F_ref_stderr": np.nan, "F_ref_speed": np.nan, "F_ref_temp": np.nan,
           "F_ref_reason": "no model selected" if mf is None else "", "cov": covariance_json(mf)}
    if mf is None or not np.isfinite(speed_hi) or speed_hi <= 0:
        out["F_ref_reason"] = out["F_ref_reason"] or "the log reached no speed"
        return out
    lv = level_with_stderr(jf, jf.selected, 0.5 * speed_hi, None, covariance_from_json(out["cov"]))
    m = jf.friction_model(jf.selected)
    out.update(F_ref=lv["value"], F_ref_stderr=lv["stderr"], F_ref_speed=0.5 * speed_hi, F_ref_reason=lv["reason"],
               F_ref_temp=m.thermal["T0"] if m.thermal else np.nan)
    return out


def fit_partition(part: Partition, digest: str, options: FitOptions) -> Outcome:
    """Read a partition's logs and fit them (one process: ``jobs=1``). Never raises: a failure is the
    outcome's ``kind`` and ``reason``."""
    t0 = time.perf_counter()
    out = Outcome(part, digest)
    try:
        logs = [lg for f in part.files for lg in read_logs(f, mapping=options.mapping, units=options.units)]
        out.stats = {lg.joint: log_stats(lg) for lg in logs}
        out.result = frictid_fit(logs, models=options.models, mapping=options.mapping, units=options.units,
                                 diagnose=options.diagnose, jobs=1)
        for j, jf in out.result.joints.items():
            out.stats.setdefault(j, {}).update(run_level(jf, out.stats.get(j, {}).get("speed_hi", np.nan)))
    except FrictidInputError as exc:
        out.kind, out.reason = "input", str(exc)
    except Exception as exc:  # noqa: BLE001 - one partition's bug must not stop the fleet; it is reported
        out.kind, out.reason = "internal", f"{exc.__class__.__name__}: {exc}"
    out.seconds = time.perf_counter() - t0
    return out


@dataclass
class FleetRun:
    """Summary of one ``frictid fit --engine dask`` run."""

    total: int = 0
    skipped: int = 0
    fitted: int = 0
    failed: list[Outcome] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def bad_input(self) -> list[Outcome]:
        return [o for o in self.failed if o.kind == "input"]

    @property
    def internal(self) -> list[Outcome]:
        return [o for o in self.failed if o.kind != "input"]


def _outcomes_serial(todo, options):
    for part, digest in todo:
        yield fit_partition(part, digest, options)


def _outcomes_dask(todo, options, scheduler: str | None, workers: int):
    """One task per partition; outcomes as they complete. A local cluster of ``workers`` processes with
    one thread each (memory per worker: one partition), or the cluster at ``scheduler``."""
    with contextlib.ExitStack() as stack:
        if scheduler:
            client = stack.enter_context(Client(scheduler))
        else:
            # (its workers' and scheduler's own log lines off: a task's failure reaches the user as its outcome,
            # and a heartbeat that meets the closing scheduler at shutdown logs a traceback that means nothing)
            cluster = stack.enter_context(LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                       dashboard_address=":0", silence_logs=logging.CRITICAL))
            client = stack.enter_context(Client(cluster))
        futures = client.map(fit_partition, [p for p, _ in todo], [d for _, d in todo], options=options,
                             key=[f"frictid-fit-{d}-{i}" for i, (_, d) in enumerate(todo)], pure=False)
        for fut in as_completed(futures):
            try:
                yield fut.result()
            except Exception as exc:  # noqa: BLE001 - a worker lost or a task that could not run
                i = futures.index(fut)
                yield Outcome(todo[i][0], todo[i][1], kind="internal", reason=f"{exc.__class__.__name__}: {exc}")
            fut.release()


def run_fleet(sources: list[str], store: str, *, engine: str = "dask", scheduler: str | None = None,
              workers: int = 2, options: FitOptions = FitOptions(), keys: KeySpec | None = None,
              progress: Callable[[int, int, Outcome], None] | None = None) -> FleetRun:
    """Fit every partition of a dataset whose inputs changed since the store last saw them; write their
    parameter files and rows into the store. ``engine``: "dask" or "serial" (same numbers). ``keys``: the
    keys that make a partition (joint keys and the time key; default every ``name=value`` level)."""
    t0 = time.perf_counter()
    if engine not in ("dask", "serial"):
        raise FrictidInputError(f"--engine {engine}: use dask (a cluster) or serial")
    for src in sources:
        if Path(src).is_dir() and Path(store).resolve().is_relative_to(Path(src).resolve()):
            raise FrictidInputError(f"-o {store}: the store is inside the dataset {src}; its tables would be read "
                                    "as logs on the next run: put it beside the dataset")
    parts = find_partitions(sources, keys)
    st = TrendStore(store)
    done = st.fitted_digests()
    salt = options.salt()
    todo, run = [], FleetRun(total=len(parts))
    for p in parts:
        digest = p.content_hash(salt)
        if done.get(p.id) == digest:
            run.skipped += 1
        else:
            todo.append((p, digest))
    outcomes = (_outcomes_serial(todo, options) if engine == "serial" or not todo
                else _outcomes_dask(todo, options, scheduler, workers))
    batch, meta = [], {"engine": engine, "frictid_version": __version__, "options": salt}
    for k, out in enumerate(outcomes, 1):
        batch.append(out)
        run.fitted += out.ok
        if not out.ok:
            run.failed.append(out)
        if progress:
            progress(k, len(todo), out)
        if len(batch) >= FLUSH_EVERY:
            st.append(batch, meta)
            batch = []
    if batch:
        st.append(batch, meta)
    run.seconds = time.perf_counter() - t0
    return run
