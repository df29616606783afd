"""Where one joint-hour's fit spends its CPU: the stages of ``fit_joint`` on one joint of run_all's log.

    python benchmarks/bench_fit_joint.py [--log FILE] [--repeat 3]

The log is run_all's (8 passes of every experiment kind, 7.5 min each at 1 kHz, the geared joint with
thermal6): 3.6 M samples of joint j1, built once (about 40 s) unless ``--log`` names a Parquet file with a
joint ``j1``. The process is set up as ``frictid fit``'s workers are (the workers' imports done), one
unmeasured fit warms the compilation caches and the allocator, then the best
of ``--repeat`` fits is printed with the CPU time of each stage (stages nest: the diagnosis check holds
its own static-map fits; the total is the whole fit).
"""
from __future__ import annotations

import argparse
import os
import collections
import functools
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import frictid  # noqa: E402
from frictid import segments as sg  # noqa: E402
from frictid import api  # noqa: E402
from frictid.identify import dynamics, maps, mechanics, thermal_fit  # noqa: E402
from frictid.identify import samples as smp  # noqa: E402
from frictid.identify import select as sel  # noqa: E402
from frictid.io.logs import joint_row_blocks, read_logs  # noqa: E402

#: (module, function) pairs timed; the label is the function's name.
STAGES = [(sg, "estimate_scales"), (sg, "derivatives"), (sg, "find_segments"), (mechanics, "regress"),
          (mechanics, "plateaus"), (mechanics, "_stage2_map"), (maps, "fit_static"), (sel, "heldout_static"),
          (dynamics, "fit_lugre"), (thermal_fit, "fit_thermal_models"), (api, "diagnose_fit"),
          (api, "check_diagnosis"), (smp, "build"), (smp, "fit_map")]


def timed_stages(spent: dict, calls: collections.Counter) -> None:
    """Wrap every function of :data:`STAGES` so that its CPU time adds to ``spent[name]``."""
    for mod, name in STAGES:
        fn = getattr(mod, name)

        @functools.wraps(fn)
        def wrapper(*a, _fn=fn, _name=name, **kw):
            t0 = time.process_time()
            try:
                return _fn(*a, **kw)
            finally:
                spent[_name] += time.process_time() - t0
                calls[_name] += 1
        setattr(mod, name, wrapper)


def joint_log(path: str | None):
    if path is None:
        from run_all import build_log

        path = str(Path(tempfile.mkdtemp(prefix="frictid-joint-")) / "one_joint_8p.parquet")
        build_log(path, 8, 1)
    blocks = {j: (a, b) for j, a, b in joint_row_blocks(path, None, None) or []}
    if "j1" not in blocks:
        raise SystemExit(f"{path}: no joint 'j1' stored as one block of rows")
    return read_logs(path, skip=api.UNUSED_CHANNELS, rows=blocks["j1"])[0]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--log", help="a Parquet log with joint j1 as one block of rows (default: build one)")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    if os.environ.get("FRICTID_SMOKE") == "1":  # the docs test: the same code path on a tiny case
        a.repeat = 1
    api.preload()
    log = joint_log(a.log)
    frictid.fit([log])  # warm: compilation caches, lazy imports, the allocator's heap
    spent: dict = collections.defaultdict(float)
    calls: collections.Counter = collections.Counter()
    timed_stages(spent, calls)
    best = None
    for _ in range(max(1, a.repeat)):
        spent.clear()
        calls.clear()
        t0 = time.process_time()
        frictid.fit([log])
        total = time.process_time() - t0
        if best is None or total < best[0]:
            best = (total, dict(spent), dict(calls))
    total, spent_, calls_ = best
    print(f"fit of one joint-hour ({log.n:,} samples): {total:.2f} s CPU, best of {a.repeat}")
    for name, s in sorted(spent_.items(), key=lambda x: -x[1]):
        print(f"  {name:18s} {s:6.3f} s  {calls_[name]:4d} call(s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
