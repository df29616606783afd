"""``frictid fit``: identify friction models (not yet available)."""
from __future__ import annotations

from typing import Annotated, List, Optional

import typer

from .app import app


@app.command()
def fit(
    logs: Annotated[Optional[List[str]], typer.Argument(help="Joint logs (CSV, Parquet, - for stdin).")] = None,
    output: Annotated[Optional[str], typer.Option("-o", "--output", help="Parameter YAML to write.")] = None,
) -> None:
    """Identify friction models and write a parameter YAML (not yet available)."""
    from ..errors import FrictidInputError

    raise FrictidInputError("fit: not yet available in this version")
