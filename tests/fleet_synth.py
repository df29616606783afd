"""A simulated fleet for the fleet tests and benchmarks/fleet_scorecard.py: robots x joints x days of
short constant-velocity logs from the plant, written as a hive-partitioned Parquet folder
(``robot=r01/joint=j1/date=2026-03-01/log.parquet``), with what was planted per joint.

Planted, per joint (chosen by the seed): ``wear`` (Coulomb and viscous levels grow linearly from an onset
day), ``step`` (a re-lubrication: levels drop by a fraction on one day), ``temperature`` (the ambient
swings day to day by several kelvin; the joint's thermal4 law turns that into friction changes that are
not wear) or ``noise`` (nothing but the sensors and a small ambient scatter); and more than one change in
the window: ``wear_step`` (wear from an onset, then a repair brings the levels back to new), ``two_steps``
(two steps of random sign) or ``recovery`` (a fault raises the levels by a step; maintenance brings them
back). Every joint has a thermal4 law, so every joint's friction follows its temperature.
"""
from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frictid.io.logs import write_logs
from frictid.plant import simulate_recipe

START = dt.date(2026, 3, 1)
KINDS = ("wear", "step", "wear_step", "two_steps", "recovery", "temperature", "noise")
#: How often each kind is drawn (wear and steps on a few joints, more than one change on fewer).
SHARES = (0.08, 0.05, 0.04, 0.04, 0.04, 0.30, 0.45)
#: The planted changes of each kind, in order (kind of each change: wear or step).
CHANGES = {"wear": ("wear",), "step": ("step",), "wear_step": ("wear", "step"), "two_steps": ("step", "step"),
           "recovery": ("step", "step"), "temperature": (), "noise": ()}


def day_recipe(velocities: int = 5, plateau: float = 0.6, temp_env: float = 25.0) -> dict:
    """One daily identification run: plateaus at ``velocities`` speeds, both signs (~15 s at 5, 0.6 s)."""
    return {"name": "fleet_day", "default_plant": "direct_drive", "start_rest": 0.3, "temp_env": float(temp_env),
            "experiments": [{"kind": "constant_velocity",
                             "velocities": {"min": 0.05, "max": 0.9, "count": velocities, "spacing": "log"},
                             "signs": "both", "plateau": plateau, "min_plateau": 0.3, "accel": 0.5, "gap": 0.2,
                             "rest": 0.3}]}


def joint_plant(name: str, Fc: float, Fs: float, sigma2: float, scale: float = 1.0) -> dict:
    """A plant of one joint: Stribeck map, levels times ``scale`` (wear, re-lubrication), thermal4 law."""
    return {"name": "fleet", "axis": "rotary",
            "sensors": {"sample_rate": 500, "encoder_counts": 1048576, "tau_noise": 0.3, "qd_noise": 0.002},
            "joints": [{"name": name, "J": 2.0,
                        "friction": {"map": "stribeck", "Fc": Fc * scale, "Fs": Fs * scale, "vs": 0.1, "delta": 2.0,
                                     "sigma2": sigma2 * scale, "sigma0": 50000.0, "sigma1": 300.0},
                        "thermal": {"law": "thermal4", "C": 50.0, "K": 1.0, "T0": 25.0, "Tenv": 25.0,
                                    "alpha": -0.006, "beta": 1.0},
                        "limits": {"velocity": 2.0, "acceleration": 8.0, "torque": 200.0, "position": [-3, 3]}}]}


@dataclass
class Planted:
    """What a joint's trend must show: ``kind``; per change its kind (wear or step), the index of its day
    (wear: the last day before the drift; step: the first day at the new level) and its size (the change
    of the levels as a fraction of the new joint's). ``day`` and ``size`` are the first change's."""

    robot: str
    joint: str
    kind: str
    changes: tuple[tuple[str, int, float], ...] = ()

    @property
    def day(self) -> int | None:
        return self.changes[0][1] if self.changes else None

    @property
    def size(self) -> float:
        return self.changes[0][2] if self.changes else 0.0


