"""``frictid export``: MuJoCo, URDF, C header and JSON (issue 23).

- C: the header's friction equals ``FrictionModel.friction`` to 1e-12 relative on 10^5 random inputs, for
  random models of every canonical shape, per-sign vectors and each thermal law; the LuGre step
  reproduces ``FrictionModel.simulate`` along a random velocity history.
- MuJoCo: the exported joint, driven by a velocity servo at 5 speeds across the validity range, applies the
  model's friction within 2 % (Coulomb-viscous, written exactly) and within the approximation error the
  export states (a Stribeck model).
- URDF and MJCF ``--into``: the user's joints matched by name; a name missing there is refused.
- Bad input: exit 2, one message, nothing written.
"""
from __future__ import annotations

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

import frictid
from frictid.export import export
from frictid.export.cheader import c_header, c_name
from frictid.model import FrictionModel, ValidityWarning
from frictid.result import FitResult, JointFit, ModelFit, ParamEstimate

UNITS = {"Fc": "N m", "Fs": "N m", "vs": "rad/s", "delta": "1", "sigma2": "N m s/rad"}


def write_model(path, map_name: str, values: dict, *, stderr: float = 0.01, speed=(0.02, 2.0), J: float = 0.5,
                joint: str = "j1", identifiable: bool = True):
    """A parameter file with one joint whose selected model is ``map_name`` with the given values."""
    params = {n: ParamEstimate(n, v, abs(v) * stderr, UNITS.get(n, ""), identifiable=identifiable,
                               reason="" if identifiable else "test: not identifiable")
              for n, v in values.items()}
    mf = ModelFit(map_name, map_name, params, metrics={"rms": 0.1})
    jf = JointFit(joint=joint, inertia=ParamEstimate("J", J, J * 0.01, "kg m^2"), models={map_name: mf},
                  selected=map_name if identifiable else None, validity={"speed": list(speed)})
    frictid.write_params(FitResult(joints={joint: jf}), path)
    return path


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "frictid", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


# ---------------------------------------------------------------------------------------------------
# C header


def random_model(rng, law: str | None, lugre: bool) -> FrictionModel:
    """A random model in canonical form: Stribeck and saturation terms, per-sign vectors, a thermal law."""
    def vec():
        return np.array([rng.uniform(0.5, 20), rng.uniform(-5, 10), rng.uniform(0.01, 0.5), rng.uniform(0.5, 2.5),
                         rng.uniform(-2, 2) * rng.integers(0, 2), rng.uniform(0.1, 2), rng.uniform(0, 5),
                         rng.uniform(-1, 1), rng.uniform(0, 0.5)])
    c_pos, c_neg = vec(), vec()
    c_pos[3] = rng.choice([1.0, 2.0, c_pos[3]])
    thermal = None
    if law:
        thermal = {"law": law, "alpha": rng.uniform(-0.01, 0.0), "beta": 1.0, "lam": rng.uniform(0, 0.02),
                   "T0": 25.0, "dc": list(rng.uniform(-0.05, 0.05, 4)), "C": None, "K": None}
    m = FrictionModel(name="random", map="stribeck_2exp_asym", c_pos=c_pos, c_neg=c_neg, thermal=thermal,
                      joint=f"joint {law or 'plain'}-{int(lugre)}",
                      ext={"tau_offset": float(rng.uniform(-1, 1))})
    if lugre:
        m.sigma0 = (float(rng.uniform(1e3, 1e5)), float(rng.uniform(1e3, 1e5)))
        m.sigma1 = (float(rng.uniform(1, 50)), float(rng.uniform(1, 50)))
    return m


C_MAIN = r"""
#include <stdio.h>
#include "friction.h"
int main(void) {
    double w, T;
    while (scanf("%lf %lf", &w, &T) == 2) printf("%.17g\n", NAME_friction(w, T));
    return 0;
}
"""

C_LUGRE = r"""
#include <stdio.h>
#include "friction.h"
int main(void) {
    int n; double z = 0.0; static double t[20000], w[20000], T[20000];
    if (scanf("%d", &n) != 1) return 1;
    for (int k = 0; k < n; k++) if (scanf("%lf %lf %lf", &t[k], &w[k], &T[k]) != 3) return 1;
    for (int k = 0; k < n; k++) {
        printf("%.17g %.17g\n", NAME_lugre_force(z, w[k], T[k]), z);
        if (k + 1 < n) z = NAME_lugre_advance(z, 0.5 * (w[k] + w[k + 1]), t[k + 1] - t[k], T[k]);
    }
    return 0;
}
"""


def compile_and_run(tmp_path, header: str, main: str, name: str, stdin: str) -> np.ndarray:
    (tmp_path / "friction.h").write_text(header)
    (tmp_path / "main.c").write_text(main.replace("NAME", name))
    exe = tmp_path / "main"
    subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Werror", "-o", str(exe), str(tmp_path / "main.c"), "-lm"],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(exe)], input=stdin, capture_output=True, text=True, check=True).stdout
    return np.array([[float(x) for x in ln.split()] for ln in out.splitlines()])


