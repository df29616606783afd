"""``frictid fit``: identify friction models from logs and write the parameter YAML."""
from __future__ import annotations

from typing import Annotated, List, Optional

import typer

from .app import app
from .common import (Console, JsonOpt, MapOpt, QuietOpt, UnitsOpt, emit_json, joint_summary,
                     refuse_json_with_stdout)


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
    robot: Annotated[Optional[str], typer.Option(
        "--robot", help="A robot (DH YAML or URDF, e.g. recipes/robots/panda.yaml): identify the rigid-body base "
                        "parameters jointly with every joint's Coulomb, viscous and offset friction from "
                        "multi-joint motion; a log that moves one joint at a time (or --joint J) is fitted one "
                        "joint at a time, with the gravity form its pose has (docs/robots.md).")] = None,
    robot_friction: Annotated[str, typer.Option(
        "--robot-friction", help="With --robot: models (then every model of frictid on each joint's friction "
                                 "torque, the rigid body held) or linear (the joint estimate's Coulomb-viscous "
                                 "friction only).")] = "models",
    rigid_body: Annotated[str, typer.Option(
        "--rigid-body", help="With --robot: identify (the rigid-body base parameters identified with the friction) "
                             "or known (the robot file's own link inertias subtracted, only friction identified; "
                             "e.g. recipes/robots/panda.urdf).")] = "identify",
    engine: Annotated[str, typer.Option(
        "--engine", help="local: fit the logs together into one parameter file; dask: LOGS is a dataset (a "
                         "hive-partitioned folder or files), one task per partition into the trend store "
                         "-o STORE (docs/fleet.md); serial: the same one after another.")] = "local",
    scheduler: Annotated[Optional[str], typer.Option(
        "--scheduler", help="With --engine dask: the cluster's scheduler (tcp://HOST:PORT); default a local "
                            "cluster of --jobs worker processes.")] = None,
    keys: Annotated[Optional[str], typer.Option(
        "--keys", help="With --engine dask|serial: the dataset keys that name a joint and, after a colon, the "
                       "key that orders its runs (robot,joint:date); a partition is one value of these, its "
                       "files below any other keys fitted together. Default: every name=value level.")] = None,
) -> None:
    """Find the segments, identify every model the data support, choose one, write the parameter file."""
    from ..errors import FrictidInputError
    from ..api import fit as run_fit, parse_models
    from ..io.atomic import check_output_path
    from ..io.params import write_params

    if engine != "local":
        from .trend import run_fleet
        return run_fleet(logs, output, engine=engine, scheduler=scheduler, jobs=jobs, models=models,
                         diagnose=not no_diagnose, mapping=mapping, units=units, quiet=quiet, as_json=as_json,
                         report=report, joint=joint, keys=keys)
    if keys is not None:
        raise FrictidInputError("fit: --keys is for a dataset (--engine dask or serial)")
    con = Console(quiet)
    if not logs:
        raise FrictidInputError("fit: give at least one log (e.g. frictid fit run.csv -o params.yaml)")
    if not output:
        raise FrictidInputError("fit: give the parameter file to write with -o PARAMS.yaml")
    if logs.count("-") > 1:
        raise FrictidInputError("fit: standard input (-) can be given only once")
    refuse_json_with_stdout("fit", as_json, output)
    check_output_path(output, logs, mapping)
    if report:
        from .report import check_fit_report
        check_fit_report(report, output, logs, mapping)
    if robot:
        return _fit_robot(logs, robot, output, mapping, units, con, as_json, robot_friction, not no_diagnose, jobs,
                          joint, rigid_body)
    if rigid_body != "identify":
        raise FrictidInputError("fit: --rigid-body is for a whole robot: give the robot with --robot ROBOT")
    parse_models(models)  # refuse unknown names before reading anything
    con.info(f"frictid: fitting {len(logs)} log{'s' if len(logs) != 1 else ''} ...")
    res = run_fit(logs, joint=joint, models=models, mapping=mapping, units=units, diagnose=not no_diagnose,
                  jobs=jobs)
    write_params(res, output)
    if report:
        from .report import command_line, report_after_fit
        cmd = command_line("fit", logs, [("-o", output), ("--joint", joint), ("--models", models),
                                         ("--map", mapping), ("--units", units), ("--no-diagnose", no_diagnose),
                                         ("--report", report)])
        report_after_fit(report, res, logs, mapping, units, output, cmd, con)
    _summarise(res, output, con, as_json, report)