def draw_changes(kind: str, days: int, rng) -> tuple[tuple[str, int, float], ...]:
    """The changes of one joint: days at least ``max(5, days // 5)`` runs apart, sizes 15..30 %."""
    sizes = rng.uniform(0.15, 0.3, 2)
    if kind in ("wear", "step"):
        return ((kind, int(rng.integers(days // 4, 3 * days // 4)), sizes[0] if kind == "wear" else -sizes[0]),)
    if kind not in CHANGES or not CHANGES[kind]:
        return ()
    d1 = int(rng.integers(days // 6, days // 2))
    d2 = int(rng.integers(min(d1 + max(5, days // 5), days - 3), days - 2))
    if kind == "wear_step":  # wear reaches sizes[0] the day before the repair, which takes it away
        return (("wear", d1, sizes[0] * (days - 1 - d1) / (d2 - 1 - d1)), ("step", d2, -sizes[0]))
    if kind == "two_steps":
        signs = rng.choice([-1.0, 1.0], 2)
        return (("step", d1, signs[0] * sizes[0]), ("step", d2, signs[1] * sizes[1]))
    return (("step", d1, sizes[0]), ("step", d2, -sizes[0]))  # recovery: a fault, then maintenance


def plan_fleet(robots: int, joints: int, days: int, seed: int, kinds=None) -> list[Planted]:
    """Which joint gets what: ``kinds`` in turn when given, else drawn (wear and step on a few joints)."""
    rng = np.random.default_rng(seed)
    out = []
    for r in range(robots):
        for j in range(joints):
            k = len(out)
            kind = str(kinds[k % len(kinds)] if kinds else rng.choice(KINDS, p=SHARES))
            changes = tuple((c, int(d), float(x)) for c, d, x in draw_changes(kind, days, rng))
            out.append(Planted(f"r{r + 1:02d}", f"j{j + 1}", kind, changes))
    return out


def level_scale(p: Planted, day: int, days: int) -> float:
    """The friction levels' factor on ``day``: wear grows linearly (to ``1 + size`` at the last day), a
    step adds its size from its day on; a step after wear is the repair: the drift ends and the levels are
    back where they were before it (the step's size is what the wear had reached)."""
    scale, wear = 1.0, None
    for kind, d, size in p.changes:  # in order of their days
        if day < d + (kind == "wear"):
            break
        if kind == "wear":
            wear = (d, size)
        elif wear is not None:
            wear = None
        else:
            scale += size
    if wear is not None:
        scale += wear[1] * (day - wear[0]) / max(days - 1 - wear[0], 1)
    return scale


def write_fleet(root, plan: list[Planted], days: int, seed: int, velocities: int = 5,
                plateau: float = 0.6) -> list[Path]:
    """Simulate and write every joint-day of ``plan`` below ``root``; returns the files."""
    root = Path(root)
    files = []
    for k, p in enumerate(plan):
        rng = np.random.default_rng([seed, k])
        Fc, sigma2 = rng.uniform(12, 25), rng.uniform(4, 10)
        swing = 8.0 if p.kind == "temperature" else 1.0
        ambient = 22.0 + swing * rng.standard_normal(days)
        for d in range(days):
            plant = joint_plant(p.joint, Fc, 1.3 * Fc, sigma2, level_scale(p, d, days))
            plant["robot"] = p.robot
            logs = simulate_recipe(day_recipe(velocities, plateau, ambient[d]), plant=plant,
                                   seed=int(rng.integers(2**31)))
            folder = root / f"robot={p.robot}" / f"joint={p.joint}" / f"date={START + dt.timedelta(days=d)}"
            folder.mkdir(parents=True, exist_ok=True)
            write_logs(logs, folder / "log.parquet")
            files.append(folder / "log.parquet")
    return files
