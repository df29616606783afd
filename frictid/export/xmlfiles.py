"""MJCF (MuJoCo) and URDF: the simulator form of each joint's model (:mod:`.approx`), as a file of its own or
written into a user's model.

- MJCF, new file: one body per joint under the world, each with one joint (``hinge`` about z for a rotary
  axis, ``slide`` along z for a linear one) carrying ``frictionloss``, ``damping`` (one number, or the three
  polynomial coefficients MuJoCo >= 3.7 takes) and the identified inertia as the body's inertia about the
  axis (its mass for a slide), and ``solimpfriction`` 0.99 0.999: with MuJoCo's default impedance its dry
  friction is soft below a few hundredths of a rad/s (the servo test in tests/test_export.py sees 16 % of
  the level at 1 mrad/s), which would smear the identified break-away. The joint axis is vertical, so gravity does no work on it: the identified
  gravity terms are the user's model's business, not friction.
- MJCF ``--into``: the same attributes on the user's joints matched by name; ``armature`` is left as it
  is (the identified inertia includes the link's, which the user's model already has).
- URDF: ``<dynamics damping friction>`` (linear damping only) per joint, into the user's URDF or as a
  snippet.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

from ..errors import FrictidInputError
from ..version import __version__
from .approx import JointFriction


#: MuJoCo solver impedance for the joint's dry friction: near-hard, so the Coulomb level holds down to slow
#: speeds (``--into`` leaves the user's solver settings alone).
SHARP_FRICTION = "0.99 0.999 0.001"


def _num(x: float) -> str:
    return repr(float(x))


def damping_attr(jf: JointFriction) -> str:
    d1, d2, d3 = jf.damping
    return _num(d1) if d2 == 0.0 and d3 == 0.0 else f"{_num(d1)} {_num(d2)} {_num(d3)}"


def mjcf_model(forms: list[JointFriction], axis: dict[str, str]) -> str:
    """A stand-alone MJCF with one body and joint per joint model."""
    root = ET.Element("mujoco", model="frictid")
    root.append(ET.Comment(f" friction identified by frictid {__version__}; one free-standing joint per "
                           "identified joint "))
    ET.SubElement(root, "option", integrator="implicitfast")
    world = ET.SubElement(root, "worldbody")
    for i, jf in enumerate(forms):
        body = ET.SubElement(world, "body", name=f"{jf.joint}_body", pos=f"{i * 0.5:g} 0 0")
        rotary = axis.get(jf.joint, "rotary") == "rotary"
        ET.SubElement(body, "joint", name=jf.joint, type="hinge" if rotary else "slide", axis="0 0 1",
                      frictionloss=_num(jf.frictionloss), damping=damping_attr(jf),
                      solimpfriction=SHARP_FRICTION)
        J = jf.armature if jf.armature > 0 else 1.0
        ET.SubElement(body, "inertial", pos="0 0 0", mass=_num(1.0 if rotary else J),
                      diaginertia=f"{_num(J)} {_num(J)} {_num(J)}" if rotary else "1e-6 1e-6 1e-6")
        ET.SubElement(body, "geom", type="sphere", size="0.05", contype="0", conaffinity="0", mass="0")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _parse(path) -> ET.ElementTree:
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    try:
        return ET.parse(path, parser=parser)
    except (OSError, ET.ParseError) as exc:
        raise FrictidInputError(f"{path}: cannot read it as XML ({exc}); give a MuJoCo MJCF or a URDF file")


def _joints_by_name(tree: ET.ElementTree, path, forms: list[JointFriction]) -> dict[str, ET.Element]:
    found = {j.get("name"): j for j in tree.iter("joint") if j.get("name")}
    missing = [jf.joint for jf in forms if jf.joint not in found]
    if missing:
        raise FrictidInputError(f"{path}: no joint named {', '.join(missing)} (its joints: "
                                f"{', '.join(sorted(found)) or 'none'}); rename the joints in the parameter "
                                "file or pick them with --joint")
    return found


def write_into_mjcf(path, forms: list[JointFriction]) -> str:
    """The user's MJCF with each matched joint's frictionloss and damping set."""
    tree = _parse(path)
    joints = _joints_by_name(tree, path, forms)
    for jf in forms:
        joints[jf.joint].set("frictionloss", _num(jf.frictionloss))
        joints[jf.joint].set("damping", damping_attr(jf))
    return ET.tostring(tree.getroot(), encoding="unicode") + "\n"


def _dynamics(jf: JointFriction) -> ET.Element:
    return ET.Element("dynamics", damping=_num(jf.damping[0]), friction=_num(jf.frictionloss))


def write_into_urdf(path, forms: list[JointFriction]) -> str:
    """The user's URDF with each matched joint's ``<dynamics>`` set (other attributes of it kept)."""
    tree = _parse(path)
    joints = _joints_by_name(tree, path, forms)
    for jf in forms:
        dyn = joints[jf.joint].find("dynamics")
        if dyn is None:
            dyn = ET.SubElement(joints[jf.joint], "dynamics")
        dyn.set("damping", _num(jf.damping[0]))
        dyn.set("friction", _num(jf.frictionloss))
    return ET.tostring(tree.getroot(), encoding="unicode") + "\n"


def urdf_snippet(forms: list[JointFriction]) -> str:
    """The ``<dynamics>`` element of each joint, to paste into its ``<joint>``."""
    out = [f"<!-- friction identified by frictid {__version__}: paste each line into its <joint> -->"]
    for jf in forms:
        out.append(f"<!-- joint {jf.joint} ({jf.model}) -->")
        out.append(ET.tostring(_dynamics(jf), encoding="unicode"))
    return "\n".join(out) + "\n"
