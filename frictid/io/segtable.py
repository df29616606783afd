"""Segment tables out: one row per segment, as CSV, Parquet or JSON, written atomically.

Columns: ``joint, kind, t_start, t_end, n`` first, then ``i0, i1`` (sample indices, end exclusive),
``cycle`` (duty-cycle index, empty otherwise), ``source`` (the log), then every per-kind statistic
(see ``docs/segments.md``), empty where a statistic does not apply to a row's kind. Units follow the log:
rad or m, rad/s or m/s, N m or N, s.

Metadata (``{"schema": 1, "sources": [...], "warnings": [...]}``: the logs read and the warnings raised
while reading them) goes where the format allows: the Parquet schema metadata under the key ``frictid``,
the JSON document's top level, or a sidecar ``<table>.meta.yaml`` beside a CSV file (as for logs).
A table on standard output carries none; :func:`read_segments_meta` reads it back.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from ..data import JointLog, Segment
from ..errors import FrictidInputError
from .atomic import atomic_path, is_stdio

FIRST_COLUMNS = ["joint", "kind", "t_start", "t_end", "n", "i0", "i1", "cycle", "source"]
FORMATS = ("csv", "parquet", "json")


def segments_frame(items: list[tuple[JointLog, list[Segment]]]) -> pd.DataFrame:
    """One row per segment of each ``(log, segments)`` pair, in the order given."""
    from ..segments import STAT_COLUMNS

    rows = []
    for log, segs in items:
        for s in segs:
            row = {"joint": str(log.joint), "kind": s.kind, "t_start": float(s.t_start), "t_end": float(s.t_end),
                   "n": int(s.n), "i0": int(s.i0), "i1": int(s.i1),
                   "cycle": s.cycle if s.cycle is not None else pd.NA, "source": log.source or ""}
            row.update({k: float(v) for k, v in s.stats.items()})
            rows.append(row)
    extra = [c for c in STAT_COLUMNS if any(c in r for r in rows)]
    extra += sorted({k for r in rows for k in r} - set(FIRST_COLUMNS) - set(extra))
    df = pd.DataFrame(rows, columns=FIRST_COLUMNS + extra)
    df["cycle"] = df["cycle"].astype("Int64")
    df["n"] = df["n"].astype("int64")
    df["i0"] = df["i0"].astype("int64")
    df["i1"] = df["i1"].astype("int64")
    for c in ("joint", "kind", "source"):
        df[c] = df[c].astype(str)
    for c in ["t_start", "t_end"] + extra:
        df[c] = df[c].astype(float)
    return df


def table_format(path: str, fmt: str | None = None) -> str:
    """csv, parquet or json, from ``fmt`` or the suffix of ``path`` (``-`` is CSV)."""
    if fmt:
        fmt = fmt.lower()
        if fmt not in FORMATS:
            raise FrictidInputError(f"--format {fmt}: use csv, parquet or json")
        return fmt
    if is_stdio(path):
        return "csv"
    suf = Path(path).suffix.lower()
    fmt = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet", ".json": "json"}.get(suf)
    if fmt is None:
        raise FrictidInputError(f"{path}: cannot tell the format from the suffix {suf or '(none)'!r}; "
                                "use .csv, .parquet or .json, or pass --format")
    return fmt


def _json_records(df: pd.DataFrame) -> list[dict]:
    recs = []
    for rec in df.to_dict(orient="records"):
        out = {}
        for k, v in rec.items():
            if v is pd.NA or v is None:
                out[k] = None
            elif isinstance(v, (float, np.floating)):
                out[k] = float(v) if math.isfinite(v) else None
            elif isinstance(v, np.integer):
                out[k] = int(v)
            else:
                out[k] = v
        recs.append(out)
    return recs


def write_segments(df: pd.DataFrame, path: str, fmt: str | None = None, meta: dict | None = None) -> None:
    """Write a segment table atomically (temporary file beside ``path``, then rename); ``-`` is stdout.

    meta : ``{"sources": [...], "warnings": [...]}`` written with the table (see the module docstring).
    """
    fmt = table_format(path, fmt)
    meta = {"schema": 1, **(meta or {})}
    if fmt == "csv":
        text = df.to_csv(index=False, float_format="%.9g", na_rep="")
        if is_stdio(path):
            sys.stdout.write(text)
            sys.stdout.flush()
            return
        with atomic_path(path) as tmp, atomic_path(f"{path}.meta.yaml") as tmp_side:
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                fh.write(text)
            with open(tmp_side, "w", encoding="utf-8") as fh:
                yaml.safe_dump(meta, fh, sort_keys=False)
        return
    if fmt == "json":
        doc = {**meta, "columns": list(df.columns), "segments": _json_records(df)}
        text = json.dumps(doc, indent=1)
        if is_stdio(path):
            sys.stdout.write(text + "\n")
            sys.stdout.flush()
            return
        with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
        return
    import pyarrow as pa

    from .logs import META_KEY, write_table

    table = pa.Table.from_pandas(df, preserve_index=False)  # keeps pandas' own metadata (dtypes) beside ours
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), META_KEY.encode(): json.dumps(meta)})
    write_table(table, path, "parquet")


def read_segments_meta(path: str) -> dict:
    """The metadata written with a segment table (``{}`` when there is none)."""
    fmt = table_format(path)
    if fmt == "parquet":
        import pyarrow.parquet as pq

        from .logs import META_KEY

        raw = (pq.read_schema(path).metadata or {}).get(META_KEY.encode())
        return json.loads(raw) if raw else {}
    if fmt == "json":
        with open(path, encoding="utf-8") as fh:
            d = json.load(fh)
        return {k: v for k, v in d.items() if k not in ("columns", "segments")}
    side = Path(f"{path}.meta.yaml")
    if not side.is_file():
        return {}
    with open(side, encoding="utf-8") as fh:
        return yaml.safe_load(fh) or {}


def read_segments(path: str) -> pd.DataFrame:
    """Read a segment table written by :func:`write_segments` (CSV, Parquet or JSON)."""
    fmt = table_format(path)
    if fmt == "parquet":
        return pd.read_parquet(path)
    if fmt == "json":
        with open(path, encoding="utf-8") as fh:
            d = json.load(fh)
        return pd.DataFrame(d["segments"], columns=d["columns"])
    return pd.read_csv(path, dtype={"joint": str, "source": str}, keep_default_na=False,
                       na_values=[""]).astype({"cycle": "Int64"})
