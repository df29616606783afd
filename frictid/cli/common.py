"""What every command shares: the log-reading options, messages on stderr, the ``--json`` summary and
output checks.

``--json`` prints exactly one JSON document on standard output (shapes in ``docs/cli.md``): the command's
summary on success, or ``{"schema": 1, "command": ..., "ok": false, "exit_code": N, "error": ...}`` when
it fails. Human messages always go to standard error.
"""
from __future__ import annotations

import json
import sys
from typing import Annotated, Optional

import typer

from ..result import plain

#: Version of the ``--json`` shapes; bumped only when a key is removed or changes meaning.
JSON_SCHEMA = 1

MapOpt = Annotated[Optional[str], typer.Option(
    "--map", help="Rename columns SOURCE=TARGET (e.g. position=q,torque=tau), or a mapping YAML file.")]
UnitsOpt = Annotated[Optional[str], typer.Option(
    "--units", help="Units of columns not in SI (e.g. q=deg,qd=deg/s,tau=mNm).")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No messages on stderr except errors.")]
JsonOpt = Annotated[bool, typer.Option(
    "--json", help="Print a machine-readable summary on stdout (one JSON document; see docs/cli.md). "
                   "Refused with -o - (standard output then carries the data).")]


class Console:
    """Human messages go to stderr; ``--quiet`` silences all but errors. Warnings are also kept (in
    :attr:`warnings`) for the ``--json`` summary and the output files."""

    def __init__(self, quiet: bool = False):
        self.quiet = quiet
        self.warnings: list[str] = []

    def info(self, msg: str) -> None:
        if not self.quiet:
            print(msg, file=sys.stderr)

    def warn(self, msg: str) -> None:
        self.warnings.append(msg)
        if not self.quiet:
            print(f"frictid: warning: {msg}", file=sys.stderr)

    @property
    def progress(self) -> bool:
        """Progress bars only on a terminal, and not with --quiet."""
        return not self.quiet and sys.stderr.isatty()


def refuse_json_with_stdout(command: str, as_json: bool, output: str | None) -> None:
    """``--json`` and ``-o -`` both want standard output: refuse the pair (exit code 2)."""
    from ..errors import FrictidInputError

    if as_json and output == "-":
        raise FrictidInputError(f"{command}: --json prints its summary on standard output, which -o - already "
                                "uses for the data; write the output to a file (-o FILE) or leave out --json")


class JsonState:
    """Whether this run asked for ``--json`` and whether its document was printed (so that a failure
    after the summary, e.g. compare's gate, does not print a second document)."""

    wanted = False
    emitted = False


def emit_json(command: str, payload: dict, ok: bool = True) -> None:
    """Print the one JSON document of a command on standard output."""
    doc = {"schema": JSON_SCHEMA, "command": command, "ok": ok, **payload}
    sys.stdout.write(json.dumps(plain(doc), indent=1, allow_nan=False) + "\n")
    sys.stdout.flush()
    JsonState.emitted = True


def emit_json_error(command: str | None, code: int, message: str) -> None:
    """The ``--json`` document of a failed run (nothing when the command already printed its own)."""
    if not JsonState.wanted or JsonState.emitted:
        return
    emit_json(command or "", {"exit_code": code, "error": message, "warnings": []}, ok=False)


def _entry(e) -> dict | None:
    if not isinstance(e, dict):
        return None
    out = {k: e.get(k) for k in ("value", "stderr", "unit", "identifiable")}
    if e.get("reason"):
        out["reason"] = e["reason"]
    return out


def joint_summary(jd: dict) -> dict:
    """The ``--json`` summary of one joint of a parameter file (schema 1, as a dictionary): the chosen
    model with its parameters, inertia and offset, what could not be identified, the diagnosis' findings
    and the warnings."""
    from ..report.build import heldout_basis

    sel = jd.get("selected")
    model = (jd.get("models") or {}).get(sel) or {} if sel else {}
    metrics = model.get("metrics") or {}
    rms = metrics.get("rms_heldout")
    return {
        "selected": sel,
        "map": model.get("map"),
        "rms_heldout": rms,
        "rms_heldout_basis": heldout_basis(jd, sel) if sel and rms is not None else None,
        "units": jd.get("units") or {},
        "params": {n: _entry(e) for n, e in (model.get("params") or {}).items()},
        "inertia": _entry(jd.get("inertia")),
        "offset": _entry(jd.get("offset")),
        "not_identified": [{"what": x.get("what"), "reason": x.get("reason")}
                           for x in jd.get("not_identified") or [] if isinstance(x, dict)],
        "findings": [{k: f.get(k) for k in ("cause", "extension", "model", "gain", "evidence")}
                     for f in jd.get("diagnosis") or [] if isinstance(f, dict)],
        "warnings": [str(w) for w in jd.get("warnings") or []],
    }
