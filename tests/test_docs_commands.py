"""Every command printed in a ```bash block of README.md, docs/*.md and sample_logs/README.md runs.

Each page's commands run in order, as a user would type them (bash, ``set -o pipefail``), from the root of
a fresh copy of the repository (so nothing in the repository is written; ``../shared`` is linked beside
the copy when it exists, as on CI), with this Python's folder first on PATH and ``FRICTID_SMOKE=1``: every
script under ``benchmarks/`` then shrinks its work to seconds (one draw, a tiny log, one repetition)
along the same code path and writes no docs. Pages run side by side, one per core. Exceptions, each said
here:

- README.md's two install commands (a new venv, ``pip install``) are run by ``.ci/run`` exactly as printed;
- docs/fleet.md's blocks are run by ``tests/test_fleet.py::test_every_command_in_docs_fleet_runs`` (it
  starts the dask cluster its ``--scheduler`` command needs), and docs/using-the-model.md's (bash and
  python, in order) by ``tests/test_export.py::test_using_the_model_page_runs``;
- docs/report.md's first block stands for a user's own files (``params.yaml`` fitted from ``run.parquet``,
  a vendor log ``raw.csv``, as ``tests/test_report.py::test_docs_examples_run`` also reads it): SETUP makes
  them from a shipped sample log before the page runs;
- a documented ``python -m pytest ...`` is collected (``--collect-only``), not run: the suite runs those
  tests itself, and running them from here would run them twice.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from conftest import REALDATA, ROOT

PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md")),
         "sample_logs/README.md"]
ELSEWHERE = {"docs/fleet.md": "tests/test_fleet.py::test_every_command_in_docs_fleet_runs",
             "docs/using-the-model.md": "tests/test_export.py::test_using_the_model_page_runs"}
#: Commands run before a page's own, making the files its commands stand for.
SETUP = {"docs/report.md": [
    "python -c \"import numpy as np, pandas as pd; d = pd.read_csv('sample_logs/hydraulic_sweep.csv'); "
    "d.to_parquet('run.parquet'); pd.DataFrame({'t': d.t, 'joint': d.joint, 'position': np.degrees(d.q), "
    "'torque': d.tau}).to_csv('raw.csv', index=False)\"",
    "frictid fit run.parquet -o params.yaml"]}
#: The copy keeps ``__pycache__``: its bytecode and numba's compiled kernels (``cache=True``) stay valid in
#: the copy (both are keyed by the source file's modification time and size, which the copy keeps), so each
#: page does not compile every kernel again (about 35 s CPU a page).
COPY_IGNORE = shutil.ignore_patterns(".git", ".venv*", "*.egg-info", ".pytest_cache", "build")
#: Run once before the pages are copied, so that the kernels every page uses are compiled in the repository
#: (the main job of README.md: simulate, fit with report, replay).
WARM_UP = ["frictid simulate {root}/recipes/ramp_presliding.yaml -o warm.parquet -q",
           "frictid fit warm.parquet -o warm.yaml --report warm.html -q",
           "frictid simulate --params warm.yaml --replay warm.parquet -o warm.csv -q"]


#: The first line of a fenced block that is a command (with an option), not output that names one.
LOOKS_LIKE_A_COMMAND = r"(frictid (simulate|segments|fit|report|compare|trend)|python (-m|-c|\S+\.py)) .* -"


def commands(page: str) -> list[str]:
    """The commands of a page's ```bash blocks, in order: continuation lines joined, comment lines dropped."""
    text = (ROOT / page).read_text()
    out = []
    for block in re.findall(r"^```bash\n(.*?)^```", text, re.S | re.M):
        for line in block.replace("\\\n", " ").splitlines():
            if line.strip() and not line.lstrip().startswith("#"):
                out.append(line.strip())
    return out


def runnable(page: str, cmd: str) -> str | None:
    """The command line to run for a documented one, or None for the README's install commands."""
    if page == "README.md" and "pip install" in cmd:
        return None  # run by .ci/run, as printed
    return re.sub(r"\bpython -m pytest\b", "python -m pytest --collect-only -p no:cacheprovider", cmd)


