"""`--json` on every command: one valid JSON document on stdout and nothing else, human text on stderr,
the documented keys (docs/cli.md), an error document on failure, and `--json` refused with `-o -`."""
from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from conftest import ROOT, run_process
from test_poor_data import DT, FC, J, NOISE, SIGMA2, velocity_profile

SPEEDS = [0.2, -0.2, 0.4, -0.4, 0.7, -0.7, 1.0, -1.0, 1.5, -1.5, 2.0, -2.0]


def documented_keys() -> dict[str, set[str]]:
    """The top-level keys of each command's document, from the table in docs/cli.md."""
    doc = (ROOT / "docs" / "cli.md").read_text()
    rows = re.findall(r"^\| `(\w+)`(?: \(([\w ]+)\))? \| (`[^|]+`) \|", doc, re.M)
    out = {}
    for cmd, mode, keys in rows:
        out[cmd + (f":{mode}" if mode else "")] = set(re.findall(r"`(\w+)`", keys))
    return out


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A small plateau log with a dropped-row warning, and its parameter file."""
    from frictid import fit
    from frictid.io.params import write_params

    tmp = tmp_path_factory.mktemp("json")
    rng = np.random.default_rng(1)
    t, w = velocity_profile(SPEEDS, hold=0.6, rest=0.3)
    q = np.round((0.3 + np.cumsum(w) * DT) / 1e-5) * 1e-5
    tau = FC * np.sign(w) + SIGMA2 * w + J * np.gradient(w, DT) + NOISE * rng.standard_normal(t.size)
    tau[100] = np.nan  # one missing value: dropped with a warning
    log = tmp / "log.csv"
    pd.DataFrame({"t": t, "q": q, "tau": tau}).to_csv(log, index=False)
    params = tmp / "params.yaml"
    write_params(fit([str(log)], models="coulomb_viscous,stribeck", diagnose=False), params)
    return {"dir": tmp, "log": log, "params": params}


def run_json(cli, *args):
    res = cli(*args, "--json")
    doc = json.loads(res.out)  # the whole of stdout is one JSON document
    assert res.out.strip().startswith("{") and res.out.strip().endswith("}")
    assert "Traceback" not in res.err
    return res, doc


def check_shape(doc, command, key):
    assert doc["schema"] == 1 and doc["command"] == command
    assert set(doc) == documented_keys()[key], (set(doc) ^ documented_keys()[key])


def test_every_command_has_a_documented_shape():
    keys = documented_keys()
    for cmd in ("simulate:recipe", "simulate:replay", "segments", "fit", "report", "compare", "error"):
        assert cmd in keys, cmd
        assert {"schema", "command", "ok", "warnings"} <= keys[cmd], cmd


def test_simulate(cli, tmp_path):
    out = tmp_path / "sim.csv"
    res, doc = run_json(cli, "simulate", "torque_steps", "-o", out, "--seed", "2")
    check_shape(doc, "simulate", "simulate:recipe")
    assert doc["ok"] and doc["output"] == str(out) and doc["rows"] == len(pd.read_csv(out))
    assert "wrote" in res.err  # the human message goes to stderr


def test_segments_and_its_warnings(cli, files, tmp_path):
    for suffix in ("csv", "parquet", "json"):
        out = tmp_path / f"seg.{suffix}"
        res, doc = run_json(cli, "segments", files["log"], "-o", out)
        check_shape(doc, "segments", "segments")
        assert doc["segments"] == sum(j["segments"] for j in doc["joints"].values()) > 0
        assert any("dropped 1 rows" in w for w in doc["warnings"]) and "dropped 1 rows" in res.err
        from frictid.io.segtable import read_segments_meta
        meta = read_segments_meta(str(out))  # the warnings are kept with the table, whatever its format
        assert meta["warnings"] == doc["warnings"] and meta["sources"] == [str(files["log"])]


def test_fit(cli, files, tmp_path):
    out = tmp_path / "p.yaml"
    res, doc = run_json(cli, "fit", files["log"], "-o", out, "--models", "coulomb_viscous,stribeck")
    check_shape(doc, "fit", "fit")
    (j,) = doc["joints"].values()
    assert set(j) == documented_keys()["joint"]
    assert j["selected"] in ("coulomb_viscous", "stribeck")
    p = j["params"]["Fc"]
    assert p["identifiable"] and abs(p["value"] - FC) < 5 * p["stderr"] + 0.05 * FC
    assert any("dropped 1 rows" in w for w in j["warnings"])
    assert any("dropped 1 rows" in w for w in doc["warnings"])
    assert "wrote" in res.err


def test_report_keeps_the_log_warnings(cli, files, tmp_path):
    out, log2 = tmp_path / "r.html", tmp_path / "log2.csv"
    df = pd.read_csv(files["log"])
    df.loc[300, "tau"] = np.nan  # a warning the parameter file does not have
    df.to_csv(log2, index=False)
    res, doc = run_json(cli, "report", files["params"], log2, "-o", out)
    check_shape(doc, "report", "report")
    assert doc["bytes"] == out.stat().st_size and set(doc["joints"]) == {"1"}
    assert any("dropped 2 rows" in w for w in doc["warnings"])
    assert "dropped 2 rows" in out.read_text()  # in the report, not only on stderr


def test_replay(cli, files, tmp_path):
    out = tmp_path / "rep.parquet"
    _, doc = run_json(cli, "simulate", "--params", files["params"], "--replay", files["log"], "-o", out)
    check_shape(doc, "simulate", "simulate:replay")
    assert doc["joints"]["1"]["rms_residual"] > 0 and any("dropped 1 rows" in w for w in doc["warnings"])
    import pyarrow.parquet as pq
    meta = json.loads(pq.read_schema(out).metadata[b"frictid"])
    assert any("dropped 1 rows" in w for w in meta["replay"]["warnings"])


def test_compare_gate_prints_one_document(cli, files):
    res, doc = run_json(cli, "compare", files["params"], files["params"], "--tol", "*=1%")
    check_shape(doc, "compare", "compare")
    assert res.code == 0 and doc["ok"] and doc["failed"] == 0 and doc["changes"]


@pytest.mark.parametrize("args", [
    ("simulate", "torque_steps", "-o", "-"),
    ("segments", "{log}", "-o", "-"),
    ("fit", "{log}", "-o", "-"),
    ("report", "{params}", "-o", "-"),
    ("simulate", "--params", "{params}", "--replay", "{log}", "-o", "-"),
])
def test_json_is_refused_when_data_go_to_stdout(cli, files, args):
    args = [a.format(**files) for a in args]
    res, doc = run_json(cli, *args)
    assert res.code == 2 and "--json" in res.err
    check_shape(doc, args[0], "error")
    assert doc["ok"] is False and doc["exit_code"] == 2 and "--json" in doc["error"]


def test_errors_give_an_error_document(cli, files, tmp_path):
    res, doc = run_json(cli, "fit", tmp_path / "missing.csv", "-o", tmp_path / "p.yaml")
    assert res.code == 2 and doc["exit_code"] == 2 and "missing.csv" in doc["error"]
    check_shape(doc, "fit", "error")
    res, doc = run_json(cli, "segments", files["log"], "-o", tmp_path / "s.csv", "--bogus")
    assert res.code == 2 and doc["exit_code"] == 2 and "--bogus" in doc["error"]


def test_real_process_stdout_is_only_json(files, tmp_path, cli):
    res = run_process(["segments", files["log"], "-o", tmp_path / "s.csv", "--json"])
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    json.loads(res.stdout)
    assert b"segments" in res.stderr
    res, doc = run_json(cli, "segments", files["log"], "-o", tmp_path / "s2.csv", "--quiet")
    assert res.code == 0 and res.err == "" and doc["ok"]  # --quiet: nothing on stderr, the JSON still out
