"""``frictid report``: one self-contained HTML file per identification (figures inline, works offline)."""
from __future__ import annotations

import shlex
import time
from typing import Annotated, List, Optional

import typer

from .app import app
from .common import (Console, JsonOpt, MapOpt, QuietOpt, UnitsOpt, emit_json, joint_summary,
                     refuse_json_with_stdout)


def command_line(name: str, positional: list[str], options: list[tuple[str, Optional[str] | bool]]) -> str:
    """The command as a user would type it again (for the report's provenance); ``True`` marks a flag."""
    parts = ["frictid", name, *positional]
    for flag, value in options:
        if value is True:
            parts.append(flag)
        elif value is not None and value is not False:
            parts += [flag, value]
    return " ".join(shlex.quote(str(p)) for p in parts)


@app.command()
def report(
    params: Annotated[Optional[str], typer.Argument(help="Parameter YAML written by frictid fit.")] = None,
    logs: Annotated[Optional[List[str]], typer.Argument(
        help="Logs to draw (the ones the fit read; CSV, Parquet, - for stdin). Without logs the report shows "
             "what the parameter file holds.")] = None,
    output: Annotated[Optional[str], typer.Option(
        "-o", "--output", help="HTML file to write (- for standard output).")] = None,
    mapping: MapOpt = None,
    units: UnitsOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
    compensation: Annotated[Optional[str], typer.Option(
        "--compensation", help="Runs file of frictid simulate --compensate: its runs are drawn per joint.")] = None,
    robot: Annotated[Optional[str], typer.Option(
        "--robot", help="For a parameter file of frictid fit --robot: the robot (DH YAML or URDF), when the file "
                        "it names is not found from here.")] = None,
    jobs: Annotated[int, typer.Option(
        "--jobs", min=0, help="Joints built at once, each in its own process (0: one per available core; "
                              "1: one after another). The report does not depend on it.")] = 0,
) -> None:
    """Write a self-contained HTML report: summary, segment timeline, friction map, presliding, thermal,
    model comparison, diagnosis and provenance for every joint of a parameter file.

    The file has no external URL, script or font: it can be mailed, attached to a CI run and printed.
    Give the logs the fit read (with the same --map / --units) to draw the data; parts the data cannot
    support say why they are empty.
    """
    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path
    from ..io.params_load import load_params_dict
    from ..report import write_report
    from ..report.build import Prefetch

    con = Console(quiet)
    logs = list(logs or [])
    if not params:
        raise FrictidInputError("report: give the parameter file (e.g. frictid report params.yaml run.csv "
                                "-o report.html)")
    if not output:
        raise FrictidInputError("report: give the output file with -o REPORT.html (or -o - for standard output)")
    if params == "-":
        raise FrictidInputError("report: the parameter file cannot be standard input; give its path")
    if sum(1 for p in logs if p == "-") > 1:
        raise FrictidInputError("report: standard input (-) can be given only once")
    refuse_json_with_stdout("report", as_json, output)
    check_output_path(output, [params, *logs] + ([compensation] if compensation else []), mapping)
    t0 = time.perf_counter()
    pre = Prefetch(logs)  # the files' hashes and the figures' imports, while the logs are planned
    try:
        pd = load_params_dict(params)
        runs = None
        if compensation:
            from ..io.replay_out import read_runs

            runs = read_runs(compensation)
        joint_logs = plan_report_logs(logs, mapping, units) if logs else []
    finally:
        hashes = pre.hashes()
    cmd = command_line("report", [params, *logs], [("-o", output), ("--map", mapping), ("--units", units),
                                                    ("--compensation", compensation), ("--robot", robot),
                                                    ("--jobs", str(jobs) if jobs else None)])
    warned: list[str] = []
    nbytes = write_report(output, pd, joint_logs, params_path=params, command=cmd, jobs=jobs, hashes=hashes,
                          log_warnings_out=warned, compensation=runs, robot_file=robot)
    for w in warned:
        con.warn(w)
    n = len(pd.get("joints") or {})
    if output != "-":
        con.info(f"frictid: wrote {output} ({nbytes / 1e6:.2f} MB, {n} joint{'s' if n != 1 else ''}, "
                 f"{len(logs)} log{'s' if len(logs) != 1 else ''}) in {time.perf_counter() - t0:.1f} s")
    if as_json:
        emit_json("report", {"output": output, "bytes": nbytes, "params": params, "logs": logs,
                             "joints": {str(j): joint_summary(jd) for j, jd in (pd.get("joints") or {}).items()
                                        if isinstance(jd, dict)},
                             "warnings": con.warnings})


def read_report_logs(paths: list[str], mapping=None, units=None) -> list:
    """The logs of ``paths`` with the columns the report uses: the references (``q_ref``, ``qd_ref``,
    ``tau_ref``: :data:`frictid.replay.REFERENCE_CHANNELS`, which only the closed-loop replay reads) only
    from a file whose logs carry controller gains (``meta.control``), which is then read again whole;
    standard input is read once, whole. Problems from all files are reported together."""
    from ..io.logs import read_many

    return read_many(paths, mapping, units, read=_read_report_log)


