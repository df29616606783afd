"""The joint-log format: round trips, mapping and units, and validation at the door."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from conftest import hand_log
from frictid.errors import FrictidInputError, LogFormatError
from frictid.io.logs import read_logs, write_logs


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_round_trip_keeps_values_joints_and_truth(tmp_path, suffix):
    logs = [hand_log(joint="1"), hand_log(joint="elbow", seed=1)]
    logs[1].axis = "linear"
    logs[0].truth = {"segment": np.array(["rest"] * logs[0].n), "cycle": np.full(logs[0].n, -1),
                     "params": {"J": 0.7}}
    path = tmp_path / f"log{suffix}"
    write_logs(logs, str(path))
    back = read_logs(str(path))
    assert [b.joint for b in back] == ["1", "elbow"]
    for a, b in zip(logs, back):
        for name in ("t", "q", "qd", "tau"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        np.testing.assert_array_equal(a.channels["temp_env"], b.channels["temp_env"])
    assert back[0].truth["params"] == {"J": 0.7}
    assert list(back[0].truth["segment"][:3]) == ["rest"] * 3
    assert back[1].axis == "linear" and back[1].units["tau"] == "N"


def test_map_and_units_convert_to_si(tmp_path):
    lg = hand_log()
    df = pd.DataFrame({"time_ms": lg.t * 1e3, "pos_deg": np.degrees(lg.q), "torque": lg.tau * 1e3,
                       "extra": 1.0})
    path = tmp_path / "vendor.csv"
    df.to_csv(path, index=False)
    (back,) = read_logs(str(path), "time_ms=t,pos_deg=q,torque=tau", "t=ms,q=deg,tau=mNm")
    np.testing.assert_allclose(back.t, lg.t, rtol=1e-12)
    np.testing.assert_allclose(back.q, lg.q, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back.tau, lg.tau, rtol=1e-12)
    assert back.qd is None


def test_linear_units_make_a_linear_axis(tmp_path):
    lg = hand_log()
    pd.DataFrame({"t": lg.t, "q": lg.q * 1e3, "tau": lg.tau}).to_csv(tmp_path / "s.csv", index=False)
    (back,) = read_logs(str(tmp_path / "s.csv"), units="q=mm,tau=N")
    assert back.axis == "linear" and back.units == {"q": "m", "qd": "m/s", "tau": "N"}
    np.testing.assert_allclose(back.q, lg.q, rtol=1e-12, atol=1e-15)


def test_mapping_file_with_headerless_csv_and_scale(tmp_path):
    lg = hand_log()
    np.savetxt(tmp_path / "raw.csv", np.column_stack([lg.t, lg.q, lg.tau / 0.5]), delimiter=",")
    (tmp_path / "map.yaml").write_text("columns: [time, angle, current]\n"
                                       "map: {time: t, angle: q, current: tau}\nscale: {tau: 0.5}\n")
    (back,) = read_logs(str(tmp_path / "raw.csv"), str(tmp_path / "map.yaml"))
    np.testing.assert_allclose(back.tau, lg.tau, rtol=1e-12)
    assert back.n == lg.n


def test_sidecar_metadata_is_read(tmp_path):
    lg = hand_log()
    pd.DataFrame({"t": lg.t, "pos": lg.q, "tau": lg.tau}).to_csv(tmp_path / "s.csv", index=False)
    (tmp_path / "s.csv.meta.yaml").write_text("map: {pos: q}\nmeta: {robot: test-arm, inertia: 0.5}\n")
    (back,) = read_logs(str(tmp_path / "s.csv"))
    assert back.meta["robot"] == "test-arm"
    np.testing.assert_array_equal(back.q, lg.q)


def _write(tmp_path, df, name="bad.csv"):
    path = tmp_path / name
    df.to_csv(path, index=False)
    return str(path)


def test_every_problem_is_reported_at_once(tmp_path):
    lg = hand_log()
    df = pd.DataFrame({"time": lg.t, "q": lg.q})
    with pytest.raises(LogFormatError) as exc:
        read_logs(_write(tmp_path, df))
    msg = str(exc.value)
    assert "'t'" in msg and "'tau'" in msg and "--map" in msg


@pytest.mark.parametrize("corrupt, words", [
    (lambda df: df.assign(tau=df.tau.astype(object).where(df.index != 7, "abc")), ["'tau'", "row 8", "abc"]),
    (lambda df: df.assign(t=df.t.where(df.index != 5, df.t[3])), ["'t'", "row 6", "increase"]),
    (lambda df: df.assign(tau=df.tau.where(df.index != 9, np.inf)), ["'tau'", "row 10", "infinite"]),
    (lambda df: df.assign(tau=df.tau.where(df.index % 10 != 0, np.nan)), ["missing values", "row 1"]),
    (lambda df: df.head(3), ["only 3 samples"]),
    (lambda df: df.assign(q=np.degrees(df.q) * 40, qd=df.qd * 40), ["degrees"]),
])
def test_bad_values_name_column_and_row(tmp_path, corrupt, words):
    lg = hand_log()
    df = pd.DataFrame({"t": lg.t, "q": lg.q, "qd": lg.qd, "tau": lg.tau})
    with pytest.raises(LogFormatError) as exc:
        read_logs(_write(tmp_path, corrupt(df)))
    for w in words:
        assert w in str(exc.value), str(exc.value)


def test_few_missing_values_are_dropped_with_a_warning(tmp_path):
    lg = hand_log(n=1000)
    df = pd.DataFrame({"t": lg.t, "q": lg.q, "tau": lg.tau})
    df.loc[17, "tau"] = np.nan
    (back,) = read_logs(_write(tmp_path, df))
    assert back.n == 999 and any("dropped 1 rows" in w for w in back.warnings)


def test_degrees_declared_as_radians_is_accepted_when_said(tmp_path):
    lg = hand_log()
    df = pd.DataFrame({"t": lg.t, "q": lg.q * 400, "tau": lg.tau})
    path = _write(tmp_path, df)
    with pytest.raises(LogFormatError):
        read_logs(path)
    (back,) = read_logs(path, units="q=rad")
    assert back.n == lg.n


@pytest.mark.parametrize("content", [b"", b"\x00\xff\xfe garbage \x89PNG\r\n", b"t,q,tau\n",
                                     b"t;q;tau\n0;1;2\n", b"PAR1 truncated"])
def test_unreadable_files_are_clean_errors(tmp_path, content):
    path = tmp_path / "x.csv"
    path.write_bytes(content)
    with pytest.raises(FrictidInputError):
        read_logs(str(path))


def test_unknown_extra_columns_are_not_an_error(tmp_path):
    lg = hand_log()
    df = pd.DataFrame({"t": lg.t, "q": lg.q, "tau": lg.tau, "motor_temp_raw": "x", "note": "hello"})
    (back,) = read_logs(_write(tmp_path, df))
    assert back.n == lg.n


def test_mat_file_with_struct_fields_per_joint_rows_and_scale(tmp_path):
    import scipy.io

    lg = hand_log()
    pos = np.vstack([np.degrees(lg.q), 2 * np.degrees(lg.q)])
    rec = {"time": lg.t, "pos_deg": pos, "torque": np.vstack([lg.tau, lg.tau]) / 4.0}
    scipy.io.savemat(tmp_path / "run.mat", {"rec": rec, "gain": np.array([4.0, 8.0])})
    (tmp_path / "map.yaml").write_text(
        "variables: {t: rec.time, q: rec.pos_deg, tau: rec.torque}\n"
        "scale: {tau: gain}\nunits: {q: deg}\njoints: [shoulder, elbow]\n")
    a, b = read_logs(str(tmp_path / "run.mat"), str(tmp_path / "map.yaml"))
    assert (a.joint, b.joint) == ("shoulder", "elbow")
    np.testing.assert_allclose(a.q, lg.q, atol=1e-12)
    np.testing.assert_allclose(b.tau, 2 * lg.tau, rtol=1e-12)
    (tmp_path / "bad.yaml").write_text("variables: {t: rec.time, q: rec.nope, tau: rec.torque}\n")
    with pytest.raises(LogFormatError, match="nope"):
        read_logs(str(tmp_path / "run.mat"), str(tmp_path / "bad.yaml"))


def test_csv_with_preamble_and_semicolons_through_a_mapping_file(tmp_path):
    lg = hand_log()
    body = "\n".join(f"{t * 1e3:.3f};{q:.9f};{tau:.9f}" for t, q, tau in zip(lg.t, lg.q, lg.tau))
    (tmp_path / "epos.csv").write_text("Date:;today\nRecorded samples:;400\nms;rad;Nm\n" + body + "\n")
    (tmp_path / "map.yaml").write_text("columns: [time, pos, torque]\ndelimiter: ';'\nskip_rows: 3\n"
                                       "map: {time: t, pos: q, torque: tau}\nunits: {t: ms}\n")
    (back,) = read_logs(str(tmp_path / "epos.csv"), str(tmp_path / "map.yaml"))
    assert back.n == lg.n
    np.testing.assert_allclose(back.tau, lg.tau, atol=1e-8)


def test_preamble_skipped_to_a_marker_and_number_prefixes_kept(tmp_path):
    lg = hand_log(n=50)
    rows = "\n".join(f"{t * 1e3:.1f};{qd:.6f};{tau:.6f},," for t, qd, tau in zip(lg.t, lg.qd, lg.tau))
    (tmp_path / "run.csv").write_text("Date:;x\nScale:;1;True,,\n;vel;torque,,\nms;rpm;%,,\n" + rows + "\n")
    (tmp_path / "map.yaml").write_text(
        "skip_to: 'ms;'\ndelimiter: ';'\ncolumns: [time, vel, torque]\nbad_rows: number_prefix\n"
        "map: {time: t, vel: qd, torque: tau}\nunits: {t: ms, qd: rpm}\nscale: {tau: -1.0}\n")
    (back,) = read_logs(str(tmp_path / "run.csv"), str(tmp_path / "map.yaml"))
    assert back.q is None and back.n == 50
    np.testing.assert_allclose(back.tau, -lg.tau, atol=1e-6)
    np.testing.assert_allclose(back.qd, lg.qd * np.pi / 30, atol=1e-6)
    (tmp_path / "strict.yaml").write_text((tmp_path / "map.yaml").read_text().replace("number_prefix", "error"))
    with pytest.raises(LogFormatError, match="not a number"):
        read_logs(str(tmp_path / "run.csv"), str(tmp_path / "strict.yaml"))


def test_folder_of_signal_files_with_interleaved_joints(tmp_path):
    a, b = hand_log(seed=1), hand_log(seed=2)
    np.savetxt(tmp_path / "time.txt", a.t)
    np.savetxt(tmp_path / "pos.txt", np.column_stack([a.q, b.q]).ravel())
    np.savetxt(tmp_path / "trq.txt", np.column_stack([a.tau, b.tau]).ravel())
    (tmp_path / "map.yaml").write_text("files: {t: time.txt, q: pos.txt, tau: trq.txt}\njoints: [j1, j2]\n")
    j1, j2 = read_logs(str(tmp_path), str(tmp_path / "map.yaml"))
    np.testing.assert_allclose(j2.tau, b.tau, rtol=1e-12)
    assert (j1.joint, j2.joint, j1.n) == ("j1", "j2", a.n)
    with pytest.raises(LogFormatError, match="folder"):
        read_logs(str(tmp_path))


def _long_parquet(path, frames, row_group_size):
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.Table.from_pandas(pd.concat(frames, ignore_index=True), preserve_index=False), path,
                   row_group_size=row_group_size)


@pytest.mark.parametrize("row_group_size", [150, 400, 1000, 5000])
def test_joint_blocks_of_a_parquet_log_read_alone_equal_the_whole_read(tmp_path, row_group_size):
    from frictid.io.logs import joint_row_blocks

    logs = [hand_log(n=300 + 50 * k, joint=name, seed=k) for k, name in enumerate(["a", "b", "c"])]
    path = tmp_path / "long.parquet"
    write_logs(logs, str(path))
    _long_parquet(path, [pd.read_parquet(path)], row_group_size)  # blocks cross row groups or share one
    blocks = joint_row_blocks(str(path))
    assert blocks == [("a", 0, 300), ("b", 300, 650), ("c", 650, 1050)]
    whole = read_logs(str(path))
    for (joint, a, b), full in zip(blocks, whole):
        (part,) = read_logs(str(path), rows=(a, b))
        assert part.joint == joint == full.joint
        for name in ("t", "q", "qd", "tau"):
            np.testing.assert_array_equal(getattr(part, name), getattr(full, name))
        np.testing.assert_array_equal(part.channels["temp_env"], full.channels["temp_env"])


def test_joint_blocks_only_where_each_joint_is_one_block(tmp_path):
    from frictid.io.logs import joint_row_blocks

    a, b = hand_log(n=200, joint="a"), hand_log(n=200, joint="b", seed=1)
    write_logs([a, b], str(tmp_path / "long.csv"))
    assert joint_row_blocks(str(tmp_path / "long.csv")) is None  # CSV: read whole
    write_logs([a], str(tmp_path / "one.parquet"))
    df = pd.read_parquet(tmp_path / "one.parquet").drop(columns=["joint"], errors="ignore")
    _long_parquet(tmp_path / "nojoint.parquet", [df], 100)
    assert joint_row_blocks(str(tmp_path / "nojoint.parquet")) is None  # no joint column
    write_logs([a, b], str(tmp_path / "long.parquet"))
    df = pd.read_parquet(tmp_path / "long.parquet")
    mixed = pd.concat([df.iloc[:100], df.iloc[200:300], df.iloc[100:200], df.iloc[300:]], ignore_index=True)
    _long_parquet(tmp_path / "mixed.parquet", [mixed], 150)
    assert joint_row_blocks(str(tmp_path / "mixed.parquet")) is None  # joint a comes back after b


def test_problems_in_a_block_name_rows_of_the_whole_file(tmp_path):
    from frictid.io.logs import joint_row_blocks

    a, b = hand_log(n=300, joint="a"), hand_log(n=300, joint="b", seed=1)
    b.tau[123] = np.inf
    path = tmp_path / "long.parquet"
    write_logs([a, b], str(path))
    _long_parquet(path, [pd.read_parquet(path)], 128)
    (_, start, stop), = [blk for blk in joint_row_blocks(str(path)) if blk[0] == "b"]
    with pytest.raises(LogFormatError) as whole:
        read_logs(str(path))
    with pytest.raises(LogFormatError) as part:
        read_logs(str(path), rows=(start, stop))
    assert "row 424 (line 425)" in str(part.value) and str(part.value) == str(whole.value)


@pytest.mark.parametrize("last", [True, False])
def test_a_row_with_the_wrong_number_of_fields_names_its_line(tmp_path, last):
    """A CSV cut short in its last line, or a row with one field too many, names the line (Arrow's
    threaded reader does not number rows) and says which of the two it looks like."""
    lg = hand_log(n=3000)
    path = tmp_path / "log.csv"
    write_logs([lg], str(path))
    lines = path.read_text().splitlines()
    if last:
        path.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][: len(lines[-1]) // 3])
    else:
        lines[1234] += ",7"
        path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogFormatError) as err:
        read_logs(str(path))
    msg = str(err.value)
    line = len(lines) if last else 1235
    assert f"line {line} has " in msg, msg
    assert ("cut short" in msg) == last and ("delimiter" in msg) != last, msg


def test_file_sha256_is_the_hash_of_the_bytes(tmp_path):
    import hashlib

    from frictid.io.logs import file_sha256

    data = np.random.default_rng(3).bytes(3 << 20)
    f = tmp_path / "log.parquet"
    f.write_bytes(data)
    empty = tmp_path / "empty.csv"
    empty.write_bytes(b"")
    assert file_sha256(str(f)) == hashlib.sha256(data).hexdigest()
    assert file_sha256(str(empty)) == hashlib.sha256(b"").hexdigest()  # cannot be mapped: read instead
    assert file_sha256("-") is None
    assert file_sha256(str(tmp_path)) is None  # not a file


def test_a_top_level_start_time_in_the_metadata_is_the_recordings(tmp_path):
    """Issue 20: a start time at the top of a Parquet file's metadata (or a sidecar) is not ignored; a
    ``meta.start_time`` still wins."""
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from frictid.io.logs import read_logs

    t = np.arange(100) * 1e-3
    table = pa.table({"t": t, "q": np.sin(t), "tau": np.cos(t)})
    table = table.replace_schema_metadata({b"frictid": json.dumps({"start_time": "2026-01-02T03:04:05"}).encode()})
    pq.write_table(table, tmp_path / "a.parquet")
    assert read_logs(str(tmp_path / "a.parquet"))[0].meta["start_time"] == "2026-01-02T03:04:05"
    both = table.replace_schema_metadata({b"frictid": json.dumps({"start_time": 1.0, "meta": {"start_time": 2.0}}).encode()})
    pq.write_table(both, tmp_path / "b.parquet")
    assert read_logs(str(tmp_path / "b.parquet"))[0].meta["start_time"] == 2.0
