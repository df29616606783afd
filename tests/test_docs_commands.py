"""Every command printed in a ```bash block of README.md, docs/*.md and sample_logs/README.md runs.

Each page's commands run in order, as a user would type them (bash, ``set -o pipefail``), from the root of
a fresh copy of the repository (so nothing in the repository is written; ``../shared`` is linked beside
the copy when it exists, as on CI), with this Python's folder first on PATH and ``FRICTID_SMOKE=1``: every
script under ``benchmarks/`` then shrinks its work to seconds (one draw, a tiny log, one repetition)
along the same code path and writes no docs. Exceptions, each said here:

- README.md's two install commands (a new venv, ``pip install``) are run by ``.ci/run`` exactly as printed;
- docs/fleet.md's blocks are run by ``tests/test_fleet.py::test_every_command_in_docs_fleet_runs`` (it
  starts the dask cluster its ``--scheduler`` command needs);
- a documented ``python -m pytest ...`` is collected (``--collect-only``), not run: the suite runs those
  tests itself, and running them from here would run them twice.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REALDATA, ROOT

PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md")),
         "sample_logs/README.md"]
ELSEWHERE = {"docs/fleet.md": "tests/test_fleet.py::test_every_command_in_docs_fleet_runs"}
COPY_IGNORE = shutil.ignore_patterns(".git", ".venv*", "__pycache__", "*.egg-info", ".pytest_cache", "build")


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
    for page, test in ELSEWHERE.items():
        path, name = test.split("::")
        assert f"def {name}(" in (ROOT / path).read_text(), (page, test)
    for page in PAGES:
        for lang, body in re.findall(r"^```(\w*)\n(.*?)^```", (ROOT / page).read_text(), re.S | re.M):
            first = body.lstrip().split("\n", 1)[0]
            if lang not in ("bash", "text") and re.match(r"(frictid|python) ", first):
                pytest.fail(f"{page}: a command in a ```{lang or '(no language)'} block: {first!r}")


@pytest.fixture
def repo_copy(tmp_path):
    """A copy of the repository to run in, with ../shared linked beside it when it exists."""
    dst = tmp_path / "repo"
    shutil.copytree(ROOT, dst, ignore=COPY_IGNORE, symlinks=True)
    if REALDATA.is_dir():
        (tmp_path / "shared").symlink_to(REALDATA.parent, target_is_directory=True)
    return dst


@pytest.mark.parametrize("page", [p for p in PAGES if p not in ELSEWHERE])
def test_documented_commands_run(page, repo_copy):
    cmds = [(c, runnable(page, c)) for c in commands(page)]
    if not cmds:
        pytest.skip(f"{page} prints no ```bash command")
    if any("shared/realdata" in c for c, _ in cmds) and not REALDATA.is_dir():
        pytest.skip(f"{page} runs on {REALDATA}, absent here (CI requires it)")
    env = dict(os.environ, FRICTID_SMOKE="1", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    env.pop("FRICTID_DEBUG", None)
    docs_before = {p: p.read_bytes() for p in (repo_copy / "docs").glob("*.md")}
    for shown, cmd in cmds:
        if cmd is None:
            continue
        p = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=repo_copy, env=env, capture_output=True,
                           text=True, timeout=600)
        assert p.returncode == 0 and "Traceback" not in p.stderr, \
            f"{page}: `{shown}` exited {p.returncode}\n{p.stderr[-3000:]}\n{p.stdout[-1500:]}"
    changed = [str(p.name) for p, b in docs_before.items() if p.read_bytes() != b]
    assert not changed, f"{page}: commands in smoke mode wrote into docs: {changed}"
