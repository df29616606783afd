"""The typer application; each command lives in its own module and registers itself here."""
from __future__ import annotations

import typer

app = typer.Typer(
    name="frictid",
    help="Identify friction in robot joints and drives from measured logs.\n\n"
    "Exit codes: 0 success, 2 bad usage or bad input, 3 a quality gate failed, 1 unexpected error. "
    "Add --debug anywhere for a traceback.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def _version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"frictid {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Print the version and exit."),
) -> None:
    """Identify friction in robot joints and drives from measured logs."""
