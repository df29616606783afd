"""Compare two identifications of the same robot: the wear and drift gate.

Works on loaded parameter files (plain dictionaries of schema 1), so it needs no numerics beyond the
change and its uncertainty ``sqrt(se_base^2 + se_new^2)``.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from .errors import FrictidInputError


@dataclass(frozen=True)
class Tolerance:
    """A limit on the change of one parameter: relative (``10%``) or absolute (in the parameter's unit)."""

    pattern: str
    limit: float
    relative: bool

    def matches(self, name: str) -> bool:
        if self.pattern == "*":
            return True
        return name == self.pattern or re.fullmatch(re.escape(self.pattern) + r"_(pos|neg)", name) is not None

    def exceeded(self, base: float, new: float) -> bool:
        change = abs(new - base)
        if self.relative:
            return change > self.limit * abs(base) if base != 0 else change > 0
        return change > self.limit

    def __str__(self) -> str:
        return f"{self.limit * 100:g}%" if self.relative else f"{self.limit:g}"


def parse_tolerances(text: str | None) -> list[Tolerance]:
    """``"Fc=10%,sigma2=15%,J=0.01,*=25%"`` -> tolerances; a name also covers its ``_pos``/``_neg`` forms."""
    out: list[Tolerance] = []
    if not text:
        return out
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*|\*)\s*=\s*([0-9.eE+-]+)\s*(%?)", item)
        if not m:
            raise FrictidInputError(f"--tol: {item!r} is not NAME=LIMIT (e.g. Fc=10% or J=0.01)")
        try:
            value = float(m.group(2))
        except ValueError:
            raise FrictidInputError(f"--tol: {m.group(2)!r} in {item!r} is not a number") from None
        if value < 0:
            raise FrictidInputError(f"--tol: {item!r}: a limit cannot be negative")
        rel = m.group(3) == "%"
        out.append(Tolerance(m.group(1), value / 100.0 if rel else value, rel))
    return out


@dataclass
class Change:
    joint: str
    model: str
    name: str
    unit: str
    base: float
    new: float
    stderr: float | None
    tolerance: Tolerance | None = None

    @property
    def change(self) -> float:
        return self.new - self.base

    @property
    def relative(self) -> float | None:
        return self.change / abs(self.base) if self.base else None

    @property
    def z(self) -> float | None:
        """Change over its standard error; None when either file has no standard error."""
        if self.stderr is None or not self.stderr > 0:
            return None
        return self.change / self.stderr

    @property
    def exceeds(self) -> bool:
        return self.tolerance is not None and self.tolerance.exceeded(self.base, self.new)

    def to_dict(self) -> dict:
        return {"joint": self.joint, "model": self.model, "param": self.name, "unit": self.unit,
                "base": self.base, "new": self.new, "change": self.change, "relative": self.relative,
                "stderr": self.stderr, "z": self.z,
                "tolerance": None if self.tolerance is None else str(self.tolerance), "exceeds": self.exceeds}


@dataclass
class Comparison:
    changes: list[Change] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def failed(self) -> list[Change]:
        return [c for c in self.changes if c.exceeds]


def _entries(joint_block: dict, model: str) -> dict[str, dict]:
    """Parameter entries of a model plus the joint's inertia/gravity/offset blocks."""
    out = {}
    params = ((joint_block.get("models") or {}).get(model) or {}).get("params") or {}
    for name, e in params.items():
        if isinstance(e, dict) and e.get("value") is not None:
            out[name] = e
    for key, name in (("inertia", "J"), ("offset", "offset")):
        e = joint_block.get(key)
        if isinstance(e, dict) and e.get("value") is not None:
            out[name] = e
    grav = joint_block.get("gravity")
    if isinstance(grav, dict):
        for name, e in grav.items():
            if isinstance(e, dict) and e.get("value") is not None:
                out[name] = e
    return out


def _f(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def compare(base: dict, new: dict, tolerances: list[Tolerance]) -> Comparison:
    """Per joint and parameter of the selected model, the change from ``base`` to ``new``."""
    res = Comparison()
    bj, nj = base.get("joints") or {}, new.get("joints") or {}
    for joint in bj:
        if joint not in nj:
            res.notes.append(f"joint {joint}: only in the base file")
            continue
        b, n = bj[joint], nj[joint]
        model = b.get("selected")
        if model != n.get("selected"):
            res.notes.append(f"joint {joint}: selected model changed from {model} to {n.get('selected')}; "
                             f"comparing {model}'s parameters where the new file has them")
        be, ne = _entries(b, model), _entries(n, model) if model in (n.get("models") or {}) else _entries(n, "")
        for name, e in be.items():
            if name not in ne:
                continue
            bv, nv = _f(e.get("value")), _f(ne[name].get("value"))
            if bv is None or nv is None:
                continue
            s1, s2 = _f(e.get("stderr")), _f(ne[name].get("stderr"))
            se = math.hypot(s1, s2) if s1 is not None and s2 is not None else None
            tol = next((t for t in tolerances if t.matches(name)), None)
            res.changes.append(Change(joint, model, name, str(e.get("unit", "")), bv, nv, se, tol))
    for joint in nj:
        if joint not in bj:
            res.notes.append(f"joint {joint}: only in the new file")
    used = {t.pattern for t in tolerances if any(c.tolerance is t for c in res.changes)}
    for t in tolerances:
        if t.pattern not in used and t.pattern != "*":
            res.notes.append(f"--tol {t.pattern}: no parameter of that name in the selected models")
    return res
