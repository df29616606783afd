"""``frictid export``: identified models for simulators and controllers (MuJoCo, URDF, C, JSON)."""
from __future__ import annotations

from typing import Annotated, List, Optional

import typer

from .app import app
from .common import Console, JsonOpt, QuietOpt, emit_json, refuse_json_with_stdout


@app.command()
def export(
    params: Annotated[str, typer.Argument(help="Parameter YAML written by frictid fit.")],
    to: Annotated[str, typer.Option("--to", help="Format: mjcf, urdf, c (a C header) or json.")],
    output: Annotated[str, typer.Option("-o", "--output", help="File to write (- for standard output).")],
    into: Annotated[Optional[str], typer.Option(
        "--into", help="An MJCF or URDF model whose joints (matched by name) get the friction attributes; "
                       "without it a new file is written (mjcf) or a snippet (urdf).")] = None,
    joint: Annotated[Optional[List[str]], typer.Option(
        "--joint", help="Export only this joint (repeat for several); default every joint.")] = None,
    model: Annotated[Optional[str], typer.Option(
        "--model", help="Export this model of each joint instead of the selected one.")] = None,
    temperature: Annotated[Optional[float], typer.Option(
        "--temperature", help="Joint temperature [degC] at which a thermal model is exported to mjcf/urdf "
                              "(default: its reference temperature).")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Export each joint's identified model: MuJoCo joint attributes (frictionloss, damping, inertia),
    URDF <dynamics>, a C header with one friction function per joint, or JSON with a sampling distribution
    per parameter. Where the format cannot hold the model, the approximation error over the joint's
    validity range is printed."""
    from ..export import export as run_export
    from ..io.atomic import atomic_open, check_output_path
    from ..models.params import unit_of

    con = Console(quiet)
    refuse_json_with_stdout("export", as_json, output)
    check_output_path(output, [params] + ([into] if into else []))
    ex = run_export(params, to, into=into, joints=joint, model=model, temperature=temperature)
    with atomic_open(output) as fh:
        fh.write(ex.text)
    lines = []
    for m in ex.models:
        form = next((f for f in ex.forms if f.joint == m.joint), None)
        unit = unit_of("F", m.axis)
        if form is None:
            lines.append({"joint": m.joint, "model": m.name, "exact": True, "text": f"{m.joint}: {m.name}"})
            continue
        d1, d2, d3 = form.damping
        text = (f"{m.joint}: {m.name} -> frictionloss {form.frictionloss:.4g} {unit}, damping {d1:.4g}"
                + (f" {d2:.4g} {d3:.4g}" if to == "mjcf" and (d2 or d3) else "") + f"; {form.summary(unit)}")
        lines.append({"joint": m.joint, "model": m.name, "exact": form.exact, "frictionloss": form.frictionloss,
                      "damping": list(form.damping), "max_error": form.max_error, "rms_error": form.rms_error,
                      "speeds": list(form.speeds), "notes": form.notes, "text": text})
    if as_json:
        emit_json("export", {"output": output, "format": to, "joints": lines})
        return
    for ln in lines:
        con.info(ln["text"])
        for note in ln.get("notes", []):
            con.info(f"  {note}")
    if output != "-":
        con.info(f"wrote {output}")