def _read_report_log(path: str, mapping=None, units=None, rows: tuple[int, int] | None = None) -> list:
    """One file's logs (``rows``: only these rows of a Parquet file), as :func:`read_report_logs` reads them."""
    from ..errors import FrictidInputError
    from ..io.logs import read_logs
    from ..replay import REFERENCE_CHANNELS, controller_from_meta

    def closed_loop(lg) -> bool:
        try:
            return controller_from_meta(lg.meta or {}) is not None
        except FrictidInputError:
            return True  # the replay reports the bad gains itself

    whole = path == "-" or _may_give_gains(path, mapping)
    got = read_logs(path, mapping, units, skip=() if whole else REFERENCE_CHANNELS, rows=rows)
    if not whole and any(closed_loop(lg) for lg in got):
        got = read_logs(path, mapping, units, rows=rows)
    return got


def plan_report_logs(paths: list[str], mapping=None, units=None) -> list:
    """The logs of ``paths`` for :func:`frictid.report.build_report`: a Parquet file whose joints are
    contiguous blocks of rows (:func:`frictid.io.logs.joint_row_blocks`) gives one
    :class:`~frictid.report.build.DeferredLogs` per joint, read by the worker that draws the joint (the
    reading is shared out between the workers and overlaps the drawing, and the parent never holds the
    data); any other file is read here, whole, as :func:`read_report_logs` reads it. Problems of the
    files read here are reported together; those of the deferred blocks when the workers read them."""
    import functools
    from pathlib import Path

    from ..errors import LogFormatError
    from ..io.logs import joint_row_blocks
    from ..report.build import DeferredLogs

    out, errors = [], []
    for p in paths:
        try:
            blocks = joint_row_blocks(p, mapping, units) if p != "-" else None
            if blocks is None:
                out.extend(_read_report_log(p, mapping, units))
                continue
        except LogFormatError as exc:
            errors.append(str(exc))
            continue
        out.extend(DeferredLogs(joint, str(Path(p)), functools.partial(_read_report_log, p, mapping, units, (a, b)))
                   for joint, a, b in blocks)
    if errors:
        raise LogFormatError("", errors)
    return out


def _may_give_gains(path: str, mapping) -> bool:
    """Whether the metadata of ``path`` (a Parquet file's schema, a sidecar ``.meta.yaml``) or the mapping
    mentions ``control`` (the controller gains of a closed loop): such a file is read whole at once instead
    of twice (first without the references, then whole). Only a hint: a file that turns out to give gains
    without it is still read again whole."""
    from pathlib import Path

    texts = [str(mapping or "")]
    try:
        m = Path(str(mapping or ""))
        if mapping and m.is_file() and m.stat().st_size < 1_000_000:
            texts.append(m.read_text(errors="replace"))
        for side in (Path(path + ".meta.yaml"), Path(path).with_suffix(".meta.yaml")):
            if side.is_file() and side.stat().st_size < 10_000_000:
                texts.append(side.read_text(errors="replace"))
        with open(path, "rb") as fh:
            parquet = fh.read(4) == b"PAR1"
        if parquet:
            import pyarrow.parquet as pq

            texts.extend(v.decode("utf-8", "replace") for v in (pq.read_schema(path).metadata or {}).values())
    except (OSError, ValueError):
        return False  # read_logs reports the file's problem itself
    return any("control" in t for t in texts)


def check_fit_report(report_path: str, output: str, logs: list[str], mapping: str | None = None) -> None:
    """Refuse a ``frictid fit --report`` path before any work (called by the fit command)."""
    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path

    if report_path == "-":
        raise FrictidInputError("fit: --report needs a file name (standard output is for the parameters)")
    if "-" in logs:
        raise FrictidInputError("fit: --report re-reads the logs, which standard input cannot give twice; "
                                "write the log to a file first (or run frictid report afterwards)")
    if output != "-" and report_path == output:
        raise FrictidInputError(f"fit: --report {report_path} is also the parameter file (-o); choose another name")
    check_output_path(report_path, logs, mapping)


def report_after_fit(report_path: str, result, logs: list[str], mapping, units, params_path: str,
                     command: str, con: Console) -> None:
    """``frictid fit --report``: the report of a fresh identification, from the same logs and options."""
    from ..report import write_report

    t0 = time.perf_counter()
    nbytes = write_report(report_path, result.to_dict(), plan_report_logs(logs, mapping, units),
                          params_path=params_path if params_path != "-" else "(standard output)", command=command)
    con.info(f"frictid: wrote {report_path} ({nbytes / 1e6:.2f} MB) in {time.perf_counter() - t0:.1f} s")
