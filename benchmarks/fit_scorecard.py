"""Scorecard of frictid fit: simulate the shipped plants with noise, fit, print recovered against true.

    python benchmarks/fit_scorecard.py [--scale 0.5] [--thermal-scale 0.25] [--seed 0] [--quick]

Only this script reads the plants' true parameters (``JointLog.truth``); the fit uses the real segment
finder and derivatives. Targets (the issue): Fc, Fs, sigma2 within 3 %, vs within 10 %, J within 3 %,
gravity amplitude within 2 %, sigma0 within 20 % where the encoder resolves it (else reported not
identifiable), thermal prediction within 5 % after warm-up with thermal6 at least as good as thermal4 where
the truth has distinct per-coefficient slopes (a variant of the geared plant: :data:`DISTINCT_SLOPES`),
published tables (001 Table 1, 004 Table 2) fitted by stribeck_2exp_asym within 1 % RMS of the range.

A value outside its target whose own error says the data do not resolve it to the target (2 stderr >= target
x |value|) cannot be held to it by these data: that line counts as met ("unresolved") when the file marks it
not identifiable or the true value lies within 2 stderr, and is a miss otherwise (the convention of the
foreign card, ``benchmarks/foreign/fit_scorecard.py``, too). The last line is the coverage: the fraction of true values within 2 stderr.
"""
from __future__ import annotations

import argparse
import os
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import frictid  # noqa: E402
from frictid.identify.static import fit_static  # noqa: E402
from frictid.models import static as sm  # noqa: E402
from frictid.models.thermal import canonical_at, thermal_code  # noqa: E402
from frictid.plant import simulate_recipe  # noqa: E402

PLANTS = ("hydraulic", "direct_drive", "geared_industrial", "linear_slide")
RECIPES = ("constant_velocity_sweep", "multisine", "ramp_presliding", "torque_steps")
ROWS: list[tuple] = []


#: (name, |fitted - true| / stderr) of every line with a true value and a standard error (coverage).
COVERAGE: list[tuple[str, float]] = []


def row(plant, joint, what, true, got, tol, unit="", note="", se=None, identifiable=True):
    """One scorecard line: relative error against tolerance (tol None: report only).

    se : the fit's standard error. When twice it reaches the target (``2 se >= tol |got|``) the data cannot
    resolve the value to the target: the honest outcome is a parameter marked not identifiable or an error
    within 2 stderr, and the line counts as met ("unresolved") in either case.
    """
    if got is None or true is None:
        err, ok = None, (tol is None)
    else:
        err = abs(got - true) / abs(true) if true else abs(got - true)
        ok = True if tol is None else err <= tol
        if se is not None and se > 0 and math.isfinite(se):
            COVERAGE.append((f"{plant} {joint} {what}", abs(got - true) / se))
            if tol is not None and not ok and true and 2 * se >= tol * abs(got):
                ok = (not identifiable) or abs(got - true) <= 2 * se
                note = (f"unresolved: 2 stderr {200 * se / abs(got or true):.0f} % >= target, error "
                        f"{abs(got - true) / se:.1f} stderr" + (f"; {note}" if note else ""))
    ROWS.append((plant, joint, what, true, got, err, tol, ok, note))


def fmt(x):
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    return f"{x:.4g}"


def curve_error(model, true_params, wmax):
    """RMS of the fitted map against the true map over |w| in [1 %, 100 %] of wmax, over the true range."""
    w = np.concatenate([np.geomspace(0.01 * wmax, wmax, 60), -np.geomspace(0.01 * wmax, wmax, 60)])
    cp, cn = np.array(true_params["canonical_pos"]), np.array(true_params["canonical_neg"])
    Ft = sm.canonical_friction(w, cp, cn)
    from frictid.identify.static import predict
    Fp = predict(model.map, model.values(), w)
    return float(np.sqrt(np.mean((Fp - Ft) ** 2)) / (Ft.max() - Ft.min()))


