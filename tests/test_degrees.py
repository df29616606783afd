"""Degrees in both columns: a rotary log whose q and qd are both degrees (consistent with each other) is
refused unless ``--units`` says so, by the rule of docs/log-format.md; legitimate logs pass (the sample
logs, with and without their metadata, a joint turning several revolutions, a motor shaft, the real data)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from conftest import REALDATA, ROOT
from frictid.errors import LogFormatError
from frictid.io.logs import read_logs

SAMPLES = ROOT / "sample_logs"
ROTARY_MOVING = ["hydraulic_sweep.csv", "direct_drive_sweep.parquet", "geared_duty_cycle.parquet"]


def as_plain_csv(path, out, factor=1.0):
    """A sample log as a CSV without metadata (nothing declared), q and qd multiplied by ``factor``."""
    df = pd.read_parquet(path) if str(path).endswith(".parquet") else pd.read_csv(path)
    df = df[[c for c in ("t", "joint", "q", "qd", "tau") if c in df]]
    df = df.assign(q=df.q * factor, qd=df.qd * factor)
    df.to_csv(out, index=False)
    return out


def turning_log(path, revs: float, speed: float, rate=500.0, seed=3):
    """A joint turning ``revs`` revolutions forward and back at ``speed`` [rad/s] (trapezoid moves)."""
    rng = np.random.default_rng(seed)
    dist = revs * 2 * np.pi
    t_move = dist / speed
    t = np.arange(0, 2 * t_move + 2.0, 1 / rate)
    qd = np.where(t < t_move, speed, np.where(t < t_move + 1.0, 0.0, np.where(t < 2 * t_move + 1.0, -speed, 0.0)))
    qd = np.convolve(qd, np.ones(50) / 50, mode="same")
    q = np.cumsum(qd) / rate
    tau = 2.0 * np.tanh(qd / 0.01) + 0.1 * qd + 0.02 * rng.standard_normal(t.size)
    pd.DataFrame({"t": t, "q": q, "qd": qd, "tau": tau}).to_csv(path, index=False)
    return path


@pytest.mark.parametrize("name", ROTARY_MOVING)
def test_sample_logs_in_degrees_are_refused(tmp_path, name):
    log = as_plain_csv(SAMPLES / name, tmp_path / "deg.csv", np.degrees(1.0))
    with pytest.raises(LogFormatError, match=r"'q' and 'qd' look like degrees.*--units q=deg,qd=deg/s"):
        read_logs(str(log))
    (lg,) = read_logs(str(log), units="q=deg,qd=deg/s")  # declared: read and converted
    plain = pd.read_csv(as_plain_csv(SAMPLES / name, tmp_path / "rad.csv"))
    assert np.allclose(lg.q, plain.q) and np.allclose(lg.qd, plain.qd)
    read_logs(str(log), units="q=rad,qd=rad/s")  # declared as radians: taken as said


@pytest.mark.parametrize("name", sorted(p.name for p in SAMPLES.glob("*") if p.suffix in (".csv", ".parquet")))
def test_sample_logs_pass_as_shipped_and_without_metadata(tmp_path, name):
    assert read_logs(str(SAMPLES / name))
    assert read_logs(str(as_plain_csv(SAMPLES / name, tmp_path / "plain.csv")))


@pytest.mark.parametrize("revs, speed", [(5, 2.0), (3, 5.0), (60, 100.0)])
def test_a_joint_turning_several_revolutions_passes(tmp_path, revs, speed):
    """Slower than one revolution per second (several turns at 2 and 5 rad/s), or a motor shaft spanning
    more than 360 rad (60 turns at 100 rad/s): radians."""
    (lg,) = read_logs(str(turning_log(tmp_path / "turns.csv", revs, speed)))
    assert np.ptp(lg.q) > 2 * np.pi * revs * 0.95


def coarse(path, src, rate, bits=12, factor=1.0):
    """Log ``src`` as a ``bits``-bit encoder with the drive's backward difference as qd, times ``factor``."""
    df = pd.read_csv(src)
    step = 2 * np.pi / 2**bits
    q = np.floor(df.q.to_numpy() / step) * step
    qd = np.concatenate([[0.0], np.diff(q) * rate])
    df.assign(q=q * factor, qd=qd * factor).to_csv(path, index=False)
    return path, qd


