"""Time the fit's static-map and thermal stages on simulated data (the stages this benchmark tracks).

    python benchmarks/bench_fit_stages.py [--repeat 3]

(a) every static map and its per-sign variant, with the 5-fold held-out refits, on the plateau points of
the constant-velocity sweeps of the hydraulic, direct-drive and linear-slide plants (recipe scale 0.5);
(b) the thermal stage (thermal4 and thermal6 with their held-out folds) of a fit on the geared plant's
duty cycles (scale 0.25). Prints the best of ``--repeat`` runs of each. Run it at two commits (a git
worktree) to compare them; the simulated inputs are built once per run (seed 0).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import frictid  # noqa: E402
from frictid.identify import thermal_fit  # noqa: E402
from frictid.identify import select as sel  # noqa: E402
from frictid.identify.static import fit_static, plateau_points  # noqa: E402
from frictid.models import static as sm  # noqa: E402
from frictid.plant import simulate_recipe  # noqa: E402
from frictid.segments import derivatives, find_segments  # noqa: E402


def plateau_sets():
    out = []
    for plant in ("hydraulic", "direct_drive", "linear_slide"):
        for lg in simulate_recipe(str(ROOT / "recipes/constant_velocity_sweep.yaml"),
                                  plant=str(ROOT / f"recipes/plants/{plant}.yaml"), seed=0, duration_scale=0.5):
            w, a = derivatives(lg)
            out.append(plateau_points(lg.t, w, lg.tau - lg.truth["params"]["J"] * a, find_segments(lg)))
    return out


def time_static(sets) -> float:
    t0 = time.perf_counter()
    for P in sets:
        for name in sm.map_names():
            mf = fit_static(name, P.w, P.F, P.F_se)
            sel.heldout_static(name, P, 5, full=mf)
    return time.perf_counter() - t0


def time_thermal(duty) -> float:
    spent = []
    orig = thermal_fit.fit_thermal_models

    def timed(*a, **k):
        t0 = time.perf_counter()
        orig(*a, **k)
        spent.append(time.perf_counter() - t0)
    thermal_fit.fit_thermal_models = timed
    try:
        frictid.fit(duty, models="polynomial_ls,thermal4,thermal6", diagnose=False)
    finally:
        thermal_fit.fit_thermal_models = orig
    return sum(spent)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.repeat = 1
    sets = plateau_sets()
    duty = simulate_recipe(str(ROOT / "recipes/duty_cycle.yaml"),
                           plant=str(ROOT / "recipes/plants/geared_industrial.yaml"), seed=0, duration_scale=0.25)
    time_thermal(duty)  # compile / load the numba caches
    ts = min(time_static(sets) for _ in range(args.repeat))
    tt = min(time_thermal(duty) for _ in range(args.repeat))
    print(f"static maps + held-out folds on {len(sets)} plateau sets x {len(sm.map_names())} maps: {ts:.2f} s")
    print(f"thermal stage (thermal4 + thermal6 + held-out) on the geared duty cycles: {tt:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
