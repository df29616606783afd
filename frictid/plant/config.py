"""Plant and recipe files: pydantic models, loading and validation.

A *plant* (``recipes/plants/*.yaml``) describes joints: inertia, gravity, LuGre friction on a static map,
a thermal law, hidden effects, sensors and the controller. A *recipe* (``recipes/*.yaml``) is a sequence
of experiments (constant-velocity sweep, presliding ramps, ...) with velocities and torques given as
fractions of the plant's declared limits, so every recipe runs on every plant.

Every model forbids unknown keys and checks ranges. Problems surface as one
:class:`frictid.errors.ConfigError` naming the file and the key path of every problem, e.g.
``recipes/plants/x.yaml: joints.1.friction.Fs: must be > 0``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError, create_model

from ..errors import ConfigError
from ..models.static import (STATIC_MAPS, canonical_friction, canonical_level, canonical_pair, map_names,
                             param_table)

RECIPES_DIR = Path(__file__).resolve().parents[2] / "recipes"


class Strict(BaseModel):
    """Base: unknown keys rejected, NaN/inf rejected."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=False)


Pos = Annotated[float, Field(gt=0)]
NonNeg = Annotated[float, Field(ge=0)]

# ---------------------------------------------------------------------------------------------------
# Friction: one model per static map (and its _asym variant), discriminated by ``map``.

_POSITIVE = {"Fs", "vs", "ws1", "ws2"}
_NONNEG = {"Fc"}


def _param_field(name: str):
    base = name.removesuffix("_pos").removesuffix("_neg")
    if base in _POSITIVE:
        return (float, Field(gt=0))
    if base in _NONNEG:
        return (float, Field(ge=0))
    if base == "delta":
        return (float, Field(gt=0, le=10))
    return (float, ...)


def _friction_model(map_name: str):
    fields: dict[str, Any] = {
        "map": (Literal[map_name], ...),
        "sigma0": (float, Field(gt=0, description="bristle stiffness [F/q] (z >= 0 side)")),
        "sigma1": (float, Field(ge=0, description="bristle damping [F s/q] (z >= 0 side)")),
        "sigma0_neg": (float | None, Field(default=None, gt=0, description="stiffness for z < 0")),
        "sigma1_neg": (float | None, Field(default=None, ge=0, description="damping for z < 0")),
    }
    for p in param_table(map_name):
        fields[p.name] = _param_field(p.name)
    cls_name = "Friction_" + map_name
    return create_model(cls_name, __base__=Strict, **fields)


FRICTION_MODELS = {name: _friction_model(name) for name in map_names()}
FrictionConfig = Annotated[Union[tuple(FRICTION_MODELS.values())], Field(discriminator="map")]


def friction_params(fr) -> dict[str, float]:
    """The static-map parameters of a friction config (without map, sigma0, sigma1)."""
    return {p.name: float(getattr(fr, p.name)) for p in param_table(fr.map)}


# ---------------------------------------------------------------------------------------------------
# Effects, discriminated by ``kind``.


class PositionEffect(Strict):
    """Friction level g modulated periodically in position: ``g (1 + amplitude sin(2 pi q / period + phase))``."""

    kind: Literal["position"]
    amplitude: float = Field(gt=0, lt=1, description="fraction of the level [1]")
    period: Pos = Field(description="period in position [q]")
    phase: float = 0.0


class LoadEffect(Strict):
    """Friction level growing with transmitted torque and payload: ``g (1 + coeff |tau| + payload_coeff m)``."""

    kind: Literal["load"]
    coeff: NonNeg = Field(0.0, description="per unit of |tau| [1/F]")
    payload_coeff: NonNeg = Field(0.0, description="per kg of payload [1/kg]")


class AsymmetryEffect(Strict):
    """Scales the whole w < 0 branch of the static map by ``factor``."""

    kind: Literal["asymmetry"]
    factor: Pos


class TorqueOffsetEffect(Strict):
    """A constant offset [F] on the logged torque (a sensor/current-offset bias)."""

    kind: Literal["torque_offset"]
    value: float


class DriftEffect(Strict):
    """Wear: the static map scaled by ``1 + per_hour t/3600 + per_run run`` (run = experiment index)."""

    kind: Literal["drift"]
    per_hour: float = Field(0.0, gt=-1, lt=10)
    per_run: float = Field(0.0, gt=-1, lt=10)


class PositionTorqueEffect(Strict):
    """A torque that depends on position and not on the velocity sign, acting on the joint like gravity
    (a gravity harmonic, a spring compensator, cogging): ``amplitude sin(2 pi q / period + phase)`` [F]. Not
    friction: the drive supplies it, so the logged torque carries it."""

    kind: Literal["position_torque"]
    amplitude: float = Field(description="amplitude [F]")
    period: Pos = Field(description="period in position [q]")
    phase: float = 0.0


