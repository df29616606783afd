"""Whole-robot identification of the UR10e harmonic run against AURT's recorded time (issue 24's speed line).

    python benchmarks/bench_robot_speed.py [--rounds 3] [--cold-rounds 1]

The job AURT did in the recorded run (benchmarks/recorded/aurt_ur10e.json: compile the rigid-body model,
compile the robot model with friction, calibrate on the whole run), done by frictid: the whole of
``ur-20_02_19_15harm50sec.csv`` (``../shared/realdata/ur10e_mamedov2020/identification_data``) identified
with recipes/robots/ur10e.yaml and recipes/realdata/ur10e_harmonic.yaml, stage 1 (base parameters with each
joint's Coulomb, viscous and offset friction) and stage 2 (frictid's single-joint fits, with the diagnosis,
on each joint's friction torque, and the guard that keeps a model only where it beats stage 1's friction on
the fitted log's own time blocks). Per round, CPU time (user + sys) and wall:

1. ``frictid fit RUN --map MAP --robot ROBOT -o P`` in a fresh process (the command a user types: Python's
   start, the imports, reading, both stages, writing the file), with numba's cache warm, and (``--cold-rounds``,
   first) with ``NUMBA_CACHE_DIR`` a new empty folder: the first run after installing, every kernel compiled
   (CPU time of the child and of the worker processes it forks);
2. ``frictid.robotfit.fit_robot`` in this process, its steps timed one by one as ``fit_robot`` runs them
   (reading; stage 1: ``identify_robot`` and ``fit_result``; stage 2's fits: ``predict``,
   ``friction_logs``, ``fit_joints`` with the diagnosis; the guard: ``guard_models``, four more
   single-joint fits without the diagnosis, each on three quarters of the run), its answer checked against
   ``fit_robot``'s own (the same model kept on every joint).

The ratio is frictid's median CPU time over AURT's recorded CPU time (compile-rbd + compile-rd +
calibrate), and the same for wall time; the load average is printed with each (a shared machine: CPU time
is the figure to compare). AURT is not re-run here. Last, the README's first command (``frictid fit
sample_logs/hydraulic_sweep.csv -o P --report R``, what every new user runs first), cold then warm, the same
way. With FRICTID_SMOKE=1: the first quarter of the run, one round, no cold run (the same code path in
seconds; its ratio means nothing).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from frictid.api import fit as fit_joints  # noqa: E402
from frictid.io.logs import read_many  # noqa: E402
from frictid.robot import identify_robot, load_robot  # noqa: E402
from frictid.robot.identify import predict  # noqa: E402
from frictid.robot.result import fit_result  # noqa: E402
from frictid.robotfit import fit_robot, friction_logs, guard_models, keep_linear  # noqa: E402

RUN = ROOT.parent / "shared/realdata/ur10e_mamedov2020/identification_data/ur-20_02_19_15harm50sec.csv"
MAP = ROOT / "recipes/realdata/ur10e_harmonic.yaml"
ROBOT = ROOT / "recipes/robots/ur10e.yaml"
RECORDED = ROOT / "benchmarks/recorded/aurt_ur10e.json"
SAMPLE = ROOT / "sample_logs/hydraulic_sweep.csv"
STEPS = ("read", "stage 1", "stage 2 fits", "guard")


def clock() -> np.ndarray:
    """[CPU (user + sys of this process, every thread), wall] in seconds."""
    return np.array([time.process_time(), time.perf_counter()])


def split_round(run: Path) -> tuple[dict, dict]:
    """fit_robot's steps on ``run``, each timed ([CPU, wall] per step), and the joints' kept models."""
    out, t = {}, clock()
    rb = load_robot(ROBOT)
    logs = read_many([str(run)], str(MAP))
    out["read"], t = clock() - t, clock()
    rf = identify_robot(rb, logs)
    first = fit_result(rb, rf, [{"path": str(run), "sha256": None, "rows": logs[0].n}], str(ROBOT))
    out["stage 1"], t = clock() - t, clock()
    p = predict(rb, rf, logs)
    flogs = friction_logs(logs, p)
    res = fit_joints(flogs, diagnose=True)
    out["stage 2 fits"], t = clock() - t, clock()
    verdict = guard_models(flogs, p, res)
    out["guard"] = clock() - t
    res = keep_linear(res, first, verdict)
    return out, {j: (v["kept"], res[j].selected) for j, v in verdict.items()}


def whole_round(run: Path) -> tuple[np.ndarray, dict]:
    """``fit_robot`` as the library runs it: [CPU, wall] and the joints' kept models."""
    t = clock()
    res = fit_robot(str(run), str(ROBOT), str(MAP))
    spent = clock() - t
    return spent, {j: (v["kept"], res[j].selected) for j, v in res.settings["robot"]["stage2"].items()}