def score_plant(plant, scale, seed):
    logs = []
    for i, r in enumerate(RECIPES):
        logs += simulate_recipe(str(ROOT / "recipes" / f"{r}.yaml"), plant=str(ROOT / "recipes/plants" / f"{plant}.yaml"),
                                seed=seed + i, duration_scale=scale)
    t0 = time.time()
    res = frictid.fit(logs)
    dt = time.time() - t0
    for j, jf in res.joints.items():
        tp = next(lg for lg in logs if lg.joint == j).truth["params"]
        wmax = float(tp["limits"]["velocity"])
        row(plant, j, "J", tp["J"], jf.inertia.value, 0.03, note=f"se {fmt(jf.inertia.stderr)}",
            se=jf.inertia.stderr)
        g = tp["gravity"]
        amp = math.hypot(g["Px"], g["Py"])
        if amp > 0 and "amplitude" in jf.gravity:
            ga = jf.gravity["amplitude"]
            row(plant, j, "gravity amplitude", amp, ga.value, 0.02, note=f"se {fmt(ga.stderr)}", se=ga.stderr)
        st = tp["static"]
        if tp["map"] in ("stribeck", "stribeck_asym") and "stribeck" in jf.models:
            m = jf.models["stribeck" if tp["map"] == "stribeck" else "stribeck_asym"]
            suf = "" if tp["map"] == "stribeck" else "_pos"
            for k, tol in (("Fc", 0.03), ("Fs", 0.03), ("sigma2", 0.03), ("vs", 0.10)):
                p = m.params.get(k + suf)
                row(plant, j, f"{m.name}.{k + suf}", st.get(k + suf, st.get(k)), p.value if p else None, tol,
                    note=("" if p is None else f"se {fmt(p.stderr)}") +
                         ("" if p is None or p.identifiable else f"; not identifiable: {p.reason}"),
                    se=None if p is None else p.stderr, identifiable=p is None or p.identifiable)
        sel = jf.selected_fit
        if sel is not None:
            row(plant, j, f"curve error of {jf.selected}", None, curve_error(sel, tp, wmax), None,
                note="RMS over the true range")
        lug = jf.models.get("lugre")
        if lug is not None:
            s0 = lug.params["sigma0"]
            if s0.identifiable:
                row(plant, j, "sigma0", tp["sigma0"], s0.value, 0.20, note=f"se {fmt(s0.stderr)}", se=s0.stderr)
            else:
                ROWS.append((plant, j, "sigma0", tp["sigma0"], None, None, None, True,
                             f"not identifiable: {s0.reason}"))
            s1 = lug.params["sigma1"]
            row(plant, j, "sigma1", tp["sigma1"], s1.value, None,
                note=(s1.source if s1.identifiable else f"not identifiable: {s1.reason}")[:70])
        ROWS.append((plant, j, "selected", None, jf.selected, None, None, True, f"fit {dt:.1f} s"))


#: Per-coefficient temperature slopes [unit/K] of the thermal variant of the geared plant. The shipped
#: plant's slopes are proportional to its coefficients (dc_i / c_i = -1.33 %/K for all four: its thermal6
#: law is a thermal4 law), so it cannot show what thermal6 adds; the variant keeps its C, K and dc2, dc3
#: and gives the Coulomb and viscous terms different rates (-0.44 %/K and -2 %/K, 002: the viscous part
#: changes most as the lubricant warms).
DISTINCT_SLOPES = {"dc0": -0.2, "dc1": -0.6}


def thermal_plant(slopes: dict | None):
    """The geared plant (a path), or a copy with its thermal slopes replaced (a loaded Plant)."""
    path = ROOT / "recipes/plants/geared_industrial.yaml"
    if not slopes:
        return str(path)
    import yaml
    from frictid.plant.config import load_plant
    data = yaml.safe_load(path.read_text())
    data["joints"][0]["thermal"].update(slopes)
    data["name"] = data["name"] + "_distinct_slopes"
    return load_plant(data, where=f"{path.name} with {slopes}")


