"""Result objects of an identification: one parameter, one model, one joint, one run.

Every number carries its standard error and an ``identifiable`` verdict with the reason when the data
could not pin it down. :meth:`FitResult.to_dict` gives the schema-1 parameter file (documented in
``docs/parameter-file.md``); :mod:`frictid.io.params` is its one writer and reader (schema-checked,
atomic). Numbers only: no files here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import ConfigError
from .model import FrictionModel
from .version import __version__

SCHEMA_VERSION = 1


def _num(x) -> float | None:
    """A plain float for YAML, or None for missing / non-finite values."""
    if x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


@dataclass
class ParamEstimate:
    """One identified number: value [unit] and its standard error [unit].

    identifiable is False (with ``reason``) when the data cannot pin the value down: then ``value`` is the
    optimiser's number (or None when there were no data at all) and must not be trusted. ``fixed``
    parameters were held at a stated value (``reason`` says why) and have no standard error.
    """

    name: str
    value: float | None
    stderr: float | None
    unit: str
    identifiable: bool = True
    reason: str = ""
    fixed: bool = False
    source: str = ""
    #: (lower, upper) the optimiser kept the value within [unit], where the fit had bounds (static maps)
    bounds: tuple[float, float] | None = None

    def to_dict(self) -> dict:
        d: dict[str, Any] = {"value": _num(self.value), "stderr": _num(self.stderr), "unit": self.unit,
                             "identifiable": bool(self.identifiable)}
        if self.reason:
            d["reason"] = self.reason
        if self.fixed:
            d["fixed"] = True
        if self.source:
            d["source"] = self.source
        if self.bounds is not None:
            d["bounds"] = [_num(self.bounds[0]), _num(self.bounds[1])]
        return d

    @classmethod
    def from_dict(cls, name: str, d: dict) -> "ParamEstimate":
        return cls(name=name, value=d.get("value"), stderr=d.get("stderr"), unit=d.get("unit", ""),
                   identifiable=bool(d.get("identifiable", True)), reason=d.get("reason", ""),
                   fixed=bool(d.get("fixed", False)), source=d.get("source", ""),
                   bounds=tuple(d["bounds"]) if d.get("bounds") else None)

    @property
    def rel_err(self) -> float:
        if self.value is None or self.stderr is None or self.value == 0:
            return math.inf
        return abs(self.stderr / self.value)


@dataclass
class ModelFit:
    """One fitted model of one joint.

    name : model name (``stribeck_asym``, ``lugre``, ``thermal6``, ...). map : the static map that evaluates
    its steady state (``frictid.models.static.evaluate(map, w, values)``). params : name -> estimate.
    metrics : rms, rms_heldout, aic, n, k (and model-specific extras). method : how it was identified.
    """

    name: str
    map: str
    params: dict[str, ParamEstimate]
    metrics: dict[str, float | int | None] = field(default_factory=dict)
    method: str = ""
    notes: list[str] = field(default_factory=list)
    success: bool = True
    cov: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def values(self) -> dict[str, float]:
        """Parameter values by name (None where unknown)."""
        return {n: p.value for n, p in self.params.items()}

    @property
    def identifiable(self) -> bool:
        return all(p.identifiable or p.fixed for p in self.params.values())

    def to_dict(self) -> dict:
        d: dict[str, Any] = {"map": self.map, "method": self.method,
                             "params": {n: p.to_dict() for n, p in self.params.items()},
                             "metrics": plain(self.metrics)}
        for k, v in self.extra.items():
            d[k] = plain(v)
        if self.notes:
            d["notes"] = list(self.notes)
        return d

    @classmethod
    def from_dict(cls, name: str, d: dict) -> "ModelFit":
        known = {"map", "method", "params", "metrics", "notes"}
        return cls(name=name, map=d.get("map", name), method=d.get("method", ""),
                   params={n: ParamEstimate.from_dict(n, p) for n, p in (d.get("params") or {}).items()},
                   metrics=dict(d.get("metrics") or {}), notes=list(d.get("notes") or []),
                   extra={k: v for k, v in d.items() if k not in known})


def plain(x):
    """Plain Python data for YAML and JSON, the one converter of the package: dicts (string keys), lists
    (from tuples and arrays), bool, int, float (non-finite ones become None), str and None; objects with
    ``to_dict`` through it; anything else as its string."""
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return [plain(v) for v in x.tolist()]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return _num(x)
    if hasattr(x, "to_dict"):
        return plain(x.to_dict())
    if x is None or isinstance(x, str):
        return x
    return str(x)


@dataclass
class JointFit:
    """Everything identified for one joint."""

    joint: str
    axis: str = "rotary"
    units: dict[str, str] = field(default_factory=dict)
    inertia: ParamEstimate | None = None
    gravity: dict[str, ParamEstimate] = field(default_factory=dict)
    offset: ParamEstimate | None = None
    segments: dict[str, int] = field(default_factory=dict)
    segments_used: dict[str, list[list[float]]] = field(default_factory=dict)
    models: dict[str, ModelFit] = field(default_factory=dict)
    selected: str | None = None
    selection: dict[str, Any] = field(default_factory=dict)
    not_identified: list[dict[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    diagnosis: list[Any] = field(default_factory=list)
    #: the segments the fit worked on, per log: {source, rows, kind, i0, i1, cycle} (lists, one item per
    #: segment; cycle -1 when none). Lets ``frictid report`` skip re-segmenting the same file.
    segment_list: list[dict[str, Any]] = field(default_factory=list)
    #: ranges the data covered: ``speed`` [lo, hi] of |w| [q/s] on the static maps' basis, ``temperature``
    #: [degC], ``position`` [q]; what :attr:`frictid.model.FrictionModel.validity` warns outside of
    validity: dict[str, list[float]] = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = self._to_dict()
        head = self._head()
        if head is not None:  # first: all a feed-forward user needs; the evidence follows
            d = {"model": head, **d}
        if self.validity:  # optional keys: files without them stay as before
            d["validity"] = plain(self.validity)
        if self.segment_list:
            d["segment_list"] = plain(self.segment_list)
        return d

    def _to_dict(self) -> dict:
        return {
            "axis": self.axis,
            "units": dict(self.units),
            "inertia": self.inertia.to_dict() if self.inertia else None,
            "gravity": {n: p.to_dict() for n, p in self.gravity.items()},
            "offset": self.offset.to_dict() if self.offset else None,
            "segments": {k: int(v) for k, v in self.segments.items()},
            "segments_used": plain(self.segments_used),
            "models": {n: m.to_dict() for n, m in self.models.items()},
            "selected": self.selected,
            "selection": plain(self.selection),
            "not_identified": plain(self.not_identified),
            "warnings": list(self.warnings),
            "diagnosis": plain(self.diagnosis),
        }

    def _head(self) -> dict | None:
        """The selected model's head (:meth:`FrictionModel.head`), or None without a usable selection."""
        if not self.selected:
            return None
        try:
            return plain(FrictionModel.from_joint(self).head())
        except (ConfigError, KeyError, ValueError):
            return None

    @classmethod
    def from_dict(cls, joint: str, d: dict) -> "JointFit":
        def pe(name, x):
            return ParamEstimate.from_dict(name, x) if x else None
        return cls(
            joint=joint, axis=d.get("axis", "rotary"), units=dict(d.get("units") or {}),
            inertia=pe("J", d.get("inertia")),
            gravity={n: ParamEstimate.from_dict(n, p) for n, p in (d.get("gravity") or {}).items()},
            offset=pe("offset", d.get("offset")),
            segments=dict(d.get("segments") or {}), segments_used=dict(d.get("segments_used") or {}),
            models={n: ModelFit.from_dict(n, m) for n, m in (d.get("models") or {}).items()},
            selected=d.get("selected"), selection=dict(d.get("selection") or {}),
            not_identified=list(d.get("not_identified") or []), warnings=list(d.get("warnings") or []),
            diagnosis=list(d.get("diagnosis") or []), segment_list=list(d.get("segment_list") or []),
            validity=dict(d.get("validity") or {}))

    @property
    def selected_fit(self) -> ModelFit | None:
        """The fit record (parameters, metrics) of the selected model."""
        return self.models.get(self.selected) if self.selected else None

    @property
    def model(self) -> FrictionModel:
        """The selected model as a :class:`~frictid.model.FrictionModel` (evaluates itself)."""
        return FrictionModel.from_joint(self)

    def friction_model(self, name: str | None = None) -> FrictionModel:
        """Model ``name`` (default: the selected one) as a :class:`~frictid.model.FrictionModel`."""
        return FrictionModel.from_joint(self, name)