def command_round(args: list[str], tmp: str, cold: bool = False) -> np.ndarray:
    """``frictid ARGS`` in a fresh process: [CPU (user + sys of the child and the workers it forks), wall].
    cold: with an empty numba cache (``NUMBA_CACHE_DIR`` a new folder: every kernel compiled, as on the first
    run after installing)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=tempfile.mkdtemp(prefix="numba_cold", dir=tmp)) if cold else None
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run([str(Path(sys.executable).parent / "frictid"), *args], check=True, cwd=tmp, env=env)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return np.array([after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, wall])


def cli_round(run: Path, tmp: str, cold: bool = False) -> np.ndarray:
    """``frictid fit RUN --map MAP --robot ROBOT`` in a fresh process (:func:`command_round`)."""
    return command_round(["fit", str(run), "--map", str(MAP), "--robot", str(ROBOT), "-o",
                          str(Path(tmp) / "ur10e.yaml"), "-q"], tmp, cold)


def readme_round(tmp: str, cold: bool = False) -> np.ndarray:
    """The README's first command, ``frictid fit sample_logs/hydraulic_sweep.csv -o P --report R``, in a fresh
    process (:func:`command_round`)."""
    return command_round(["fit", str(SAMPLE), "-o", str(Path(tmp) / "params.yaml"), "--report",
                          str(Path(tmp) / "report.html"), "-q"], tmp, cold)


def smoke_run(tmp: str) -> Path:
    """The first quarter of the run's rows (FRICTID_SMOKE)."""
    lines = RUN.read_text().splitlines()
    path = Path(tmp) / "ur10e_quarter.csv"
    path.write_text("\n".join(lines[: len(lines) // 4]) + "\n")
    return path


def recorded() -> tuple[np.ndarray | None, str]:
    """AURT's recorded [CPU, wall] over its stages (benchmarks/recorded/aurt_ur10e.json), printed, and how
    a ratio to it reads ("at most " when the record is a lower bound: a run stopped before its end); None
    when there is no recorded run."""
    if not RECORDED.exists():
        print(f"no recorded AURT run ({RECORDED.relative_to(ROOT)} missing): frictid's times only")
        return None, ""
    rec = json.loads(RECORDED.read_text())
    st = rec["stages"]
    tot = np.array([sum(s["user_s"] + s["sys_s"] for s in st.values()), sum(s["wall_s"] for s in st.values())])
    print(f"AURT {rec['aurt_version']} recorded {rec['date']} ({rec['machine']}, load average {rec['load_average']}): "
          + "; ".join(f"{k} CPU {s['user_s'] + s['sys_s']:.0f} s wall {s['wall_s']:.0f} s" for k, s in st.items())
          + f"; total CPU {tot[0]:.0f} s ({tot[0] / 60:.1f} min), wall {tot[1]:.0f} s ({tot[1] / 60:.1f} min)"
          + ("" if rec["complete"] is True else f" (a lower bound: {rec['complete']})"))
    return tot, ("" if rec["complete"] is True else "at most ")


def report(name: str, rows: list[np.ndarray], aurt: tuple = (None, ""), whole: float | None = None) -> None:
    """One line: the median [CPU, wall] of ``rows``, with its ratio to AURT's (``aurt``: as
    :func:`recorded` returns it) or its share of ``whole``'s CPU."""
    med = np.median(np.array(rows), axis=0)
    a, bound = aurt
    tail = "" if a is None else (f"; {bound}1/{a[0] / med[0]:.0f} of AURT's CPU time, {bound}1/{a[1] / med[1]:.0f} "
                                 "of its wall time")
    tail += "" if whole is None else f"; {100 * med[0] / whole:4.1f} % of the steps' CPU"
    print(f"  {name:<46} CPU {med[0]:7.2f} s  wall {med[1]:7.2f} s (median of {len(rows)}){tail}")


def stage_one_blas(run: Path) -> np.ndarray:
    """Stage 1 (``identify_robot``) with BLAS held to one thread (threadpoolctl), then as it runs:
    [[CPU, wall] one thread, [CPU, wall] default]. Since c9471f5 ``identify_robot`` holds BLAS to one thread
    itself (``frictid.parallel.one_blas_thread``), so the two agree; before, the default spent 5x the CPU."""
    from threadpoolctl import threadpool_limits
    rb, logs = load_robot(ROBOT), read_many([str(run)], str(MAP))
    out = []
    for limit in (1, None):
        with threadpool_limits(limits=limit, user_api="blas"):
            t = clock()
            identify_robot(rb, logs)
            out.append(clock() - t)
    return np.array(out)


def rounds_of(run: Path, tmp: str, rounds: int, smoke: bool) -> dict:
    """Each round: the command in a fresh process (not under smoke), fit_robot, its steps, stage 1 with
    BLAS at one thread and as it runs."""
    out: dict = {"cli": [], "whole": [], "blas": [], **{k: [] for k in STEPS}}
    for _ in range(rounds):
        if not smoke:
            out["cli"].append(cli_round(run, tmp))
        spent, kept = whole_round(run)
        out["whole"].append(spent)
        split, kept_split = split_round(run)
        assert kept_split == kept, f"the timed steps' answer differs from fit_robot's: {kept_split} != {kept}"
        for k in STEPS:
            out[k].append(split[k])
        out["blas"].append(stage_one_blas(run))
    out["kept"] = kept
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cold-rounds", type=int, default=1, help="runs with numba's cache empty (each ~20 s CPU)")
    args = ap.parse_args(argv)
    smoke = os.environ.get("FRICTID_SMOKE") == "1"
    aurt = recorded()
    with tempfile.TemporaryDirectory() as tmp:
        run = smoke_run(tmp) if smoke else RUN
        load0 = os.getloadavg()[0]
        cold = [] if smoke else [cli_round(run, tmp, cold=True) for _ in range(args.cold_rounds)]
        r = rounds_of(run, tmp, 1 if smoke else args.rounds, smoke)
        print(f"frictid on {run.name} ({'the first quarter, smoke' if smoke else 'the whole run'}), load average "
              f"{load0:.1f} -> {os.getloadavg()[0]:.1f}:")
        if cold:
            report("frictid fit, fresh process, numba cache empty", cold, aurt)
            report("frictid fit (fresh process)", r["cli"], aurt)
        report("fit_robot (in process)", r["whole"], aurt)
        total = np.median(np.array([sum(r[k][i] for k in STEPS) for i in range(len(r["whole"]))]), axis=0)
        for k in STEPS:
            report(f"  {k}", r[k], whole=total[0])
        blas = np.median(np.array(r["blas"]), axis=0)
        print(f"  stage 1 alone, BLAS at one thread / as it runs: CPU {blas[0, 0]:.2f} / {blas[1, 0]:.2f} s, "
              f"wall {blas[0, 1]:.2f} / {blas[1, 1]:.2f} s (median of {len(r['blas'])}, alternating)")
        print("  kept per joint: " + ", ".join(f"{j} {m} ({k})" for j, (k, m) in r["kept"].items()))
        if not smoke:
            load0 = os.getloadavg()[0]
            first = [readme_round(tmp, cold=True) for _ in range(args.cold_rounds)]
            warm = [readme_round(tmp) for _ in range(args.rounds)]
            print(f"the README's first command, frictid fit {SAMPLE.relative_to(ROOT)} -o P --report R, load average "
                  f"{load0:.1f} -> {os.getloadavg()[0]:.1f}:")
            report("fresh process, numba cache empty", first)
            report("fresh process", warm)
    return 0


if __name__ == "__main__":
    sys.exit(main())
