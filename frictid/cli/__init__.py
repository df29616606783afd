"""Command-line entry point. Thin: parse, call one pipeline function, turn exceptions into exit codes.

Exit codes: 0 success; 2 bad usage or bad input; 3 a quality gate failed; 1 unexpected internal error.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys
import traceback

import typer

from ..errors import FrictidInputError, QualityGateError
from .app import app
from .common import JsonState, emit_json_error

try:  # typer >= 0.24 carries its own click
    from typer._click.exceptions import ClickException
except ImportError:  # pragma: no cover - older typer on click
    from click import ClickException


COMMANDS = ("simulate", "segments", "fit", "report", "compare", "trend", "export", "design")
for _name in COMMANDS:  # each command module registers itself on `app`
    try:
        importlib.import_module(f"{__name__}.{_name}")
    except ModuleNotFoundError as _exc:
        if _exc.name != f"{__name__}.{_name}":
            raise


def _on_sigterm(signum, frame):  # turn SIGTERM into SystemExit so atomic writers clean up
    from ..io.atomic import STOP_REQUESTED

    STOP_REQUESTED.set()
    print("frictid: terminated; no output was written", file=sys.stderr)
    raise SystemExit(128 + signum)


def main(argv: list[str] | None = None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv or bool(os.environ.get("FRICTID_DEBUG"))
    argv = [a for a in argv if a != "--debug"]
    signal.signal(signal.SIGTERM, _on_sigterm)
    JsonState.wanted, JsonState.emitted = "--json" in argv, False
    command = next((a for a in argv if a in COMMANDS), None)
    code, message = 0, ""
    try:
        rv = app(args=argv, prog_name="frictid", standalone_mode=False)
        code = rv if isinstance(rv, int) else 0
        if code == 130:  # typer turns Ctrl-C into a returned 130 when not standalone
            print("frictid: interrupted; no output was written", file=sys.stderr)
    except typer.Exit as exc:
        code = exc.exit_code
    except ClickException as exc:
        exc.show()
        code, message = 2, exc.format_message()
    except (typer.Abort, KeyboardInterrupt):
        print("frictid: interrupted; no output was written", file=sys.stderr)
        code = 130
    except FrictidInputError as exc:
        if debug:
            traceback.print_exc()
        print(f"frictid: error: {exc}", file=sys.stderr)
        code, message = 2, str(exc)
    except QualityGateError as exc:
        if debug:
            traceback.print_exc()
        print(f"frictid: gate failed: {exc}", file=sys.stderr)
        code, message = 3, str(exc)
    except BrokenPipeError:  # the reader of standard output went away (`| head`): 1, as click does
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        code = 1
    except Exception as exc:  # noqa: BLE001 - the one place that turns bugs into exit code 1
        if debug:
            traceback.print_exc()
        message = f"internal error: {exc.__class__.__name__}: {exc}"
        print(f"frictid: {message} (run again with --debug for the traceback, and please report it)",
              file=sys.stderr)
        code = 1
    if code not in (0, 130) and not isinstance(code, bool):
        try:
            emit_json_error(command, code, message or f"exit code {code}")
        except (BrokenPipeError, ValueError):
            pass
    sys.exit(code)