def score_thermal(scale, seed, slopes=None):
    label = "thermal" if not slopes else "thermal distinct"
    plant = thermal_plant(slopes)
    duty = simulate_recipe(str(ROOT / "recipes/duty_cycle.yaml"), plant=plant, seed=seed, duration_scale=scale)
    ms = simulate_recipe(str(ROOT / "recipes/multisine.yaml"), plant=plant, seed=seed + 1)
    t0 = time.time()
    res = frictid.fit(duty + ms, models="polynomial_ls,thermal4,thermal6")
    dt = time.time() - t0
    lg = duty[0]
    jf = res[lg.joint]
    errs = {}
    from frictid.segments import derivatives
    w, _ = derivatives(lg)
    tp = lg.truth["params"]["thermal"]
    cp = np.array(lg.truth["params"]["canonical_pos"])
    code, theta, dc9 = thermal_code(tp["law"], tp.get("alpha", 0.0), tp.get("beta", 1.0), tp.get("lam", 0.0),
                                    tp["T0"], [tp.get(f"dc{i}", 0.0) for i in range(4)])
    T_true = lg.truth["temp_joint"]
    effs = {}
    for m in ("thermal4", "thermal6"):
        mf = jf.models.get(m)
        if mf is None:
            ROWS.append((label, lg.joint, m, None, None, None, None, False, "not fitted"))
            continue
        # predicted friction per cycle at the model's cycle temperature, against the plant's friction,
        # over the second half of each run (after warm-up), moving samples; and the temperature effect
        # alone (friction at the cycle temperature minus friction at T0) against the plant's
        cyc_T = [T for run in mf.extra["cycle_temperature"] for T in run]
        cyc_t = jf.segments_used["duty_cycle"]
        v = mf.values()
        num = den = num_e = 0.0
        run_len = len(mf.extra["cycle_temperature"][0])
        for k, ((ta, tb, _), T) in enumerate(zip(cyc_t, cyc_T)):
            if (k % run_len) < run_len // 2:
                continue
            i0, i1 = np.searchsorted(lg.t, [ta, tb])
            ww = w[i0:i1]
            mv = np.abs(ww) > 0.1 * np.max(np.abs(w))
            if m == "thermal4":
                c_ref = np.array([v[f"c{i}"] for i in range(4)])
                c, c_T0 = c_ref * (v["alpha"] * (T - v["T0"]) + v["beta"]), c_ref * v["beta"]
            else:
                c_T0 = np.array([v[f"c{i}"] for i in range(4)])
                c = c_T0 + np.array([v[f"dc{i}"] for i in range(4)]) * (T - v["T0"])
            Fp = sm.polynomial(ww[mv], *c)
            Ft = lg.truth["friction"][i0:i1][mv]
            num += float(np.sum((Fp - Ft) ** 2))
            den += float(np.sum(Ft ** 2))
            Tt = float(np.mean(T_true[i0:i1]))
            dF_true = (sm.canonical_friction(ww[mv], canonical_at(cp, Tt, code, theta, dc9))
                       - sm.canonical_friction(ww[mv], cp))
            num_e += float(np.sum((Fp - sm.polynomial(ww[mv], *c_T0) - dF_true) ** 2))
        errs[m] = math.sqrt(num / den) if den else None
        effs[m] = math.sqrt(num_e / den) if den else None
        tc = mf.extra["time_constant"]
        row(label, lg.joint, f"{m} friction after warm-up", 0.0, errs[m], 0.05,
            note=f"time constant {fmt(tc['value'])} +- {fmt(tc['stderr'])} s, held-out gain "
                 f"{fmt(mf.metrics.get('heldout_gain'))}, fit {dt:.1f} s")
        ROWS.append((label, lg.joint, f"{m} temperature effect error", 0.0, effs[m], None, None, True,
                     "(F(T) - F(T0)) against the plant's, RMS / friction RMS"))
    c = lg.truth["params"]["static"]
    rates = [tp.get(f"dc{i}", 0.0) / c[f"c{i}"] for i in range(4)] if tp["law"] == "thermal6" else []
    distinct = bool(rates) and (max(rates) - min(rates)) > 0.1 * max(abs(r) for r in rates)
    ROWS.append((label, lg.joint, "true C/K [s]", None, tp["C"] / tp["K"], None, None, True,
                 f"{tp['law']}, slopes dc_i/c_i " + ", ".join(f"{100 * r:.2g}" for r in rates) + " %/K"))
    both = errs.get("thermal6") is not None and errs.get("thermal4") is not None
    ok = both and errs["thermal6"] <= errs["thermal4"]
    ROWS.append((label, lg.joint, "thermal6 <= thermal4", None, None, None, None, ok or not distinct,
                 f"{fmt(errs.get('thermal6'))} vs {fmt(errs.get('thermal4'))}, friction after warm-up"
                 + ("" if distinct else " (not counted: the true slopes are proportional, the true law is "
                                        "a thermal4 law)")))