class DwellEffect(Strict):
    """Static friction that grows with the time spent at rest (Dieterich's ageing of the contacts): the
    level times ``1 + amplitude ln(1 + t_rest / t0) exp(-s / distance)``, with ``t_rest`` the time at rest
    before the current move (at rest: so far) and ``s`` the travel since the move started (the contacts
    renew over ``distance``). Rests and moves are those of the program's reference."""

    kind: Literal["dwell"]
    amplitude: float = Field(gt=0, lt=1, description="level change per unit of ln(1 + t_rest / t0) [1]")
    t0: Pos = Field(1.0, description="ageing time scale [s]")
    distance: Pos = Field(description="travel over which the aged contacts renew [q]")


EffectConfig = Annotated[
    Union[PositionEffect, LoadEffect, AsymmetryEffect, TorqueOffsetEffect, DriftEffect, PositionTorqueEffect,
          DwellEffect],
    Field(discriminator="kind"),
]


# ---------------------------------------------------------------------------------------------------
# Joint pieces


class Gravity(Strict):
    """``G(q) = Px cos q + Py sin q + offset + m_payload 9.81 payload_arm cos q`` [F]."""

    Px: float = 0.0
    Py: float = 0.0
    offset: float = 0.0
    payload_arm: NonNeg = Field(0.0, description="moment arm of the payload [m] (rotary)")


class Thermal(Strict):
    """Heat balance ``C dT/dt = F w - K (T - Tenv)`` and the law mapping T onto friction."""

    law: Literal["none", "thermal4", "thermal6", "exponential"] = "none"
    C: Pos = Field(1000.0, description="heat capacity [J/K]")
    K: Pos = Field(1.0, description="heat transfer to ambient [W/K]")
    T0: float = Field(25.0, ge=-50, le=150, description="reference temperature of the map [degC]")
    Tenv: float = Field(25.0, ge=-50, le=150, description="default ambient temperature [degC]")
    alpha: float = Field(0.0, gt=-1, lt=1, description="thermal4 slope [1/K]")
    beta: float = Field(1.0, gt=0, lt=10, description="thermal4 scale at T0 [1]")
    lam: float = Field(0.0, gt=-1, lt=1, description="exponential law rate [1/K]")
    dc0: float = Field(0.0, description="thermal6 slope of c0 [F/K]")
    dc1: float = Field(0.0, description="thermal6 slope of c1 [F s/q/K]")
    dc2: float = Field(0.0, description="thermal6 slope of c2 [F s^2/q^2/K]")
    dc3: float = Field(0.0, description="thermal6 slope of c3 [F s^3/q^3/K]")


class Limits(Strict):
    """Declared limits: recipes express velocities and torques as fractions of these."""

    velocity: Pos = Field(description="max velocity [q/s]")
    acceleration: Pos = Field(description="max acceleration [q/s^2]")
    torque: Pos = Field(description="actuator saturation [F]")
    position: tuple[float, float] | None = Field(None, description="travel range [q]")


class Control(Strict):
    """Controller at the log's sample rate. Gains default from bandwidth and the inertia."""

    bandwidth_hz: Pos = 10.0
    damping: Pos = 1.0
    integral: NonNeg = Field(0.2, description="integral corner as a fraction of the bandwidth")
    kp: Pos | None = None
    kd: NonNeg | None = None
    ki: NonNeg | None = None
    kv: Pos | None = None
    kvi: NonNeg | None = None


class Joint(Strict):
    name: str = Field(min_length=1)
    J: Pos = Field(description="inertia [kg m^2] or mass [kg]")
    gravity: Gravity = Gravity()
    friction: FrictionConfig
    thermal: Thermal = Thermal()
    effects: list[EffectConfig] = []
    limits: Limits
    control: Control = Control()


class Sensors(Strict):
    sample_rate: Pos = Field(1000.0, le=1e6, description="log sample rate [Hz]")
    tau_noise: NonNeg = Field(0.0, description="torque noise std [F]")
    q_noise: NonNeg = Field(0.0, description="position noise std [q]")
    qd_noise: NonNeg = Field(0.0, description="velocity noise std [q/s]")
    encoder_counts: int | None = Field(None, gt=0, description="counts per revolution (rotary)")
    encoder_step: Pos | None = Field(None, description="position quantum [q]")
    delay: int = Field(0, ge=0, le=1000, description="q/qd lag behind tau [samples]")


