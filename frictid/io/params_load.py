"""Load a parameter file as a plain dictionary, with a clear error when it is not one."""
from __future__ import annotations

from pathlib import Path

import yaml

from ..errors import ConfigError

SCHEMA = 1


def load_params_dict(path: str) -> dict:
    """The parsed parameter YAML (schema 1); ``-`` reads it from standard input. Raises
    :class:`ConfigError` naming the file and key."""
    try:
        if str(path) == "-":
            import sys

            path, text = "<stdin>", sys.stdin.buffer.read().decode("utf-8")
        else:
            p = Path(path)
            if not p.is_file():
                raise ConfigError(f"{path}: parameter file not found")
            text = p.read_text(encoding="utf-8")
        # libyaml's loader when built in: 5x faster on the segment lists of long logs, same values
        d = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: not a valid YAML parameter file ({exc.__class__.__name__})") from None
    if not isinstance(d, dict):
        raise ConfigError(f"{path}: expected a mapping with keys schema, frictid, joints, sources")
    if d.get("schema") != SCHEMA:
        raise ConfigError(f"{path}: schema: expected {SCHEMA}, found {d.get('schema')!r}; "
                          "was it written by frictid fit?")
    if not isinstance(d.get("joints"), dict):
        raise ConfigError(f"{path}: joints: missing or not a mapping")
    return d