def test_a_coarse_encoder_differenced_at_a_high_rate_passes(tmp_path):
    """A 12-bit encoder logged at 5 kHz with the drive's backward difference as qd: single counts read as a
    count times the rate (7.7 rad/s) on a joint turning 1.4 revolutions at 1.9 rad/s. Radians, as the
    position's speed over 50 ms says (a foreign-scorecard draw, seed 100189, was refused for it); a quarter
    turn of the same encoder logged in degrees is still refused."""
    rate = 5000.0
    log, qd = coarse(tmp_path / "coarse.csv", turning_log(tmp_path / "a.csv", 1.4, 1.9, rate=rate), rate)
    assert np.percentile(np.abs(qd), 99) > 2 * np.pi  # the counts alone would pass for a turning joint
    (lg,) = read_logs(str(log))
    assert np.ptp(lg.q) > 2 * np.pi
    deg, _ = coarse(tmp_path / "deg.csv", turning_log(tmp_path / "b.csv", 0.25, 1.9, rate=rate), rate,
                    factor=np.degrees(1.0))
    with pytest.raises(LogFormatError, match="look like degrees"):
        read_logs(str(deg))


def test_refused_turning_log_and_the_cli_exit(tmp_path, cli):
    """Two turns at 2 rev/s read as radians is within the rule's doubt: exit 2, one message, no output;
    --units q=rad,qd=rad/s accepts it."""
    log = turning_log(tmp_path / "fast.csv", 2, 4 * np.pi)
    r = cli("segments", log, "-o", tmp_path / "seg.csv")
    assert r.code == 2 and "look like degrees" in r.err and "Traceback" not in r.err, r
    assert len([ln for ln in r.err.splitlines() if ln.strip()]) == 1
    assert not (tmp_path / "seg.csv").exists()
    r = cli("segments", log, "--units", "q=rad,qd=rad/s", "-o", tmp_path / "seg.csv")
    assert r.code == 0 and (tmp_path / "seg.csv").exists(), r


def test_degrees_sweep_fits_the_truth_once_declared(tmp_path, cli):
    """The issue's case: the hydraulic sweep in deg and deg/s. Refused as it is; with --units the fit
    gives the plant's Stribeck map in rad (vs 0.08 rad/s, sigma2 60 N m s/rad)."""
    import yaml

    log = as_plain_csv(SAMPLES / "hydraulic_sweep.csv", tmp_path / "deg.csv", np.degrees(1.0))
    r = cli("fit", log, "-o", tmp_path / "p.yaml", "--models", "stribeck", "--no-diagnose")
    assert r.code == 2 and "look like degrees" in r.err and not (tmp_path / "p.yaml").exists(), r
    r = cli("fit", log, "-o", tmp_path / "p.yaml", "--models", "stribeck", "--no-diagnose",
            "--units", "q=deg,qd=deg/s")
    assert r.code == 0, r
    p = yaml.safe_load((tmp_path / "p.yaml").read_text())["joints"]["j1"]["models"]["stribeck"]["params"]
    assert p["vs"]["value"] == pytest.approx(0.08, rel=0.1)
    assert p["sigma2"]["value"] == pytest.approx(60.0, rel=0.1)


@pytest.mark.realdata
def test_real_rotary_data_pass_and_in_degrees_are_refused(tmp_path):
    if not REALDATA.is_dir():
        pytest.skip(f"{REALDATA} is absent (the real-data sets)")
    maps = ROOT / "recipes" / "realdata"
    logs = read_logs(str(REALDATA / "franka_panda_gaz2019"), str(maps / "franka_panda.yaml"))
    logs += read_logs(str(REALDATA / "ur10e_mamedov2020" / "jointwise_motion" / "ur-20_01_22-joint_1.csv"),
                      str(maps / "ur10e_joint1.yaml"))
    refused = 0
    for lg in logs:
        rad = tmp_path / f"rad_{lg.joint}.csv"
        pd.DataFrame({"t": lg.t, "q": lg.q, "qd": lg.qd, "tau": lg.tau}).to_csv(rad, index=False)
        read_logs(str(rad))  # in SI without metadata: passes
        deg = tmp_path / f"deg_{lg.joint}.csv"
        pd.DataFrame({"t": lg.t, "q": np.degrees(lg.q), "qd": np.degrees(lg.qd), "tau": lg.tau}).to_csv(deg, index=False)
        with pytest.raises(LogFormatError, match="look like degrees"):
            read_logs(str(deg))
        refused += 1
    assert refused == 8
