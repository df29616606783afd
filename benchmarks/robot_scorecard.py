"""Scorecard of whole-robot identification (issue 24): rigid-body base parameters and per-joint friction.

    python benchmarks/robot_scorecard.py [--arms 20] [--seed-base 400000]

1. Random simulated arms (tests/test_robot.py's generator: 4 DH joints, and 6-axis arms with the UR10e's
   kinematics, random inertias, Coulomb 0.5-8,
   viscous 0.5-5, offsets +-1 N m, a 5-harmonic Fourier excitation logged at 500 Hz with 0.05 N m torque
   noise): per parameter, the share of joints within tolerance (Coulomb 3 %, viscous 10 %, offset 0.1 N m)
   and the share whose truth lies within 2 standard errors.
2. The UR10e harmonic run (Mamedov et al. 2020; DH of recipes/robots/ur10e.yaml, torque = drive gain x
   current): first 70 % identified, last 30 % predicted; held-out RMS per joint, whole run and moving
   samples, against AURT's figures (issue 24), for the torque as logged and low-passed at 20 Hz.
3. The Franka Panda excitation run against Gaz et al. 2019 Table III (classical LS on the same run):
   Coulomb, viscous and offset per joint, the relative torque error and the condition number.
With FRICTID_SMOKE=1: two arms and the Franka run.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from frictid.io.logs import read_logs  # noqa: E402
from frictid.robot import identify_robot, load_robot  # noqa: E402
from frictid.robotfit import heldout_models  # noqa: E402
from frictid.robot.identify import heldout_errors  # noqa: E402
from test_robot import AURT_20HZ, random_arm, simulate_excitation  # noqa: E402

AURT_RAW = {"1": 3.44, "2": 6.25, "3": 2.27, "4": 0.65, "5": 1.19, "6": 0.80}

TABLE3 = {"1": (0.0665, 0.2450, -0.1073), "2": (0.1987, 0.1523, -0.1566), "3": (0.0399, 0.1827, -0.0686),
          "4": (0.2257, 0.3591, -0.2522), "5": (0.1023, 0.2669, 0.0045), "6": (-0.0132, 0.1658, 0.0910),
          "7": (0.0638, 0.2109, -0.0127)}
TOL = {"fc": ("rel", 0.03), "fv": ("rel", 0.10), "fo": ("abs", 0.1)}


def ur10e_arm(rng):
    """The UR10e's kinematics with random link inertias (2-15 kg) and random friction per joint."""
    import pinocchio as pin

    robot = load_robot(ROOT / "recipes/robots/ur10e.yaml")
    robot.armature = False  # simulated link-side torques
    for i in range(1, robot.nv + 1):
        robot.model.inertias[i] = pin.Inertia(rng.uniform(2, 15), rng.uniform(-0.1, 0.1, 3),
                                              np.diag(rng.uniform(0.01, 0.3, 3)))
    friction = {j: (rng.uniform(0.5, 5), rng.uniform(0.5, 8), rng.uniform(-1, 1)) for j in robot.joints}
    return robot, friction


def arms(n: int, base: int, make=random_arm, label: str = "random arms, 4 DH joints each") -> None:
    hits = {k: [0, 0, 0] for k in TOL}   # within tolerance, within 2 se, count
    rel = []
    for s in range(base, base + n):
        rng = np.random.default_rng(s)
        robot, friction = make(rng)
        fit = identify_robot(robot, simulate_excitation(robot, friction, rng))
        rel.append(fit.rel_error)
        for j, truth in friction.items():
            for k, true in zip(("fv", "fc", "fo"), truth):
                got = fit.friction[j][k]
                kind, tol = TOL[k]
                err = abs(got.value - true) / (abs(true) if kind == "rel" else 1.0)
                hits[k][0] += err <= tol
                hits[k][1] += abs(got.value - true) <= 2 * got.stderr
                hits[k][2] += 1
    print(f"{label}: {n} (seeds {base}..{base + n - 1}); relative torque error median "
          f"{100 * np.median(rel):.2f} %")
    for k, (ok, cov, cnt) in hits.items():
        kind, tol = TOL[k]
        print(f"  {k}: within {tol:g}{' (relative)' if kind == 'rel' else ' N m'}: {ok}/{cnt} ({100 * ok / cnt:.0f} %); "
              f"truth within 2 se: {cov}/{cnt} ({100 * cov / cnt:.0f} %)")


