"""`frictid compare`: the change of every parameter and the exit-code-3 gate."""
from __future__ import annotations

import json

import pytest
import yaml

from frictid.compare import compare, parse_tolerances
from frictid.errors import FrictidInputError


def params_file(Fc=10.0, sigma2=2.0, J=0.5, model="stribeck"):
    return {"schema": 1, "frictid": "test", "joints": {"1": {
        "inertia": {"value": J, "stderr": 0.01, "unit": "kg m^2"},
        "models": {model: {"params": {
            "Fc_pos": {"value": Fc, "stderr": 0.1, "unit": "N m", "identifiable": True},
            "sigma2": {"value": sigma2, "stderr": 0.05, "unit": "N m s/rad", "identifiable": True}}}},
        "selected": model}}}


def test_relative_tolerance_covers_per_sign_names():
    res = compare(params_file(), params_file(Fc=11.5), parse_tolerances("Fc=10%"))
    (failed,) = res.failed
    assert failed.name == "Fc_pos" and failed.relative == pytest.approx(0.15)
    assert failed.z == pytest.approx(1.5 / (0.1 * 2 ** 0.5))


def test_within_tolerance_passes_and_absolute_limits_work():
    assert not compare(params_file(), params_file(Fc=10.5), parse_tolerances("Fc=10%")).failed
    assert compare(params_file(), params_file(J=0.53), parse_tolerances("J=0.02")).failed
    assert not compare(params_file(), params_file(J=0.51), parse_tolerances("J=0.02")).failed


@pytest.mark.parametrize("text", ["Fc", "Fc=ten%", "=5%", "Fc=-3%"])
def test_bad_tolerances_are_input_errors(text):
    with pytest.raises(FrictidInputError):
        parse_tolerances(text)


def test_cli_exit_codes_and_json(tmp_path, cli):
    b, n = tmp_path / "b.yaml", tmp_path / "n.yaml"
    b.write_text(yaml.safe_dump(params_file()))
    n.write_text(yaml.safe_dump(params_file(sigma2=2.5)))
    r = cli("compare", b, n, "--tol", "sigma2=15%", "--json")
    assert r.code == 3, r
    data = json.loads(r.out)
    assert data["failed"] == 1 and "sigma2" in r.err
    assert cli("compare", b, n, "--tol", "sigma2=30%").code == 0
    r = cli("compare", b, tmp_path / "missing.yaml")
    assert r.code == 2 and "missing.yaml" in r.err and "Traceback" not in r.err
    (tmp_path / "junk.yaml").write_text("schema: 7\n")
    assert cli("compare", b, tmp_path / "junk.yaml").code == 2


def test_cli_reads_one_parameter_file_from_stdin(tmp_path, cli, monkeypatch):
    """``frictid fit LOG -o - | frictid compare base.yaml -``: either side may be standard input, not both."""
    import io

    b = tmp_path / "b.yaml"
    b.write_text(yaml.safe_dump(params_file()))
    new = yaml.safe_dump(params_file(sigma2=2.5)).encode()

    def stdin(data: bytes):
        monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(data)))

    stdin(new)
    r = cli("compare", b, "-", "--tol", "sigma2=15%")
    assert r.code == 3 and "sigma2" in r.err, r
    stdin(new)
    assert cli("compare", "-", b, "--tol", "sigma2=30%").code == 0
    stdin(new)
    r = cli("compare", "-", "-")
    assert r.code == 2 and "only one" in r.err, r
    stdin(b"joints: [\n")
    r = cli("compare", b, "-")
    assert r.code == 2 and "<stdin>" in r.err and "Traceback" not in r.err, r
