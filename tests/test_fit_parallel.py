"""Joints fitted in parallel (``frictid fit --jobs``): the same result as one after another, the work really
done in other processes, errors surfacing exactly as in the serial path."""
from __future__ import annotations

import os
import time

import numpy as np
import pytest

import frictid
from frictid import api, parallel
from frictid.data import JointLog
from frictid.errors import FrictidInputError, LogFormatError
from frictid.io.logs import write_logs
from frictid.io.params import dump_yaml

from fit_synth import synth_log, truth_derivatives, truth_segments

MODELS = "stribeck,coulomb_viscous,polynomial,polynomial_ls"


def three_joints() -> list[JointLog]:
    v = np.geomspace(0.02, 2.0, 6)
    return [synth_log(np.concatenate([v, -v]), seed=k, joint=str(k + 1), noise=0.02 * (k + 1), excitation=False)
            for k in range(3)]


@pytest.fixture(scope="module")
def serial():
    return frictid.fit(three_joints(), models=MODELS, segmenter=truth_segments, differentiate=truth_derivatives,
                       jobs=1)


def test_parallel_result_equals_serial_and_runs_in_workers(serial, tmp_path):
    pids = tmp_path / "pids"

    def segmenter(log):  # records which process segmented which joint
        with open(pids, "a") as fh:
            fh.write(f"{log.joint} {os.getpid()}\n")
        return truth_segments(log)

    par = frictid.fit(three_joints(), models=MODELS, segmenter=segmenter, differentiate=truth_derivatives,
                      jobs=2)
    assert dump_yaml(par.to_dict()) == dump_yaml(serial.to_dict())  # every number, warning and selection identical
    assert list(par.joints) == ["1", "2", "3"]
    seen = dict(line.split() for line in pids.read_text().splitlines())
    assert set(seen) == {"1", "2", "3"}
    assert str(os.getpid()) not in seen.values(), "the joints were fitted in worker processes"
    assert 1 <= len(set(seen.values())) <= 2, "at most --jobs workers"


def test_number_of_workers():
    cores = len(os.sched_getaffinity(0))
    assert parallel.n_workers(0, 6) == min(6, cores)
    assert parallel.n_workers(0, 1) == 1
    assert parallel.n_workers(4, 3) == 3
    assert parallel.n_workers(1, 6) == 1
    with pytest.raises(FrictidInputError):
        parallel.n_workers(-1, 6)


def test_workers_use_one_blas_thread():
    """Each worker limits BLAS to one thread (the joints already share the cores)."""
    import scipy.linalg  # noqa: F401 - loads scipy's OpenBLAS too
    from threadpoolctl import threadpool_info

    def blas_threads(_):
        return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

    assert blas_threads(0), "numpy's BLAS is visible to threadpoolctl"
    assert parallel.map_ordered(blas_threads, [0, 1], 2) == [[1], [1]]


def _square_or_fail(x):
    """x squared and the process that computed it; items 2 and 4 fail (4 first in time)."""
    if x in (2, 4):
        time.sleep(0.5 if x == 2 else 0.0)
        raise LogFormatError(f"f{x}.csv", [f"row {x}", "more"])
    return x * x, os.getpid()


def test_map_keeps_the_order_raises_the_first_error_and_leaves_the_process_alone():
    """Results in the items' order from worker processes; the first failing item in order raises its own
    exception (class, message, attributes); the caller's signal handling, GC and environment unchanged."""
    import gc
    import signal

    handlers = {s: signal.getsignal(s) for s in parallel.STOP_SIGNALS}
    mask, env = signal.pthread_sigmask(signal.SIG_BLOCK, []), dict(os.environ)
    got = parallel.map_ordered(_square_or_fail, [0, 1, 3, 5], 2)
    assert [v for v, _ in got] == [0, 1, 9, 25]
    assert os.getpid() not in {pid for _, pid in got}
    with pytest.raises(LogFormatError) as info:
        parallel.map_ordered(_square_or_fail, [1, 2, 3, 4], 2)
    assert (info.value.path, info.value.problems) == ("f2.csv", ["row 2", "more"])
    assert str(info.value) == "f2.csv: 2 problems:\n  - row 2\n  - more"
    assert {s: signal.getsignal(s) for s in parallel.STOP_SIGNALS} == handlers
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == mask
    assert gc.get_freeze_count() == 0 and dict(os.environ) == env


@pytest.mark.parametrize("exc", [LogFormatError("run.csv", ["a", "b"]), LogFormatError("", ["one"]),
                                 FrictidInputError("--jobs -1: bad")])
def test_errors_pickle_to_the_same_class_and_message(exc):
    import pickle

    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is type(exc) and str(back) == str(exc) and back.__dict__ == exc.__dict__


def _failing(monkeypatch, exc_for):
    real = api.fit_joint

    def fit_joint(jlogs, *a, **kw):
        exc = exc_for(jlogs[0].joint)
        if exc is not None:
            raise exc
        return real(jlogs, *a, **kw)
    monkeypatch.setattr(api, "fit_joint", fit_joint)  # forked workers inherit the patched module


@pytest.mark.parametrize("jobs", [1, 3])
def test_first_failing_joint_raises_its_own_exception(monkeypatch, jobs):
    # every joint fails, joint 3 first in time: the first joint in order is the one reported
    delay = {"1": 0.5, "2": 0.3, "3": 0.0}

    def exc_for(j):
        time.sleep(delay[j])
        return LogFormatError("run.csv", [f"joint {j}: problem one", "problem two"])
    _failing(monkeypatch, exc_for)
    with pytest.raises(LogFormatError) as info:
        frictid.fit(three_joints(), models=MODELS, segmenter=truth_segments, differentiate=truth_derivatives,
                    jobs=jobs)
    assert str(info.value) == "run.csv: 2 problems:\n  - joint 1: problem one\n  - problem two"
    assert info.value.problems == ["joint 1: problem one", "problem two"]


