"""``frictid segments``: find the identification experiments in logs and write one row per segment."""
from __future__ import annotations

from typing import Annotated, List, Optional

import typer

from .app import app
from .common import Console, MapOpt, QuietOpt, UnitsOpt


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
) -> None:
    """Find constant-velocity, ramp-presliding, step, duty-cycle, rest and other segments.

    One row per segment (one per duty cycle, one per monotonic torque ramp) with joint, kind, t_start,
    t_end, n and per-kind statistics. A log without any segment is not an error: the table is empty and
    stderr says so.
    """
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
    check_output_path(output, logs)
    fmt = table_format(output, fmt)
    joint_logs = read_many(logs, mapping, units)
    for lg in joint_logs:
        for w in lg.warnings:
            con.warn(w)
    items = [(lg, find_segments(lg)) for lg in joint_logs]
    df = segments_frame(items)
    write_segments(df, output, fmt)
    if df.empty:
        con.info(f"frictid: no segments found in {len(joint_logs)} joint log(s); wrote an empty table "
                 f"to {output}")
        return
    counts = df["kind"].value_counts()
    summary = ", ".join(f"{int(counts[k])} {k}" for k in counts.index)
    con.info(f"frictid: {len(df)} segments ({summary}) in {len(joint_logs)} joint log(s); wrote {output}")
