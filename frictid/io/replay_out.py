"""Write a replayed log: the input log's columns plus the model's prediction, one row per input row."""
from __future__ import annotations

import json
import sys

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import yaml

from .atomic import atomic_path, is_stdio
from .logs import META_KEY, logs_metadata, logs_table, output_format

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
    if fmt == "parquet":
        table = table.replace_schema_metadata({META_KEY: json.dumps(meta)})
        if is_stdio(path):
            buf = pa.BufferOutputStream()
            pq.write_table(table, buf)
            sys.stdout.buffer.write(buf.getvalue().to_pybytes())
            sys.stdout.buffer.flush()
            return
        with atomic_path(path) as tmp:
            pq.write_table(table, tmp)
        return
    if is_stdio(path):
        pacsv.write_csv(table, sys.stdout.buffer)
        sys.stdout.buffer.flush()
        return
    with atomic_path(path) as tmp, atomic_path(str(path) + ".meta.yaml") as tmp_side:
        pacsv.write_csv(table, tmp)
        with open(tmp_side, "w", encoding="utf-8") as fh:
            yaml.safe_dump(meta, fh, sort_keys=False)