class Plant(Strict):
    name: str = Field(min_length=1)
    description: str = ""
    robot: str = ""
    source: str = ""
    axis: Literal["rotary", "linear"] = "rotary"
    substeps: int = Field(1, ge=1, le=100, description="integration steps per sample")
    sensors: Sensors = Sensors()
    joints: list[Joint] = Field(min_length=1)

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise ConfigError(f"plant {self.name}: no joint {name!r}; joints: "
                          + ", ".join(j.name for j in self.joints))

    @property
    def q_quantum(self) -> float:
        """Encoder position quantum [q] (0: none)."""
        s = self.sensors
        if s.encoder_step:
            return float(s.encoder_step)
        if s.encoder_counts:
            return 2.0 * np.pi / s.encoder_counts
        return 0.0


# ---------------------------------------------------------------------------------------------------
# Recipes


class ExperimentBase(Strict):
    label: str = ""
    payload: NonNeg | None = Field(None, description="payload mass [kg] during this experiment")
    temp_env: float | None = Field(None, ge=-50, le=150, description="ambient [degC]")
    cold_start: bool = Field(False, description="joint temperature reset to ambient (a night of rest)")
    rest: NonNeg = Field(1.0, description="rest after the experiment [s]")


class LevelSpacing(Strict):
    min: Pos
    max: Pos
    count: int = Field(ge=1, le=200)
    spacing: Literal["log", "linear"] = "log"


Signs = Literal["both", "positive", "negative"]


def _spacing_or_list(v):
    return "list" if isinstance(v, list) else "spacing"


Velocities = Annotated[Union[Annotated[LevelSpacing, Tag("spacing")], Annotated[list[Pos], Tag("list")]],
                       Discriminator(_spacing_or_list)]


class ConstantVelocity(ExperimentBase):
    """Closed-loop plateaus at log-spaced velocities (fractions of limits.velocity), both signs."""

    kind: Literal["constant_velocity"]
    velocities: Velocities
    relative: bool = True
    signs: Signs = "both"
    plateau: Pos = Field(3.0, description="plateau length [s] (shortened to fit the travel)")
    min_plateau: Pos = Field(0.4, description="shortest plateau [s]")
    accel: Pos = Field(0.5, le=1, description="fraction of limits.acceleration")
    control: Literal["position_pid", "velocity_pi"] = "position_pid"
    gap: NonNeg = Field(0.3, description="hold between plateaus [s]")


class RampPresliding(ExperimentBase):
    """Open-loop torque ramps below break-away: ramp up, hold, ramp down, rest; both signs."""

    kind: Literal["ramp_presliding"]
    peaks: list[Annotated[float, Field(gt=0, lt=1)]] = [0.6]
    relative: bool = True
    signs: Signs = "both"
    ramp_up: Pos = 4.0
    hold: NonNeg = 1.0
    ramp_down: Pos = 4.0
    settle: NonNeg = Field(1.0, description="open-loop rest before each ramp [s]")


class TorqueSteps(ExperimentBase):
    """Open-loop torque steps below break-away and back to zero, both signs."""

    kind: Literal["torque_steps"]
    levels: list[Annotated[float, Field(gt=0, lt=1)]] = [0.3, 0.6]
    relative: bool = True
    signs: Signs = "both"
    hold: Pos = 0.5
    release: Pos = Field(0.3, description="labelled transient after the step back [s]")
    settle: NonNeg = 0.5


class DutyCycle(ExperimentBase):
    """002 duty cycles: cycles of ``slots`` slots, moving in the first ``round(duty*slots)`` of them."""

    kind: Literal["duty_cycle"]
    duty: Annotated[float, Field(gt=0, le=1)] = 1.0
    cycles: int = Field(10, ge=1, le=10000)
    cycle_time: Pos = 240.0
    slots: int = Field(4, ge=1, le=100)
    speeds: list[Annotated[float, Field(gt=0, le=1)]] = [0.05, 0.24, 0.43, 0.62, 0.81, 1.0]
    positions_deg: tuple[float, float] = (-45.0, 70.0)
    relative_positions: bool = Field(False, description="positions as fractions of limits.position")
    accel: Pos = Field(0.5, le=1)


class ValidationPtp(DutyCycle):
    """002 validation: cycles of continuous point-to-point motion, never stopping."""

    kind: Literal["validation_ptp"]  # type: ignore[assignment]
    cycle_time: Pos = 180.0
    slots: int = Field(1, ge=1, le=100)
    speeds: list[Annotated[float, Field(gt=0, le=1)]] = [0.10, 0.25, 0.40, 0.55, 0.70, 0.85, 1.0]
    positions_deg: tuple[float, float] = (-30.0, 60.0)


