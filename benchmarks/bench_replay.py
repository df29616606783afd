"""Benchmark of the replay kernel on a measured velocity: speed, against a straightforward ``solve_ivp``,
and error against a tight reference.

    python benchmarks/bench_replay.py [--hours 1] [--repeat 3] [--quick]

Input: the geared industrial joint (its true model: polynomial map, LuGre sigma0 1.5e5, thermal6 heat
balance; a benchmark may read the plant's truth) and the *measured*, noisy velocity and ambient temperature
of its one-hour ``validation_ptp`` run (the simulated log, as a user's log would hold them).

1. kernel: :func:`frictid.models.replay_kernel.replay_friction` along the whole log (LuGre bristle state
   and joint temperature driven by the predicted friction power), best CPU time of ``--repeat`` runs;
2. baseline: the same model written as users write it, ``solve_ivp`` (LSODA, rtol 1e-6) on (z, T) with
   the velocity and ambient interpolated (:func:`run_all.ivp_replay`), on ten 2000-sample stretches spread
   evenly over the log (its mix of motion and rest); the ratio of the two rates;
3. error: kernel and baseline friction against Radau (rtol 1e-10, interval by interval, the velocity
   linear within each sample interval) on 3000 samples centred on a velocity reversal at speed;
4. the same kernel and baseline on an always-moving input (a noisy multi-sine, the baseline over its
   first 10 s), the input ``benchmarks/run_all.py`` also reports;
5. :func:`frictid.replay.replay` end to end on the log (derivatives, gravity, multipliers, kernel, torque).
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
sys.path.insert(0, str(ROOT / "benchmarks"))

from frictid.models.replay_kernel import replay_friction  # noqa: E402
from frictid.models.static import canonical_level, canonical_pair, canonical_viscous  # noqa: E402
from frictid.models.thermal import canonical_at, thermal_code  # noqa: E402

# the always-moving input (also used by run_all.py): the geared joint's map with round numbers
C_POS, C_NEG = canonical_pair("polynomial", dict(c0=45.0, c1=30.0, c2=-4.0, c3=1.5))
SIGMA0, SIGMA1 = 1.5e5, 2000.0
TH = dict(C=600.0, K=1.0, Tenv=25.0)


def velocity(n, dt, seed=0):
    """A noisy multi-sine velocity [rad/s] with reversals, always moving."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    w = (1.2 * np.sin(2 * np.pi * 0.05 * t) + 0.6 * np.sin(2 * np.pi * 0.31 * t + 1.0)
         + 0.2 * np.sin(2 * np.pi * 1.7 * t)) + 0.002 * rng.standard_normal(n)
    return t, w


def thermal():
    code, theta, dc = thermal_code("thermal6", T0=25.0, dc=(-0.6, -0.4, 0.053, -0.02))
    return dict(code=code, theta=theta, dc_pos=dc, **TH)


def ivp_friction(t, w, seconds):
    """F along the multi-sine's first `seconds` by solve_ivp (LSODA, rtol 1e-6, max_step one sample)."""
    from scipy.integrate import solve_ivp

    m = int(seconds / (t[1] - t[0])) + 1
    tt, ww = t[:m], w[:m]
    th = thermal()

    def rhs(ti, x):
        z, T = x
        wi = float(np.interp(ti, tt, ww))
        c = canonical_at(C_POS if wi >= 0 else C_NEG, T, th["code"], th["theta"], th["dc_pos"])
        g = float(canonical_level(wi, c))
        zd = wi - SIGMA0 * abs(wi) / g * z
        F = SIGMA0 * z + SIGMA1 * zd + float(canonical_viscous(wi, c))
        return [zd, (F * wi - TH["K"] * (T - TH["Tenv"])) / TH["C"]]

    t0 = time.perf_counter()
    sol = solve_ivp(rhs, (tt[0], tt[-1]), [0.0, TH["Tenv"]], method="LSODA", t_eval=tt, rtol=1e-6,
                    atol=[1e-12, 1e-6], max_step=tt[1] - tt[0])
    el = time.perf_counter() - t0
    F = np.empty(m)
    for k in range(m):
        z, T = sol.y[:, k]
        c = canonical_at(C_POS if ww[k] >= 0 else C_NEG, T, th["code"], th["theta"], th["dc_pos"])
        g = float(canonical_level(ww[k], c))
        F[k] = SIGMA0 * z + SIGMA1 * (ww[k] - SIGMA0 * abs(ww[k]) / g * z) + float(canonical_viscous(ww[k], c))
    return F, el, m


