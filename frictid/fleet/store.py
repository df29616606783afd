"""The trend store: one appendable Parquet table of fitted parameters, and the parameter files beside it.

Layout of a store folder::

    STORE/table/part-<ns>-<pid>.parquet   one file per flush of a run; together one table
    STORE/params/<partition>.yaml          the parameter file of each fitted partition

The table has one row per partition, joint and parameter of the selected model (a partition that failed
has one row with its reason). Its columns are in :data:`COLUMNS` plus one string column per dataset key
(``robot``, ``joint``, ``date``, ...); ``docs/fleet.md`` describes them. pandas reads it with
``TrendStore(path).read()`` or ``pd.concat(map(pd.read_parquet, glob("STORE/table/*.parquet")))``,
DuckDB with ``SELECT * FROM read_parquet('STORE/table/*.parquet', union_by_name=true)``.
"""
from __future__ import annotations

import json
import os
import re
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..io.params import write_params
from ..errors import FrictidInputError
from ..io.atomic import atomic_path
from ..result import plain

#: The table's own columns and their meaning (the dataset's key columns come first).
COLUMNS = {
    "partition": "the partition's id, key=value/... (a list of files: file=<path>)",
    "log_joint": "the joint's name in the log",
    "status": "ok, or failed (then error_kind and reason say why)",
    "error_kind": "input (bad input: the log cannot be read or fitted) or internal (a bug); empty when ok",
    "reason": "why the partition failed, or why the joint has no model",
    "content_hash": "BLAKE2b of the partition's files and the fit options; a re-run skips an unchanged one",
    "model": "the selected model of the joint",
    "param": "parameter name",
    "value": "its estimate [unit]",
    "stderr": "its standard error [unit] (NaN when not estimated)",
    "unit": "its unit",
    "identifiable": "whether the data identified it",
    "param_reason": "why it is not identifiable",
    "speed_hi": "99th percentile of |qd| in the log [q/s]",
    "temp_mean": "mean temperature of the log (joint, else ambient) [degC]",
    "temp_lo": "lowest temperature [degC]",
    "temp_hi": "highest temperature [degC]",
    "n_samples": "samples of the joint's log",
    "F_ref": "the run's friction level at F_ref_speed (its selected model; docs/fleet.md) [unit of tau]",
    "F_ref_stderr": "its standard error by the delta method from the model's covariance [unit of tau] (NaN: see F_ref_reason)",
    "F_ref_speed": "the speed F_ref is taken at: half the log's speed_hi [q/s]",
    "F_ref_temp": "the temperature F_ref is taken at: the thermal law's reference T0 [degC] (NaN: no thermal law)",
    "F_ref_reason": "why F_ref or its standard error is missing",
    "cov": "the selected model's parameter covariance, JSON {names, cov} (empty when it has none)",
    "duration": "duration of the joint's log [s]",
    "findings": "the diagnosis' findings (JSON list of cause, extension, model, gain)",
    "params_file": "the parameter file, relative to the store",
    "fit_seconds": "time to read and fit the partition [s]",
    "engine": "dask or serial",
    "frictid_version": "the frictid that fitted it",
    "options": "the fit options (models, diagnose, map, units)",
    "inputs": "JSON list of the partition's files",
    "written": "when the row was written [ns since 1970, UTC]; the latest per partition counts",
    "created": "the same as ISO 8601 text",
}
_NUM = ("value", "stderr", "speed_hi", "temp_mean", "temp_lo", "temp_hi", "duration", "fit_seconds", "F_ref",
        "F_ref_stderr", "F_ref_speed", "F_ref_temp")


def safe_name(partition_id: str) -> str:
    """A file name for a partition id (``robot=r1/joint=j2`` -> ``robot=r1,joint=j2``)."""
    return re.sub(r"[^A-Za-z0-9=._-]+", "_", partition_id.replace("/", ",")).strip("_") or "partition"


