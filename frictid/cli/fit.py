"""``frictid fit``: identify friction models from logs and write the parameter YAML."""
from __future__ import annotations

import json
from typing import Annotated, List, Optional

import typer

from .app import app
from .common import Console, JsonOpt, MapOpt, QuietOpt, UnitsOpt


@app.command()
def fit(
    logs: Annotated[Optional[List[str]], typer.Argument(help="Joint logs (CSV, Parquet, - for stdin).")] = None,
    output: Annotated[Optional[str], typer.Option("-o", "--output", help="Parameter YAML to write (- for stdout).")] = None,
    joint: Annotated[Optional[str], typer.Option("--joint", help="Fit only this joint.")] = None,
    models: Annotated[Optional[str], typer.Option(
        "--models", help="Comma list of models (default all): coulomb_viscous, stribeck, stribeck_2exp, "
                         "polynomial (each also _asym), polynomial_ls, lugre, thermal4, thermal6.")] = None,
    no_diagnose: Annotated[bool, typer.Option(
        "--no-diagnose", help="Skip the diagnosis (no extensions beyond the velocity-only models).")] = False,
    mapping: MapOpt = None,
    units: UnitsOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
    report: Annotated[Optional[str], typer.Option(
        "--report", help="Also write the HTML report (as frictid report PARAMS LOG... -o REPORT.html).")] = None,
    jobs: Annotated[int, typer.Option(
        "--jobs", min=0, help="Joints fitted at once, each in its own process (0: one per available core; "
                              "1: one after another). The result does not depend on it.")] = 0,
) -> None:
    """Find the segments, identify every model the data support, choose one, write the parameter file."""
    from ..errors import FrictidInputError
    from ..fit.pipeline import fit as run_fit, parse_models
    from ..io.atomic import check_output_path
    from ..io.params import write_params

    con = Console(quiet)
    if not logs:
        raise FrictidInputError("fit: give at least one log (e.g. frictid fit run.csv -o params.yaml)")
    if not output:
        raise FrictidInputError("fit: give the parameter file to write with -o PARAMS.yaml")
    if logs.count("-") > 1:
        raise FrictidInputError("fit: standard input (-) can be given only once")
    if as_json and output == "-":
        raise FrictidInputError("fit: --json prints on standard output; write the parameters to a file (-o FILE)")
    check_output_path(output, logs)
    if report:
        from .report import check_fit_report
        check_fit_report(report, output, logs)
    parse_models(models)  # refuse unknown names before reading anything
    res = run_fit(logs, joint=joint, models=models, mapping=mapping, units=units, diagnose=not no_diagnose,
                  jobs=jobs)
    write_params(res, output)
    if report:
        from .report import command_line, report_after_fit
        cmd = command_line("fit", logs, [("-o", output), ("--joint", joint), ("--models", models),
                                         ("--map", mapping), ("--units", units), ("--no-diagnose", no_diagnose),
                                         ("--report", report)])
        report_after_fit(report, res, logs, mapping, units, output, cmd, con)
    summary = {}
    for j, jf in res.joints.items():
        m = jf.model
        summary[j] = {"selected": jf.selected, "rms_heldout": m.metrics.get("rms_heldout") if m else None,
                      "warnings": jf.warnings, "not_identified": len(jf.not_identified)}
        sel = f"{jf.selected}" if jf.selected else "no model"
        con.info(f"frictid: joint {j}: {sel}" + (f" (held-out RMS {summary[j]['rms_heldout']:.4g} "
                                                  f"{jf.units.get('tau', '')})" if summary[j]["rms_heldout"] else "")
                 + (f", {len(jf.not_identified)} item(s) not identifiable" if jf.not_identified else ""))
        for w in jf.warnings:
            con.warn(f"joint {j}: {w}")
    if output != "-":
        con.info(f"frictid: wrote {output}")
    if as_json:
        typer.echo(json.dumps({"output": output, "joints": summary}, default=str))
