"""The parameter file (schema 1): validation, atomic writing and loading. See docs/parameter-file.md.

:func:`write_params` validates a :class:`~frictid.result.FitResult` (or its dictionary) against the
schema before anything is written, then writes it atomically (``-`` writes to standard output).
:func:`read_params` loads a file back into a ``FitResult`` with the same values: every float is written
by YAML's shortest round-tripping representation.
"""
from __future__ import annotations

from typing import Any, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ..errors import ConfigError
import yaml

from ..model import FrictionModel
from ..result import FitResult
from .atomic import atomic_open
from .params_load import load_params_dict

Number = Optional[float]


class _Open(BaseModel):
    model_config = ConfigDict(extra="allow")


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ParamEntry(_Closed):
    """One number: value and standard error in ``unit``; identifiable false with a reason when the data
    could not pin it down; fixed when held at a stated value; source when it did not come from a fit;
    bounds [lower, upper] the optimiser kept it within."""

    value: Number
    stderr: Number = None
    unit: str
    identifiable: bool
    reason: Optional[str] = None
    fixed: Optional[bool] = None
    source: Optional[str] = None
    bounds: Optional[list[Number]] = None


class ModelEntry(_Open):
    map: str
    method: str = ""
    params: dict[str, ParamEntry]
    metrics: dict[str, Union[float, int, None]] = Field(default_factory=dict)
    notes: list[str] = Field(default_factory=list)


class SegmentList(_Closed):
    """The segments the fit worked on in one log (one joint of one source): one item per segment in each
    list; sample indices count from the joint's first row in that source, i1 exclusive; cycle -1 when the
    segment belongs to no duty cycle."""

    source: int = Field(ge=0)
    rows: int = Field(ge=0)
    kind: list[str]
    i0: list[int]
    i1: list[int]
    cycle: list[int]
    #: the log's scales as the fit measured them (frictid.segments.Scales: noise levels, encoder and torque
    #: steps, derivative windows), when it used the default derivatives; the report reuses them
    scales: Optional[dict[str, Union[float, int, bool, None]]] = None  # null: not measured (NaN)

    @model_validator(mode="after")
    def _same_length(self):
        n = len(self.kind)
        if not (len(self.i0) == len(self.i1) == len(self.cycle) == n):
            raise ValueError(f"kind, i0, i1 and cycle must have one item per segment (lengths {n}, "
                             f"{len(self.i0)}, {len(self.i1)}, {len(self.cycle)})")
        bad = [k for k in range(n) if not 0 <= self.i0[k] < self.i1[k] <= self.rows]
        if bad:
            raise ValueError(f"segment {bad[0]}: needs 0 <= i0 < i1 <= rows ({self.i0[bad[0]]}, "
                             f"{self.i1[bad[0]]}, {self.rows})")
        return self


class ModelHead(_Closed):
    """The head of a joint: its selected model as a feed-forward user reads it (derived, not read back)."""
    name: str
    words: str
    friction: list[str]
    torque: str
    params: dict[str, dict[str, Any]]
    rigid_body: dict[str, Number]
    validity: dict[str, list[Number]] = Field(default_factory=dict)


class JointEntry(_Closed):
    model: Optional[ModelHead] = None
    axis: Literal["rotary", "linear"] = "rotary"
    units: dict[str, str] = Field(default_factory=dict)
    inertia: Optional[ParamEntry] = None
    gravity: dict[str, ParamEntry] = Field(default_factory=dict)
    offset: Optional[ParamEntry] = None
    segments: dict[str, int] = Field(default_factory=dict)
    segments_used: dict[str, list[list[float]]] = Field(default_factory=dict)
    models: dict[str, ModelEntry] = Field(default_factory=dict)
    selected: Optional[str] = None
    selection: dict[str, Any] = Field(default_factory=dict)
    not_identified: list[dict[str, str]] = Field(default_factory=list)
    warnings: list[str] = Field(default_factory=list)
    diagnosis: list[Any] = Field(default_factory=list)
    segment_list: list[SegmentList] = Field(default_factory=list)
    validity: dict[str, list[Optional[float]]] = Field(default_factory=dict)


class Source(_Open):
    path: str
    sha256: Optional[str] = None
    rows: int


class ParamFile(_Closed):
    """The whole file (schema 1)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    schema_: Literal[1] = Field(alias="schema")
    frictid: str
    joints: dict[str, JointEntry]
    sources: list[Source] = Field(default_factory=list)
    settings: dict[str, Any] = Field(default_factory=dict)


def validate_params(d: dict, where: str = "parameter file") -> ParamFile:
    """Check a parameter-file dictionary against schema 1; every problem in one :class:`ConfigError`."""
    try:
        pf = ParamFile.model_validate(d)
    except ValidationError as exc:
        probs = []
        for e in exc.errors():
            loc = ".".join(str(x) for x in e["loc"])
            probs.append(f"{loc}: {e['msg']}")
        raise ConfigError(f"{where}: {len(probs)} problem(s):\n" + "\n".join(f"  - {p}" for p in probs)) from None
    for j, je in pf.joints.items():
        if je.selected is not None and je.selected not in je.models:
            raise ConfigError(f"{where}: joints.{j}.selected: {je.selected!r} is not one of its models")
    return pf


def dump_yaml(d: dict) -> str:
    """The parameter file's text: keys in order, floats in YAML's shortest round-tripping form."""
    # libyaml's emitter when built in: the same text, several times faster on long segment lists
    return yaml.dump(d, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), sort_keys=False,
                     default_flow_style=None, width=120, allow_unicode=True)


def write_params(result: FitResult | dict, path) -> None:
    """Validate, then write the parameter file atomically (``-``: standard output)."""
    d = result.to_dict() if isinstance(result, FitResult) else result
    validate_params(d)
    text = dump_yaml(d)
    with atomic_open(path, "w") as fh:
        fh.write(text)


def read_params(path) -> FitResult:
    """Load and validate a parameter file into a :class:`FitResult` (same values as written)."""
    d = load_params_dict(path)
    validate_params(d, str(path))
    return FitResult.from_dict(d)


def load_model(path, joint: str | None = None, model: str | None = None) -> FrictionModel:
    """The identified model of one joint of a parameter file, ready to evaluate
    (:class:`~frictid.model.FrictionModel`): ``frictid.load("params.yaml", joint="j1")``.

    joint : may be left out when the file holds one joint. model : a model name of that joint (default: the
    selected one). Raises :class:`~frictid.errors.ConfigError` naming the file and what it holds.
    """
    res = read_params(path)
    if joint is None:
        if len(res.joints) != 1:
            raise ConfigError(f"{path}: holds joints {', '.join(res.joints)}; name one with joint=")
        joint = next(iter(res.joints))
    if str(joint) not in res.joints:
        raise ConfigError(f"{path}: no joint {joint!r}; joints: {', '.join(res.joints)}")
    return res.joints[str(joint)].friction_model(model)
