"""``frictid design``: an excitation trajectory for whole-robot identification, as CSV a controller can play."""
from __future__ import annotations

from typing import Annotated

import typer

from .app import app
from .common import Console, JsonOpt, QuietOpt, emit_json, refuse_json_with_stdout


@app.command()
def design(
    robot: Annotated[str, typer.Argument(help="Robot description: a DH YAML with limits (recipes/robots/) or a URDF.")],
    output: Annotated[str, typer.Option("-o", "--output", help="CSV to write (- for standard output).")],
    period: Annotated[float, typer.Option("--period", min=1.0, help="Period of the Fourier motion [s].")] = 10.0,
    harmonics: Annotated[int, typer.Option("--harmonics", min=1, max=20, help="Harmonics per joint.")] = 5,
    fraction: Annotated[float, typer.Option(
        "--fraction", min=0.01, max=1.0, help="Share of the speed and acceleration limits the motion may use.")] = 0.5,
    rate: Annotated[float, typer.Option("--rate", min=1.0, help="Sample rate of the CSV [Hz].")] = 100.0,
    iterations: Annotated[int, typer.Option("--iterations", min=1, help="Optimiser evaluations.")] = 300,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the random starts.")] = 0,
    experiment: Annotated[str, typer.Option(
        "--experiment", help="fourier (the excitation), sweep (each joint's constant-velocity plateaus, position "
                             "mode) or ramps (each joint's presliding torque ramps, torque mode; needs --params).")] = "fourier",
    params: Annotated[str, typer.Option(
        "--params", help="With --experiment ramps: a parameter file of frictid fit --robot (the holding torque "
                         "and each joint's Coulomb level).")] = None,
    speeds: Annotated[int, typer.Option("--speeds", min=2, help="With --experiment sweep: speeds per joint.")] = 12,
    plateau: Annotated[float, typer.Option("--plateau", min=0.5, help="With --experiment sweep: plateau length [s].")] = 2.0,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Design a band-limited Fourier excitation of every joint, optimised for the condition number of the
    identification's regressor (rigid-body base parameters and each joint's friction) within the joints'
    position, speed and acceleration limits. It starts and ends at rest at the centre of each joint's
    range. Columns: t, then q_J, qd_J, qdd_J per joint J [rad, rad/s, rad/s^2]."""
    import numpy as np
    import pyarrow as pa

    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path
    from ..io.logs import write_table
    from ..robot import load_robot
    from ..robot.design import design_excitation, robot_limits

    con = Console(quiet)
    refuse_json_with_stdout("design", as_json, output)
    check_output_path(output, [robot] + ([params] if params else []))
    if experiment not in ("fourier", "sweep", "ramps"):
        raise FrictidInputError(f"design: --experiment must be fourier, sweep or ramps, not {experiment!r}")
    if (experiment == "ramps") != (params is not None):
        raise FrictidInputError("design: --params goes with --experiment ramps (the ramps' holding torque and "
                                "levels come from a parameter file of frictid fit --robot)")
    rb = load_robot(robot)
    lim = robot_limits(rb, fraction)
    if experiment != "fourier":
        return _experiment(rb, lim, experiment, params, output, rate, speeds, plateau, con, as_json)
    tr = design_excitation(rb, lim, period=period, harmonics=harmonics, iterations=iterations, rate=rate, seed=seed)
    cols = {"t": tr.t}
    for i, j in enumerate(rb.joints):
        cols[f"q_{j}"], cols[f"qd_{j}"], cols[f"qdd_{j}"] = tr.q[:, i], tr.qd[:, i], tr.qdd[:, i]
    write_table(pa.table({k: pa.array(np.asarray(v, dtype=float)) for k, v in cols.items()}), output, "csv")
    con.info(f"frictid: {rb.name}: condition number {tr.condition:.1f} (random starts: median "
             f"{tr.condition_start:.1f}); {tr.t.size} samples over {period:g} s")
    if output != "-":
        con.info(f"frictid: wrote {output}")
    if as_json:
        emit_json("design", {"output": output, "robot": rb.name, "condition": tr.condition,
                             "condition_random_start": tr.condition_start, "period": period, "samples": int(tr.t.size),
                             "joints": {j: {"range": [float(tr.q[:, i].min()), float(tr.q[:, i].max())],
                                            "peak_speed": float(np.abs(tr.qd[:, i]).max()),
                                            "peak_acceleration": float(np.abs(tr.qdd[:, i]).max())}
                                        for i, j in enumerate(rb.joints)}})


def _experiment(rb, lim, kind, params, output, rate, speeds, plateau, con, as_json) -> None:
    """``frictid design --experiment sweep|ramps``: each joint's single-joint experiment, as CSV."""
    import numpy as np
    import pyarrow as pa

    from ..io.logs import write_table
    from ..io.params import read_params
    from ..robot.experiments import holding_torque, ramp_experiment, sweep_experiment
    from ..robot.replay import fit_from_params

    if kind == "sweep":
        ex = sweep_experiment(rb, lim, speeds=speeds, plateau_s=plateau, rate=rate)
    else:
        res = read_params(params)
        fit = fit_from_params(rb, res)
        fr = res.settings["robot"].get("friction") or {j: {"fc": {"value": res[j].models["coulomb_viscous"].params["Fc"].value},
                                                           "fo": {"value": res[j].offset.value}} for j in rb.joints}
        levels = {j: abs(float(fr[j]["fc"]["value"])) for j in rb.joints}
        offsets = np.array([float(fr[j]["fo"]["value"]) for j in rb.joints])
        hold = holding_torque(rb, fit, 0.5 * (lim.lo + lim.hi), offsets)
        ex = ramp_experiment(rb, lim, hold, levels, rate=rate)
    cols = {"t": ex.t, "active_joint": ex.active + 1.0}
    for i, j in enumerate(rb.joints):
        if ex.tau is not None:
            cols[f"q_{j}"], cols[f"tau_{j}"] = ex.q[:, i], ex.tau[:, i]
        else:
            cols[f"q_{j}"], cols[f"qd_{j}"], cols[f"qdd_{j}"] = ex.q[:, i], ex.qd[:, i], ex.qdd[:, i]
    write_table(pa.table({k: pa.array(np.asarray(v, dtype=float)) for k, v in cols.items()}), output, "csv")
    for n in ex.notes:
        con.info(f"frictid: {n}")
    con.info(f"frictid: {rb.name}: {kind}, {ex.t.size} samples over {ex.t[-1]:.1f} s")
    if output != "-":
        con.info(f"frictid: wrote {output}")
    if as_json:
        emit_json("design", {"output": output, "robot": rb.name, "experiment": kind, "samples": int(ex.t.size),
                             "duration": float(ex.t[-1]), "notes": ex.notes})
