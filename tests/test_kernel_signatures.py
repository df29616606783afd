"""The compiled kernels a fit calls get the one signature each declares (``KERNELS``): numba compiles a new
copy of a kernel for every combination of argument types it meets (a read-only input, an int for a float, a
layout), each a second or more on the first run after installing, and ``frictid.api.compile_kernels``
compiles the declared ones before the joints' worker processes fork. In a fresh process (the kernels' compiled
copies are then only this fit's), the README's sample log is fitted with its diagnosis and each kernel's
compiled signatures compared with the declared one."""
from __future__ import annotations

import json
import subprocess
import sys

from conftest import ROOT

SCRIPT = """
import json, sys
from frictid.api import fit
from frictid.diagnose import samples
from frictid.identify import varpro
from frictid.models import replay_kernel
from frictid.segments import duty, runs
fit(sys.argv[1], diagnose=True)
print(json.dumps({k.py_func.__name__: [[str(t) for t in s] for s in k.signatures] + [[str(t) for t in sig]]
                  for m in (runs, duty, varpro, replay_kernel, samples) for k, sig in m.KERNELS}))
"""


def test_a_fit_compiles_each_kernel_for_its_declared_signature_only():
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT / "sample_logs/hydraulic_sweep.csv")], cwd=ROOT,
                         capture_output=True, timeout=600)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.decode().strip().splitlines()[-1])
    called = {name for name, sigs in got.items() if len(sigs) > 1}
    assert {"_project_nb", "_bvls_nb", "_kernel", "_best_chain_nb", "_offset_cumsum", "_rise_nb"} <= called, got
    for name, (*compiled, declared) in got.items():
        assert all(s == declared for s in compiled), f"{name}: compiled for {compiled}, declared {declared}"