def best_cpu(fn, repeat):
    """(best CPU time, best wall time, last result) of ``fn()`` over ``repeat`` runs."""
    cpu = wall = np.inf
    out = None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        cpu = min(cpu, time.process_time() - c0)
        wall = min(wall, time.perf_counter() - t0)
    return cpu, wall, out


def main(argv=None):
    from run_all import _plant_log, _thermal, ivp_replay  # the shared benchmark's input and baseline

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0, help="length of the validation_ptp log")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="0.1 h, shorter baselines and reference")
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.quick, args.repeat = True, 1
    hours = 0.1 if args.quick else args.hours
    print(f"load average {os.getloadavg()[0]:.1f}, {time.strftime('%Y-%m-%d %H:%M')}")
    t0 = time.perf_counter()
    lg, model = _plant_log("validation_ptp", hours)
    t = np.asarray(lg.t, dtype=float)
    w = np.asarray(lg.qd, dtype=float)
    Tenv = np.asarray(lg.channels["temp_env"], dtype=float)
    n = t.size
    print(f"input: geared_industrial validation_ptp, {t[-1] / 3600:.2f} h at {1 / lg.dt:.0f} Hz, {n} samples of "
          f"measured velocity (simulated in {time.perf_counter() - t0:.1f} s); true model polynomial, "
          f"sigma0 {model['sigma0'][0]:.3g}, thermal6 C {model['C']:.0f} K {model['K']:.2g}")

    def kernel(a=t, b=w, c=Tenv):
        return replay_friction(a, b, model["c_pos"], model["c_neg"], sigma0=model["sigma0"],
                               sigma1=model["sigma1"], thermal=_thermal(model, c))

    kernel(t[:1000], w[:1000], Tenv[:1000])  # compile / load the cache
    cpu, wall, (F, _, T) = best_cpu(kernel, args.repeat)
    rate, rate_w = n / cpu, n / wall
    print(f"1. kernel: {n} samples in {cpu:.3f} s CPU ({wall:.3f} s wall): {rate / 1e6:.1f} M samples/s CPU "
          f"({rate_w / 1e6:.1f} M/s wall, {1e9 * cpu / n:.0f} ns/sample); the joint warms by "
          f"{np.max(T) - T[0]:.1f} K")
    n_str, per = (6, 500) if args.quick else (10, 2000)
    starts = np.linspace(0, n - per, n_str).astype(int)

    def baseline():
        for i0 in starts:
            sl = slice(i0, i0 + per)
            ivp_replay(t[sl] - t[i0], w[sl], Tenv[sl], model)

    cpu_b, wall_b, _ = best_cpu(baseline, 1)
    rate_b = n_str * per / cpu_b
    print(f"2. solve_ivp LSODA rtol 1e-6 on {n_str} x {per} samples spread over the log: {cpu_b:.2f} s CPU, "
          f"{rate_b / 1e3:.1f} k samples/s CPU ({n_str * per / wall_b / 1e3:.1f} k/s wall); the whole log would "
          f"take {n / rate_b / 60:.0f} min. Kernel / solve_ivp: {rate / rate_b:,.0f}x CPU "
          f"({rate_w / (n_str * per / wall_b):,.0f}x wall)")
    nr = 400 if args.quick else 3000
    fast = np.convolve(np.abs(w) > 0.1 * np.abs(w).max(), np.ones(201), mode="same") > 0
    rev = np.flatnonzero((np.sign(w[:-1]) * np.sign(w[1:]) < 0) & fast[:-1])
    j0 = int(np.clip(rev[len(rev) // 2] - nr // 2, 0, n - nr)) if rev.size else 0
    ws = slice(j0, j0 + nr)
    tw = t[ws] - t[j0]
    t1 = time.perf_counter()
    F_ref = ivp_replay(tw, w[ws], Tenv[ws], model, method="Radau", rtol=1e-10, atol=(1e-14, 1e-10),
                       per_interval=True)
    t_ref = time.perf_counter() - t1
    F_k = kernel(tw, w[ws], Tenv[ws])[0]
    F_b = ivp_replay(tw, w[ws], Tenv[ws], model)
    rms_ref = np.sqrt(np.mean(F_ref ** 2))
    err = np.sqrt(np.mean((F_k - F_ref) ** 2)) / rms_ref
    err_b = np.sqrt(np.mean((F_b - F_ref) ** 2)) / rms_ref
    print(f"3. friction error against Radau rtol 1e-10 (interval by interval, {t_ref:.0f} s) on {nr} samples "
          f"around a reversal at speed (t = {t[j0]:.1f} s): kernel {100 * err:.4f} % RMS, solve_ivp LSODA "
          f"{100 * err_b:.2g} % RMS (target 1 %)")
    t2, w2 = velocity(n, lg.dt)

    def kernel2():
        return replay_friction(t2, w2, C_POS, C_NEG, sigma0=SIGMA0, sigma1=SIGMA1, thermal=thermal())

    kernel2()
    cpu2, _, _ = best_cpu(kernel2, args.repeat)
    secs = 2.0 if args.quick else 10.0
    c0 = time.process_time()
    _, _, m = ivp_friction(t2, w2, secs)
    cpu_b2 = time.process_time() - c0
    print(f"4. always-moving multi-sine input: kernel {n / cpu2 / 1e6:.1f} M samples/s CPU, solve_ivp LSODA "
          f"(first {secs:g} s) {m / cpu_b2 / 1e3:.1f} k samples/s CPU: {(n / cpu2) / (m / cpu_b2):,.0f}x")
    from frictid.replay import ReplayModel, replay

    tp = lg.truth["params"]
    th = tp["thermal"]
    rm = ReplayModel(name="lugre", map=tp["map"], c_pos=np.asarray(model["c_pos"]),
                     c_neg=np.asarray(model["c_neg"]), sigma0=model["sigma0"], sigma1=model["sigma1"],
                     J=tp["J"], Px=tp["gravity"]["Px"], Py=tp["gravity"]["Py"],
                     offset=tp["gravity"].get("offset", 0.0),
                     thermal={"law": th["law"], "alpha": th.get("alpha", 0.0), "beta": th.get("beta", 1.0),
                              "lam": th.get("lam", 0.0), "T0": th["T0"],
                              "dc": [th.get(k, 0.0) for k in ("dc0", "dc1", "dc2", "dc3")],
                              "C": th["C"], "K": th["K"]})
    replay(lg, rm)
    cpu3, wall3, r = best_cpu(lambda: replay(lg, rm), args.repeat)
    mv = np.abs(lg.truth["velocity"]) > 0.05
    e3 = np.sqrt(np.mean((r.F_model - lg.truth["friction"])[mv] ** 2))
    print(f"5. frictid.replay.replay end to end (Savitzky-Golay derivatives, gravity, kernel, torque): "
          f"{cpu3:.2f} s CPU ({wall3:.2f} s wall) for the {t[-1] / 3600:.2f} h log, {n / cpu3 / 1e6:.1f} M samples/s "
          f"CPU; friction RMS error against the plant's {e3:.3g} N m while moving (true model, estimated "
          f"velocity)")
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