def _summarise(res, output, con, as_json, report=None, extra=None) -> None:
    """Each joint's choice and warnings on the console (and as JSON with ``--json``)."""
    summary = {}
    for j, jd in res.to_dict()["joints"].items():
        js = summary[j] = joint_summary(jd)
        rms = js["rms_heldout"]
        con.info(f"frictid: joint {j}: {js['selected'] or 'no model'}"
                 + (f" (held-out RMS {rms:.4g} {js['units'].get('tau', '')} on {js['rms_heldout_basis']})"
                    if rms else "")
                 + (f", {len(js['not_identified'])} item(s) not identifiable" if js["not_identified"] else ""))
        for w in js["warnings"]:
            con.warn(f"joint {j}: {w}")
    if output != "-":
        con.info(f"frictid: wrote {output}")
    if as_json:
        emit_json("fit", {"output": output, "report": report, **(extra or {}), "joints": summary,
                          "warnings": con.warnings})


def _fit_robot(logs, robot, output, mapping, units, con, as_json, friction, diagnose, jobs, joint=None,
               rigid_body="identify") -> None:
    """``frictid fit LOG... --robot ROBOT``: the whole-robot identification into a parameter file."""
    from ..io.params import write_params
    from ..robotfit import fit_robot

    con.info(f"frictid: identifying the robot of {robot} from {len(logs)} log{'s' if len(logs) != 1 else ''} ...")
    res = fit_robot(logs, robot, mapping, units, friction=friction, diagnose=diagnose, jobs=jobs,
                    robot_file=str(robot), joint=joint, rigid_body=rigid_body)
    write_params(res, output)
    if "robot_pose" in res.settings:
        rp = res.settings["robot_pose"]
        con.info(f"frictid: {rp['robot']}: fitted one joint at a time ({rp['motion']})")
        for j, said in rp["joints"].items():
            con.info(f"frictid: joint {j}: gravity {said['form']}: {said['note']}")
        return _summarise(res, output, con, as_json, extra={"robot_pose": rp})
    rs = res.settings["robot"]
    rigid = (f"rigid body known from {rs['rigid_body']['file']}" if rs["rigid_body"]["mode"] == "known"
             else f"{len(rs['base_parameters'])} base parameters")
    con.info(f"frictid: {rs['name']}: {rigid}, condition number {rs['condition_number']:.3g}, relative torque "
             f"error {100 * rs['relative_torque_error']:.2f} %")
    for note in rs["notes"]:  # a passed check is said; what was marked or not shown is warned
        if note.startswith(("physical feasibility: ", "known rigid body: the log bears")):
            con.info(f"frictid: {note}")
        else:
            con.warn(note)
    summary = {j: joint_summary(jd) for j, jd in res.to_dict()["joints"].items()}
    for j, f in rs["friction"].items():
        sel = summary[j]["selected"] if friction == "models" else "coulomb_viscous"
        fh = f.get("fh", {})
        held = f", standing {fh['value']:.3g} N m" if "value" in fh and fh.get("identifiable", True) else ""
        if "reason" in f["fc"] and f["fc"].get("stderr") is None:  # nothing estimated (the joint does not move)
            con.info(f"frictid: joint {j}: friction not identifiable: {f['fc']['reason']}")
            continue
        con.info(f"frictid: joint {j}: Fc {f['fc']['value']:.4g} +- {f['fc']['stderr']:.2g}, sigma2 "
                 f"{f['fv']['value']:.4g} +- {f['fv']['stderr']:.2g}, offset {f['fo']['value']:.4g} N m{held} "
                 f"(joint estimate); selected on the friction torque: {sel or 'no model'}")
    if output != "-":
        con.info(f"frictid: wrote {output}")
    if as_json:
        emit_json("fit", {"output": output, "robot": rs, "joints": summary, "warnings": con.warnings})