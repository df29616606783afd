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

COMMANDS = ("segments", "fit")


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


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(sorted(CORRUPTIONS)), row=st.integers(5, 250),
       fmt=st.sampled_from(["csv", "parquet"]), command=st.sampled_from(COMMANDS))
def test_corrupted_logs_are_refused_cleanly(tmp_path_factory, cli, kind, row, fmt, command):
    tmp = tmp_path_factory.mktemp("bad")
    func, words = CORRUPTIONS[kind]
    df = func(valid_frame(), row)
    path = tmp / f"log.{fmt}"
    path.write_bytes(_csv(df) if fmt == "csv" else _parquet(df))
    out = tmp / ("out.yaml" if command == "fit" else "out.csv")
    res = cli(command, path, "-o", out)
    assert_clean_refusal(res, out, words + [str(path)])


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(frac=st.floats(0.0, 0.95), fmt=st.sampled_from(["csv", "parquet"]),
       junk=st.binary(min_size=0, max_size=64), command=st.sampled_from(COMMANDS))
def test_truncated_or_garbage_files_are_refused_cleanly(tmp_path_factory, cli, frac, fmt, junk, command):
    tmp = tmp_path_factory.mktemp("trunc")
    data = _csv(valid_frame()) if fmt == "csv" else _parquet(valid_frame())
    path = tmp / f"log.{fmt}"
    path.write_bytes(corrupt_truncate(data, frac) + junk if fmt == "parquet" else junk + corrupt_truncate(data, frac))
    out = tmp / ("out.yaml" if command == "fit" else "out.csv")
    res = cli(command, path, "-o", out)
    if res.code == 0:  # a CSV cut after a complete line, with harmless junk, can still be a valid log
        assert fmt == "csv" and out.exists()
        return
    assert_clean_refusal(res, out, [])


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("content, words", [
    (b"", ["empty"]),
    (b"t;q;tau\n0;1;2\n0.1;1;2\n", ["';'-separated"]),
    (b"t\tq\ttau\n0\t1\t2\n", ["'\\t'-separated"]),
])
def test_empty_and_wrong_delimiter(tmp_path, cli, command, content, words):
    path = tmp_path / "log.csv"
    path.write_bytes(content)
    out = tmp_path / ("out.yaml" if command == "fit" else "out.csv")
    assert_clean_refusal(cli(command, path, "-o", out), out, words)


def test_unknown_extra_columns_are_fine(tmp_path, cli):
    df = valid_frame().assign(motor_current=1.0, comment="ok")
    path = tmp_path / "log.csv"
    path.write_bytes(_csv(df))
    res = cli("segments", path, "-o", tmp_path / "seg.csv")
    assert res.code == 0, res


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
