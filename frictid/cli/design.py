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
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Design a band-limited Fourier excitation of every joint, optimised for the condition number of the
    identification's regressor (rigid-body base parameters and each joint's friction) within the joints'
    position, speed and acceleration limits. It starts and ends at rest at the centre of each joint's
    range. Columns: t, then q_J, qd_J, qdd_J per joint J [rad, rad/s, rad/s^2]."""
    import numpy as np
    import pyarrow as pa

    from ..io.atomic import check_output_path
    from ..io.logs import write_table
    from ..robot import load_robot
    from ..robot.design import design_excitation, robot_limits

    con = Console(quiet)
    refuse_json_with_stdout("design", as_json, output)
    check_output_path(output, [robot])
    rb = load_robot(robot)
    lim = robot_limits(rb, fraction)
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
