"""Fleets: a simulated fleet fitted on a real distributed.LocalCluster (2 worker processes, started and
closed here) and serially, the trend store, re-runs, a bad partition, and the trend's verdicts.

The fleet: 2 robots x 2 joints x 12 days of ~15 s logs; one joint with planted wear, one with a
re-lubrication step, one whose ambient swings by +-8 K day to day (thermal4 law: friction follows it,
not wear) and one with nothing but noise. Seeds here are disjoint from benchmarks/fleet_scorecard.py's.
"""
from __future__ import annotations

import contextlib
import io
import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from distributed import LocalCluster

from conftest import ROOT
from fleet_synth import plan_fleet, write_fleet
from test_json import documented_keys
from frictid.cli import main
from frictid.fleet.store import TrendStore
from frictid.fleet.trend import SeriesTrend, explain, parse_limits, trend_fleet

DAYS = 12
SEED = 101
FIT = ["--models", "stribeck", "--no-diagnose"]


def run_cli(*args) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    plan = plan_fleet(2, 2, DAYS, seed=SEED, kinds=["wear", "step", "temperature", "noise"])
    write_fleet(root / "fleet", plan, DAYS, seed=SEED)
    bad = root / "fleet" / "robot=r02" / "joint=j2" / "date=2026-03-20"
    bad.mkdir(parents=True)
    (bad / "log.parquet").write_bytes(b"PAR1 this is not a parquet file")
    return root, plan


@pytest.fixture(scope="module")
def fitted(fleet):
    """The fleet fitted on a LocalCluster (twice: the second run must skip) and serially."""
    root, plan = fleet
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        first = run_cli("fit", root / "fleet", "--engine", "dask", "--scheduler", cluster.scheduler_address,
                        "-o", root / "store", *FIT)
        again = run_cli("fit", root / "fleet", "--engine", "dask", "--scheduler", cluster.scheduler_address,
                        "-o", root / "store", *FIT, "--json")
    serial = run_cli("fit", root / "fleet", "--engine", "serial", "-o", root / "serial", *FIT)
    return root, plan, first, again, serial


def test_bad_partition_is_reported_and_the_others_complete(fitted):
    root, plan, first, _, _ = fitted
    code, _, err = first
    assert code == 2, err[-2000:]
    assert re.search(r"robot=r02/joint=j2/date=2026-03-20: FAILED \(input\)", err)
    assert "1 of 49 partitions have bad input" in err
    df = TrendStore(root / "store").latest()
    assert df["partition"].nunique() == 49
    failed = df[df["status"] == "failed"]
    assert failed["partition"].tolist() == ["robot=r02/joint=j2/date=2026-03-20"]
    assert failed["error_kind"].tolist() == ["input"] and failed["reason"].iloc[0]
    assert len(list((root / "store" / "params").glob("*.yaml"))) == 48


def test_bad_usage_is_refused_before_any_work(fleet):
    root = fleet[0]
    code, _, err = run_cli("fit", root / "fleet", "--engine", "dask", "-o", root / "fleet" / "store")
    assert code == 2 and "inside the dataset" in err and not (root / "fleet" / "store").exists()
    code, _, err = run_cli("fit", root / "fleet", "--engine", "serial", "--scheduler", "tcp://x:1", "-o", root / "s")
    assert code == 2 and "--scheduler is for --engine dask" in err
    code, _, err = run_cli("trend", root / "nothing")
    assert code == 2 and "not a trend store" in err


def test_rerun_skips_unchanged_partitions(fitted):
    _, _, _, again, _ = fitted
    code, out, err = again
    doc = json.loads(out)
    assert set(doc) == documented_keys()["fit:dask"]
    assert code == 2 and doc["ok"] is False
    assert (doc["partitions"], doc["skipped"], doc["fitted"]) == (49, 48, 0)
    assert [f["partition"] for f in doc["failed"]] == ["robot=r02/joint=j2/date=2026-03-20"]


