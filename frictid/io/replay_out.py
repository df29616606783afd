"""Write a replayed log: the input log's columns plus the model's prediction, one row per input row."""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from .logs import logs_metadata, logs_table, output_format, write_table

#: Columns added by ``frictid simulate --replay`` (in this order, where present).
REPLAY_COLUMNS = ("tau_model", "residual", "F_model", "z_model", "T_model", "q_model", "qd_model")


def write_replay(logs, results, path: str, fmt: str | None = None, info: dict | None = None) -> None:
    """Write logs with their :class:`frictid.replay.ReplayResult` columns appended (atomically).

    logs, results : equal-length lists (one per joint). info : written to the metadata under ``replay``.
    Columns a joint does not have (``q_model`` without a closed loop, ``T_model`` without a thermal law)
    are empty (null) for that joint's rows.
    """
    fmt = output_format(path, fmt)
    table = logs_table(logs)
    cols = {c: [] for c in REPLAY_COLUMNS}
    for lg, r in zip(logs, results):
        vals = {"tau_model": r.tau_model, "residual": r.residual, "F_model": r.F_model,
                "z_model": r.z if r.z is not None and np.any(r.z) else None,
                "T_model": r.T if r.T is not None and np.any(np.isfinite(r.T)) else None,
                "q_model": r.q_model, "qd_model": r.qd_model}
        for c in REPLAY_COLUMNS:
            v = vals[c]
            cols[c].append(np.full(lg.n, np.nan) if v is None else np.asarray(v, dtype=float))
    for c in REPLAY_COLUMNS:
        arr = np.concatenate(cols[c]) if cols[c] else np.zeros(0)
        if np.all(np.isnan(arr)):
            continue
        table = table.append_column(c, pa.array(arr, from_pandas=True))
    meta = logs_metadata(logs)
    meta["replay"] = info or {}
    write_table(table, path, fmt, meta)


#: Columns of ``frictid simulate --compensate``'s runs file, one row per sample of each run of each joint.
RUN_COLUMNS = ("joint", "run", "t", "q_ref", "q", "qd", "tau", "tau_comp")


def write_runs(runs: dict, path: str, fmt: str | None = None, info: dict | None = None) -> None:
    """Write compensation runs (joint -> run name -> :class:`frictid.compensate.Run`) atomically, long
    format: joint, run, t [s], q_ref and q [q], qd [q/s], tau (the controller's torque) and tau_comp (the
    friction feed-forward in it) [F]; ``info`` (the metrics) in the metadata under ``compensate``."""
    fmt = output_format(path, fmt)
    parts = {c: [] for c in RUN_COLUMNS}
    for joint, by_name in runs.items():
        for name, r in by_name.items():
            n = r.t.shape[0]
            for c, v in zip(RUN_COLUMNS, (np.full(n, str(joint), dtype=object), np.full(n, name, dtype=object),
                                          r.t, r.q_ref, r.q, r.w, r.u, r.ff)):
                parts[c].append(v)
    table = pa.table({c: pa.array(np.concatenate(parts[c])) if parts[c] else pa.array([]) for c in RUN_COLUMNS})
    write_table(table, path, fmt, {"compensate": info or {}})


def read_runs(path: str) -> dict:
    """A runs file of ``frictid simulate --compensate``: joint -> run -> {t, q_ref, q, metrics}, and the
    recorded information under ``"_info"``. FrictidInputError when the file is not one."""
    import json

    import pyarrow.parquet as pq

    from ..errors import FrictidInputError
    from .logs import META_KEY

    try:
        table = pq.read_table(path)
        info = json.loads((table.schema.metadata or {}).get(META_KEY.encode(), b"{}")).get("compensate")
    except Exception as exc:  # noqa: BLE001 - unreadable for any reason: one message
        raise FrictidInputError(f"{path}: not a runs file of frictid simulate --compensate ({exc.__class__.__name__}); "
                                "write it with -o RUNS.parquet") from None
    if not info or not set(RUN_COLUMNS) <= set(table.column_names):
        raise FrictidInputError(f"{path}: not a runs file of frictid simulate --compensate (Parquet with "
                                f"columns {', '.join(RUN_COLUMNS)})")
    df = table.to_pandas()
    out: dict = {"_info": info}
    for (joint, run), g in df.groupby(["joint", "run"], sort=False):
        metrics = (info.get("joints", {}).get(joint, {}).get("runs", {}).get(run)) or {}
        out.setdefault(str(joint), {})[str(run)] = {"t": g["t"].to_numpy(), "q_ref": g["q_ref"].to_numpy(),
                                                     "q": g["q"].to_numpy(), "metrics": metrics}
    return out
