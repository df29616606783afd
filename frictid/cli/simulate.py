"""``frictid simulate``: run an experiment recipe on a plant and write the log."""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from .app import app
from .common import QuietOpt, Console


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
    quiet: QuietOpt = False,
) -> None:
    """Simulate a recipe on a plant and write a joint log with truth labels."""
    from ..errors import FrictidInputError
    from ..io.atomic import check_output_path
    from ..io.logs import output_format, write_logs
    from ..plant import simulate_recipe

    con = Console(quiet)
    if recipe is None:
        raise FrictidInputError("simulate: give a recipe (e.g. recipes/constant_velocity_sweep.yaml)")
    check_output_path(output, [recipe] + ([plant] if plant else []))
    fmt = output_format(output, fmt)
    plant_path = resolve_recipe(plant, "recipes/plants") if plant else None
    logs = simulate_recipe(resolve_recipe(recipe), plant_path, seed=seed, progress=con.progress)
    write_logs(logs, output, fmt)
    rows = sum(lg.n for lg in logs)
    con.info(f"frictid: wrote {rows} rows ({len(logs)} joint{'s' if len(logs) != 1 else ''}) to {output}")
