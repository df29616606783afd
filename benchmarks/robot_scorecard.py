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
4. The friction values against the published ones, one choice of the joint estimate changed at a time
   (standing band, weighting, parallel filtering, cut-off), then the published methods' own processing
   (classical least squares: every sample, the torque low-passed, the regressor not; for the UR10e exactly
   Mamedov et al.'s filterData.m), per joint; and the published friction held with the base parameters
   re-fitted, against the free fit (the residual each joint gains).
5. The Franka run with the rigid body known (``--rigid-body known``: the catalogue inertias of
   recipes/robots/panda.urdf, with the hand, and panda_arm.urdf, without, subtracted) against identified:
   friction against Table III, the known rigid body's F test, held-out torque error of both stages; and on
   random simulated arms (seeds from --seed-base + 2000) with the true inertias and with them 10 % off
   (``--part known``).
6. Stage 2 held out (``--part stage2``): the UR10e harmonic run and the Franka run (rigid body identified and
   known from panda_arm.urdf), per joint stage 1's linear friction, every joint's selected stage-2 model, and
   what the fit keeps (robotfit.guard_models), with each joint's verdict on the fitted part's own time blocks;
   and 5 simulated 3-joint arms (seeds from --seed-base + 3000) whose joint 1 has a Stribeck drop.
With FRICTID_SMOKE=1: two arms, the Franka run, part 4 on the first eighth of the Franka run and part 5 on
its first quarter.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.signal import butter, sosfiltfilt

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from frictid.io.logs import read_logs  # noqa: E402
from frictid.robot import identify_robot, load_robot  # noqa: E402
from frictid.robotfit import heldout_models  # noqa: E402
from frictid.robot.identify import (RobotFit, align, cut_log, design, heldout_errors, parallel_filter,  # noqa: E402
                                    predict, prepare, solve)
from frictid.robot.regressor import base_parameters  # noqa: E402
from test_robot import AURT_20HZ, physical_inertia, random_arm, simulate_excitation  # noqa: E402

AURT_RAW = {"1": 3.44, "2": 6.25, "3": 2.27, "4": 0.65, "5": 1.19, "6": 0.80}

TABLE3 = {"1": (0.0665, 0.2450, -0.1073), "2": (0.1987, 0.1523, -0.1566), "3": (0.0399, 0.1827, -0.0686),
          "4": (0.2257, 0.3591, -0.2522), "5": (0.1023, 0.2669, 0.0045), "6": (-0.0132, 0.1658, 0.0910),
          "7": (0.0638, 0.2109, -0.0127)}
#: UR10E_parameters.txt (Mamedov et al. 2020): fv, fc, fo per joint
MAMEDOV = {"1": (21.2560, 12.5484, 0.1961), "2": (20.2209, 13.2656, -0.7535), "3": (10.3777, 4.9943, 0.1979),
           "4": (3.5751, 1.9979, 0.0548), "5": (2.4909, 2.6905, -0.0096), "6": (3.0256, 2.2979, 0.0425)}
TOL = {"fc": ("rel", 0.03), "fv": ("rel", 0.10), "fo": ("abs", 0.1)}


def ur10e_arm(rng):
    """The UR10e's kinematics with random link inertias (2-15 kg) and random friction per joint."""
    robot = load_robot(ROOT / "recipes/robots/ur10e.yaml")
    robot.armature = False  # simulated link-side torques
    for i in range(1, robot.nv + 1):
        robot.model.inertias[i] = physical_inertia(rng, rng.uniform(2, 15), (0.05, 0.6))
    friction = {j: (rng.uniform(0.5, 5), rng.uniform(0.5, 8), rng.uniform(-1, 1)) for j in robot.joints}
    return robot, friction


def arms(n: int, base: int, make=random_arm, label: str = "random arms, 4 DH joints each") -> None:
    hits = {k: [0, 0, 0] for k in TOL}   # within tolerance, within 2 se, count
    rel, cls = [], []   # cls: the classical processing's relative errors of fv and fc (signed)
    consistent = 0      # estimates found physically consistent (every simulated arm is)
    for s in range(base, base + n):
        rng = np.random.default_rng(s)
        robot, friction = make(rng)
        logs = simulate_excitation(robot, friction, rng)
        fit = identify_robot(robot, logs)
        rel.append(fit.rel_error)
        consistent += any(note.startswith("physical feasibility: ") for note in fit.notes)
        truth_all = np.array([friction[j] for j in robot.joints])
        cls.append((classical(robot, logs)[0][:, :2] - truth_all[:, :2]) / np.abs(truth_all[:, :2]))
        for j, truth in friction.items():
            for k, true in zip(("fv", "fc", "fo"), truth):
                got = fit.friction[j][k]
                kind, tol = TOL[k]
                err = abs(got.value - true) / (abs(true) if kind == "rel" else 1.0)
                hits[k][0] += err <= tol
                hits[k][1] += abs(got.value - true) <= 2 * got.stderr
                hits[k][2] += 1
    print(f"{label}: {n} (seeds {base}..{base + n - 1}); relative torque error median "
          f"{100 * np.median(rel):.2f} %; base parameters physically consistent (as the simulated links are): "
          f"{consistent}/{n}")
    for k, (ok, cov, cnt) in hits.items():
        kind, tol = TOL[k]
        print(f"  {k}: within {tol:g}{' (relative)' if kind == 'rel' else ' N m'}: {ok}/{cnt} ({100 * ok / cnt:.0f} %); "
              f"truth within 2 se: {cov}/{cnt} ({100 * cov / cnt:.0f} %)")
    c = np.concatenate(cls)
    print(f"  classical LS on the same logs (torque low-passed, regressor not; ordinary LS; part 4): fc within 3 %: "
          f"{int(np.sum(np.abs(c[:, 1]) <= 0.03))}/{len(c)}, fv within 10 %: {int(np.sum(np.abs(c[:, 0]) <= 0.1))}/{len(c)}; "
          f"median error fc {100 * np.median(c[:, 1]):+.1f} %, fv {100 * np.median(c[:, 0]):+.1f} %")


def alternation(robot, logs, rounds: int, fraction: float = 0.3) -> list[np.ndarray]:
    """Stage 2 with the rigid body re-estimated by alternation (issue 24): identify on the head, then in
    each round fit frictid's models on each joint's friction torque, hold them (the selected law where the
    joint moves, its offset everywhere) and re-fit the base parameters by the joint estimate's WLS on the
    parallel-filtered torque less that friction. Per round (0: the rigid body of stage 1, held), the held-out
    RMS per joint [N m] of the rigid body plus the models, at the tail's own samples, as logged."""
    from frictid.api import fit as fit_joints
    from frictid.robotfit import friction_logs, model_torque

    k = int(round((1.0 - fraction) * min(lg.n for lg in logs)))
    head, tail = [cut_log(lg, slice(0, k)) for lg in logs], [cut_log(lg, slice(k, None)) for lg in logs]
    rf = identify_robot(robot, head)
    d = prepare(robot, head, rf.cutoff_hz)
    nb, mov = rf.bp.n, d.moving()
    Y = design(robot, rf.bp, d)[:, :nb]
    _, ordered = align(robot, tail)
    out = []
    for r in range(rounds + 1):
        res = fit_joints(friction_logs(head, predict(robot, rf, head)), diagnose=False)
        pr = model_torque(res, predict(robot, rf, tail), tail)
        out.append(np.array([np.sqrt(np.mean((np.asarray(lg.tau) - pr[j]) ** 2)) for j, lg in zip(robot.joints, ordered)]))
        if r == rounds:
            return out
        F = np.zeros_like(d.qd)
        for i, j in enumerate(robot.joints):
            off = res[j].offset.value if res[j].offset is not None and res[j].offset.value is not None else 0.0
            F[:, i] = off
            F[mov[:, i], i] += res[j].model.friction(d.qd[mov[:, i], i], q=d.q[mov[:, i], i])
        A, y, jid = parallel_filter(d, np.hstack([Y, F.reshape(-1, 1)]), d.tau.reshape(-1))
        rf.x = rf.x.copy()
        rf.x[:nb] = solve(A[:, :nb], y - A[:, nb], jid, robot.nv)[0]
    return out


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
    print("  " + "; ".join(n for n in fit.notes if "physical" in n))
    print(f"  {'joint':<5} {'whole':>6} {'AURT':>6} {'moving':>7}   {'whole 20Hz':>10} {'AURT':>6} {'moving':>7}   fv fc fo")
    for j in robot.joints:
        f = fit.friction[j]
        print(f"  {j:<5} {raw['whole'][j]:6.2f} {AURT_RAW[j]:6.2f} {raw['moving'][j]:7.2f}   {smooth['whole'][j]:10.2f} "
              f"{AURT_20HZ[j]:6.2f} {smooth['moving'][j]:7.2f}   {f['fv'].value:.2f} {f['fc'].value:.2f} {f['fo'].value:.2f}")
    stage_two(robot, logs)
    t0 = time.time()
    rounds = 1 if os.environ.get("FRICTID_SMOKE") else 3
    alt = alternation(robot, logs, rounds)
    print(f"  stage 2 with the rigid body re-estimated by alternation, same split, as logged, per round "
          f"({time.time() - t0:.1f} s): " + "; ".join(f"{r}: " + " ".join(f"{v:.2f}" for v in e) for r, e in enumerate(alt)))
    standing(robot, logs)


def stage_two(robot, logs, rigid_body: str = "identify", label: str = "") -> None:
    """Stage 2 held out (first 70 % fitted, last 30 % predicted, as logged): per joint the RMS of stage 1's
    linear friction, of every joint's selected stage-2 model (the choice unguarded, as before session 22),
    and of what fit_robot keeps (robotfit.guard_models: the model only where it beats the linear friction on
    the fitted part's own 4 time blocks), with the blocks' verdict."""
    t0 = time.process_time()
    both = heldout_models(robot, logs, 0.3, rigid_body=rigid_body)
    print(f"  stage 2 {label}(frictid's velocity models on each joint's friction torque, rigid body held), same "
          f"split, as logged, {time.process_time() - t0:.1f} s CPU; kept: robotfit.guard_models on the fitted "
          "part's own 4 time blocks (block RMS model / linear)")
    print(f"  {'joint':<5} {'linear':>7} {'models':>7} {'kept':>7}   {'moving: linear':>14} {'models':>7} {'kept':>7}"
          "   verdict")
    a, b, c = both["linear"], both["models_all"], both["models"]
    for j in robot.joints:
        v = both["stage2"][j]
        e = v.get("heldout_rms", {})
        blk = f"{e['models']:.3f} / {e['linear']:.3f}" if e else v["reason"]
        print(f"  {j:<5} {a['whole'][j]:7.3f} {b['whole'][j]:7.3f} {c['whole'][j]:7.3f}   {a['moving'][j]:14.3f} "
              f"{b['moving'][j]:7.3f} {c['moving'][j]:7.3f}   {v['kept']:<6} ({v['model']}: {blk})")


def stage_two_arms(n: int, base: int) -> None:
    """Stage 2's guard on simulated 3-joint arms (tests/test_robot.py's generator, 20 s at 500 Hz, 0.05 N m
    noise): joint 1 with a Stribeck drop (0.5-2 N m over its Coulomb level, Stribeck speed 0.05-0.3 rad/s,
    which the linear friction cannot follow), joints 2 and 3 linear. Per arm, held out (first 70 % fitted,
    last 30 % predicted): which joints keep stage 2's model and the RMS of linear / every model / kept."""
    kept_drop, kept_lin, worse = 0, 0, 0
    for s in range(base, base + n):
        rng = np.random.default_rng(s)
        robot, friction = random_arm(rng, 3)
        logs = simulate_excitation(robot, friction, rng, duration=20.0)
        amp, vs = rng.uniform(0.5, 2.0), rng.uniform(0.05, 0.3)
        w = logs[0].qd
        logs[0].tau = logs[0].tau + amp * np.exp(-(w / vs) ** 2) * np.sign(w)
        both = heldout_models(robot, logs, 0.3)
        a, b, c = (both[k]["whole"] for k in ("linear", "models_all", "models"))
        verdict = {j: both["stage2"][j]["kept"] for j in robot.joints}
        kept_drop += verdict["1"] == "models"
        kept_lin += sum(verdict[j] == "linear" for j in robot.joints[1:])
        worse += sum(c[j] > 1.05 * a[j] for j in robot.joints)
        print(f"  arm {s}: drop {amp:.2f} N m at {vs:.2f} rad/s; " + "; ".join(
            f"joint {j} {verdict[j]} {a[j]:.3f}/{b[j]:.3f}/{c[j]:.3f}" for j in robot.joints))
    print(f"  simulated arms {base}..{base + n - 1}: the drop's joint keeps stage 2's model on {kept_drop}/{n}; the "
          f"linear joints keep stage 1 on {kept_lin}/{2 * n}; kept law more than 5 % worse than linear held out on "
          f"{worse}/{3 * n} joints (RMS per joint: linear/every model/kept)")


def standing(robot, logs, fraction: float = 0.3) -> None:
    """The standing level (frictid/robot/hold.py) on a held-out tail: identify on the head, predict the tail
    as logged with and without each joint's level; per joint the level and the RMS error, whole tail and its
    standing samples."""
    k = int(round((1.0 - fraction) * min(lg.n for lg in logs)))
    fit = identify_robot(robot, [cut_log(lg, slice(0, k)) for lg in logs])
    tail = [cut_log(lg, slice(k, None)) for lg in logs]
    _, ordered = align(robot, tail)
    levels = {j: f["fh"] for j, f in fit.friction.items()}
    with_level = predict(robot, fit, tail)
    fit.friction = {j: {kk: v for kk, v in f.items() if kk != "fh"} for j, f in fit.friction.items()}
    without = predict(robot, fit, tail)
    print("  standing level (robot/hold.py), held out as logged: fh [N m], whole tail without -> with, standing "
          "samples without -> with")
    for j, lg in zip(robot.joints, ordered):
        h, st = levels[j], ~with_level.moving[j]
        r0, r1 = np.asarray(lg.tau) - without.tau[j], np.asarray(lg.tau) - with_level.tau[j]
        rms = (lambda r, m=slice(None): float(np.sqrt(np.mean(r[m] ** 2))) if np.size(r[m]) else float("nan"))
        lev = f"{h.value:6.3f} +- {h.stderr:.3f}" if h.identifiable else f"{'-':>15}"
        why = "" if h.identifiable else f"; not identifiable: {h.reason.split(' (')[0]}"
        print(f"  {j:<5} {lev:<15} {rms(r0):7.3f} -> {rms(r1):7.3f}   {rms(r0, st):7.3f} -> {rms(r1, st):7.3f} "
              f"({100 * st.mean():.0f} % standing{why})")


def franka() -> None:
    logs = read_logs(str(ROOT.parent / "shared/realdata/franka_panda_gaz2019"),
                     str(ROOT / "recipes/realdata/franka_panda.yaml"))
    t0 = time.time()
    panda = load_robot(ROOT / "recipes/robots/panda.yaml")
    fit = identify_robot(panda, logs)
    print(f"Franka Panda (Gaz 2019 Table III, classical LS): relative torque error {100 * fit.rel_error:.2f} % "
          f"(published 1.41 %), condition {fit.condition:.1f} (published 121.88), {len(fit.base)} base parameters, "
          f"cut-off {fit.cutoff_hz:.1f} Hz, {time.time() - t0:.1f} s")
    print("  " + "; ".join(n for n in fit.notes if "physical" in n))
    print(f"  {'joint':<5} {'fc':>8} {'se':>6} {'Table III':>9} {'diff':>7} {'/se':>5}  {'fv':>8} {'se':>6} {'Table III':>9} "
          f"{'/se':>5}  {'fo':>8} {'Table III':>9} {'diff':>7}")
    for j, (fv_p, fc_p, fo_p) in TABLE3.items():
        f = fit.friction[j]
        fc, fv = f["fc"], f["fv"]
        print(f"  {j:<5} {fc.value:8.4f} {fc.stderr:6.4f} {fc_p:9.4f} {100 * (fc.value / fc_p - 1):+6.1f}% "
              f"{(fc.value - fc_p) / fc.stderr:+5.1f}  {fv.value:8.4f} {fv.stderr:6.4f} {fv_p:9.4f} "
              f"{(fv.value - fv_p) / fv.stderr:+5.1f}  {f['fo'].value:8.4f} {fo_p:9.4f} {f['fo'].value - fo_p:+7.3f}")
    standing(panda, logs)


def _solve(A, y, jid, nb: int, nv: int, weighted: bool, hold=None):
    """(friction (nv, 3) [fv fc fo], residual RMS per joint, relative torque error, the estimate [base |
    friction]), all on the fitted samples: WLS as frictid
    or ordinary LS; with ``hold`` ((nv, 3)) the friction is held and only the base parameters are fitted."""
    if hold is not None:
        fh = np.asarray(hold, float).reshape(-1)
        yb = y - A[:, nb:] @ fh
        xb = solve(A[:, :nb], yb, jid, nv)[0] if weighted else np.linalg.lstsq(A[:, :nb], yb, rcond=None)[0]
        x = np.concatenate([xb, fh])
    else:
        x = solve(A, y, jid, nv)[0] if weighted else np.linalg.lstsq(A, y, rcond=None)[0]
    r = y - A @ x
    rms = np.array([np.sqrt(np.mean(r[jid == j] ** 2)) for j in range(nv)])
    return x[nb:].reshape(nv, 3), rms, float(np.linalg.norm(r) / np.linalg.norm(y)), x


def variant(robot, logs, cutoff=None, standing=True, weighted=True, parallel=True, hold=None):
    """frictid's joint estimate (frictid.robot.identify) with one choice changed: the cut-off [Hz], the
    standing band (off: every sample keeps its friction sign), WLS or ordinary LS, parallel filtering (off:
    the torque low-passed at the cut-off, the regressor left as built)."""
    d = prepare(robot, logs, cutoff)
    if not standing:
        d.still = None
    bp = base_parameters(robot, robot.armature)
    A = design(robot, bp, d)
    if parallel:
        A2, y2, jid = parallel_filter(d, A, d.tau.reshape(-1))
    else:
        fs = 1.0 / float(np.median(np.diff(d.t)))
        y = sosfiltfilt(butter(4, d.cutoff, fs=fs, output="sos"), d.tau, axis=0).reshape(-1)
        keep = d.moving().reshape(-1)
        A2, y2, jid = A[keep], y[keep], np.tile(np.arange(robot.nv), d.q.shape[0])[keep]
    return _solve(A2, y2, jid, bp.n, robot.nv, weighted, hold) + (d.cutoff, bp)


def classical(robot, logs, cutoff=None, mamedov=False, hold=None):
    """The published methods' processing: ordinary LS on every sample (sign of the filtered velocity
    throughout), the torque low-passed, the regressor not filtered. Default: position and velocity
    low-passed (4th order, zero phase) at ``cutoff`` (frictid's when None), acceleration their derivative.
    ``mamedov``: filterData.m of Mamedov et al. (5th-order Butterworth at 0.15 of Nyquist on velocity and on
    the central-difference acceleration, 0.20 on the torque; position unfiltered), on the samples from the
    first to the last at which a joint moves."""
    d = prepare(robot, logs)
    _, ordered = align(robot, logs)
    q, qd = (np.column_stack([np.interp(d.t, lg.t, getattr(lg, k)) for lg in ordered]) for k in ("q", "qd"))
    fs = 1.0 / float(np.median(np.diff(d.t)))
    if mamedov:
        lp = butter(5, 0.15, output="sos")
        qd = sosfiltfilt(lp, qd, axis=0)
        qdd = sosfiltfilt(lp, np.gradient(qd, d.t, axis=0), axis=0)
        tau = sosfiltfilt(butter(5, 0.20, output="sos"), d.tau, axis=0)
        idx = np.flatnonzero(d.moving().any(axis=1))
        span = slice(idx[0], idx[-1] + 1)
    else:
        cutoff = d.cutoff if cutoff is None else cutoff
        sos = butter(4, cutoff, fs=fs, output="sos")
        q, qd, tau = (sosfiltfilt(sos, x, axis=0) for x in (q, qd, d.tau))
        qdd = np.gradient(qd, d.t, axis=0)
        span = slice(None)
    d.q, d.qd, d.qdd, d.tau, d.still = q[span], qd[span], qdd[span], tau[span], None
    bp = base_parameters(robot, robot.armature)
    A = design(robot, bp, d)
    jid = np.tile(np.arange(robot.nv), d.q.shape[0])
    return _solve(A, d.tau.reshape(-1), jid, bp.n, robot.nv, False, hold)


def published(name: str, robot, logs, pub: dict, rows: list) -> None:
    """Part 4 for one robot: rows of (label, kwargs of :func:`variant` or ('classical', kwargs))."""
    P = np.array([pub[j] for j in robot.joints])
    print(f"{name}: friction against the published values, one change at a time (fc, fv: % off; fo: N m off; "
          "relative torque error on the samples each fits)")
    print(f"  {'':<46} " + " ".join(f"fc{j:<5}" for j in robot.joints) + " | "
          + " ".join(f"fv{j:<5}" for j in robot.joints) + " | " + " ".join(f"fo{j:<5}" for j in robot.joints) + " | torque error")
    for label, kind, kw in rows:
        f, _, rel = (classical(robot, logs, **kw) if kind == "classical" else variant(robot, logs, **kw))[:3]
        print(f"  {label:<46} " + " ".join(f"{v:+6.1f}%" for v in 100 * (f[:, 1] / P[:, 1] - 1)) + " | "
              + " ".join(f"{v:+6.1f}%" for v in 100 * (f[:, 0] / P[:, 0] - 1)) + " | "
              + " ".join(f"{v:+7.3f}" for v in f[:, 2] - P[:, 2]) + f" | {100 * rel:.2f} %")
    for label, kind, kw in rows[:1] + rows[-1:]:
        run = classical if kind == "classical" else variant
        free, held = run(robot, logs, **kw)[1], run(robot, logs, hold=P, **kw)[1]  # residual on the fitted rows
        print(f"  published friction held, base re-fitted ({label}): residual RMS per joint "
              + " ".join(f"{a:.3g}->{b:.3g}" for a, b in zip(free, held))
              + f" N m ({' '.join(f'{100 * (b / a - 1):+.0f}%' for a, b in zip(free, held))})")
    (_, free), (_, held) = heldout_held(robot, logs, P)
    print("  held out (first 70 % identified, last 30 % predicted, frictid without the standing level), RMS per joint, free -> published friction "
          "held: " + " ".join(f"{a:.3g}->{b:.3g}" for a, b in zip(free, held)) + " N m")


def heldout_held(robot, logs, P, fraction: float = 0.3) -> list[tuple[str, np.ndarray]]:
    """Identify on the head (frictid's joint estimate, free and with the published friction ``P`` held),
    predict the tail with frictid's predict (the fit's cut-off); RMS per joint at the logs' own samples."""
    k = int(round((1.0 - fraction) * min(lg.n for lg in logs)))
    head, tail = [cut_log(lg, slice(0, k)) for lg in logs], [cut_log(lg, slice(k, None)) for lg in logs]
    _, ordered = align(robot, tail)
    out = []
    for label, hold in (("free", None), ("published friction held", P)):
        *_, x, cutoff, bp = variant(robot, head, hold=hold)
        p = predict(robot, RobotFit([], [], {}, np.nan, np.nan, {}, cutoff, 0, x=x, bp=bp), tail)
        out.append((label, np.array([np.sqrt(np.mean((np.asarray(lg.tau) - p.tau[j]) ** 2))
                                     for j, lg in zip(robot.joints, ordered)])))
    return out


def friction_values(smoke: bool) -> None:
    franka = read_logs(str(ROOT.parent / "shared/realdata/franka_panda_gaz2019"),
                       str(ROOT / "recipes/realdata/franka_panda.yaml"))
    if smoke:
        franka = [cut_log(lg, slice(0, lg.n // 8)) for lg in franka]
    panda = load_robot(ROOT / "recipes/robots/panda.yaml")
    cut = prepare(panda, franka).cutoff
    rows = [("frictid (WLS, parallel filter, standing band)", "variant", {}),
            ("standing band off", "variant", {"standing": False}),
            ("ordinary LS", "variant", {"weighted": False}),
            ("no parallel filter (torque low-passed)", "variant", {"parallel": False}),
            (f"cut-off x0.5 ({cut / 2:.1f} Hz)", "variant", {"cutoff": cut / 2}),
            (f"cut-off x2 ({cut * 2:.1f} Hz)", "variant", {"cutoff": cut * 2}),
            (f"classical LS, cut-off {cut / 2:.1f} Hz", "classical", {"cutoff": cut / 2}),
            (f"classical LS, cut-off {cut * 2:.1f} Hz", "classical", {"cutoff": cut * 2}),
            (f"classical LS, cut-off {cut:.1f} Hz", "classical", {})]
    published("Franka Panda (Table III)", panda, franka, TABLE3, rows[:1] + rows[-1:] if smoke else rows)
    if smoke:
        return
    run = ROOT.parent / "shared/realdata/ur10e_mamedov2020/identification_data/ur-20_02_19_15harm50sec.csv"
    ur = read_logs(str(run), str(ROOT / "recipes/realdata/ur10e_harmonic.yaml"))
    ur10e = load_robot(ROOT / "recipes/robots/ur10e.yaml")
    cut = prepare(ur10e, ur).cutoff
    rows = rows[:4] + [(f"cut-off x0.5 ({cut / 2:.1f} Hz)", "variant", {"cutoff": cut / 2}),
                       (f"cut-off x2 ({cut * 2:.1f} Hz)", "variant", {"cutoff": cut * 2}),
                       ("Mamedov et al.'s processing (OLS)", "classical", {"mamedov": True})]
    published("UR10e harmonic run, whole (UR10E_parameters.txt)", ur10e, ur, MAMEDOV, rows)


def known_arms(n: int, base: int) -> None:
    """Part 5 on simulated arms (tests/test_robot_known.py's generator: random 4-joint DH arms whose YAML
    carries the true link inertias, friction as part 1, 500 Hz, 0.05 N m noise): the rigid body known exactly
    and 10 % off (every mass and inertia x1.1): the share of joints within tolerance per parameter, the
    share whose truth lies within 2 standard errors, and how often the F test says the log bears the rigid
    body out."""
    from frictid.robot.description import DHRobot, robot_from_dh
    from frictid.robot.known import identify_known
    from test_robot_known import arm_yaml, scaled

    hits = {f: {k: [0, 0, 0] for k in TOL} for f in (1.0, 1.1)}
    borne = {1.0: 0, 1.1: 0}
    for s in range(base, base + n):
        rng = np.random.default_rng(s)
        desc, friction = arm_yaml(rng)
        logs = simulate_excitation(robot_from_dh(DHRobot.model_validate(desc)), friction, rng)
        for factor in hits:
            fit = identify_known(robot_from_dh(DHRobot.model_validate(scaled(desc, factor))), logs)
            borne[factor] += any(nt.startswith("known rigid body: the log bears it out") for nt in fit.notes)
            for j, truth in friction.items():
                for k, true in zip(("fv", "fc", "fo"), truth):
                    got, (kind, tol) = fit.friction[j][k], TOL[k]
                    err = abs(got.value - true) / (abs(true) if kind == "rel" else 1.0)
                    h = hits[factor][k]
                    h[0] += err <= tol
                    h[1] += abs(got.value - true) <= 2 * got.stderr
                    h[2] += 1
    print(f"rigid body known, random arms: {n} (seeds {base}..{base + n - 1}), 4 DH joints, the YAML's inertias exact "
          "and x1.1")
    for factor, h in hits.items():
        print(f"  inertias x{factor:g}: log bears the rigid body out: {borne[factor]}/{n}; " + "; ".join(
            f"{k} within {TOL[k][1]:g}: {ok}/{cnt}, truth within 2 se: {cov}/{cnt}" for k, (ok, cov, cnt) in h.items()))


def known(smoke: bool = False) -> None:
    """Part 5: the Franka run with the rigid body known from the shipped URDFs' catalogue inertias
    (example-robot-data: recipes/robots/panda.urdf with the hand, panda_arm.urdf without) against the rigid
    body identified from the run (recipes/robots/panda.yaml): per joint fc, fv, fo against Table III, the F test of the known rigid body,
    and the held-out torque error (first 70 % fitted, last 30 % predicted, as logged) of the joint estimate
    and of stage 2's selected models."""
    from frictid.robot.known import identify_known

    logs = read_logs(str(ROOT.parent / "shared/realdata/franka_panda_gaz2019"),
                     str(ROOT / "recipes/realdata/franka_panda.yaml"))
    if smoke:
        logs = [cut_log(lg, slice(0, lg.n // 4)) for lg in logs]
    routes = {"identify": (load_robot(ROOT / "recipes/robots/panda.yaml"), identify_robot, "identify"),
              "known+hand": (load_robot(ROOT / "recipes/robots/panda.urdf"), identify_known, "known"),
              "known arm": (load_robot(ROOT / "recipes/robots/panda_arm.urdf"), identify_known, "known")}
    print("Franka Panda, rigid body identified (panda.yaml) vs known from the catalogue inertias of "
          "example-robot-data (known+hand: panda.urdf; known arm: panda_arm.urdf, no hand): friction against "
          "Table III (fc, fv: % off; fo: N m off)")
    print(f"  {'route':<10} " + " ".join(f"fc{j:<5}" for j in TABLE3) + " | " + " ".join(f"fv{j:<5}" for j in TABLE3)
          + " | " + " ".join(f"fo{j:<5}" for j in TABLE3) + " | torque error")
    P = np.array([TABLE3[j] for j in TABLE3])
    for name, (robot, estimate, _) in routes.items():
        t0 = time.process_time()
        fit = estimate(robot, logs)
        f = np.array([[fit.friction[j][k].value for k in ("fv", "fc", "fo")] for j in TABLE3])
        print(f"  {name:<10} " + " ".join(f"{v:+6.1f}%" for v in 100 * (f[:, 1] / P[:, 1] - 1)) + " | "
              + " ".join(f"{v:+6.1f}%" for v in 100 * (f[:, 0] / P[:, 0] - 1)) + " | "
              + " ".join(f"{v:+7.3f}" for v in f[:, 2] - P[:, 2])
              + f" | {100 * fit.rel_error:.2f} % ({time.process_time() - t0:.1f} s CPU)")
        print("    " + "; ".join(n for n in fit.notes if n.startswith("known rigid body")))
        ses = " ".join(f"{fit.friction[j]['fc'].stderr:.3g}" for j in TABLE3)
        print(f"    fc standard errors [N m]: {ses}")
    print("  held out (first 70 % fitted, last 30 % predicted, as logged), RMS per joint [N m], "
          "joint estimate | stage 2's models, every joint's | stage 2 as kept (robotfit.guard_models):")
    for name, (robot, estimate, mode) in routes.items():
        lin = heldout_errors(robot, logs, 0.3, estimate=estimate)["whole"]
        both = heldout_models(robot, logs, 0.3, rigid_body=mode)
        mod, kept = both["models_all"]["whole"], both["models"]["whole"]
        print(f"  {name:<10} " + " ".join(f"{lin[j]:.3f}" for j in TABLE3) + " | "
              + " ".join(f"{mod[j]:.3f}" for j in TABLE3) + " | "
              + " ".join(f"{kept[j]:.3f}{'*' if both['stage2'][j]['kept'] == 'models' else ''}" for j in TABLE3))
    print("  (*: stage 2's model kept; otherwise stage 1's linear friction)")


#: the real runs of the standing level's lines: (run under shared/realdata, mapping file, robot file)
REAL_RUNS = [("ur10e_mamedov2020/identification_data/ur-20_02_19_15harm50sec.csv", "recipes/realdata/ur10e_harmonic.yaml",
              "recipes/robots/ur10e.yaml"),
             ("franka_panda_gaz2019", "recipes/realdata/franka_panda.yaml", "recipes/robots/panda.yaml")]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--arms", type=int, default=20)
    ap.add_argument("--ur-arms", type=int, default=5, help="6-axis arms with the UR10e's kinematics")
    ap.add_argument("--seed-base", type=int, default=400000)
    ap.add_argument("--part", choices=("all", "published", "standing", "known", "stage2"), default="all",
                    help="published: part 4 only (friction values against the published ones); standing: the "
                         "standing level's held-out lines of the UR10e and Franka runs only; known: part 5 only "
                         "(the Franka run with the rigid body known from recipes/robots/panda.urdf); stage2: "
                         "stage 2 held out on the UR10e harmonic run and the Franka run (rigid body identified, "
                         "and known from panda_arm.urdf)")
    args = ap.parse_args(argv)
    smoke = bool(os.environ.get("FRICTID_SMOKE"))
    if smoke:
        args.arms, args.ur_arms = 2, 1
    if args.part == "published":
        friction_values(smoke)
        return 0
    if args.part == "known":
        known_arms(args.arms, args.seed_base + 2000)
        known(smoke)
        return 0
    if args.part == "stage2":
        ur = read_logs(str(ROOT.parent / "shared/realdata" / REAL_RUNS[0][0]), str(ROOT / REAL_RUNS[0][1]))
        print("UR10e harmonic run")
        stage_two(load_robot(ROOT / REAL_RUNS[0][2]), ur)
        fr = read_logs(str(ROOT.parent / "shared/realdata" / REAL_RUNS[1][0]), str(ROOT / REAL_RUNS[1][1]))
        if smoke:
            fr = [cut_log(lg, slice(0, lg.n // 4)) for lg in fr]
        print("Franka Panda")
        stage_two(load_robot(ROOT / REAL_RUNS[1][2]), fr, label="rigid body identified ")
        stage_two(load_robot(ROOT / "recipes/robots/panda_arm.urdf"), fr, "known", "rigid body known (panda_arm.urdf) ")
        print("simulated arms, a Stribeck drop on joint 1 (seeds from --seed-base + 3000)")
        stage_two_arms(min(args.arms, 2 if smoke else 5), args.seed_base + 3000)
        return 0
    if args.part == "standing":
        for run, mapping, robot in REAL_RUNS:
            print(run)
            standing(load_robot(ROOT / robot), read_logs(str(ROOT.parent / "shared/realdata" / run), str(ROOT / mapping)))
        return 0
    arms(args.arms, args.seed_base)
    arms(args.ur_arms, args.seed_base + 1000, ur10e_arm, "UR10e kinematics, random inertias (6-axis, 500 Hz)")
    ur10e()
    franka()
    friction_values(smoke)
    known_arms(args.arms, args.seed_base + 2000)
    known(smoke)
    return 0


if __name__ == "__main__":
    sys.exit(main())
