"""What every command shares: the log-reading options, messages on stderr, and output checks."""
from __future__ import annotations

import sys
from typing import Annotated, Optional

import typer

MapOpt = Annotated[Optional[str], typer.Option(
    "--map", help="Rename columns SOURCE=TARGET (e.g. position=q,torque=tau), or a mapping YAML file.")]
UnitsOpt = Annotated[Optional[str], typer.Option(
    "--units", help="Units of columns not in SI (e.g. q=deg,qd=deg/s,tau=mNm).")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No messages on stderr except errors.")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print a machine-readable summary on stdout.")]


class Console:
    """Human messages go to stderr; ``--quiet`` silences all but errors."""

    def __init__(self, quiet: bool = False):
        self.quiet = quiet

    def info(self, msg: str) -> None:
        if not self.quiet:
            print(msg, file=sys.stderr)

    def warn(self, msg: str) -> None:
        if not self.quiet:
            print(f"frictid: warning: {msg}", file=sys.stderr)

    @property
    def progress(self) -> bool:
        """Progress bars only on a terminal, and not with --quiet."""
        return not self.quiet and sys.stderr.isatty()