def score_tables():
    """Steady-state points from 001 Table 1 (joint 1) and 004 Table 2 (link 1), MODELS.md section 6."""
    tables = {
        "001 Table 1 joint 1": (dict(alpha0=40.854, alpha1=-32.454, alpha2=-31.233, alpha3=-0.760, alpha4=-0.262,
                                     ws1=0.19, ws2=0.17),
                                dict(alpha0=-46.473, alpha1=53.873, alpha2=55.738, alpha3=-0.293, alpha4=-0.177,
                                     ws1=0.14, ws2=0.15), 2.0),
        "004 Table 2 link 1": (dict(alpha0=1.4396, alpha1=2.4848, ws1=0.8962, alpha2=2.8494, ws2=4.1190,
                                    alpha3=-0.0483, alpha4=0.0190),
                               dict(alpha0=2.6364, alpha1=1.2772, ws1=0.3535, alpha2=0.8615, ws2=18.6965,
                                    alpha3=0.1084, alpha4=-0.0156), 2.0),
    }
    rng = np.random.default_rng(0)
    for name, (pos, neg, wmax) in tables.items():
        v = np.geomspace(0.01 * wmax, wmax, 20)
        w = np.concatenate([v, -v])
        F = np.where(w > 0, sm.stribeck_2exp(w, **pos), sm.stribeck_2exp(w, **neg))
        Fn = F + rng.normal(0, 0.002 * (F.max() - F.min()), F.size)
        m = fit_static("stribeck_2exp_asym", w, Fn, np.full(w.size, 0.002 * (F.max() - F.min())))
        from frictid.identify.static import predict
        rms = float(np.sqrt(np.mean((predict(m.name, m.values(), w) - F) ** 2)) / (F.max() - F.min()))
        row("tables", name, "stribeck_2exp_asym RMS / range", 0.0, rms, 0.01)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=0.5, help="duration scale of the identification recipes")
    ap.add_argument("--thermal-scale", type=float, default=0.25, help="duration scale of the duty cycles")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plants", default=",".join(PLANTS))
    ap.add_argument("--no-thermal", action="store_true")
    args = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        args.scale, args.thermal_scale, args.plants = 0.05, 0.02, args.plants.split(",")[0]
    t0 = time.time()
    score_tables()
    for plant in args.plants.split(","):
        score_plant(plant, args.scale, args.seed)
    if not args.no_thermal:
        score_thermal(args.thermal_scale, args.seed)
        score_thermal(args.thermal_scale, args.seed, slopes=DISTINCT_SLOPES)
    print(f"frictid {frictid.__version__} fit scorecard: recipe scale {args.scale}, duty-cycle scale "
          f"{args.thermal_scale}, seed {args.seed}, {time.time() - t0:.0f} s")
    print(f"{'plant':18} {'joint':20} {'quantity':34} {'true':>10} {'fitted':>10} {'error':>8} {'target':>7}  ok  note")
    n_bad = 0
    for plant, joint, what, true, got, err, tol, ok, note in ROWS:
        n_bad += not ok
        print(f"{plant:18} {joint:20} {what:34} {fmt(true):>10} {fmt(got):>10} "
              f"{(f'{100 * err:.2f}%' if err is not None else '-'):>8} {(f'{100 * tol:g}%' if tol else '-'):>7}  "
              f"{'ok' if ok else 'MISS'}  {note}")
    print(f"{len(ROWS) - n_bad} of {len(ROWS)} lines within target")
    n_unres = sum(1 for r in ROWS if r[7] and r[8].startswith("unresolved"))
    print(f"strict: {len(ROWS) - n_bad - n_unres} of {len(ROWS)} lines within target whatever the error "
          f"({n_unres} met as unresolved)")
    if COVERAGE:
        z = np.array([c[1] for c in COVERAGE])
        print(f"coverage: {int(np.sum(z <= 2))} of {z.size} true values within 2 stderr of the fitted value "
              f"({100 * np.mean(z <= 2):.0f} %; Gaussian errors: 95 %); outside: "
              + (", ".join(f"{n} ({v:.1f})" for n, v in COVERAGE if v > 2) or "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