class Multisine(ExperimentBase):
    """003 eq 14: closed-loop tracking of ``q(t) = sum_j a_j sin(2 pi f_j t + phi_j)``."""

    kind: Literal["multisine"]
    duration: Pos = 30.0
    f0: Pos = Field(0.1, description="base frequency [Hz]")
    harmonics: int = Field(5, ge=1, le=50)
    velocity: Pos = Field(0.6, le=1, description="peak velocity, fraction of limits.velocity")
    amplitude: Pos | None = Field(None, description="peak position excursion [q] (default: from range)")


class RandomPtp(ExperimentBase):
    """Random point-to-point moves (no identification experiment): closed-loop trapezoidal moves to
    targets drawn uniformly over the travel, at random peak speeds and accelerations, with random dwells."""

    kind: Literal["random_ptp"]
    moves: int = Field(40, ge=1, le=100000)
    speed: tuple[Pos, Pos] = Field((0.05, 1.0), description="peak speed range, fractions of limits.velocity")
    accel: tuple[Pos, Pos] = Field((0.2, 1.0), description="acceleration range, fractions of limits.acceleration")
    dwell: tuple[NonNeg, NonNeg] = Field((0.05, 3.0), description="dwell range after each move [s]")
    seed: int = Field(0, ge=0, description="seed of the moves (the sensor noise follows the simulation seed)")


class Hold(ExperimentBase):
    """Closed-loop rest at the current position."""

    kind: Literal["rest"]
    duration: Pos = 1.0


ExperimentConfig = Annotated[
    Union[ConstantVelocity, RampPresliding, TorqueSteps, DutyCycle, ValidationPtp, Multisine, RandomPtp,
          Hold],
    Field(discriminator="kind"),
]


class Recipe(Strict):
    name: str = Field(min_length=1)
    description: str = ""
    identifies: list[str] = []
    default_plant: str = Field(description="plant name or path (relative to the recipe file)")
    joints: list[str] | None = None
    temp_env: float | None = Field(None, ge=-50, le=150)
    payload: NonNeg = 0.0
    start_rest: NonNeg = 1.0
    experiments: list[ExperimentConfig] = Field(min_length=1)


# ---------------------------------------------------------------------------------------------------
# Loading and error formatting


def _fmt_loc(loc: tuple) -> str:
    """'joints.1.friction.Fs' from a pydantic location, without the tags that unions insert."""
    parts = []
    skip = False
    for i, x in enumerate(loc):
        if skip:
            skip = False
            continue
        parts.append(str(x))
        nxt = loc[i + 1] if i + 1 < len(loc) else None
        if not isinstance(nxt, str):
            continue
        prev = loc[i - 1] if i > 0 else None
        if ((x == "friction" and nxt in FRICTION_MODELS)
                or (isinstance(x, int) and prev == "effects" and nxt in _EFFECT_KINDS)
                or (isinstance(x, int) and prev == "experiments" and nxt in _EXP_KINDS)
                or (x == "velocities" and nxt in ("spacing", "list"))):
            skip = True
    return ".".join(parts)


_EFFECT_KINDS = {"position", "load", "asymmetry", "torque_offset", "drift", "position_torque", "dwell"}
_EXP_KINDS = {"constant_velocity", "ramp_presliding", "torque_steps", "duty_cycle", "validation_ptp",
              "multisine", "rest"}


def _fmt_msg(err: dict) -> str:
    typ = err.get("type", "")
    ctx = err.get("ctx") or {}
    if typ == "greater_than":
        return f"must be > {ctx.get('gt')}"
    if typ == "greater_than_equal":
        return f"must be >= {ctx.get('ge')}"
    if typ == "less_than":
        return f"must be < {ctx.get('lt')}"
    if typ == "less_than_equal":
        return f"must be <= {ctx.get('le')}"
    if typ == "extra_forbidden":
        return "unknown key (check spelling; see docs/plant.md)"
    if typ == "missing":
        return "required key missing"
    if typ in ("union_tag_invalid", "union_tag_not_found"):
        tags = ctx.get("expected_tags", "")
        return f"{err.get('msg', 'invalid')}" if not tags else f"unknown value; expected one of {tags}"
    return err.get("msg", "invalid")


def validation_problems(exc: ValidationError) -> list[str]:
    """One 'key.path: message' line per pydantic error."""
    out = []
    for e in exc.errors(include_url=False):
        loc = _fmt_loc(tuple(e.get("loc", ())))
        out.append(f"{loc or '(top level)'}: {_fmt_msg(e)}")
    return out


