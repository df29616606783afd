"""``frictid compare``: the change of every parameter between two identifications, and a gate on it."""
from __future__ import annotations

from typing import Annotated, Optional

import typer

from .app import app
from .common import Console, JsonOpt, QuietOpt, emit_json


def _fmt(x, digits=4) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


@app.command()
def compare(
    base: Annotated[str, typer.Argument(help="Parameter YAML of the reference identification (- for stdin).")],
    new: Annotated[str, typer.Argument(help="Parameter YAML of the new identification (- for stdin).")],
    tol: Annotated[Optional[str], typer.Option(
        "--tol", help="Limits, e.g. Fc=10%,sigma2=15%,J=0.01 (absolute, in the unit); *=20% for all.")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Compare two parameter files; exit code 3 when a change exceeds its tolerance."""
    from ..compare import compare as run_compare, parse_tolerances
    from ..errors import FrictidInputError, QualityGateError
    from ..io.params_load import load_params_dict

    con = Console(quiet)
    if base == "-" and new == "-":
        raise FrictidInputError("compare: standard input (-) can give only one of the two parameter files")
    tolerances = parse_tolerances(tol)
    result = run_compare(load_params_dict(base), load_params_dict(new), tolerances)
    if as_json:
        emit_json("compare", {"base": base, "new": new, "tolerances": [str(t.pattern) + "=" + str(t)
                                                                      for t in tolerances],
                              "changes": [c.to_dict() for c in result.changes], "failed": len(result.failed),
                              "exceeded": [f"{c.joint}:{c.name}" for c in result.failed],
                              "notes": result.notes, "warnings": result.notes},
                  ok=not result.failed)
    else:
        head = f"{'joint':<8} {'param':<14} {'base':>11} {'new':>11} {'change':>9} {'+-':>9} {'z':>6}  tol"
        print(head)
        for c in result.changes:
            rel = "-" if c.relative is None else f"{100 * c.relative:+.1f}%"
            flag = "  EXCEEDS" if c.exceeds else ""
            print(f"{c.joint:<8} {c.name:<14} {_fmt(c.base):>11} {_fmt(c.new):>11} {rel:>9} "
                  f"{_fmt(c.stderr, 2):>9} {_fmt(c.z, 2):>6}  {c.tolerance or '-'}{flag}")
    for note in result.notes:
        con.warn(note)
    if result.failed:
        names = ", ".join(f"{c.joint}:{c.name}" for c in result.failed)
        raise QualityGateError(f"{len(result.failed)} parameter(s) changed beyond tolerance: {names}")
