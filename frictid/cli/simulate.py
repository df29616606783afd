"""``frictid simulate``: run an experiment recipe on a plant and write the log."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from .app import app
from .common import Console, JsonOpt, MapOpt, QuietOpt, UnitsOpt, emit_json, refuse_json_with_stdout


def resolve_recipe(name: str, folder: str = "recipes") -> str:
    """A recipe or plant given as a path, or by name from the shipped ``recipes/`` folder."""
    p = Path(name)
    if p.exists():
        return str(p)
    for base in (Path.cwd() / folder, Path(__file__).resolve().parents[2] / folder):
        for cand in (base / name, base / f"{name}.yaml"):
            if cand.is_file():
                return str(cand)
    return name  # let the loader report it, with the name as given


@app.command()
def simulate(
    recipe: Annotated[Optional[str], typer.Argument(help="Recipe YAML (path, or a name in recipes/).")] = None,
    output: Annotated[str, typer.Option("-o", "--output", help="Output log (.csv or .parquet; - for stdout).")] = ...,
    plant: Annotated[Optional[str], typer.Option(
        "--plant", help="Plant YAML (path, or a name in recipes/plants/); default: the recipe's plant.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Random seed; the same seed gives the same log.")] = 0,
    fmt: Annotated[Optional[str], typer.Option("--format", help="csv or parquet (default: from the suffix).")] = None,
    params: Annotated[Optional[str], typer.Option(
        "--params", help="Parameter YAML from frictid fit: replay its model along --replay LOG.")] = None,
    replay_log: Annotated[Optional[str], typer.Option(
        "--replay", help="Measured log to replay the model along (with --params); writes tau_model, "
                         "residual and, with a known controller, q_model.")] = None,
    model: Annotated[Optional[str], typer.Option(
        "--model", help="With --replay or --compensate: the model to run (default: each joint's selected "
                        "model).")] = None,
    compensate: Annotated[Optional[str], typer.Option(
        "--compensate", help="Parameter YAML from frictid fit: run the recipe in closed loop without friction "
                             "compensation, with the model as feed-forward (along the reference; its static map from "
                             "the measured velocity), with the LuGre friction observer of "
                             "000 on it (when its sigma0 is identified) and with the plant's true friction; "
                             "-o gets the runs (Parquet or CSV).")] = None,
    robot: Annotated[Optional[str], typer.Option(
        "--robot", help="With --params (from frictid fit --robot) and --replay: the robot (DH YAML or URDF); "
                        "predicts every joint's torque, rigid body and friction (docs/robots.md).")] = None,
    mapping: MapOpt = None,
    units: UnitsOpt = None,
    quiet: QuietOpt = False,
    as_json: JsonOpt = False,
) -> None:
    """Simulate a recipe on a plant and write a joint log with truth labels; or, with --params and
    --replay, run an identified model along a measured log and write its prediction and residual."""
    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path
    from ..io.logs import output_format, write_logs
    from ..plant import simulate_recipe

    con = Console(quiet)
    refuse_json_with_stdout("simulate", as_json, output)
    if compensate is not None:
        if params is not None or replay_log is not None or recipe is None:
            raise FrictidInputError("simulate: --compensate takes a recipe and no --params/--replay "
                                    "(frictid simulate --compensate PARAMS.yaml RECIPE -o RUNS.parquet)")
        _compensate(compensate, recipe, output, plant, model, fmt, seed, con, as_json)
        return
    if params is not None or replay_log is not None:
        if params is None or replay_log is None:
            raise FrictidInputError("simulate: --params and --replay go together "
                                    "(frictid simulate --params PARAMS.yaml --replay LOG -o OUT)")
        if recipe is not None:
            raise FrictidInputError("simulate: give either a recipe or --params/--replay, not both")
        _replay(params, replay_log, output, plant, model, fmt, mapping, units, con, as_json, robot)
        return
    if robot is not None:
        raise FrictidInputError("simulate: --robot applies to --params/--replay only "
                                "(frictid simulate --params PARAMS.yaml --replay LOG --robot ROBOT -o OUT)")
    if model is not None or mapping is not None or units is not None:
        raise FrictidInputError("simulate: --model, --map and --units apply to --replay and --compensate only")
    if recipe is None:
        raise FrictidInputError("simulate: give a recipe (e.g. recipes/constant_velocity_sweep.yaml)")
    fmt = output_format(output, fmt)
    recipe_path = resolve_recipe(recipe)
    plant_path = resolve_recipe(plant, "recipes/plants") if plant else None
    check_output_path(output, [recipe_path, plant_path], sidecar=fmt == "csv")
    logs = simulate_recipe(recipe_path, plant_path, seed=seed, progress=con.progress)
    write_logs(logs, output, fmt)
    rows = sum(lg.n for lg in logs)
    con.info(f"frictid: wrote {rows} rows ({len(logs)} joint{'s' if len(logs) != 1 else ''}) to {output}")
    if as_json:
        emit_json("simulate", {"mode": "recipe", "output": output, "format": fmt, "recipe": recipe_path,
                               "plant": plant_path or (logs[0].meta.get("plant") if logs else None),
                               "seed": seed, "rows": rows,
                               "joints": {str(lg.joint): {"rows": lg.n, "duration": float(lg.t[-1] - lg.t[0])}
                                          for lg in logs},
                               "warnings": con.warnings})


def _replay(params, log_path, output, plant, model, fmt, mapping, units, con, as_json=False, robot=None) -> None:
    from ..data import log_warnings
    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path
    from ..io.logs import output_format, read_logs
    from ..io.params import read_params
    from ..io.replay_out import write_replay
    from ..replay import replay_logs

    fmt = output_format(output, fmt)
    plant_path = resolve_recipe(plant, "recipes/plants") if plant else None
    check_output_path(output, [params, log_path, plant_path], mapping, sidecar=fmt == "csv")
    res = read_params(params)
    logs = read_logs(log_path, mapping, units)
    for w in log_warnings(logs):
        con.warn(w)
    if robot is not None:
        if plant is not None or model is not None:
            raise FrictidInputError("simulate: --robot replays the whole-robot model; it takes no --plant or --model")
        from ..robot import load_robot
        from ..robot.replay import replay_robot

        results, info = replay_robot(load_robot(robot), res, logs)
    else:
        results, info = replay_logs(logs, res, model=model, plant=plant_path)
    write_replay(logs, results, output, fmt, {"params": str(params), "log": str(log_path), "joints": info,
                                              "warnings": con.warnings})
    for j, rec in info.items():
        msg = f"frictid: joint {j}: {rec['model']}, residual RMS {rec['rms_residual']:.4g}"
        if rec.get("rms_q_error") is not None:
            msg += f", closed-loop position error RMS {rec['rms_q_error']:.4g}"
        con.info(msg)
    rows = sum(lg.n for lg in logs)
    con.info(f"frictid: wrote {rows} rows to {output}")
    if as_json:
        emit_json("simulate", {"mode": "replay", "output": output, "format": fmt, "params": str(params),
                               "log": str(log_path), "rows": rows, "joints": info, "warnings": con.warnings})


def _compensate(params, recipe, output, plant, model, fmt, seed, con, as_json=False) -> None:
    from ..compensate import compensation_runs
    from ..io.atomic import check_output_path
    from ..io.logs import output_format
    from ..io.params import read_params
    from ..io.replay_out import write_runs

    fmt = output_format(output, fmt)
    recipe_path = resolve_recipe(recipe)
    plant_path = resolve_recipe(plant, "recipes/plants") if plant else None
    check_output_path(output, [params, recipe_path, plant_path], sidecar=fmt == "csv")
    res = read_params(params)
    models = {j: res[j].friction_model(model) for j in res.joints}
    runs = compensation_runs(models, recipe_path, plant_path, seed=seed)
    info = {j: {"model": models[j].name, "runs": {k: r.metrics.to_dict() for k, r in by.items()}}
            for j, by in runs.items()}
    write_runs(runs, output, fmt, {"params": str(params), "recipe": recipe_path, "joints": info})
    for j, rec in info.items():
        m = rec["runs"]
        base = m["none"]["rms_error"]
        parts = [f"{k} {v['rms_error']:.3g} (x{base / v['rms_error']:.3g}), {v['stick_slip_episodes']} stick"
                 for k, v in m.items() if v["rms_error"] > 0]
        con.info(f"frictid: joint {j} ({rec['model']}): tracking error RMS " + "; ".join(parts))
    con.info(f"frictid: wrote the runs to {output}")
    if as_json:
        emit_json("simulate", {"mode": "compensate", "output": output, "params": str(params),
                               "recipe": recipe_path, "seed": seed,
                               "joints": {j: {"model": rec["model"], "runs": rec["runs"]} for j, rec in info.items()},
                               "warnings": con.warnings})