@pytest.mark.parametrize("law", [None, "thermal4", "thermal6", "exponential"])
def test_c_header_friction_equals_the_model(tmp_path, law):
    rng = np.random.default_rng(230 + (0 if law is None else len(law)))
    m = random_model(rng, law, lugre=False)
    n = 100_000
    w = rng.normal(0.0, 1.0, n) * 10.0 ** rng.uniform(-4, 0.5, n)
    w[:50] = 0.0
    T = rng.uniform(0.0, 80.0, n)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)
        F_py = m.friction(w, T=T)
    got = compile_and_run(tmp_path, c_header([m]), C_MAIN, c_name(m.joint),
                          "\n".join(f"{float(a)!r} {float(b)!r}" for a, b in zip(w, T)))[:, 0]
    rel = np.abs(got - F_py) / np.maximum(np.abs(F_py), 1e-300)
    assert rel.max() <= 1e-12, (law, rel.max(), w[np.argmax(rel)])


def test_c_header_lugre_step_reproduces_simulate(tmp_path):
    rng = np.random.default_rng(231)
    m = random_model(rng, "thermal4", lugre=True)
    n = 5000
    t = np.cumsum(rng.uniform(5e-4, 2e-3, n))
    w = np.cumsum(rng.normal(0, 0.01, n))  # a random walk through many reversals
    T = 25.0 + np.cumsum(rng.normal(0, 0.01, n))
    F_py, z_py, _ = m.simulate(t, w, T=T)
    stdin = f"{n}\n" + "\n".join(f"{float(a)!r} {float(b)!r} {float(c)!r}" for a, b, c in zip(t, w, T))
    got = compile_and_run(tmp_path, c_header([m]), C_LUGRE, c_name(m.joint), stdin)
    scale = np.max(np.abs(F_py))
    assert np.max(np.abs(got[:, 0] - F_py)) <= 1e-9 * scale
    assert np.max(np.abs(got[:, 1] - z_py)) <= 1e-9 * np.max(np.abs(z_py))


def test_c_header_refuses_a_model_with_a_position_term(tmp_path):
    m = random_model(np.random.default_rng(232), None, lugre=False)
    m.ext.update(pos_amp=0.1, pos_period=0.5, pos_phase=0.0)
    with pytest.raises(frictid.errors.FrictidInputError, match="position"):
        c_header([m])


# ---------------------------------------------------------------------------------------------------
# MuJoCo

def drive_mujoco(xml: str, joint: str, speeds, peak: float) -> list[tuple[float, float]]:
    """(velocity, applied friction) at each commanded speed: a velocity servo stiff enough to push the
    joint's peak friction at 1 % of the lowest speed holds it there; in steady state the servo's force is
    the friction the joint's attributes apply."""
    import mujoco

    kv = float(100.0 * peak / np.min(np.abs(speeds)))
    xml = xml.replace("</mujoco>", f'<actuator><velocity joint="{joint}" kv="{kv!r}"/></actuator></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.timestep = 1e-3
    data = mujoco.MjData(model)
    out = []
    for v in speeds:
        mujoco.mj_resetData(model, data)
        data.ctrl[0] = v
        for _ in range(2000):
            mujoco.mj_step(model, data)
        out.append((float(data.qvel[0]), float(data.actuator_force[0])))
    return out


def test_mujoco_applies_a_coulomb_viscous_model_within_2_percent(tmp_path):
    p = write_model(tmp_path / "cv.yaml", "coulomb_viscous", {"Fc": 3.0, "sigma2": 2.0}, speed=(0.05, 2.0))
    ex = export(p, "mjcf")
    assert ex.forms[0].exact
    m = frictid.load(p)
    for v, F in drive_mujoco(ex.text, "j1", np.r_[np.geomspace(0.05, 2.0, 5), -1.0], peak=ex.forms[0].peak):
        assert F == pytest.approx(float(m.friction(v)), rel=0.02)


def test_mujoco_applies_a_stribeck_model_within_the_stated_error(tmp_path):
    p = write_model(tmp_path / "st.yaml", "stribeck",
                    {"Fc": 3.0, "Fs": 4.2, "vs": 0.1, "delta": 2.0, "sigma2": 1.5}, speed=(0.02, 2.0))
    ex = export(p, "mjcf")
    form = ex.forms[0]
    assert not form.exact and 0 < form.max_error < 0.25 * form.peak
    m = frictid.load(p)
    for v, F in drive_mujoco(ex.text, "j1", np.geomspace(0.02, 2.0, 5), peak=form.peak):
        assert F == pytest.approx(float(form.friction(v)), rel=0.02)
        assert abs(F - float(m.friction(v))) <= 1.02 * form.max_error + 0.02 * abs(F)


def test_mjcf_into_sets_the_matched_joints_and_refuses_a_missing_one(tmp_path):
    p = write_model(tmp_path / "cv.yaml", "coulomb_viscous", {"Fc": 3.0, "sigma2": 2.0})
    user = tmp_path / "robot.xml"
    user.write_text('<mujoco><!-- keep me --><worldbody><body><joint name="j1" armature="0.2"/>'
                    '<geom size=".1" mass="1"/></body></worldbody></mujoco>')
    r = run_cli("export", p, "--to", "mjcf", "--into", user, "-o", tmp_path / "out.xml")
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "out.xml").read_text()
    assert 'frictionloss="3.0"' in text and 'damping="2.0"' in text and 'armature="0.2"' in text
    assert "keep me" in text
    user.write_text('<mujoco><worldbody><body><joint name="other"/><geom size=".1"/></body></worldbody></mujoco>')
    r = run_cli("export", p, "--to", "mjcf", "--into", user, "-o", tmp_path / "out2.xml")
    assert r.returncode == 2 and "no joint named j1" in r.stderr and "other" in r.stderr
    assert not (tmp_path / "out2.xml").exists() and "Traceback" not in r.stderr


