"""Bad input: exit code 2, one message naming the problem, no traceback, no output file.

Property-based: hypothesis corrupts valid CSV and Parquet logs in many ways and every command that reads
logs must refuse each corrupted file cleanly. Unknown extra columns are not an error.
"""
from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import hand_log

#: Every command line that reads a log: (name, arguments before the log, output suffix).
COMMANDS = {
    "segments": (["segments"], "csv"),
    "fit": (["fit"], "yaml"),
    "report": (["report", "{params}"], "html"),
    "replay": (["simulate", "--params", "{params}", "--replay"], "csv"),
}


@pytest.fixture(scope="session")
def params_file(tmp_path_factory):
    """A parameter file of the valid log (report and replay need one beside the log)."""
    from frictid import fit
    from frictid.io.params import write_params

    tmp = tmp_path_factory.mktemp("params")
    src = tmp / "valid.csv"
    src.write_bytes(_csv(valid_frame()))
    out = tmp / "params.yaml"
    write_params(fit([str(src)], models="coulomb_viscous,polynomial", diagnose=False), out)
    return out


def run_on(cli, command, log, out, params):
    pre, _ = COMMANDS[command]
    return cli(*[a.format(params=params) for a in pre], log, "-o", out)


def out_path(tmp, command):
    return tmp / f"out.{COMMANDS[command][1]}"


def valid_frame(n=300) -> pd.DataFrame:
    lg = hand_log(n=n)
    return pd.DataFrame({"t": lg.t, "q": lg.q, "qd": lg.qd, "tau": lg.tau})


def _csv(df: pd.DataFrame) -> bytes:
    return df.to_csv(index=False).encode()


def _parquet(df: pd.DataFrame) -> bytes:
    buf = io.BytesIO()
    df.to_parquet(buf, index=False)
    return buf.getvalue()


# Each corruption: (name, function(df, draw) -> bytes-for-csv-or-None, words the message must contain)
def corrupt_truncate(data: bytes, frac: float) -> bytes:
    return data[: max(1, int(len(data) * frac))]


CORRUPTIONS = {
    "nan_many": (lambda df, i: df.assign(tau=df.tau.where(df.index % 7 != i % 7, np.nan)), ["missing values"]),
    "inf": (lambda df, i: df.assign(q=df.q.where(df.index != i, np.inf)), ["'q'", f"infinite"]),
    "huge": (lambda df, i: df.assign(tau=df.tau.where(df.index != i, 1e300)), ["'tau'", "implausibly large"]),
    "duplicated_time": (lambda df, i: df.assign(t=df.t.where(df.index != i + 1, df.t[i])), ["'t'", "repeats"]),
    "reversed_time": (lambda df, i: df.iloc[::-1].reset_index(drop=True), ["'t'", "goes back"]),
    "swapped_columns": (lambda df, i: df.rename(columns={"t": "tau", "tau": "t"}), ["'t'"]),
    "degrees": (lambda df, i: df.assign(q=np.degrees(df.q) * 50, qd=df.qd * 50), ["degrees"]),
    "missing_tau": (lambda df, i: df.drop(columns=["tau"]), ["'tau'", "missing"]),
    "missing_t": (lambda df, i: df.drop(columns=["t"]), ["'t'", "missing"]),
    "text_value": (lambda df, i: df.assign(tau=df.tau.map(repr).where(df.index != i, "n/a?")),
                   ["'tau'", "n/a?"]),
    "few_rows": (lambda df, i: df.head(i % 9 + 1), ["samples"]),
}


def assert_clean_refusal(res, out_path, words):
    assert res.code == 2, res
    assert "Traceback" not in res.err
    assert res.err.strip(), "an error message on stderr"
    for w in words:
        assert w in res.err, (w, res.err)
    assert not out_path.exists(), "no output file on bad input"


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("kind", sorted(CORRUPTIONS))
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(row=st.integers(5, 250))
def test_corrupted_logs_are_refused_cleanly(tmp_path_factory, cli, params_file, kind, fmt, command, row):
    """Every listed corruption, in both formats, for every command that reads logs."""
    tmp = tmp_path_factory.mktemp("bad")
    func, words = CORRUPTIONS[kind]
    df = func(valid_frame(), row)
    path = tmp / f"log.{fmt}"
    path.write_bytes(_csv(df) if fmt == "csv" else _parquet(df))
    out = out_path(tmp, command)
    res = run_on(cli, command, path, out, params_file)
    assert_clean_refusal(res, out, words + [str(path)])


