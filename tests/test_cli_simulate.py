"""`frictid simulate` at the command line: outputs, determinism, and bad input giving exit 2 and no file."""
from __future__ import annotations

import numpy as np

from conftest import ROOT
from frictid.io.logs import read_logs


def test_simulate_writes_csv_and_parquet_that_read_back_alike(tmp_path, cli):
    a, b = tmp_path / "a.csv", tmp_path / "b.parquet"
    assert cli("simulate", ROOT / "recipes/torque_steps.yaml", "-o", a, "--seed", "3").code == 0
    assert cli("simulate", "torque_steps", "-o", b, "--seed", "3").code == 0  # by name, from recipes/
    (la,), (lb,) = read_logs(str(a)), read_logs(str(b))
    np.testing.assert_array_equal(la.tau, lb.tau)
    np.testing.assert_array_equal(la.truth["segment"], lb.truth["segment"])
    assert la.truth["params"] == lb.truth["params"]
    assert (a.parent / "a.csv.meta.yaml").exists()


def test_bad_plant_is_exit_2_and_no_output(tmp_path, cli):
    plant = (ROOT / "recipes/plants/hydraulic.yaml").read_text()
    bad = tmp_path / "bad_plant.yaml"
    bad.write_text(plant + "\nunexpected_key: 1\n")
    out = tmp_path / "log.csv"
    res = cli("simulate", "torque_steps", "--plant", bad, "-o", out)
    assert res.code == 2 and "unexpected_key" in res.err and "Traceback" not in res.err
    assert not out.exists()


def test_missing_recipe_and_bad_format(tmp_path, cli):
    out = tmp_path / "log.csv"
    res = cli("simulate", "no_such_recipe", "-o", out)
    assert res.code == 2 and "no_such_recipe" in res.err and not out.exists()
    res = cli("simulate", "torque_steps", "-o", tmp_path / "log.xlsx")
    assert res.code == 2 and "--format" in res.err


def test_existing_output_survives_a_failed_run(tmp_path, cli):
    out = tmp_path / "log.csv"
    out.write_text("precious\n")
    res = cli("simulate", "torque_steps", "--plant", tmp_path / "missing.yaml", "-o", out)
    assert res.code == 2
    assert out.read_text() == "precious\n"
