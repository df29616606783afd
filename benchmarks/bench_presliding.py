"""Benchmark of the LuGre dynamic-parameter fits of :mod:`frictid.identify.presliding`.

    python benchmarks/bench_presliding.py [--repeat 5]

1. ``simulate_step`` (the step simulation sigma1's simulation-error fit runs at every residual
   evaluation): compiled, on the canonical vectors, against the same step loop in python over scalar
   ``level`` / ``viscous`` callables (what it was before it was compiled; still what callables run), on a
   1391-sample torque step of the geared joint's map, and their largest position difference;
2. ``fit_sigma0`` on 12 ramps of 2000 samples (quantised presliding paths with torque noise), the
   estimate and its CPU time; and ``fit_sigma1_steps`` on 6 simulated steps with position noise.

CPU times (``time.process_time``), best of ``--repeat``; the BLAS thread count matters for the optimiser's
own overhead on a loaded machine (``OPENBLAS_NUM_THREADS=1`` to pin it).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from frictid.identify import presliding as pre  # noqa: E402
from frictid.models.static import canonical_level, canonical_pair, canonical_viscous  # noqa: E402


def best(fn, repeat):
    out, cpu = None, math.inf
    for _ in range(repeat):
        c0 = time.process_time()
        out = fn()
        cpu = min(cpu, time.process_time() - c0)
    return cpu, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.repeat = 1
    print(f"load average {os.getloadavg()[0]:.1f}, {time.strftime('%Y-%m-%d %H:%M')}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    c_pos, c_neg = canonical_pair("polynomial", dict(c0=45.0, c1=30.0, c2=-4.0, c3=1.5))
    J, s0 = 12.0, 1.5e5
    s1 = 0.9 * 2 * math.sqrt(s0 * J)
    n = 1391
    t = np.arange(n) * 1e-3
    u = np.where(t < 0.5, 60.0, -60.0)
    u[0] = 0.0

    def level(w):
        return float(canonical_level(w, c_pos if w >= 0 else c_neg))

    def viscous(w):
        return float(canonical_viscous(w, c_pos if w >= 0 else c_neg))

    pre.simulate_step(t[:10], u[:10], 0.0, 0.0, J, s0, s1, c_pos, c_neg, 0.0)  # compile / load the cache
    tc, qc = best(lambda: pre.simulate_step(t, u, 0.0, 0.0, J, s0, s1, c_pos, c_neg, 0.0), args.repeat)
    tp, qp = best(lambda: pre.simulate_step(t, u, 0.0, 0.0, J, s0, s1, level, viscous, 0.0), 2)
    print(f"1. simulate_step, {n} samples x 2 substeps: compiled {1e3 * tc:.2f} ms, python loop over callables "
          f"{1e3 * tp:.1f} ms: {tp / tc:.0f}x; largest position difference "
          f"{np.max(np.abs(qc - qp)) / np.ptp(qc):.1e} of the span")

    rng = np.random.default_rng(1)
    g, res = 45.0, 2e-8
    ramps = []
    for k in range(12):
        m = 2000
        F = np.linspace(0.0, 0.9 * g, m) * (1 if k % 2 == 0 else -1)
        z = F / s0
        dz = np.diff(z)
        q = np.concatenate([[0.0], np.cumsum(dz / (1 - np.sign(dz) * z[:-1] * s0 / g))])  # LuGre's path
        ramps.append((np.round((q + 1e-3 * k) / res) * res, F + 0.05 * rng.standard_normal(m)))
    pre.fit_sigma0(ramps[:2], g, res)
    t0, e0 = best(lambda: pre.fit_sigma0(ramps, g, res), args.repeat)
    print(f"2. fit_sigma0, 12 ramps x 2000 samples: {1e3 * t0:.1f} ms; sigma0 {e0.value:.6g} +- {e0.stderr:.3g} "
          f"(true {s0:.6g})")
    steps = []
    for k in range(6):
        m = 400
        ts = np.arange(m) * 1e-3
        amp = (30.0 + 12.0 * k) * (1 if k % 2 == 0 else -1)
        us = np.where(ts < 0.2, amp, 0.3 * amp)
        us[0] = 0.0
        qs = pre.simulate_step(ts, us, 0.0, 0.0, J, s0, s1, c_pos, c_neg, 0.0)
        steps.append((ts, qs + 1e-3 * np.ptp(qs) * rng.standard_normal(m), us))
    t1, e1 = best(lambda: pre.fit_sigma1_steps(steps, J, s0, c_pos, c_neg, 30.0), args.repeat)
    print(f"   fit_sigma1_steps, 6 steps x 400 samples (and the 6 single-step refits of its spread): "
          f"{1e3 * t1:.0f} ms; sigma1 {e1.value:.6g} +- {e1.stderr:.3g} (true {s1:.6g})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