def test_pages_hold_commands_and_every_block_is_bash_or_marked():
    """Each page with a bash block is run here or by the test named in ELSEWHERE; a fenced block that looks
    like a command without being ```bash would escape this test."""
    assert sum(len(commands(p)) for p in PAGES) >= 40
    assert [runnable("README.md", c) for c in commands("README.md")][:2] == [None, None]  # the installs
    assert sum(runnable(p, c) is None for p in PAGES for c in commands(p)) == 2  # and only they
    for page, test in ELSEWHERE.items():
        path, name = test.split("::")
        assert f"def {name}(" in (ROOT / path).read_text(), (page, test)
    for page in PAGES:
        for lang, body in re.findall(r"^```(\w*)\n(.*?)^```", (ROOT / page).read_text(), re.S | re.M):
            first = body.lstrip().split("\n", 1)[0]
            if lang not in ("bash", "text") and re.match(LOOKS_LIKE_A_COMMAND, first):
                pytest.fail(f"{page}: a command in a ```{lang or '(no language)'} block: {first!r}")


def run_page(page: str, base: Path) -> tuple[str, str | None]:
    """Run a page's commands in order in a fresh copy of the repository below ``base``: ("ok", seconds),
    ("skip", why) or ("fail", what failed)."""
    cmds = [(c, runnable(page, c)) for c in commands(page)]
    if not cmds:
        return "skip", f"{page} prints no ```bash command"
    cmds = [(f"(setup) {c}", c) for c in SETUP.get(page, [])] + cmds
    if any("shared/realdata" in c for c, _ in cmds) and not REALDATA.is_dir():
        return "skip", f"{page} runs on {REALDATA}, absent here (CI requires it)"
    repo = base / "repo"
    shutil.copytree(ROOT, repo, ignore=COPY_IGNORE, symlinks=True)
    if REALDATA.is_dir():
        (base / "shared").symlink_to(REALDATA.parent, target_is_directory=True)
    env = dict(os.environ, FRICTID_SMOKE="1", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    env.pop("FRICTID_DEBUG", None)
    docs_before = {p: p.read_bytes() for p in (repo / "docs").glob("*.md")}
    t0 = time.perf_counter()
    for shown, cmd in cmds:
        if cmd is None:
            continue
        p = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=repo, env=env, capture_output=True,
                           text=True, timeout=900)
        if p.returncode or "Traceback" in p.stderr:
            return "fail", f"{page}: `{shown}` exited {p.returncode}\n{p.stderr[-3000:]}\n{p.stdout[-1500:]}"
    changed = [p.name for p, b in docs_before.items() if p.read_bytes() != b]
    if changed:
        return "fail", f"{page}: commands in smoke mode wrote into docs: {changed}"
    return "ok", f"{time.perf_counter() - t0:.0f} s"


@pytest.fixture(scope="module")
def page_results(tmp_path_factory):
    """Every page run at once, one page per core (each page's commands in order, in its own copy)."""
    pages = [p for p in PAGES if p not in ELSEWHERE and commands(p)]
    warm = tmp_path_factory.mktemp("warm-up")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    for cmd in WARM_UP:
        subprocess.run(["bash", "-c", cmd.format(root=ROOT)], cwd=warm, env=env, capture_output=True, timeout=900)
    pages.sort(key=lambda p: -len(commands(p)))  # the longest first
    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1)) as ex:
        futs = {p: ex.submit(run_page, p, tmp_path_factory.mktemp(Path(p).stem)) for p in pages}
        return {p: f.result() for p, f in futs.items()}


@pytest.mark.parametrize("page", [p for p in PAGES if p not in ELSEWHERE and commands(p)])
def test_documented_commands_run(page, page_results):
    status, what = page_results[page]
    if status == "skip":
        pytest.skip(what)
    assert status == "ok", what