def test_cli_error_in_a_worker_is_exit_2_without_traceback(monkeypatch, tmp_path, cli):
    n = 400
    t = np.arange(n) * 1e-3
    logs = [JointLog(joint=j, t=t, q=0.5 * np.sin(2 * np.pi * t), qd=np.pi * np.cos(2 * np.pi * t),
                     tau=np.sign(np.cos(2 * np.pi * t)) + 0.01 * k) for k, j in enumerate(("a", "b"))]
    path = tmp_path / "two.csv"
    write_logs(logs, str(path), "csv")
    _failing(monkeypatch, lambda j: FrictidInputError(f"joint {j}: the logs disagree on the axis"))
    outs = {}
    for jobs in ("1", "2"):
        out = tmp_path / f"p{jobs}.yaml"
        r = cli("fit", str(path), "-o", str(out), "--jobs", jobs)
        assert r.code == 2, r
        assert not out.exists(), "no partial output"
        assert "Traceback" not in r.err
        outs[jobs] = r.err
    assert outs["1"] == outs["2"]
    assert outs["2"].endswith("frictid: error: joint a: the logs disagree on the axis\n")
    r = cli("fit", str(path), "-o", str(tmp_path / "x.yaml"), "--jobs", "-1")
    assert r.code == 2 and "Traceback" not in r.err


@pytest.mark.parametrize("sig, code, word", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
def test_interrupt_stops_the_workers_and_writes_nothing(tmp_path, sig, code, word):
    """Ctrl-C (to the whole process group, as a terminal sends it) or SIGTERM (to the parent) while the
    workers fit: one message, no traceback, no output, no worker left behind."""
    import signal
    import subprocess
    import sys

    from conftest import ROOT, default_signals

    path = tmp_path / "two.parquet"
    # long enough (seconds of fitting per joint) that the signal lands while the workers fit
    write_logs([synth_log(seed=k, joint=str(k + 1), dt=5e-4, hold=3.0) for k in range(2)], str(path),
               "parquet")
    out = tmp_path / "p.yaml"
    proc = subprocess.Popen([sys.executable, "-m", "frictid", "fit", str(path), "-o", str(out), "--jobs", "2"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=default_signals)
    kids: list[str] = []
    deadline = time.monotonic() + 120
    while len(kids) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
        try:
            kids = open(f"/proc/{proc.pid}/task/{proc.pid}/children").read().split()
        except OSError:
            kids = []
    assert len(kids) == 2, "two workers started"
    if sig == "SIGINT":
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    err = err.decode()
    assert proc.returncode == code, err[-1000:]
    assert word in err and "Traceback" not in err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]

    def running(k):  # alive and not a zombie waiting to be reaped
        try:
            return open(f"/proc/{k}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False
    deadline = time.monotonic() + 10  # a terminated worker may wait for a core on a loaded machine
    while any(running(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [k for k in kids if running(k)], "no worker left running"


@pytest.fixture(scope="module")
def three_joint_file(tmp_path_factory):
    """The three joints in one Parquet file (each one block of rows) and their fit from the logs read
    whole (in memory, one after another)."""
    from frictid.io.logs import read_logs

    path = tmp_path_factory.mktemp("blocks") / "three.parquet"
    write_logs(three_joints(), str(path))
    whole = frictid.fit(read_logs(str(path)), models=MODELS, segmenter=truth_segments, jobs=1)
    return path, whole


@pytest.mark.parametrize("jobs", [1, 2])
def test_joints_read_by_their_workers_give_the_same_fit(three_joint_file, jobs):
    """A Parquet log whose joints are blocks of rows is read joint by joint by the process that fits the
    joint: the same models as the logs read whole, and the file's rows in its source entry."""
    path, whole = three_joint_file
    got = frictid.fit(str(path), models=MODELS, segmenter=truth_segments, jobs=jobs)
    assert list(got.joints) == list(whole.joints) == ["1", "2", "3"]
    for j, jf in whole.joints.items():
        a, b = got.joints[j].to_dict(), jf.to_dict()
        assert (a["selected"], a["models"]) == (b["selected"], b["models"]), j
    assert got.sources == [{"path": str(path), "sha256": got.sources[0]["sha256"],
                            "rows": sum(lg.n for lg in three_joints())}]


def test_problems_of_joints_read_by_their_workers_come_together(tmp_path):
    """Every joint's bad rows are reported in one error naming rows of the whole file (no fit is
    returned), with one worker or two; a row with a missing value is dropped and the file's rows count
    it out."""
    logs = three_joints()
    logs[0].tau[7] = np.inf
    logs[2].tau[3] = np.inf
    path = tmp_path / "bad.parquet"
    write_logs(logs, str(path))
    for jobs in (1, 2):
        with pytest.raises(LogFormatError) as err:
            frictid.fit(str(path), models=MODELS, segmenter=truth_segments, jobs=jobs)
        msg = str(err.value)
        first = logs[0].n + logs[1].n
        assert "joint 1: column 'tau': row 8 " in msg and f"joint 3: column 'tau': row {first + 4} " in msg, msg
    logs = three_joints()
    logs[1].tau[5] = np.nan
    write_logs(logs, str(path))
    got = frictid.fit(str(path), models=MODELS, segmenter=truth_segments, jobs=2)
    assert got.sources[0]["rows"] == sum(lg.n for lg in logs) - 1
    assert any("dropped 1 rows" in w for w in got.joints["2"].warnings)