@pytest.mark.parametrize("command", sorted(COMMANDS))
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(frac=st.floats(0.0, 0.95), fmt=st.sampled_from(["csv", "parquet"]), junk=st.binary(min_size=0, max_size=64))
def test_truncated_or_garbage_files_are_refused_cleanly(tmp_path_factory, cli, params_file, command, frac, fmt,
                                                        junk):
    tmp = tmp_path_factory.mktemp("trunc")
    data = _csv(valid_frame()) if fmt == "csv" else _parquet(valid_frame())
    path = tmp / f"log.{fmt}"
    path.write_bytes(corrupt_truncate(data, frac) + junk if fmt == "parquet" else junk + corrupt_truncate(data, frac))
    out = out_path(tmp, command)
    res = run_on(cli, command, path, out, params_file)
    if res.code == 0:  # a CSV cut after a complete line, with harmless junk, can still be a valid log
        assert fmt == "csv" and out.exists()
        return
    assert_clean_refusal(res, out, [str(path)])


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("suffix", ["csv", "parquet"])
@settings(max_examples=3, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(min_size=1, max_size=2048))
def test_binary_garbage_is_refused_cleanly(tmp_path_factory, cli, params_file, command, suffix, data):
    tmp = tmp_path_factory.mktemp("garbage")
    path = tmp / f"log.{suffix}"
    path.write_bytes(b"\x00\xff" + data)  # never a valid log: a NUL byte in the first line
    out = out_path(tmp, command)
    assert_clean_refusal(run_on(cli, command, path, out, params_file), out, [str(path)])


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("content, words", [
    (b"", ["empty"]),
    (b"t;q;tau\n0;1;2\n0.1;1;2\n", ["';'-separated"]),
    (b"t\tq\ttau\n0\t1\t2\n", ["'\\t'-separated"]),
])
def test_empty_and_wrong_delimiter(tmp_path, cli, params_file, command, content, words):
    path = tmp_path / "log.csv"
    path.write_bytes(content)
    out = out_path(tmp_path, command)
    assert_clean_refusal(run_on(cli, command, path, out, params_file), out, words)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_unknown_extra_columns_are_fine(tmp_path, cli, params_file, command):
    df = valid_frame().assign(motor_current=1.0, comment="ok")
    path = tmp_path / "log.csv"
    path.write_bytes(_csv(df))
    out = out_path(tmp_path, command)
    res = run_on(cli, command, path, out, params_file)
    assert res.code == 0, res
    assert out.exists() and "Traceback" not in res.err


def test_missing_file_and_output_over_input(tmp_path, cli):
    out = tmp_path / "out.csv"
    res = cli("segments", tmp_path / "nope.csv", "-o", out)
    assert_clean_refusal(res, out, ["nope.csv", "not found"])
    path = tmp_path / "log.csv"
    path.write_bytes(_csv(valid_frame()))
    before = path.read_bytes()
    res = cli("segments", path, "-o", path)
    assert res.code == 2 and "never overwrites an input" in res.err
    assert path.read_bytes() == before


def test_output_equal_to_an_input_is_refused(tmp_path, cli, params_file, monkeypatch):
    """`-o` naming any input (log, parameter file, recipe, plant, --map file, a log's sidecar) is exit 2,
    for every command, and the input is unchanged."""
    import shutil

    from conftest import ROOT

    log = tmp_path / "log.csv"
    log.write_bytes(_csv(valid_frame()))
    side = tmp_path / "log.csv.meta.yaml"
    side.write_text("axis: rotary\n")
    params = tmp_path / "params.yaml"
    shutil.copy(params_file, params)
    mapping = tmp_path / "map.yaml"
    mapping.write_text("map: {}\n")
    recipe, plant = tmp_path / "recipe.yaml", tmp_path / "plant.yaml"
    shutil.copy(ROOT / "recipes/torque_steps.yaml", recipe)
    shutil.copy(ROOT / "recipes/plants/hydraulic.yaml", plant)
    cases = [
        ["segments", log, "-o", log],
        ["segments", log, "-o", side, "--format", "csv"],
        ["segments", log, "-o", mapping, "--format", "csv", "--map", mapping],
        ["fit", log, "-o", log],
        ["fit", log, "-o", side],
        ["fit", log, "-o", mapping, "--map", mapping],
        ["fit", log, "-o", tmp_path / "p.yaml", "--report", log],
        ["report", params, log, "-o", params],
        ["report", params, log, "-o", log],
        ["simulate", recipe, "-o", recipe, "--format", "csv"],
        ["simulate", recipe, "--plant", plant, "-o", plant, "--format", "csv"],
        ["simulate", "--params", params, "--replay", log, "-o", log],
        ["simulate", "--params", params, "--replay", log, "-o", params, "--format", "csv"],
    ]
    before = {p: p.read_bytes() for p in (log, side, params, mapping, recipe, plant)}
    for args in cases:
        res = cli(*args)
        assert res.code == 2 and "never overwrites an input" in res.err and "Traceback" not in res.err, (args, res)
    assert {p: p.read_bytes() for p in before} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in before)
    # by name: a recipe given as "mine" is the file recipes/mine.yaml of the working folder
    monkeypatch.chdir(tmp_path)
    (tmp_path / "recipes").mkdir()
    shutil.copy(recipe, tmp_path / "recipes" / "mine.yaml")
    res = cli("simulate", "mine", "-o", "recipes/mine.yaml", "--format", "csv")
    assert res.code == 2 and "never overwrites an input" in res.err
    assert (tmp_path / "recipes" / "mine.yaml").read_bytes() == before[recipe]


def test_unexpected_errors_are_exit_1_and_debug_shows_the_traceback(tmp_path, cli, monkeypatch):
    """A bug is exit code 1 with one message saying so; --debug (anywhere) adds the traceback; --json gets
    the error document."""
    import json

    import frictid.segments as seg

    def broken(log):
        raise RuntimeError("segmenter exploded")

    monkeypatch.setattr(seg, "find_segments", broken)
    path = tmp_path / "log.csv"
    path.write_bytes(_csv(valid_frame()))
    out = tmp_path / "seg.csv"
    res = cli("segments", path, "-o", out)
    assert res.code == 1 and "internal error" in res.err and "segmenter exploded" in res.err
    assert "Traceback" not in res.err and "--debug" in res.err and not out.exists()
    res = cli("--debug", "segments", path, "-o", out)
    assert res.code == 1 and "Traceback" in res.err and not out.exists()
    res = cli("segments", path, "-o", out, "--json")
    doc = json.loads(res.out)
    assert res.code == 1 and doc["ok"] is False and doc["exit_code"] == 1 and "segmenter exploded" in doc["error"]