@dataclass
class FitResult:
    """The result of :func:`frictid.fit`: per-joint fits and the sources they came from."""

    joints: dict[str, JointFit] = field(default_factory=dict)
    sources: list[dict[str, Any]] = field(default_factory=list)
    version: str = ""
    settings: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, joint: str) -> JointFit:
        return self.joints[joint]

    def to_dict(self) -> dict:
        """The schema-1 parameter file as plain Python data."""
        joints = {j: jf.to_dict() for j, jf in self.joints.items()}
        robot = self.settings.get("robot")
        if isinstance(robot, dict):  # a whole robot: the rigid-body torque is the robot model's, not a joint's
            for jd in joints.values():
                if isinstance(jd.get("model"), dict):
                    jd["model"]["torque"] = (f"tau = the rigid-body torque of {robot.get('name', 'the robot')} "
                                             "(settings.robot: its base parameters along all joints' q, qd, qdd) "
                                             "+ offset + F(w)")
        return {
            "schema": SCHEMA_VERSION,
            "frictid": self.version or __version__,
            "joints": joints,
            "sources": plain(self.sources),
            "settings": plain(self.settings),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "FitResult":
        if not isinstance(d, dict) or d.get("schema") != SCHEMA_VERSION:
            got = d.get("schema") if isinstance(d, dict) else type(d).__name__
            raise ConfigError(f"parameter file: schema {got!r} is not supported (expected {SCHEMA_VERSION})")
        return cls(joints={str(j): JointFit.from_dict(str(j), jd) for j, jd in (d.get("joints") or {}).items()},
                   sources=list(d.get("sources") or []), version=str(d.get("frictid", "")),
                   settings=dict(d.get("settings") or {}))
