"""A robot's kinematic tree from the files users have: a URDF, or a DH table in YAML.

DH YAML (``recipes/robots/*.yaml``)::

    name: UR10e
    convention: standard          # standard (Denavit-Hartenberg) or modified (Craig)
    gravity: [0, 0, -9.81]        # in the base frame [m/s^2]
    joints:                       # base to tip; names match the log's joints
      - {name: "1", a: 0.0, d: 0.1807, alpha: 1.5707963, offset: 0.0}
      ...

Lengths in m, angles in rad; ``offset`` is added to the joint angle. Only revolute joints about z (DH).
The model is a Pinocchio ``Model`` (package ``pin``); the inertial parameters of the links are what the
identification estimates, so a DH table needs none and a URDF's are used only with ``--rigid-body known``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..errors import ConfigError


class DHJoint(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    a: float = 0.0
    d: float = 0.0
    alpha: float = 0.0
    offset: float = 0.0
    #: limits for a designed excitation (frictid design): range [rad], speed [rad/s], acceleration [rad/s^2]
    position: tuple[float, float] | None = None
    velocity: float | None = Field(None, gt=0)
    acceleration: float | None = Field(None, gt=0)


class DHRobot(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    convention: Literal["standard", "modified"] = "standard"
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    joints: list[DHJoint] = Field(min_length=1)
    #: the torque is estimated from motor current (drive gain x current): each drive's reflected rotor
    #: inertia enters it and is identified with the base parameters; false for link-side torque sensors
    armature: bool = False
    source: str = ""


@dataclass
class Robot:
    """A kinematic tree: the Pinocchio model and its joints' names in order (the log's joint ids)."""

    name: str
    model: object   # pinocchio.Model
    joints: list[str]
    armature: bool = False
    #: per joint name: position (lo, hi), velocity, acceleration, where the description gives them
    limits: dict | None = None

    @property
    def nv(self) -> int:
        return int(self.model.nv)


def _pin():
    try:
        import pinocchio
    except ImportError:  # pragma: no cover - pin is a dependency of the robot extra
        raise ConfigError("whole-robot identification needs Pinocchio: pip install 'frictid[robot]'") from None
    return pinocchio


def _se3(pin, rot_x: float = 0.0, trans_x: float = 0.0, trans_z: float = 0.0, rot_z: float = 0.0):
    """RotX(rot_x) TransX(trans_x) TransZ(trans_z) RotZ(rot_z) as a pin.SE3."""
    def rx(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])

    def rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    R = rx(rot_x) @ rz(rot_z)
    p = np.array([trans_x, 0.0, 0.0]) + rx(rot_x) @ np.array([0.0, 0.0, trans_z])
    return pin.SE3(R, p)


def _placements(dh: DHRobot, pin) -> list:
    """Placement of each joint frame in its parent's, for a revolute joint about its own z."""
    out = []
    if dh.convention == "modified":  # T = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i)
        for j in dh.joints:
            out.append(_se3(pin, j.alpha, j.a, j.d, j.offset))
        return out
    prev = None  # standard: T_i = RotZ(theta_i) TransZ(d_i) TransX(a_i) RotX(alpha_i); the fixed part after
    for j in dh.joints:  # joint i's rotation is the next joint's placement
        if prev is None:
            out.append(_se3(pin, rot_z=j.offset))
        else:
            T = pin.SE3(np.eye(3), np.array([0.0, 0.0, prev.d])) * pin.SE3(np.eye(3), np.array([prev.a, 0.0, 0.0]))
            out.append(T * _se3(pin, rot_x=prev.alpha) * _se3(pin, rot_z=j.offset))
        prev = j
    return out


def robot_from_dh(dh: DHRobot) -> Robot:
    pin = _pin()
    model = pin.Model()
    model.name = dh.name
    parent = 0
    for j, placement in zip(dh.joints, _placements(dh, pin)):
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint_{j.name}")
        # a small placeholder body: the identification estimates every link's inertial parameters
        model.appendBodyToJoint(parent, pin.Inertia(1.0, np.zeros(3), np.eye(3) * 1e-2), pin.SE3.Identity())
    model.gravity.linear = np.asarray(dh.gravity, dtype=float)
    limits = {j.name: {"position": j.position, "velocity": j.velocity, "acceleration": j.acceleration}
              for j in dh.joints}
    return Robot(dh.name, model, [j.name for j in dh.joints], dh.armature, limits)


def robot_from_urdf(path: Path, joints: list[str] | None = None) -> Robot:
    """A URDF's movable joints (names as in the file, or renamed in order by ``joints``)."""
    pin = _pin()
    try:
        model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as exc:
        raise ConfigError(f"{path}: not a readable URDF ({exc})") from None
    names = [model.names[i] for i in range(1, model.njoints)]
    if joints is not None:
        if len(joints) != len(names):
            raise ConfigError(f"{path}: {len(names)} movable joints ({', '.join(names)}), but {len(joints)} "
                              "joint names were given")
        names = list(joints)
    limits = {}
    for i, name in enumerate(names):  # one configuration and velocity entry per revolute/prismatic joint
        lo, hi = float(model.lowerPositionLimit[i]), float(model.upperPositionLimit[i])
        v = float(model.velocityLimit[i])
        limits[name] = {"position": (lo, hi) if np.isfinite([lo, hi]).all() and hi > lo else None,
                        "velocity": v if v > 0 else None, "acceleration": None}
    return Robot(model.name or Path(path).stem, model, names, False, limits)


def load_robot(path) -> Robot:
    """A robot from a URDF (``.urdf``) or a DH YAML; ConfigError with the reason otherwise."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{path}: no such robot file (a URDF or a DH YAML, e.g. recipes/robots/ur10e.yaml)")
    if p.suffix.lower() == ".urdf":
        return robot_from_urdf(p)
    try:
        raw = yaml.safe_load(p.read_text())
        return robot_from_dh(DHRobot.model_validate(raw))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc.__class__.__name__})") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(x) for x in first["loc"])
        raise ConfigError(f"{path}: {where}: {first['msg']} (see frictid/robot/description.py)") from None