def test_cluster_gives_the_serial_numbers(fitted):
    root = fitted[0]
    cols = ["partition", "log_joint", "model", "param", "value", "stderr"]
    a = TrendStore(root / "store").latest().query("status == 'ok'")[cols].sort_values(cols[:4])
    b = TrendStore(root / "serial").latest().query("status == 'ok'")[cols].sort_values(cols[:4])
    assert len(a) > 4 * 48
    pd.testing.assert_frame_equal(a.reset_index(drop=True), b.reset_index(drop=True))


def test_store_is_one_table_for_pandas_and_its_files(fitted):
    root = fitted[0]
    parts = sorted((root / "store" / "table").glob("*.parquet"))
    df = pd.concat([pd.read_parquet(p) for p in parts])
    assert {"robot", "joint", "date", "value", "stderr", "temp_mean", "speed_hi", "model", "findings",
            "content_hash", "frictid_version"} <= set(df.columns)
    ok = df[df["status"] == "ok"]
    assert (ok["params_file"].map(lambda f: (root / "store" / f).is_file())).all()


def test_trend_finds_the_planted_changes_and_nothing_else(fitted):
    root, plan = fitted[:2]
    ft = trend_fleet(str(root / "store"))
    got = {j.joint: j for j in ft.joints}
    for p in plan:
        jt = got[f"robot={p.robot}/joint={p.joint}"]
        if p.kind in ("wear", "step"):
            assert jt.kind == p.kind, (p, jt.to_dict()["quantities"]["F_ref"]["scores"])
            assert abs(jt.level.dates.index(jt.level.date) - p.day) <= 2
            assert np.sign(jt.level.change) == np.sign(p.size)
        else:
            assert jt.kind == "steady", (p, jt.to_dict()["quantities"]["F_ref"]["scores"])
    temp = got["robot=r02/joint=j1"].level
    assert temp.normalised == "regression" and temp.temp_coeff < 0  # warmer: less friction (thermal4)
    assert ft.joints[0].kind in ("wear", "step")


def test_trend_cli_limits_json_and_page(fitted, tmp_path):
    root, plan = fitted[:2]
    page = tmp_path / "trend.html"
    code, out, err = run_cli("trend", root / "store", "--limit", "F_ref=+10%", "--report", page, "--json")
    doc = json.loads(out)
    assert set(doc) == documented_keys()["trend"]
    wear = next(p for p in plan if p.kind == "wear")
    assert code == 3, err
    assert [c["joint"] for j in doc["joints"] for c in [dict(x, joint=j["joint"]) for x in j["crossings"]]] \
        == [f"robot={wear.robot}/joint={wear.joint}"]
    assert doc["summary"]["failed_partitions"] == 1
    text = page.read_text()
    assert text.count("<svg") == 4 and "Fleet overview" in text and "http" not in text.split("<svg")[0]
    code, out, _ = run_cli("trend", root / "store", "--limit", "F_ref=-10%", "--json")
    step = next(p for p in plan if p.kind == "step")
    assert code == 3 and [j["joint"] for j in json.loads(out)["joints"] if j["crossings"]] \
        == [f"robot={step.robot}/joint={step.joint}"]
    code, _, _ = run_cli("trend", root / "store", "--limit", "F_ref=50%", "--quiet")
    assert code == 0


