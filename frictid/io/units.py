"""Units of the joint-log columns: what can be declared and how it converts to SI.

Declared with ``--units q=deg,qd=deg/s,tau=mNm`` or in metadata (``units:``). A declared linear unit
(m, mm, N, ...) makes the axis linear. Scaling factors are also accepted: ``tau=0.125*A`` is not a unit;
use the mapping file's ``scale:`` for that.
"""
from __future__ import annotations

import math

from ..errors import FrictidInputError

_DEG = math.pi / 180.0
_REV = 2.0 * math.pi

# unit -> (factor to SI, axis it implies or None)
POSITION = {"rad": (1.0, "rotary"), "deg": (_DEG, "rotary"), "rev": (_REV, "rotary"),
            "mrad": (1e-3, "rotary"), "m": (1.0, "linear"), "mm": (1e-3, "linear"), "um": (1e-6, "linear")}
VELOCITY = {"rad/s": (1.0, "rotary"), "deg/s": (_DEG, "rotary"), "rpm": (_REV / 60.0, "rotary"),
            "rev/s": (_REV, "rotary"), "m/s": (1.0, "linear"), "mm/s": (1e-3, "linear"),
            "m/min": (1.0 / 60.0, "linear")}
TORQUE = {"N m": (1.0, "rotary"), "Nm": (1.0, "rotary"), "mN m": (1e-3, "rotary"), "mNm": (1e-3, "rotary"),
          "kN m": (1e3, "rotary"), "kNm": (1e3, "rotary"), "N": (1.0, "linear"), "kN": (1e3, "linear"),
          "mN": (1e-3, "linear")}
TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0}
MASS = {"kg": 1.0, "g": 1e-3}

_COLUMN_TABLES = {
    "q": POSITION, "q_ref": POSITION,
    "qd": VELOCITY, "qd_ref": VELOCITY,
    "tau": TORQUE, "tau_ref": TORQUE,
    "t": TIME,
    "payload": MASS,
}
_TEMPERATURE = ("temp_env", "temp_joint")


def parse_units(text: str | None) -> dict[str, str]:
    """``"q=deg,qd=deg/s"`` -> ``{"q": "deg", "qd": "deg/s"}``."""
    out: dict[str, str] = {}
    if not text:
        return out
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        if "=" not in item:
            raise FrictidInputError(f"--units: {item!r} is not COLUMN=UNIT (e.g. --units q=deg,qd=deg/s)")
        col, unit = (s.strip() for s in item.split("=", 1))
        out[col] = unit
    return out


def conversion(column: str, unit: str, where: str = "--units") -> tuple[float, float, str | None]:
    """(factor, offset, axis) converting ``column`` given in ``unit`` to SI: ``si = factor * x + offset``."""
    unit = unit.strip()
    if column in _TEMPERATURE:
        if unit in ("degC", "C", "celsius"):
            return 1.0, 0.0, None
        if unit == "K":
            return 1.0, -273.15, None
        raise FrictidInputError(f"{where}: unit {unit!r} of column {column!r} unknown; use degC or K")
    table = _COLUMN_TABLES.get(column)
    if table is None:
        raise FrictidInputError(
            f"{where}: column {column!r} takes no unit; units apply to "
            f"{', '.join(list(_COLUMN_TABLES) + list(_TEMPERATURE))}")
    if unit not in table:
        raise FrictidInputError(
            f"{where}: unit {unit!r} of column {column!r} unknown; known: {', '.join(table)}")
    entry = table[unit]
    if isinstance(entry, tuple):
        return entry[0], 0.0, entry[1]
    return entry, 0.0, None