class TrendStore:
    """A store folder: :meth:`append` the outcomes of a run, :meth:`read` / :meth:`latest` the table."""

    def __init__(self, path):
        self.path = Path(path)
        self.table_dir = self.path / "table"
        self.params_dir = self.path / "params"

    def create(self) -> None:
        if self.path.exists() and not self.path.is_dir():
            raise FrictidInputError(f"{self.path}: is a file; the trend store is a folder (-o STORE)")
        if not self.path.parent.exists():
            raise FrictidInputError(f"{self.path.parent}: no such folder for the store")
        self.table_dir.mkdir(parents=True, exist_ok=True)
        self.params_dir.mkdir(exist_ok=True)

    def exists(self) -> bool:
        return self.table_dir.is_dir()

    def read(self) -> pd.DataFrame:
        """Every row ever written (empty frame when none)."""
        files = sorted(self.table_dir.glob("part-*.parquet")) if self.exists() else []
        if not files:
            return pd.DataFrame(columns=list(COLUMNS))
        return typed(pd.concat([pq.read_table(f).to_pandas() for f in files], ignore_index=True))

    def latest(self) -> pd.DataFrame:
        """The rows of each partition's latest fit."""
        df = self.read()
        if df.empty:
            return df
        last = df.groupby("partition")["written"].transform("max")
        return df[df["written"] == last].reset_index(drop=True)

    def fitted_digests(self) -> dict[str, str]:
        """Partition id -> content hash of its latest fit that succeeded (failed ones are tried again)."""
        df = self.latest()
        ok = df[df["status"] == "ok"] if not df.empty else df
        return dict(zip(ok["partition"], ok["content_hash"]))

    def append(self, outcomes, meta: dict) -> Path:
        """Write the outcomes' parameter files and one new part of the table (each atomically)."""
        self.create()
        now = time.time_ns()
        rows = []
        for out in outcomes:
            params_file = ""
            if out.ok:
                params_file = f"params/{safe_name(out.partition.id)}.yaml"
                write_params(out.result, self.path / params_file)
            rows += outcome_rows(out, params_file, meta, now)
        df = typed(pd.DataFrame(rows))
        path = self.table_dir / f"part-{now}-{os.getpid()}.parquet"
        with atomic_path(path) as tmp:
            pq.write_table(pa.Table.from_pandas(df, preserve_index=False), tmp)
        return path


def typed(df: pd.DataFrame) -> pd.DataFrame:
    """Every column of :data:`COLUMNS`, with the same types in every part of the table (a part of failed
    partitions only has no values, yet its columns must not turn into nulls of another type)."""
    for c in COLUMNS:
        if c not in df:
            df[c] = None
    for c in df.columns:
        if c in _NUM:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype("float64")
        elif c in ("n_samples", "written"):
            df[c] = pd.to_numeric(df[c], errors="coerce").astype("Int64")
        elif c == "identifiable":
            df[c] = df[c].astype("boolean")
        else:
            df[c] = df[c].map(lambda v: None if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
    return df


def _joint_rows(jd: dict, stats: dict) -> list[dict]:
    sel = jd.get("selected")
    model = ((jd.get("models") or {}).get(sel) or {}) if sel else {}
    findings = [{k: f.get(k) for k in ("cause", "extension", "model", "gain")}
                for f in jd.get("diagnosis") or [] if isinstance(f, dict)]
    base = {"model": sel, "findings": json.dumps(plain(findings)), **stats,
            "reason": "" if sel else "; ".join(str(x.get("reason")) for x in jd.get("not_identified") or [])}
    params = model.get("params") or {}
    if not params:
        return [dict(base, param=None, value=np.nan, stderr=np.nan, unit="", identifiable=False, param_reason="")]
    out = []
    for name, e in params.items():
        e = e if isinstance(e, dict) else {"value": e}
        out.append(dict(base, param=name, value=e.get("value"), stderr=e.get("stderr"), unit=e.get("unit") or "",
                        identifiable=bool(e.get("identifiable", True)), param_reason=e.get("reason") or ""))
    return out


def outcome_rows(out, params_file: str, meta: dict, now: int) -> list[dict]:
    """The table rows of one partition's outcome."""
    keys = dict(out.partition.keys)
    clash = set(keys) & set(COLUMNS)
    if clash:
        raise FrictidInputError(f"dataset key {sorted(clash)[0]!r} is also a column of the trend store; "
                                "rename that folder level")
    common = {**keys, "partition": out.partition.id, "content_hash": out.digest, "params_file": params_file,
              "fit_seconds": out.seconds, "inputs": json.dumps(list(out.partition.files)), "written": now,
              "created": datetime.fromtimestamp(now / 1e9, timezone.utc).isoformat(), **meta}
    if not out.ok:
        return [dict(common, log_joint=None, status="failed", error_kind=out.kind, reason=out.reason,
                     model=None, param=None, findings="[]")]
    rows = []
    for j, jd in out.result.to_dict()["joints"].items():
        for r in _joint_rows(jd, out.stats.get(j, {})):
            rows.append(dict(common, log_joint=j, status="ok", error_kind="", **r))
    return rows
