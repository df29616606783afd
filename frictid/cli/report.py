"""``frictid report``: the HTML report (not yet available)."""
from __future__ import annotations

from typing import Annotated, List, Optional

import typer

from .app import app


@app.command()
def report(
    params: Annotated[Optional[str], typer.Argument(help="Parameter YAML written by frictid fit.")] = None,
    logs: Annotated[Optional[List[str]], typer.Argument(help="Logs to draw.")] = None,
    output: Annotated[Optional[str], typer.Option("-o", "--output", help="Output HTML file.")] = None,
) -> None:
    """Write a self-contained HTML report (not yet available)."""
    from ..errors import FrictidInputError

    raise FrictidInputError("report: not yet available in this version")
