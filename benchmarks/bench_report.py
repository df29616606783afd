"""Report benchmark: size and time of the HTML report of a 6-joint, one-hour, 1 kHz log.

    python benchmarks/bench_report.py               # 6 joints x 60 min at 1 kHz (21.6 M samples)
    python benchmarks/bench_report.py --quick       # 2 joints x 5 min, for a smoke run
    python benchmarks/bench_report.py --keep DIR    # keep the report (and its screenshot) in DIR
    python benchmarks/bench_report.py --resegment   # without the fit's segments (segment every log again)

The logs: one plant run per joint and seed on the geared industrial joint, about an hour: a multi-sine,
a constant-velocity sweep, presliding ramps, torque steps and 14 duty cycles of 4 minutes. The parameter
file: one real identification of the tests' short run (tests/test_report.py), copied to every joint, with
a diagnosis entry.
The logs are written to a Parquet file and each joint's segments found by the real segmenter are
recorded in the parameter file as ``frictid fit`` records them (``segment_list``, outside the timing: the
fit's cost); the report is then built as ``frictid report`` builds it from the file read back (recorded
segments reused, joints in parallel), timed per part (CPU), and loaded in headless Chromium when one is
installed (load time to the load event). ``--resegment`` leaves the segments out: the report segments
every log again, as before they were recorded.

Targets (issue): under 5 MB, and under 10 s to render.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]

RECIPE = {
    "name": "bench_report_hour",
    "description": "every experiment kind in about an hour (14 duty cycles of 4 minutes)",
    "default_plant": "geared_industrial",
    "temp_env": 25.0,
    "start_rest": 1.0,
    "experiments": [
        {"kind": "multisine", "duration": 60.0, "f0": 0.1, "harmonics": 5, "velocity": 0.7, "rest": 1.0},
        {"kind": "constant_velocity", "velocities": {"min": 0.01, "max": 0.95, "count": 12, "spacing": "log"},
         "relative": True, "signs": "both", "plateau": 3.0, "min_plateau": 0.5, "accel": 0.5, "gap": 0.3,
         "rest": 1.0},
        {"kind": "ramp_presliding", "peaks": [0.3, 0.6], "relative": True, "signs": "both", "ramp_up": 3.0,
         "hold": 1.0, "ramp_down": 3.0, "settle": 1.0, "rest": 1.0},
        {"kind": "torque_steps", "levels": [0.3, 0.6], "relative": True, "signs": "both", "hold": 0.5,
         "release": 0.3, "settle": 0.5, "rest": 1.0},
        {"kind": "duty_cycle", "duty": 0.5, "cycles": 14, "cycle_time": 240.0, "slots": 4, "cold_start": True,
         "rest": 2.0},
    ],
}


def make_inputs(n_joints: int, minutes: float, workdir: Path):
    """Logs (one plant run per joint, cut to ``minutes``) and a parameter file for every joint."""
    import frictid
    from frictid.data import JointLog
    from frictid.plant import simulate_recipe

    sys.path.insert(0, str(ROOT / "tests"))
    from test_report import FINDING, MODELS, RECIPE as SHORT, truth_segments

    recipe = workdir / "bench_recipe.yaml"
    recipe.write_text(yaml.safe_dump(RECIPE))
    t0 = time.perf_counter()
    logs = []
    for i in range(n_joints):
        lg = simulate_recipe(str(recipe), seed=i, duration_scale=min(1.0, minutes / 61.0))[0]
        n = min(lg.n, int(round(minutes * 60.0 / lg.dt)))
        logs.append(JointLog(joint=f"j{i + 1}", t=lg.t[:n], tau=lg.tau[:n], q=lg.q[:n],
                             qd=None if lg.qd is None else lg.qd[:n],
                             channels={k: v[:n] for k, v in lg.channels.items()}, axis=lg.axis,
                             meta=dict(lg.meta), source=f"bench-j{i + 1}.parquet"))
    t_sim = time.perf_counter() - t0
    # one real identification of the tests' short run (segments from the plant's labels), for every joint
    short = workdir / "short_recipe.yaml"
    short.write_text(yaml.safe_dump(SHORT))
    t0 = time.perf_counter()
    res = frictid.fit(simulate_recipe(str(short), seed=3), models=MODELS, segmenter=truth_segments)
    t_fit = time.perf_counter() - t0
    d = res.to_dict()
    jd = next(iter(d["joints"].values()))
    jd["diagnosis"] = [dict(FINDING)]
    jd.pop("segment_list", None)  # the short run's segments; each joint gets its own log's below
    d["joints"] = {lg.joint: dict(jd) for lg in logs}
    return d, logs, t_sim, t_fit


def record_segments(params: dict, logs, path: Path) -> float:
    """Write the logs to ``path`` (Parquet) and record in ``params`` what ``frictid fit`` records: the
    file as source 0 and each joint's segments found by the real segmenter (``segment_list``). Returns
    the seconds the segmenter took (the fit's cost, not the report's)."""
    from frictid.identify.prepare import segment_list
    from frictid.io.logs import file_sha256, write_logs
    from frictid.segments import find_segments

    write_logs(logs, str(path), "parquet")
    params["sources"] = [{"path": str(path), "sha256": file_sha256(str(path)), "rows": sum(lg.n for lg in logs)}]
    t0 = time.perf_counter()
    for lg in logs:
        params["joints"][lg.joint]["segment_list"] = [segment_list(0, lg.n, find_segments(lg))]
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--joints", type=int, default=6)
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--quick", action="store_true", help="2 joints x 5 minutes")
    ap.add_argument("--keep", help="folder to keep the report and the screenshot in")
    ap.add_argument("--no-browser", action="store_true")
    ap.add_argument("--resegment", action="store_true",
                    help="do not record the fit's segments: the report segments every log again")
    ap.add_argument("--jobs", type=int, default=0, help="joints built at once (0: one per core)")
    a = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        a.joints, a.minutes, a.quick = 1, 0.5, False
    if a.quick:
        a.joints, a.minutes = 2, 5.0
    work = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="bench-report-"))
    work.mkdir(parents=True, exist_ok=True)
    params, logs, t_sim, t_fit = make_inputs(a.joints, a.minutes, work)
    n = sum(lg.n for lg in logs)
    print(f"inputs: {a.joints} joints x {a.minutes:g} min, {n / 1e6:.1f} M samples "
          f"(simulated in {t_sim:.1f} s; parameter file fitted in {t_fit:.1f} s)")

    import resource

    from frictid.cli.report import read_report_logs
    from frictid.report import write_report
    from frictid.report.build import Prefetch

    def cpu():  # this process and its finished workers
        r, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime

    hashes = None
    if not a.resegment:
        t_seg = record_segments(params, logs, work / "bench_log.parquet")
        print(f"segments recorded as frictid fit records them (the segmenter took {t_seg:.1f} s, in the fit)")
        t0, c0 = time.perf_counter(), cpu()
        path = str(work / "bench_log.parquet")
        pre = Prefetch([path])  # as frictid report reads them: hashes and imports while reading
        logs = read_report_logs([path])
        hashes = pre.hashes()
        print(f"read, hashed and imported (threads): {time.perf_counter() - t0:.1f} s wall, {cpu() - c0:.1f} s CPU")
    out = work / "report.html"
    timings: dict = {}

    t0, c0 = time.perf_counter(), cpu()
    size = write_report(str(out), params, logs, params_path="bench_params.yaml",
                        command="python benchmarks/bench_report.py", timings=timings, jobs=a.jobs, hashes=hashes)
    total, total_cpu = time.perf_counter() - t0, cpu() - c0
    parts = ", ".join(f"{k} {v:.1f} s" for k, v in timings.items())
    print(f"report: {size / 1e6:.2f} MB in {total:.1f} s wall, {total_cpu:.1f} s CPU (CPU per part: {parts}; "
          f"load {os.getloadavg()[0]:.1f})")
    print(f"  derivatives and {'segmentation' if a.resegment else 'the recorded segments'}: "
          f"{timings.get('segments', 0):.1f} s CPU; figures, replays and HTML: "
          f"{total_cpu - timings.get('segments', 0):.1f} s CPU")
    ok = size < 5e6
    if not a.no_browser:
        sys.path.insert(0, str(ROOT / "tests"))
        from test_report_browser import find_browser, load_report
        exe = find_browser()
        if exe is None:
            print("browser: no Chromium installed; load time not measured")
        else:
            r = load_report(exe, out, work / "report.png")
            c = r["checks"]
            print(f"browser: loaded in {r['load_s']:.2f} s, {c['figures']} figures, page {c['height']} px high, "
                  f"console errors {len(r['errors'])}, overflow {len(c['overflow'])}")
            ok = ok and r["load_s"] < 10.0 and not r["errors"]
    print(f"targets (< 5 MB, browser < 10 s): {'met' if ok else 'NOT met'}; report in {out}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
