"""Benchmark of the replay: a 1 kHz, one-hour log through the compiled kernel, against a naive
``scipy.integrate.solve_ivp`` of the same equations.

    python benchmarks/bench_replay.py [--hours 1] [--ivp-seconds 20]

1. The kernel (:func:`frictid.models.replay_kernel.replay_friction`) on 3.6 million samples of a measured-like
   velocity (a multi-sine with reversals and noise): LuGre bristle state along the velocity, thermal6 with
   the heat balance driven by the predicted friction power, position and drift multipliers.
2. The same equations, ``dz/dt = w - sigma0 |w| z / g(w, T)`` and ``C dT/dt = F w - K (T - Tenv)``, with the
   velocity interpolated linearly between samples, by ``solve_ivp`` (LSODA, the bristle equation is stiff;
   rtol 1e-6) over the first ``--ivp-seconds`` of the log; its time is extrapolated to the whole log and
   the ratio printed, with the RMS difference between the two friction predictions on that stretch.
3. ``frictid.replay.replay`` end to end (derivatives, multipliers, kernel, torque) on a simulated one-hour
   log (the geared joint's 002 validation motion).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from frictid.models.replay_kernel import replay_friction  # noqa: E402
from frictid.models.static import canonical_level, canonical_pair, canonical_viscous  # noqa: E402
from frictid.models.thermal import canonical_at, thermal_code  # noqa: E402

C_POS, C_NEG = canonical_pair("polynomial", dict(c0=45.0, c1=30.0, c2=-4.0, c3=1.5))
SIGMA0, SIGMA1 = 1.5e5, 2000.0
TH = dict(C=600.0, K=1.0, Tenv=25.0)


def velocity(n, dt, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    w = (1.2 * np.sin(2 * np.pi * 0.05 * t) + 0.6 * np.sin(2 * np.pi * 0.31 * t + 1.0)
         + 0.2 * np.sin(2 * np.pi * 1.7 * t)) + 0.002 * rng.standard_normal(n)
    return t, w


def thermal():
    code, theta, dc = thermal_code("thermal6", T0=25.0, dc=(-0.6, -0.4, 0.053, -0.02))
    return dict(code=code, theta=theta, dc_pos=dc, **TH)


def ivp_friction(t, w, seconds):
    """F along w over the first `seconds` by solve_ivp (LSODA), the velocity interpolated linearly."""
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--ivp-seconds", type=float, default=20.0)
    ap.add_argument("--no-end-to-end", action="store_true")
    args = ap.parse_args(argv)
    dt = 1e-3
    n = int(args.hours * 3600 / dt)
    t, w = velocity(n, dt)
    gm = 1 + 0.05 * np.sin(2 * np.pi * np.cumsum(w) * dt / 0.3)
    fm = 1 + 0.02 * t / 3600
    replay_friction(t[:100], w[:100], C_POS, C_NEG, sigma0=SIGMA0, sigma1=SIGMA1, thermal=thermal(),
                    gmul=gm[:100], fmul=fm[:100])  # compile / load the cache
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        F, z, T = replay_friction(t, w, C_POS, C_NEG, sigma0=SIGMA0, sigma1=SIGMA1, thermal=thermal(),
                                  gmul=gm, fmul=fm)
        best = min(best, time.perf_counter() - t0)
    print(f"replay kernel: {n} samples ({args.hours:g} h at 1 kHz), LuGre + thermal6 + multipliers: "
          f"{best:.2f} s ({1e9 * best / n:.0f} ns/sample); joint warms {T[-1] - T[0]:.1f} K")
    Fs, _, _ = replay_friction(t, w, C_POS, C_NEG, sigma0=SIGMA0, sigma1=SIGMA1, thermal=thermal())
    Fi, el, m = ivp_friction(t, w, args.ivp_seconds)
    per_sample = el / m
    ratio = per_sample * n / best
    diff = float(np.sqrt(np.mean((Fi - Fs[:m]) ** 2)) / np.sqrt(np.mean(Fi ** 2)))
    print(f"solve_ivp (LSODA, rtol 1e-6) of the same equations: {el:.1f} s for the first {args.ivp_seconds:g} s "
          f"({m} samples) -> {per_sample * n / 60:.0f} min extrapolated to the whole log; kernel is "
          f"{ratio:,.0f}x faster; friction difference on that stretch {100 * diff:.3f} % RMS")
    if not args.no_end_to_end:
        from frictid.fit.result import JointFit, ModelFit, ParamEstimate
        from frictid.plant import simulate_recipe
        from frictid.replay import joint_model, replay

        t0 = time.perf_counter()
        lg = simulate_recipe(str(ROOT / "recipes/validation_ptp.yaml"), seed=0,
                             duration_scale=args.hours * 3600 / (20 * 180.0))[0]
        sim = time.perf_counter() - t0
        pe = lambda k, v: ParamEstimate(k, float(v), None, "", True)  # noqa: E731
        tp = lg.truth["params"]  # the plant's own model (a benchmark may read the truth)
        th = tp["thermal"]
        vals = dict(tp["static"], sigma0=tp["sigma0"], sigma1=tp["sigma1"], C=th["C"], K=th["K"], T0=th["T0"],
                    **{f"dc{i}": th[f"dc{i}"] for i in range(4)})
        params = {k: pe(k, v) for k, v in vals.items()}
        g = tp["gravity"]
        jf = JointFit(lg.joint, inertia=pe("J", tp["J"]), gravity={"Px": pe("Px", g["Px"]), "Py": pe("Py", g["Py"])},
                      offset=pe("offset", g["offset"]), models={"m": ModelFit("m", tp["map"], params)}, selected="m")
        m_ = joint_model(jf)
        t0 = time.perf_counter()
        r = replay(lg, m_)
        el = time.perf_counter() - t0
        mv = np.abs(lg.truth["velocity"]) > 0.05
        err = np.sqrt(np.mean((r.F_model - lg.truth["friction"])[mv] ** 2))
        print(f"frictid.replay.replay end to end on a simulated {lg.t[-1] / 3600:.2f} h log ({lg.n} samples, "
              f"simulated in {sim:.1f} s): {el:.2f} s; friction RMS error against the plant's "
              f"{err:.3g} N m (true model)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
