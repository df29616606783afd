"""``frictid trend STORE``: each joint's friction over time from a trend store; and the fleet run behind
``frictid fit DATASET --engine dask -o STORE`` (:func:`run_fleet`)."""
from __future__ import annotations

import os
import sys
from typing import Annotated, List, Optional

import typer

from .app import app
from .common import Console, JsonOpt, QuietOpt, emit_json


def _progress(con: Console):
    def show(k: int, n: int, out) -> None:
        if out.ok:
            con.info(f"frictid: [{k}/{n}] {out.partition.id}: fitted ({out.seconds:.2f} s)")
        else:  # failures are shown even with --quiet
            print(f"frictid: [{k}/{n}] {out.partition.id}: FAILED ({out.kind}): {out.reason}", file=sys.stderr)
    return show


def run_fleet(logs: List[str], output: Optional[str], *, engine: str, scheduler: Optional[str], jobs: int,
              models: Optional[str], diagnose: bool, mapping: Optional[str], units: Optional[str],
              quiet: bool, as_json: bool, report: Optional[str] = None, joint: Optional[str] = None,
              keys: Optional[str] = None) -> None:
    """``frictid fit DATASET --engine dask [--scheduler tcp://HOST:PORT] -o STORE``: one task per
    partition; exit code 0 when every partition was fitted, 2 when some had bad input, 1 when some
    failed for an internal reason."""
    from ..errors import FrictidInputError
    from ..fleet.dataset import parse_keys
    from ..fleet.run import FitOptions, run_fleet as run
    from ..identify.pipeline import parse_models

    if not logs or not output or output == "-":
        raise FrictidInputError("fit --engine dask: give a dataset (folder or log files) and the store folder "
                                "(frictid fit DATASET --engine dask -o STORE)")
    if scheduler and engine != "dask":
        raise FrictidInputError(f"fit: --scheduler is for --engine dask, not {engine}")
    if report or joint:
        raise FrictidInputError("fit --engine dask: --report and --joint are for one parameter file; "
                                "use frictid trend STORE --report PAGE.html")
    parse_models(models)
    spec = parse_keys(keys)
    con = Console(quiet)
    workers = jobs or len(os.sched_getaffinity(0))
    where = scheduler or f"a local cluster of {workers} worker process(es)"
    con.info(f"frictid: fitting the partitions of {', '.join(logs)} on {where} into {output} ...")
    res = run(logs, output, engine=engine, scheduler=scheduler, workers=workers,
              options=FitOptions(models=models, diagnose=diagnose, mapping=mapping, units=units),
              progress=_progress(con), keys=spec)
    con.info(f"frictid: {res.total} partition(s): {res.fitted} fitted, {res.skipped} unchanged (skipped), "
             f"{len(res.failed)} failed, in {res.seconds:.1f} s; store {output}")
    if as_json:
        emit_json("fit", {"engine": engine, "store": output, "partitions": res.total, "fitted": res.fitted,
                          "skipped": res.skipped, "seconds": res.seconds,
                          "failed": [{"partition": o.partition.id, "kind": o.kind, "reason": o.reason}
                                     for o in res.failed], "warnings": con.warnings}, ok=not res.failed)
    if res.internal:
        raise RuntimeError(f"{len(res.internal)} of {res.total} partitions failed for an internal reason "
                           f"(listed above and in the store); the others were fitted")
    if res.bad_input:
        raise FrictidInputError(f"{len(res.bad_input)} of {res.total} partitions have bad input (listed above "
                                f"and in the store); the other {res.total - len(res.bad_input)} are in {output}")


def _joint_line(jt) -> str:
    """``robot=r01/joint=j1: wear at 2026-03-05 (+6.1 N m), step at 2026-03-21 (-6.3 N m); level -0.4 %
    first to last; crossed ...``"""
    lv = jt.level
    changes = lv.changes if lv is not None else []
    text = ", ".join(f"{c['kind']} at {c['date']} ({c['size']:+.3g}{' ' + lv.unit if lv.unit else ''})"
                     for c in changes) or jt.kind
    if changes and lv.fitted[0]:
        text += f"; level {lv.change_rel * 100:+.1f} % first to last"
    return (f"frictid: {jt.joint}: {text}"
            + "".join(f"; crossed {c['quantity']} {c['limit']} ({c['change'] * 100:+.1f} %)"
                      if "%" in c["limit"] else f"; crossed {c['quantity']} {c['limit']} ({c['change']:+.4g})"
                      for c in jt.crossings))


@app.command()
def trend(
    store: Annotated[str, typer.Argument(help="The trend store (frictid fit DATASET --engine dask -o STORE).")],
    limit: Annotated[Optional[str], typer.Option(
        "--limit", help="Comma list of limits on the change from the first run to the last: Fc=+20% (rise), "
                        "Fc=-10% (fall), F_ref=15% (either way), sigma2=0.5 (in its unit); * for every "
                        "quantity. Exit code 3 when a joint crosses one.")] = None,
    report: Annotated[Optional[str], typer.Option(
        "--report", "-o", help="Write the trend page (self-contained HTML).")] = None,
    keys: Annotated[Optional[str], typer.Option(
        "--keys", help="The store's dataset keys that name a joint and, after a colon, the key that orders its "
                       "runs (robot,joint:date). Default: date, day, run or time (else the last key) orders the "
                       "runs, the other keys name the joint.")] = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Per joint, each parameter over time: normalised; its steps and wear, each dated; limits."""
    from ..errors import QualityGateError
    from ..fleet.page import write_page
    from ..fleet.dataset import parse_keys
    from ..fleet.trend import parse_limits, trend_fleet

    con = Console(quiet)
    ft = trend_fleet(store, parse_limits(limit), parse_keys(keys))
    for jt in ft.joints:
        con.info(_joint_line(jt))
    for f in ft.failed:
        con.warn(f"partition {f['partition']} failed ({f['kind']}): {f['reason']}")
    if report:
        write_page(ft, report)
        con.info(f"frictid: wrote {report}")
    if as_json:
        emit_json("trend", {**ft.to_dict(), "warnings": con.warnings})
    if ft.crossings:
        raise QualityGateError(f"{len({c['joint'] for c in ft.crossings})} joint(s) crossed a limit: "
                               + "; ".join(f"{c['joint']} {c['quantity']} {c['limit']}" for c in ft.crossings))
