"""frictid in shell pipelines and CI jobs: stdin/stdout, a real shell, and interrupted writes."""
from __future__ import annotations

import shlex
import signal
import subprocess
import sys

import yaml

from conftest import ROOT, default_signals, run_process


def frictid_cmd() -> str:
    return f"{shlex.quote(sys.executable)} -m frictid"


def test_simulate_to_fit_through_a_real_shell_pipe(tmp_path):
    params = tmp_path / "params.yaml"
    cmd = (f"{frictid_cmd()} simulate recipes/ramp_presliding.yaml -o - --format csv | "
           f"{frictid_cmd()} fit - -o {shlex.quote(str(params))} --json")
    res = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=ROOT, capture_output=True, timeout=600)
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    d = yaml.safe_load(params.read_text())
    assert d["schema"] == 1 and d["joints"]
    assert d["sources"][0]["path"] in ("-", "<stdin>")
    summary = __import__("json").loads(res.stdout)  # --json: machine-readable summary on stdout
    assert set(summary["joints"]) == set(d["joints"])


def test_parquet_through_a_pipe_into_segments(tmp_path):
    """Parquet on a pipe into segments, with the --json summary on stdout, through a real shell."""
    seg = tmp_path / "seg.parquet"
    cmd = (f"{frictid_cmd()} simulate recipes/torque_steps.yaml -o - --format parquet --quiet | "
           f"{frictid_cmd()} segments - -o {shlex.quote(str(seg))} --json")
    res = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=ROOT, capture_output=True, timeout=600)
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    summary = __import__("json").loads(res.stdout)
    assert summary["segments"] > 0 and seg.exists()


def test_fit_report_and_replay_read_the_log_from_stdin(tmp_path, cli, monkeypatch):
    import io

    from conftest import hand_log
    from frictid.io.logs import write_logs

    log, params = tmp_path / "log.csv", tmp_path / "p.yaml"
    write_logs([hand_log(n=600)], str(log))
    data = log.read_bytes()

    def stdin():
        monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(data)))

    stdin()
    r = cli("fit", "-", "-o", params, "--models", "coulomb_viscous", "--no-diagnose")
    assert r.code == 0, r
    assert yaml.safe_load(params.read_text())["sources"][0]["path"] in ("-", "<stdin>")
    stdin()
    r = cli("report", params, "-", "-o", tmp_path / "r.html")
    assert r.code == 0 and (tmp_path / "r.html").stat().st_size > 10_000, r
    stdin()
    r = cli("simulate", "--params", params, "--replay", "-", "-o", "-")
    assert r.code == 0 and r.out.startswith('"t","joint"') and "tau_model" in r.out.split("\n", 1)[0], r


def test_simulate_to_stdout_is_only_csv(tmp_path):
    res = run_process(["simulate", "recipes/torque_steps.yaml", "-o", "-", "--format", "csv", "--quiet"])
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    head = res.stdout.split(b"\n", 1)[0].decode()
    assert head.replace('"', "").startswith("t,joint")
    assert res.stderr == b""  # --quiet: nothing on stderr


def _interrupt_during_fit(tmp_path, sig):
    """Start ``frictid fit``, send ``sig`` as soon as it says the fit has started, return what it did."""
    # two shipped sample logs (two joints, so the parallel path too): reading and fitting them take several
    # seconds after the fit says it started, far longer than the signal takes to arrive on a loaded machine
    # (a fit that finished first would make this test fail without any fault in frictid)
    logs = [str(ROOT / "sample_logs" / name) for name in ("hydraulic_sweep.csv", "linear_slide_multisine.csv")]
    out = tmp_path / "params.yaml"
    out.write_text("previous: result\n")
    proc = subprocess.Popen([sys.executable, "-m", "frictid", "fit", *logs, "-o", str(out)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=default_signals)
    first = b""
    while b"fitting" not in first:  # the fit has started: reading, segmenting and fitting take seconds
        line = proc.stderr.readline()
        assert line, "frictid fit ended before saying it started"
        first += line
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, (first + err).decode(), out, tmp_path


def test_sigterm_during_fit_keeps_the_previous_output(tmp_path):
    code, err, out, folder = _interrupt_during_fit(tmp_path, signal.SIGTERM)
    assert code != 0
    assert out.read_text() == "previous: result\n"
    assert not [p for p in folder.iterdir() if p.name.endswith(".tmp")], "no temporary file left behind"
    assert "Traceback" not in err and "terminated" in err


def test_ctrl_c_during_fit_keeps_the_previous_output(tmp_path):
    code, err, out, folder = _interrupt_during_fit(tmp_path, signal.SIGINT)
    assert code == 130
    assert out.read_text() == "previous: result\n"
    assert not [p for p in folder.iterdir() if p.name.endswith(".tmp")]
    assert "Traceback" not in err and "interrupted" in err
