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

With ``--rigid-body known`` every link's inertial parameters come from the file. A DH joint then carries
its link's (all three, or none)::

      - {name: "2", a: 0.0, d: 0.0, alpha: -1.57, mass: 0.65, com: [-0.003, -0.029, 0.003],
         inertia: [0.008, 0.028, 0.026, -0.0039, 0.0103, 0.0007]}

``mass`` [kg]; ``com`` [m], the centre of mass; ``inertia`` [kg m^2], Ixx Iyy Izz Ixy Ixz Iyz about the
centre of mass; both in the link's DH frame: for the standard convention the frame at the link's far end
(frame i of ``T_i = RotZ TransZ TransX RotX``, as robot makers publish them, e.g. Universal Robots), for
the modified convention Craig's frame i (on joint i's axis). A robot with ``armature: true`` also needs
each joint's ``rotor`` [kg m^2], the reflected rotor inertia. A URDF gives them in ``<inertial>``.
"""
from __future__ import annotations

import hashlib
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
    #: the link's inertial parameters, for --rigid-body known (module docstring): mass [kg], centre of mass
    #: [m] and inertia about it [kg m^2] (Ixx Iyy Izz Ixy Ixz Iyz) in the link's DH frame; rotor [kg m^2]
    mass: float | None = Field(None, gt=0)
    com: tuple[float, float, float] | None = None
    inertia: tuple[float, float, float, float, float, float] | None = None
    rotor: float | None = Field(None, ge=0)


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
    #: what the description lacks for a known rigid body (--rigid-body known), one phrase per joint; empty
    #: when every link's inertial parameters are given
    inertia_gaps: list[str] | None = None
    #: each joint's reflected rotor inertia [kg m^2] (DH ``rotor``; with ``armature``), for a known rigid body
    rotor: np.ndarray | None = None
    #: the robot file's path and sha256, when read from a file
    file: str | None = None
    sha256: str | None = None

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


def _link_frame(dh: DHRobot, j: DHJoint, pin):
    """The link's DH frame in its joint's Pinocchio frame: the fixed part ``TransZ(d) TransX(a) RotX(alpha)``
    for the standard convention (the frame at the link's far end), none for the modified (Craig's frame i)."""
    if dh.convention == "modified":
        return pin.SE3.Identity()
    return pin.SE3(np.eye(3), np.array([j.a, 0.0, j.d])) * _se3(pin, rot_x=j.alpha)


def _link_inertia(dh: DHRobot, j: DHJoint, pin) -> tuple[object, str | None]:
    """(the link's inertia in its joint's frame, what is missing for a known rigid body or None)."""
    given = [k for k in ("mass", "com", "inertia") if getattr(j, k) is not None]
    gap = None
    if len(given) < 3:
        gap = (f"joint {j.name}: no mass, com, inertia" if not given else
               f"joint {j.name}: {', '.join(given)} given but not {', '.join(k for k in ('mass', 'com', 'inertia') if k not in given)}")
    elif dh.armature and j.rotor is None:
        gap = f"joint {j.name}: no rotor (armature: true)"
    if given != ["mass", "com", "inertia"]:
        # a small placeholder body: the identification estimates every link's inertial parameters
        return pin.Inertia(1.0, np.zeros(3), np.eye(3) * 1e-2), gap
    xx, yy, zz, xy, xz, yz = j.inertia
    inner = pin.Inertia(j.mass, np.asarray(j.com, float), np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]))
    return _link_frame(dh, j, pin).act(inner), gap


def robot_from_dh(dh: DHRobot) -> Robot:
    pin = _pin()
    model = pin.Model()
    model.name = dh.name
    parent = 0
    gaps = []
    for j, placement in zip(dh.joints, _placements(dh, pin)):
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint_{j.name}")
        inertia, gap = _link_inertia(dh, j, pin)
        model.appendBodyToJoint(parent, inertia, pin.SE3.Identity())
        gaps += [gap] if gap else []
    model.gravity.linear = np.asarray(dh.gravity, dtype=float)
    limits = {j.name: {"position": j.position, "velocity": j.velocity, "acceleration": j.acceleration}
              for j in dh.joints}
    out = Robot(dh.name, model, [j.name for j in dh.joints], dh.armature, limits, gaps)
    out.rotor = np.array([j.rotor or 0.0 for j in dh.joints], dtype=float)
    return out


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
    # a link without <inertial> is massless in Pinocchio: a known rigid body needs every moving link's
    gaps = [f"joint {name}: its link has no mass (no <inertial>)" for i, name in enumerate(names)
            if not model.inertias[i + 1].mass > 0]
    return Robot(model.name or Path(path).stem, model, names, False, limits, gaps)


def load_robot(path) -> Robot:
    """A robot from a URDF (``.urdf``) or a DH YAML; ConfigError with the reason otherwise."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{path}: no such robot file (a URDF or a DH YAML, e.g. recipes/robots/ur10e.yaml)")
    digest = hashlib.sha256(p.read_bytes()).hexdigest()
    if p.suffix.lower() == ".urdf":
        out = robot_from_urdf(p)
        out.file, out.sha256 = str(path), digest
        return out
    try:
        raw = yaml.safe_load(p.read_text())
        out = robot_from_dh(DHRobot.model_validate(raw))
        out.file, out.sha256 = str(path), digest
        return out
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc.__class__.__name__})") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(x) for x in first["loc"])
        raise ConfigError(f"{path}: {where}: {first['msg']} (see frictid/robot/description.py)") from None