def test_urdf_into_and_snippet(tmp_path):
    p = write_model(tmp_path / "cv.yaml", "coulomb_viscous", {"Fc": 3.0, "sigma2": 2.0})
    urdf = tmp_path / "arm.urdf"
    urdf.write_text('<robot name="arm"><link name="a"/><link name="b"/><joint name="j1" type="revolute">'
                    '<parent link="a"/><child link="b"/><dynamics damping="9" friction="9"/></joint></robot>')
    assert run_cli("export", p, "--to", "urdf", "--into", urdf, "-o", tmp_path / "arm2.urdf").returncode == 0
    text = (tmp_path / "arm2.urdf").read_text()
    assert '<dynamics damping="2.0" friction="3.0"' in text and 'name="arm"' in text
    r = run_cli("export", p, "--to", "urdf", "-o", "-")
    assert r.returncode == 0 and '<dynamics damping="2.0" friction="3.0" />' in r.stdout


# ---------------------------------------------------------------------------------------------------
# JSON and bad input


def test_json_carries_distributions(tmp_path):
    p = write_model(tmp_path / "st.yaml", "stribeck", {"Fc": 3.0, "Fs": 4.2, "vs": 0.1, "delta": 2.0,
                                                        "sigma2": 1.5})
    doc = json.loads(export(p, "json").text)
    j = doc["joints"]["j1"]
    assert j["model"] == "stribeck" and j["validity"]["speed"] == [0.02, 2.0]
    fc = j["parameters"]["Fc"]["distribution"]
    assert fc == {"kind": "normal", "mean": 3.0, "std": pytest.approx(0.03), "low": 0.0, "high": None}


def test_bad_input_exits_2_and_writes_nothing(tmp_path):
    p = write_model(tmp_path / "none.yaml", "coulomb_viscous", {"Fc": 3.0, "sigma2": 2.0}, identifiable=False)
    cases = [(p, "mjcf", []), (write_model(tmp_path / "cv.yaml", "coulomb_viscous", {"Fc": 3.0, "sigma2": 2.0}),
                               "stl", []),
             (tmp_path / "cv.yaml", "c", ["--into", str(tmp_path / "cv.yaml")]),
             (tmp_path / "cv.yaml", "json", ["--joint", "j9"])]
    for params, fmt, extra in cases:
        out = tmp_path / f"out-{fmt}"
        r = run_cli("export", params, "--to", fmt, "-o", out, *extra)
        assert r.returncode == 2, (fmt, r.stderr)
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not out.exists()


def test_using_the_model_page_runs(tmp_path):
    """Every block of docs/using-the-model.md, in order, from a folder holding copies of sample_logs/,
    recipes/ and docs/examples/."""
    import os
    import re
    import shutil

    from conftest import ROOT

    shutil.copytree(ROOT / "sample_logs", tmp_path / "sample_logs")
    shutil.copytree(ROOT / "docs" / "examples", tmp_path / "docs" / "examples")
    shutil.copytree(ROOT / "recipes", tmp_path / "recipes")
    env = dict(os.environ, PATH=f"{os.path.dirname(sys.executable)}{os.pathsep}{os.environ.get('PATH', '')}")
    text = (ROOT / "docs" / "using-the-model.md").read_text()
    blocks = re.findall(r"```(bash|python)\n(.*?)```", text, re.S)
    assert [k for k, _ in blocks].count("bash") >= 4 and [k for k, _ in blocks].count("python") == 2
    for kind, code in blocks:
        cmd = ["bash", "-e", "-c", code] if kind == "bash" else [sys.executable, "-c", code]
        r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True)
        assert r.returncode == 0, (code, r.stdout[-2000:], r.stderr[-2000:])
    assert (tmp_path / "joint.xml").exists() and (tmp_path / "friction.json").exists()
    assert "friction" in r.stdout  # the C program's output
