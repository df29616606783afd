"""Shared test helpers: small hand-made logs and a way to run the CLI in-process or in a real process."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from frictid.data import JointLog

ROOT = Path(__file__).resolve().parents[1]
REALDATA = ROOT.parent / "shared" / "realdata"


def hand_log(n: int = 400, joint: str = "1", seed: int = 0, dt: float = 1e-3) -> JointLog:
    """A small valid log: a sine move with Coulomb + viscous friction and a little noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    q = 0.5 * np.sin(2 * np.pi * t)
    qd = np.pi * np.cos(2 * np.pi * t)
    tau = 2.0 * np.sign(qd) + 0.3 * qd + 0.01 * rng.standard_normal(n)
    return JointLog(joint=joint, t=t, q=q, qd=qd, tau=tau, channels={"temp_env": np.full(n, 21.0)})


class CliResult:
    def __init__(self, code, out, err):
        self.code, self.out, self.err = code, out, err

    def __repr__(self):
        return f"CliResult(code={self.code}, err={self.err[-400:]!r})"


@pytest.fixture
def cli(capsysbinary):
    """Run ``frictid ARGS`` in this process; returns exit code, stdout and stderr (text)."""
    from frictid.cli import main

    def run(*args: str) -> CliResult:
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        cap = capsysbinary.readouterr()
        return CliResult(code, cap.out.decode("utf-8", "replace"), cap.err.decode("utf-8", "replace"))

    return run


def default_signals() -> None:
    """``preexec_fn`` of a child that a test interrupts: Ctrl-C and SIGTERM at their defaults, as in a
    terminal. A shell without job control starts background commands (a CI runner's) with SIGINT
    ignored, and Python then leaves it ignored in every child: the interrupt tests would test nothing."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def run_process(args, input_bytes=None, cwd=None, timeout=300) -> subprocess.CompletedProcess:
    """Run ``python -m frictid ARGS`` in a real process."""
    env = dict(os.environ)
    env.pop("FRICTID_DEBUG", None)
    return subprocess.run([sys.executable, "-m", "frictid", *map(str, args)], input=input_bytes,
                          capture_output=True, cwd=cwd or ROOT, env=env, timeout=timeout)
