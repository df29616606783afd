"""``frictid segments``: find the identification experiments in logs and write one row per segment."""
from __future__ import annotations

from typing import Annotated, List, Optional

import typer

from .app import app
from .common import Console, JsonOpt, MapOpt, QuietOpt, UnitsOpt, emit_json, refuse_json_with_stdout


@app.command()
def segments(
    logs: Annotated[Optional[List[str]], typer.Argument(help="Joint logs (CSV, Parquet, - for stdin).")] = None,
    output: Annotated[str, typer.Option(
        "-o", "--output", help="Segment table to write (.csv, .parquet, .json; - prints CSV).")] = ...,
    mapping: MapOpt = None,
    units: UnitsOpt = None,
    fmt: Annotated[Optional[str], typer.Option(
        "--format", help="csv, parquet or json (default: from the suffix).")] = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Find constant-velocity, ramp-presliding, step, duty-cycle, rest and other segments.

    One row per segment (one per duty cycle, one per monotonic torque ramp) with joint, kind, t_start,
    t_end, n and per-kind statistics. A log without any segment is not an error: the table is empty and
    stderr says so. Warnings raised while reading the logs are written with the table (Parquet
    metadata, the JSON document, or a sidecar TABLE.csv.meta.yaml).
    """
    from ..data import log_warnings
    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path
    from ..io.logs import read_many
    from ..io.segtable import segments_frame, table_format, write_segments
    from ..segments import find_segments

    con = Console(quiet)
    if not logs:
        raise FrictidInputError("segments: give at least one log (e.g. frictid segments run.csv -o seg.csv)")
    if sum(1 for p in logs if p == "-") > 1:
        raise FrictidInputError("segments: standard input (-) can be given only once")
    refuse_json_with_stdout("segments", as_json, output)
    fmt = table_format(output, fmt)
    check_output_path(output, logs, mapping, sidecar=fmt == "csv")
    joint_logs = read_many(logs, mapping, units)
    for w in log_warnings(joint_logs):
        con.warn(w)
    items = [(lg, find_segments(lg)) for lg in joint_logs]
    df = segments_frame(items)
    sources = sorted({lg.source or "<log>" for lg in joint_logs})
    write_segments(df, output, fmt, {"sources": sources, "warnings": con.warnings})
    joints: dict[str, dict] = {}
    for lg, segs in items:
        js = joints.setdefault(str(lg.joint), {"segments": 0, "kinds": {}})
        js["segments"] += len(segs)
        for sg in segs:
            js["kinds"][sg.kind] = js["kinds"].get(sg.kind, 0) + 1
    if df.empty:
        con.info(f"frictid: no segments found in {len(joint_logs)} joint log(s); wrote an empty table "
                 f"to {output}")
    else:
        counts = df["kind"].value_counts()
        summary = ", ".join(f"{int(counts[k])} {k}" for k in counts.index)
        con.info(f"frictid: {len(df)} segments ({summary}) in {len(joint_logs)} joint log(s); wrote {output}")
    if as_json:
        emit_json("segments", {"output": output, "format": fmt, "segments": int(len(df)),
                               "kinds": {str(k): int(v) for k, v in df["kind"].value_counts().items()},
                               "joints": joints, "warnings": con.warnings})