def ur10e() -> None:
    run = ROOT.parent / "shared/realdata/ur10e_mamedov2020/identification_data/ur-20_02_19_15harm50sec.csv"
    logs = read_logs(str(run), str(ROOT / "recipes/realdata/ur10e_harmonic.yaml"))
    robot = load_robot(ROOT / "recipes/robots/ur10e.yaml")
    t0 = time.time()
    raw, smooth = heldout_errors(robot, logs, 0.3), heldout_errors(robot, logs, 0.3, smooth_hz=20.0)
    fit = raw["fit"]
    print(f"UR10e harmonic run: last 30 % held out; {len(fit.base)} base parameters (with rotor inertias), "
          f"condition {fit.condition:.1f}, relative torque error in the fit {100 * fit.rel_error:.2f} %, "
          f"{time.time() - t0:.1f} s for both")
    print(f"  {'joint':<5} {'whole':>6} {'AURT':>6} {'moving':>7}   {'whole 20Hz':>10} {'AURT':>6} {'moving':>7}   fv fc fo")
    for j in robot.joints:
        f = fit.friction[j]
        print(f"  {j:<5} {raw['whole'][j]:6.2f} {AURT_RAW[j]:6.2f} {raw['moving'][j]:7.2f}   {smooth['whole'][j]:10.2f} "
              f"{AURT_20HZ[j]:6.2f} {smooth['moving'][j]:7.2f}   {f['fv'].value:.2f} {f['fc'].value:.2f} {f['fo'].value:.2f}")
    t0 = time.time()
    both = heldout_models(robot, logs, 0.3)
    print(f"  stage 2 (frictid's velocity models on each joint's friction torque, rigid body held), same split, "
          f"as logged, {time.time() - t0:.1f} s:")
    print(f"  {'joint':<5} {'linear':>7} {'models':>7}   {'moving: linear':>14} {'models':>7}")
    for j in robot.joints:
        a, b = both["linear"], both["models"]
        print(f"  {j:<5} {a['whole'][j]:7.2f} {b['whole'][j]:7.2f}   {a['moving'][j]:14.2f} {b['moving'][j]:7.2f}")


def franka() -> None:
    logs = read_logs(str(ROOT.parent / "shared/realdata/franka_panda_gaz2019"),
                     str(ROOT / "recipes/realdata/franka_panda.yaml"))
    t0 = time.time()
    fit = identify_robot(load_robot(ROOT / "recipes/robots/panda.yaml"), logs)
    print(f"Franka Panda (Gaz 2019 Table III, classical LS): relative torque error {100 * fit.rel_error:.2f} % "
          f"(published 1.41 %), condition {fit.condition:.1f} (published 121.88), {len(fit.base)} base parameters, "
          f"cut-off {fit.cutoff_hz:.1f} Hz, {time.time() - t0:.1f} s")
    print(f"  {'joint':<5} {'fc':>8} {'Table III':>9} {'diff':>7}  {'fv':>8} {'Table III':>9}  {'fo':>8} {'Table III':>9} {'diff':>7}")
    for j, (fv_p, fc_p, fo_p) in TABLE3.items():
        f = fit.friction[j]
        print(f"  {j:<5} {f['fc'].value:8.4f} {fc_p:9.4f} {100 * (f['fc'].value / fc_p - 1):+6.1f}%  "
              f"{f['fv'].value:8.4f} {fv_p:9.4f}  {f['fo'].value:8.4f} {fo_p:9.4f} {f['fo'].value - fo_p:+7.3f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--arms", type=int, default=20)
    ap.add_argument("--ur-arms", type=int, default=5, help="6-axis arms with the UR10e's kinematics")
    ap.add_argument("--seed-base", type=int, default=400000)
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE"):
        args.arms, args.ur_arms = 2, 1
    arms(args.arms, args.seed_base)
    arms(args.ur_arms, args.seed_base + 1000, ur10e_arm, "UR10e kinematics, random inertias (6-axis, 500 Hz)")
    ur10e()
    franka()
    return 0


if __name__ == "__main__":
    sys.exit(main())
