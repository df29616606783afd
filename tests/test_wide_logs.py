"""Wide logs (issue 24): one row per instant with each joint's columns side by side, read through a
mapping file whose ``joints`` name every joint's own columns and scale factors: the UR10e harmonic run,
and a UR RTDE recording (Universal Robots' client: space-separated, ``actual_q_0`` ...)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from frictid.errors import ConfigError, LogFormatError
from frictid.io.logs import read_logs

from conftest import REALDATA, ROOT

RUN = REALDATA / "ur10e_mamedov2020" / "identification_data" / "ur-20_02_19_15harm50sec.csv"


@pytest.fixture(scope="module")
def harmonic():
    if not RUN.is_file():
        pytest.fail(f"real data missing: {RUN} (the shared folder beside the checkout)", pytrace=False)
    return read_logs(str(RUN), str(ROOT / "recipes/realdata/ur10e_harmonic.yaml"))


def test_the_wide_mapping_reads_what_six_single_joint_mappings_read(harmonic):
    assert [lg.joint for lg in harmonic] == ["1", "2", "3", "4", "5", "6"]
    for lg in harmonic:
        one = read_logs(str(RUN), str(ROOT / f"recipes/realdata/ur10e_joint{lg.joint}.yaml"))[0]
        np.testing.assert_array_equal(lg.t, one.t)
        np.testing.assert_array_equal(lg.q, one.q)
        np.testing.assert_array_equal(lg.qd, one.qd)
        np.testing.assert_allclose(lg.tau, one.tau, rtol=1e-15)
    assert harmonic[0].meta["gravity"] == [0, 0] and "gravity" not in harmonic[1].meta


def rtde_record(path, logs, gains, temperatures=True):
    """The logs as Universal Robots' RTDE client records them: space-separated, vector fields as NAME_k,
    the torque as motor current (torque / drive gain)."""
    cols = {"timestamp": logs[0].t}  # seconds since the controller started
    for field in ("target_q", "actual_q", "actual_qd", "actual_current", "joint_temperatures"):
        for k, lg in enumerate(logs):
            cols[f"{field}_{k}"] = {"target_q": lg.q, "actual_q": lg.q, "actual_qd": lg.qd,
                                    "actual_current": lg.tau / gains[k],
                                    "joint_temperatures": np.full(lg.n, 30.0 + k)}[field]
    frame = pd.DataFrame(cols)
    if not temperatures:
        frame = frame[[c for c in frame.columns if not c.startswith("joint_temperatures")]]
    frame.to_csv(path, sep=" ", index=False, float_format="%.17g")


GAINS = [10.0, 10.6956, 8.4566, 9.0029, 9.48, 10.1232]


@pytest.mark.parametrize("temperatures", [True, False])
def test_an_rtde_record_is_read_with_the_shipped_mapping(tmp_path, harmonic, temperatures):
    rtde_record(tmp_path / "record.csv", harmonic, GAINS, temperatures)
    logs = read_logs(str(tmp_path / "record.csv"), str(ROOT / "recipes/robots/ur10e_rtde.yaml"))
    assert [lg.joint for lg in logs] == [lg.joint for lg in harmonic]
    for lg, ref in zip(logs, harmonic):
        np.testing.assert_allclose(lg.t, ref.t, atol=1e-6)
        np.testing.assert_array_equal(lg.q, ref.q)
        np.testing.assert_allclose(lg.tau, ref.tau, rtol=1e-12)
        if temperatures:
            np.testing.assert_array_equal(lg.channels["temp_joint"], 30.0 + int(lg.joint) - 1)
        else:
            assert "temp_joint" not in lg.channels  # an optional signal the recording lacks is left out


def write_mapping(path, text):
    path.write_text(text)
    return str(path)


def test_wide_mappings_that_cannot_be_read_are_refused_with_the_reason(tmp_path):
    log = tmp_path / "wide.csv"
    pd.DataFrame({"time": np.arange(50) * 0.01, "p1": np.zeros(50), "p2": np.zeros(50), "c1": np.ones(50),
                  "c2": np.ones(50), "v2": np.zeros(50)}).to_csv(log, index=False)
    odd = write_mapping(tmp_path / "odd.yaml", "map: {time: t}\njoints:\n  a: {map: {p1: q, c1: tau}}\n"
                                               "  b: {map: {p2: q, c2: tau, v2: qd}}\n")
    with pytest.raises(LogFormatError, match="map the same signals for every joint"):
        read_logs(str(log), odd)
    absent = write_mapping(tmp_path / "absent.yaml", "map: {time: t}\njoints:\n  a: {map: {p1: q, c9: tau}}\n")
    with pytest.raises(LogFormatError, match="c9"):
        read_logs(str(log), absent)
    unknown = write_mapping(tmp_path / "unknown.yaml", "joints:\n  a: {mapping: {p1: q}}\n")
    with pytest.raises(ConfigError, match="unknown key.*mapping"):
        read_logs(str(log), unknown)
    ok = write_mapping(tmp_path / "ok.yaml", "map: {time: t}\njoints:\n  a: {map: {p1: q, c1: tau}, scale: {tau: 2}}\n"
                                             "  b: {map: {p2: q, c2: tau}}\n")
    a, b = read_logs(str(log), ok)
    assert (a.joint, b.joint) == ("a", "b") and a.tau[0] == 2.0 and b.tau[0] == 1.0


def test_a_bad_wide_mapping_exits_2_with_one_message(tmp_path, cli):
    log = tmp_path / "wide.csv"
    pd.DataFrame({"time": np.arange(50) * 0.01, "p1": np.zeros(50), "c1": np.ones(50)}).to_csv(log, index=False)
    bad = write_mapping(tmp_path / "bad.yaml", "map: {time: t}\njoints:\n  a: {map: {p1: q, c7: tau}}\n")
    out = tmp_path / "p.yaml"
    r = cli("fit", log, "--map", bad, "-o", out)
    assert r.code == 2 and "c7" in r.err and "Traceback" not in r.err and not out.exists()
