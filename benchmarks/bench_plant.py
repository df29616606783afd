"""Plant simulator benchmark: speed (steps/s) and friction-torque accuracy against a tight reference.

    python benchmarks/bench_plant.py            # full: one hour at 1 kHz + accuracy on every plant
    python benchmarks/bench_plant.py --quick    # smaller, for a smoke run

Speed: a one-hour 1 kHz run (the validation_ptp recipe, 20 cycles of 3 minutes) on each plant; the
kernel alone (steps/s) and the whole simulate_recipe call (compile + kernel + labels).

Accuracy: the kernel against :func:`frictid.plant.reference.simulate_joint_ivp` (Radau, rtol 1e-10,
unfrozen nonlinear ODE) on the same closed loop with sensor noise and quantisation off, over windows of
motion with velocity reversals (multisine) and plateaus with their transients (constant-velocity
sweep), each window centred on a velocity reversal at speed (the hardest case for the step: the
bristles flip within a few samples). Error: RMS(F_kernel - F_ref) / RMS(F_ref) over the window, for
1, 2 and 4 substeps.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from frictid.plant import load_plant, simulate_recipe
from frictid.plant.config import Recipe, Sensors, load_recipe
from frictid.plant.kernel import simulate_joint
from frictid.plant.reference import simulate_joint_ivp
from frictid.plant.simulate import prepare_joint

PLANTS = ["direct_drive", "hydraulic", "geared_industrial", "linear_slide"]


def one_hour_recipe() -> Recipe:
    rec, _ = load_recipe("validation_ptp")
    return rec


def speed(plant_name: str, repeats: int = 3, scale: float = 1.0):
    plant = load_plant(plant_name)
    rec = one_hour_recipe()
    joint = plant.joints[0]
    prog, args, _ = prepare_joint(plant, joint, rec, 0, scale)
    n = len(prog["mode"])
    simulate_joint(**args)  # warm (compile cache)
    best = best_cpu = np.inf
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        simulate_joint(**args)
        best = min(best, time.perf_counter() - t0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    t0 = time.perf_counter()
    simulate_recipe(rec, plant=plant, joints=[joint.name], duration_scale=scale)
    total = time.perf_counter() - t0
    return n, n / best, n / best_cpu, total


def noiseless(plant):
    pl = plant.model_copy(deep=True)
    pl.sensors = Sensors(sample_rate=plant.sensors.sample_rate)
    return pl


def accuracy(plant_name: str, recipe: str, n_window: int, start_frac: float, substeps=(1, 2, 4),
             scale: float = 1.0):
    """Relative RMS friction error of the kernel vs Radau over a window of n_window samples."""
    plant = noiseless(load_plant(plant_name))
    rec, _ = load_recipe(recipe)
    joint = plant.joints[0]
    prog, args, _ = prepare_joint(plant, joint, rec, 0, scale)
    n = len(prog["mode"])
    # run the kernel once to find the window and the state at its start, then both from that state
    q, w, z, F, T, u, _, _ = simulate_joint(**args)
    vmax = joint.limits.velocity
    fast = np.convolve(np.abs(w) > 0.1 * vmax, np.ones(201), mode="same") > 0
    rev = np.flatnonzero((np.sign(w[:-1]) * np.sign(w[1:]) < 0) & fast[:-1])
    if rev.size:   # centre the window on a velocity reversal at speed, the hardest case
        i0 = int(np.clip(rev[int(start_frac * (rev.size - 1))] - n_window // 2, 0, n - n_window))
    else:
        i0 = int(start_frac * (n - n_window))
    sl = slice(i0, i0 + n_window)
    win = {k: (v[sl] if isinstance(v, np.ndarray) and v.shape == (n,) else v) for k, v in args.items()}
    win["state0"] = np.array([q[i0], w[i0], z[i0], T[i0]])
    ref_args = {k: v for k, v in win.items() if k != "nsub"}
    ref_args["code"] = ref_args.pop("th_code")
    t0 = time.perf_counter()
    _, _, _, F_ref, _, _ = simulate_joint_ivp(**ref_args)
    t_ref = time.perf_counter() - t0
    out = {}
    for ns in substeps:
        win["nsub"] = ns
        Fk = simulate_joint(**win)[3]
        out[ns] = float(np.sqrt(np.mean((Fk - F_ref) ** 2)) / np.sqrt(np.mean(F_ref**2)))
    vel = w[sl]
    return out, t_ref, float(np.abs(vel).max()), int(np.sum(np.diff(np.sign(vel)) != 0))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--speed-only", action="store_true", help="skip the accuracy part")
    a = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        a.quick = True
    scale = 0.1 if a.quick else 1.0
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print("== speed: validation_ptp (20 x 3 min) at each plant's sample rate, duration_scale", scale)
    print(f"   (machine: {os.cpu_count()} CPUs, load average {load:.1f}; wall-clock rates suffer from load,")
    print("    CPU-time rates less so)")
    print(f"{'plant':20s} {'steps':>10s} {'kernel steps/s':>15s} {'(CPU time)':>12s} {'simulate_recipe [s]':>20s}")
    for name in PLANTS:
        n, rate, rate_cpu, total = speed(name, repeats=1 if a.quick else 3, scale=scale)
        print(f"{name:20s} {n:10d} {rate / 1e6:13.1f} M {rate_cpu / 1e6:10.1f} M {total:20.2f}")
    if a.speed_only:
        return
    nwin = 600 if a.quick else 2000
    print(f"\n== accuracy: friction RMS error vs Radau rtol 1e-10, windows of {nwin} samples (no noise)")
    print(f"{'plant':20s} {'recipe':24s} {'|w|max':>8s} {'reversals':>9s} "
          f"{'1 substep':>10s} {'2':>9s} {'4':>9s} {'ref time':>9s}")
    for name in PLANTS:
        for recipe, frac in (("multisine", 0.5), ("constant_velocity_sweep", 0.8)):
            err, t_ref, vmax, rev = accuracy(name, recipe, nwin, frac)
            print(f"{name:20s} {recipe:24s} {vmax:8.3g} {rev:9d} {err[1]:10.2e} {err[2]:9.2e} {err[4]:9.2e}"
                  f" {t_ref:8.1f}s")


if __name__ == "__main__":
    main()
