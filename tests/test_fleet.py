"""Fleets: a simulated fleet fitted on a real distributed.LocalCluster (2 worker processes, started and
closed here, in a child process) and serially, the trend store, re-runs, a bad partition, and the trend's verdicts.

The fleet: 2 robots x 2 joints x 12 days of ~15 s logs; one joint with planted wear, one with a
re-lubrication step, one whose ambient swings by +-8 K day to day (thermal4 law: friction follows it,
not wear) and one with nothing but noise. Seeds here are disjoint from benchmarks/fleet_scorecard.py's.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import re
import shlex
import subprocess
import sys
import threading

import numpy as np
import pandas as pd
import pytest

from conftest import ROOT
from fleet_synth import plan_fleet, write_fleet
from test_json import documented_keys
from frictid.cli import main
from frictid.fleet.store import TrendStore
from frictid.fleet.dataset import find_partitions, parse_keys
from frictid.fleet.level import level, level_with_stderr, param_covariance
from frictid.fleet.trend import SeriesTrend, explain, parse_limits, trend_fleet
from frictid.result import JointFit, ModelFit, ParamEstimate

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


def run_cli_process(*args) -> tuple[int, str, str]:
    """``frictid ARGS`` in a child process: a dask client leaves a thread behind in the process that ran it
    (distributed's offload thread), and a process with other threads never forks workers
    (:func:`frictid.parallel.map_ordered`), which tests/test_fit_parallel.py checks in the same worker."""
    p = subprocess.run([sys.executable, "-m", "frictid", *map(str, args)], capture_output=True, text=True,
                       timeout=900)
    return p.returncode, p.stdout, p.stderr


@contextlib.contextmanager
def local_cluster():
    """The address of a distributed.LocalCluster (2 worker processes) run by a child process, closed on exit."""
    code = ("import sys\nfrom distributed import LocalCluster\n"
            "with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=':0') as c:\n"
            "    print(c.scheduler_address, flush=True)\n    sys.stdin.read()\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        address = proc.stdout.readline().strip()
        assert address.startswith("tcp://"), f"the cluster did not start: {address!r}"
        yield address
    finally:
        proc.stdin.close()
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:  # pragma: no cover - a cluster that does not close
            proc.kill()


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
    threads = threading.active_count()
    with local_cluster() as address:
        first = run_cli_process("fit", root / "fleet", "--engine", "dask", "--scheduler", address,
                                "-o", root / "store", *FIT)
        again = run_cli_process("fit", root / "fleet", "--engine", "dask", "--scheduler", address,
                                "-o", root / "store", *FIT, "--json")
    serial = run_cli("fit", root / "fleet", "--engine", "serial", "-o", root / "serial", *FIT)
    assert threading.active_count() == threads, "a fleet fit left a thread behind in the test process"
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


def planted_series(kind: str, rng, n: int = 30) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """A level of 10 with noise 0.1 and the changes of ``kind`` at random days (sizes 8..15 sigma)."""
    x = np.arange(n)
    d1 = int(rng.integers(5, 12))
    d2 = int(rng.integers(d1 + 7, n - 3))
    a, b = rng.uniform(0.8, 1.5, 2) * rng.choice([-1, 1], 2)
    y = 10.0 + 0.1 * rng.standard_normal(n)
    if kind == "wear_step":  # wear from d1, a repair at d2 takes it away
        return y + abs(a) / (d2 - 1 - d1) * np.clip(x - d1, 0, None) * (x < d2), [("wear", d1), ("step", d2)]
    if kind == "two_steps":
        return y + a * (x >= d1) + b * (x >= d2), [("step", d1), ("step", d2)]
    if kind == "recovery":  # a fault, then maintenance brings the level back
        return y + abs(a) * ((x >= d1) & (x < d2)), [("step", d1), ("step", d2)]
    return y, []


@pytest.mark.parametrize("kind", ["wear_step", "two_steps", "recovery", "noise"])
def test_more_than_one_change_each_dated_and_classified(kind):
    hits, total = 0, 0
    for seed in range(20):
        y, want = planted_series(kind, np.random.default_rng([seed, len(kind)]))
        got = [(c["kind"], c["index"]) for c in explain(series(y)).changes]
        ok = len(got) == len(want) and all(g[0] == w[0] and abs(g[1] - w[1]) <= 2 for g, w in zip(got, want))
        hits += ok
        total += 1
    assert hits >= 18, (kind, hits)  # chance fits of noise: the penalty keeps them rare, not impossible


def test_no_change_on_temperature_only_variation():
    """The competing explanation: the ambient swings by +-8 K and friction follows it (thermal4 sign),
    including two warm weeks that look like a fault and its repair."""
    alarms = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        temp = 20 + 8 * rng.standard_normal(30) + 6.0 * ((np.arange(30) >= 9) & (np.arange(30) < 20))
        y = 10.0 - 0.12 * (temp - 20) + 0.1 * rng.standard_normal(30)
        alarms += bool(explain(series(y, temp=temp)).changes)
    assert alarms <= 1


def test_a_change_must_stand_clear_of_the_runs_own_uncertainty():
    rng = np.random.default_rng(7)
    y = 10.0 + 0.01 * rng.standard_normal(30) + 0.3 * (np.arange(30) >= 15)
    assert [c["kind"] for c in explain(series(y)).changes] == ["step"]  # 30 scatter-sigma: a step
    s = explain(series(y, stderr=np.full(30, 0.5)))  # each run known to +-0.5 only: not a change
    assert s.kind == "steady" and s.sigma >= 0.5


def hand_joint(cov: np.ndarray) -> JointFit:
    se = np.sqrt(np.diag(cov))
    params = {"Fc": ParamEstimate("Fc", 12.0, float(se[0]), "N m"),
              "sigma2": ParamEstimate("sigma2", 4.0, float(se[1]), "N m s/rad")}
    mf = ModelFit("coulomb_viscous", "coulomb_viscous", params, cov=cov)
    return JointFit("j1", models={"coulomb_viscous": mf}, selected="coulomb_viscous")


def test_level_stderr_by_hand_and_by_sampling():
    cov = np.array([[0.04, -0.006], [-0.006, 0.0025]])
    jf = hand_joint(cov)
    nc = param_covariance(jf.models["coulomb_viscous"])
    assert nc[0] == ["Fc", "sigma2"]
    lv = level_with_stderr(jf, "coulomb_viscous", 0.5, None, nc)
    # F_ref = Fc + sigma2 w: var = C_FcFc + w^2 C_ss + 2 w C_Fcs
    assert lv["value"] == pytest.approx(12.0 + 4.0 * 0.5)
    assert lv["stderr"] == pytest.approx(math.sqrt(0.04 + 0.25 * 0.0025 - 2 * 0.5 * 0.006), rel=1e-6)
    draws = np.random.default_rng(5).multivariate_normal([12.0, 4.0], cov, 4000)
    sampled = [level(hand_joint_at(cov, *d), "coulomb_viscous", 0.5, None)[0] for d in draws[:400]]
    assert np.std(sampled) == pytest.approx(lv["stderr"], rel=0.1)
    # standard errors wider than the covariance's (the fit widens some): the correlation is kept, the
    # diagonal follows the standard errors
    jf.models["coulomb_viscous"].params["Fc"].stderr = 0.3
    names, c2 = param_covariance(jf.models["coulomb_viscous"])
    cov0 = np.asarray(jf.models["coulomb_viscous"].cov, float)
    assert c2[0, 0] == pytest.approx(0.09) and c2[1, 1] == pytest.approx(cov0[1, 1])
    assert c2[0, 1] / np.sqrt(c2[0, 0] * c2[1, 1]) == pytest.approx(cov0[0, 1] / np.sqrt(cov0[0, 0] * cov0[1, 1]))


def hand_joint_at(cov, Fc, sigma2) -> JointFit:
    jf = hand_joint(cov)
    jf.models["coulomb_viscous"].params["Fc"].value = Fc
    jf.models["coulomb_viscous"].params["sigma2"].value = sigma2
    return jf


def test_store_holds_each_runs_level_and_its_stderr(fitted):
    root = fitted[0]
    runs = TrendStore(root / "store").latest().query("status == 'ok'").drop_duplicates("partition")
    assert runs["F_ref_stderr"].gt(0).all() and np.isfinite(runs["F_ref"]).all()
    assert (runs["F_ref_stderr"] < 0.02 * runs["F_ref"]).all() and (runs["cov"].str.len() > 10).all()
    ft = trend_fleet(str(root / "store"))
    assert all(np.isfinite(j.level.stderr).all() for j in ft.joints)


def test_keys_name_the_joint_and_order_the_runs(fitted, tmp_path):
    root = fitted[0]
    code, out, err = run_cli("trend", root / "store", "--keys", "robot:date", "--json")
    assert code == 0, err
    a = {j["joint"].split("#")[0].replace("robot=", "") + "/" + j["joint"].split("#")[1]: j["kind"]
         for j in json.loads(out)["joints"]}
    b = {j.joint.replace("robot=", "").replace("joint=", ""): j.kind for j in trend_fleet(str(root / "store")).joints}
    assert a == b
    for bad, msg in [("robot,joint", "after a colon"), ("robot,joint:hour", "has no key 'hour'"),
                     ("joint:joint", "named twice"), ("robot:joint", "more than one run at joint=")]:
        code, out, err = run_cli("trend", root / "store", "--keys", bad)
        assert code == 2 and msg in err and "Traceback" not in err and err.count("error") == 1, (bad, err)
    code, _, err = run_cli("fit", root / "fleet", "--engine", "serial", "--keys", "robot,site:date", "-o", tmp_path / "s")
    assert code == 2 and "has no key 'site'" in err and not (tmp_path / "s").exists()
    # the runs of a joint split into hours: one partition per robot, joint and date, its hours fitted together
    src = next((root / "fleet").glob("robot=r01/joint=j1/date=*/log.parquet"))
    hours = tmp_path / "ds" / "robot=r01" / "joint=j1" / src.parent.name
    for h in ("hour=08", "hour=14"):
        (hours / h).mkdir(parents=True)
        (hours / h / "log.parquet").write_bytes(src.read_bytes())
    parts = find_partitions([str(tmp_path / "ds")], parse_keys("robot,joint:date"))
    assert [p.id for p in parts] == [f"robot=r01/joint=j1/{src.parent.name}"] and len(parts[0].files) == 2
    assert len(find_partitions([str(tmp_path / "ds")])) == 2


def test_parse_limits():
    lim = parse_limits("Fc=+20%,F_ref=15%,sigma2=-0.5")
    assert [(x.name, x.value, x.relative, x.sign) for x in lim] == [("Fc", 0.2, True, 1), ("F_ref", 0.15, True, 0),
                                                                    ("sigma2", 0.5, False, -1)]
    assert lim[0].covers("Fc_pos") and lim[0].crossed(10.0, 12.5) == pytest.approx(0.25)
    assert lim[0].crossed(10.0, 7.0) is None and lim[1].crossed(10.0, 8.0) == pytest.approx(-0.2)
    with pytest.raises(ValueError, match="--limit"):
        parse_limits("Fc=lots")


#: The sizes the documented commands run with here (the page shows the full sizes).
SMALL = {"--robots 6": "--robots 1", "--robots 2": "--robots 1", "--joints 6": "--joints 2", "--days 30": "--days 8",
         "--days 12": "--days 6",
         "--partitions 8": "--partitions 2", "--seconds 60": "--seconds 10"}


def doc_commands() -> list[str]:
    text = (ROOT / "docs" / "fleet.md").read_text()
    return [ln.strip() for block in re.findall(r"```bash\n(.*?)```", text, re.S)
            for ln in block.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]


def test_every_command_in_docs_fleet_runs(tmp_path):
    cmds = doc_commands()
    assert len(cmds) >= 8 and any("--scheduler" in c for c in cmds)
    with local_cluster() as address:
        for cmd in cmds:
            for a, b in SMALL.items():
                cmd = cmd.replace(a, b)
            cmd = cmd.replace("tcp://127.0.0.1:8786", address)
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
    assert (tmp_path / "demo" / "trend.html").read_text().count("<svg") == 2  # 1 robot x 2 joints


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