def series(y, stderr=None, temp=None) -> SeriesTrend:
    n = len(y)
    return SeriesTrend("Fc", "N m", [f"d{i}" for i in range(n)], np.asarray(y, float),
                       np.full(n, np.nan) if stderr is None else np.asarray(stderr, float),
                       np.full(n, 20.0) if temp is None else np.asarray(temp, float))


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_explain_by_hand(seed):
    rng = np.random.default_rng(seed)
    noise = 0.1 * rng.standard_normal(30)
    step = np.where(np.arange(30) >= 17, 9.0, 10.0) + noise
    s = explain(series(step))
    assert (s.kind, s.index) == ("step", 17) and s.change == pytest.approx(-1.0, abs=0.15)
    wear = 10.0 + 0.08 * np.maximum(np.arange(30) - 12, 0) + noise
    s = explain(series(wear))
    assert s.kind == "wear" and abs(s.index - 12) <= 2
    # the competing explanation: a temperature swing with the same size as the step, not a change
    temp = 20 + 8 * rng.standard_normal(30)
    warm = 10.0 - 0.12 * (temp - 20) + noise
    s = explain(series(warm, temp=temp))
    assert s.kind == "steady" and s.normalised == "regression" and s.temp_coeff == pytest.approx(-0.12, abs=0.03)
    assert explain(series(10.0 + noise)).kind == "steady"


def test_parse_limits():
    lim = parse_limits("Fc=+20%,F_ref=15%,sigma2=-0.5")
    assert [(x.name, x.value, x.relative, x.sign) for x in lim] == [("Fc", 0.2, True, 1), ("F_ref", 0.15, True, 0),
                                                                    ("sigma2", 0.5, False, -1)]
    assert lim[0].covers("Fc_pos") and lim[0].crossed(10.0, 12.5) == pytest.approx(0.25)
    assert lim[0].crossed(10.0, 7.0) is None and lim[1].crossed(10.0, 8.0) == pytest.approx(-0.2)
    with pytest.raises(ValueError, match="--limit"):
        parse_limits("Fc=lots")


#: The sizes the documented commands run with here (the page shows the full sizes).
SMALL = {"--robots 20": "--robots 1", "--joints 6": "--joints 2", "--days 30": "--days 8",
         "--partitions 8": "--partitions 2", "--seconds 60": "--seconds 10"}


def doc_commands() -> list[str]:
    text = (ROOT / "docs" / "fleet.md").read_text()
    return [ln.strip() for block in re.findall(r"```bash\n(.*?)```", text, re.S)
            for ln in block.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]


def test_every_command_in_docs_fleet_runs(tmp_path):
    cmds = doc_commands()
    assert len(cmds) >= 8 and any("--scheduler" in c for c in cmds)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        for cmd in cmds:
            for a, b in SMALL.items():
                cmd = cmd.replace(a, b)
            cmd = cmd.replace("tcp://127.0.0.1:8786", cluster.scheduler_address)
            argv = shlex.split(cmd)
            if argv[0] == "python":
                argv = [sys.executable, str(ROOT / argv[1]), *argv[2:]]
            else:
                assert argv[0] == "frictid", cmd
                argv = [sys.executable, "-m", "frictid", *argv[1:]]
            p = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=900)
            allowed = {0, 3} if "--limit" in cmd else {0, 1} if "scorecard" in cmd else {0}
            assert p.returncode in allowed and "Traceback" not in p.stderr, (cmd, p.returncode, p.stderr[-3000:])
            if "scorecard" in cmd:
                assert "false alarms:" in p.stdout
    assert (tmp_path / "demo" / "trend.html").read_text().count("<svg") == 4


def test_store_reads_in_duckdb(fitted):
    duckdb = pytest.importorskip("duckdb")  # not a dependency of frictid: the store is plain Parquet
    root = fitted[0]
    glob = str(root / "store" / "table" / "*.parquet")
    n = duckdb.sql(f"SELECT count(DISTINCT partition) FROM read_parquet('{glob}', union_by_name=true)").fetchall()[0][0]
    rows = duckdb.sql(f"SELECT robot, joint, count(*) FROM read_parquet('{glob}', union_by_name=true) "
                      "WHERE param = 'Fc' AND status = 'ok' GROUP BY robot, joint").fetchall()
    df = TrendStore(root / "store").latest().query("param == 'Fc' and status == 'ok'")
    assert n == 49 and dict(((r, j), c) for r, j, c in rows) == df.groupby(["robot", "joint"]).size().to_dict()
    assert sum(c for *_, c in rows) == 48