def _read_yaml(path: Path) -> dict:
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror or e}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        raise ConfigError(f"{path}: not valid YAML{where}: {getattr(e, 'problem', e)}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level, got {type(data).__name__}")
    return data


def plant_problems(plant: Plant) -> list[str]:
    """Physical checks beyond ranges: friction level positive and map dissipative over the velocity range."""
    probs = []
    for i, j in enumerate(plant.joints):
        c_pos, c_neg = canonical_pair(j.friction.map, friction_params(j.friction))
        v = np.concatenate([[0.0], np.geomspace(1e-6, 1.0, 60)]) * j.limits.velocity
        for side, c, sgn in (("w > 0", c_pos, 1.0), ("w < 0", c_neg, -1.0)):
            g = canonical_level(v, c)
            if np.any(g <= 0):
                probs.append(f"joints.{i}.friction: level g(|w|) <= 0 for {side} within limits.velocity")
            F = canonical_friction(sgn * v[1:], c, c)
            if np.any(F * sgn <= 0):
                vbad = v[1:][F * sgn <= 0][0]
                probs.append(f"joints.{i}.friction: not dissipative for {side} at |w| = {vbad:.3g} "
                             f"(F w <= 0); lower limits.velocity or fix the map")
        if j.limits.position is not None and j.limits.position[0] >= j.limits.position[1]:
            probs.append(f"joints.{i}.limits.position: min must be < max")
        if j.thermal.law == "thermal4" and j.thermal.beta + j.thermal.alpha * 100 <= 0:
            probs.append(f"joints.{i}.thermal: thermal4 scale turns negative within 100 K of T0")
    names = [j.name for j in plant.joints]
    if len(set(names)) != len(names):
        probs.append("joints: joint names must be unique")
    return probs


def load_plant(src, where: str | None = None) -> Plant:
    """A :class:`Plant` from a path, a dict or a Plant; raises ConfigError naming file and keys."""
    if isinstance(src, Plant):
        return src
    if isinstance(src, dict):
        data, name = src, where or "<plant>"
    else:
        path = resolve_plant_path(src)
        data, name = _read_yaml(path), str(src if where is None else where)
    try:
        plant = Plant.model_validate(data)
    except ValidationError as e:
        raise _config_error(name, validation_problems(e)) from None
    probs = plant_problems(plant)
    if probs:
        raise _config_error(name, probs)
    return plant


def load_recipe(src) -> tuple[Recipe, Path | None]:
    """A :class:`Recipe` and the directory it came from (for its default_plant)."""
    if isinstance(src, Recipe):
        return src, RECIPES_DIR
    if isinstance(src, dict):
        data, name, base = src, "<recipe>", RECIPES_DIR
    else:
        path = resolve_recipe_path(src)
        data, name, base = _read_yaml(path), str(src), path.parent
    try:
        return Recipe.model_validate(data), base
    except ValidationError as e:
        raise _config_error(name, validation_problems(e)) from None


def _config_error(name: str, probs: list[str]) -> ConfigError:
    if len(probs) == 1:
        return ConfigError(f"{name}: {probs[0]}")
    return ConfigError(f"{name}: {len(probs)} problems:\n" + "\n".join(f"  - {p}" for p in probs))


def resolve_recipe_path(src) -> Path:
    """A recipe path; a bare name (``constant_velocity_sweep``) looks in the shipped recipes/ folder."""
    p = Path(src)
    if p.exists():
        return p
    for cand in (RECIPES_DIR / p, RECIPES_DIR / (p.name + ".yaml")):
        if cand.exists() and cand.is_file():
            return cand
    raise ConfigError(f"{src}: recipe file not found (shipped recipes: "
                      + ", ".join(sorted(x.stem for x in RECIPES_DIR.glob("*.yaml"))) + ")")


def resolve_plant_path(src, base: Path | None = None) -> Path:
    """A plant path; bare names look in ``<base>/plants/`` and the shipped recipes/plants/."""
    p = Path(src)
    cands = [p]
    if base is not None:
        cands += [base / p, base / "plants" / p, base / "plants" / (p.name + ".yaml")]
    cands += [RECIPES_DIR / "plants" / p, RECIPES_DIR / "plants" / (p.name + ".yaml")]
    for c in cands:
        if c.exists() and c.is_file():
            return c
    raise ConfigError(f"{src}: plant file not found (shipped plants: "
                      + ", ".join(sorted(x.stem for x in (RECIPES_DIR / "plants").glob("*.yaml"))) + ")")


__all__ = [
    "Plant", "Joint", "Recipe", "Sensors", "Thermal", "Gravity", "Limits", "Control",
    "load_plant", "load_recipe", "friction_params", "plant_problems", "STATIC_MAPS",
]
