"""``frictid simulate --compensate`` (issue 23): the closed-loop what-if with and without friction
feed-forward.

- With the plant's own friction given as the "identified" model, the model run is the true run (the same
  feed-forward through FrictionModel as through the plant's kernel inputs).
- Compensation with a good model reduces the tracking error and the true friction reduces it most.
- The LuGre friction observer of 000 on a model 20 % low beats the model's feed-forward; without a presliding
  stiffness there is no observer run.
- The static map fed forward from the measured velocity: the kernel's map equals ``FrictionModel.friction``
  at the filtered velocity, and in closed loop it reduces the error too.
- ``recipes/tracking_slow.yaml`` runs on every shipped plant; the CLI writes the runs and prints JSON with
  ``runs: {none, model, measured, true}`` (and ``observer`` for a LuGre model); a joint the plant lacks is
  refused.
"""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from frictid.compensate import compensation_runs, plant_friction_model, stick_episodes
from frictid.model import FrictionModel
from frictid.plant.config import load_plant

from conftest import ROOT

RECIPE = str(ROOT / "recipes" / "tracking_slow.yaml")
PLANTS = ROOT / "recipes" / "plants"


def true_model(plant: str, joint: str) -> FrictionModel:
    pl = load_plant(str(PLANTS / f"{plant}.yaml"))
    return plant_friction_model(pl, pl.joint(joint))


def test_the_true_friction_as_model_gives_the_true_run():
    runs = compensation_runs({"j1": true_model("hydraulic", "j1")}, RECIPE, str(PLANTS / "hydraulic.yaml"), seed=3)
    model, true = runs["j1"]["model"], runs["j1"]["true"]
    np.testing.assert_allclose(model.ff, true.ff, rtol=1e-9, atol=1e-9 * np.max(np.abs(true.ff)))
    assert model.metrics.rms_error == pytest.approx(true.metrics.rms_error, rel=1e-6)


def test_compensation_reduces_the_tracking_error():
    m = true_model("direct_drive", "j2")
    m.c_pos = m.c_pos * 0.9  # a model 10 % low: most, not all, of the ideal reduction
    m.c_neg = m.c_neg * 0.9
    runs = compensation_runs({"j2": m}, RECIPE, str(PLANTS / "direct_drive.yaml"), seed=4)["j2"]
    none, model, true = (runs[k].metrics.rms_error for k in ("none", "model", "true"))
    assert true < model < none / 3
    assert runs["none"].metrics.stick_slip_episodes > runs["true"].metrics.stick_slip_episodes == 0


@pytest.mark.parametrize("plant,joint", [("hydraulic", "j1"), ("direct_drive", "j2")])
def test_the_lugre_observer_corrects_what_the_model_gets_wrong(plant, joint):
    """000's observer (eq. 17) on a LuGre model 20 % low: the tracking error's own feedback through the
    bristle state makes up much of what the feed-forward of the same model misses; no stick episode."""
    m = true_model(plant, joint)
    m.c_pos, m.c_neg = 0.8 * m.c_pos, 0.8 * m.c_neg
    runs = compensation_runs({joint: m}, RECIPE, str(PLANTS / f"{plant}.yaml"), seed=4, duration_scale=0.3)[joint]
    none, model, obs, true = (runs[k].metrics for k in ("none", "model", "observer", "true"))
    assert true.rms_error < obs.rms_error < 0.75 * model.rms_error < none.rms_error
    assert obs.stick_slip_episodes == 0 and np.all(np.isfinite(runs["observer"].q))


def test_no_observer_without_a_presliding_stiffness():
    m = true_model("hydraulic", "j1")
    m.sigma0 = None
    runs = compensation_runs({"j1": m}, RECIPE, str(PLANTS / "hydraulic.yaml"), seed=4, duration_scale=0.1)["j1"]
    assert set(runs) == {"none", "model", "measured", "true"}


#: The tracking recipes and the duration scale their test runs them at.
TRACKING = {"tracking_slow": 0.3, "tracking_lv": 0.3, "tracking_warm": 0.03}


@pytest.mark.parametrize("recipe", sorted(TRACKING))
@pytest.mark.parametrize("plant", sorted(p.stem for p in PLANTS.glob("*.yaml")))
def test_tracking_recipe_runs_on_every_shipped_plant(plant, recipe):
    pl = load_plant(str(PLANTS / f"{plant}.yaml"))
    j = pl.joints[0].name
    runs = compensation_runs({j: true_model(plant, j)}, str(ROOT / "recipes" / f"{recipe}.yaml"),
                             str(PLANTS / f"{plant}.yaml"), seed=5, duration_scale=TRACKING[recipe])[j]
    assert runs["none"].t.size > 1000 and np.all(np.isfinite(runs["none"].q))
    assert runs["true"].metrics.rms_error < runs["none"].metrics.rms_error


def test_stick_episodes_counts_stretches_where_the_reference_moves_and_the_joint_does_not():
    t = np.arange(0, 2, 1e-3)
    qd_ref = np.full(t.size, 0.1)
    w = qd_ref.copy()
    w[100:200] = 0.0     # 0.1 s stuck
    w[500:510] = 0.0     # 10 ms: too short
    w[1500:1800] = 0.005  # 0.3 s at 5 % of the reference
    n, seconds = stick_episodes(t, w, qd_ref, np.ones(t.size, bool))
    assert n == 2 and seconds == pytest.approx(0.4, abs=2e-3)


def test_cli_writes_the_runs_and_json(tmp_path):
    import frictid
    from frictid.result import FitResult, JointFit, ModelFit, ParamEstimate

    params = {"Fc": 120.0, "sigma2": 40.0}
    mf = ModelFit("coulomb_viscous", "coulomb_viscous",
                  {k: ParamEstimate(k, v, 0.01 * v, "") for k, v in params.items()})
    jf = JointFit(joint="j1", inertia=ParamEstimate("J", 25.0, 0.1, "kg m^2"), models={mf.name: mf},
                  selected=mf.name, validity={"speed": [0.01, 1.0]})
    frictid.write_params(FitResult(joints={"j1": jf}), tmp_path / "p.yaml")
    out = tmp_path / "runs.parquet"
    cmd = [sys.executable, "-m", "frictid", "simulate", "--compensate", str(tmp_path / "p.yaml"), RECIPE,
           "--plant", "hydraulic", "-o", str(out), "--json"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    runs = doc["joints"]["j1"]["runs"]
    assert set(runs) == {"none", "model", "measured", "true"}
    for v in runs.values():
        assert {"rms_error", "peak_error", "stick_slip_episodes"} <= set(v)
    import pandas as pd
    df = pd.read_parquet(out)
    assert set(df["run"]) == {"none", "model", "measured", "true"} and set(df["joint"]) == {"j1"}
    jf.joint = "j9"
    frictid.write_params(FitResult(joints={"j9": jf}), tmp_path / "p9.yaml")
    bad = subprocess.run([sys.executable, "-m", "frictid", "simulate", "--compensate", str(tmp_path / "p9.yaml"),
                          RECIPE, "--plant", "hydraulic", "-o", str(tmp_path / "x.parquet")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "no joint j9" in bad.stderr and not (tmp_path / "x.parquet").exists()
    # the report draws the runs: one section with the overlay and a row per run
    rep = subprocess.run([sys.executable, "-m", "frictid", "report", str(tmp_path / "p.yaml"), "--compensation",
                          str(out), "-o", str(tmp_path / "r.html")], capture_output=True, text=True)
    assert rep.returncode == 0, rep.stderr
    html = (tmp_path / "r.html").read_text()
    part = html[html.index('data-section="compensation"'):]
    part = part[:part.index("</section>")]
    assert part.count("<tr><td>") == 4 and "<svg" in part and "no compensation" in part
    wrong = subprocess.run([sys.executable, "-m", "frictid", "report", str(tmp_path / "p.yaml"), "--compensation",
                            str(tmp_path / "p.yaml"), "-o", str(tmp_path / "r2.html")], capture_output=True, text=True)
    assert wrong.returncode == 2 and "not a runs file" in wrong.stderr and not (tmp_path / "r2.html").exists()


def test_on_003s_lv_test_a_static_map_suffices_on_joint_2_not_on_joint_1():
    """tracking_lv (003's LV test) on the direct-drive arm: the plant's own friction as a static map (its
    bristle dynamics left out) cuts joint 2's error by more than 8x and removes its stick-slip, as 003's
    static LuGre model did; on joint 1 (sigma1 = 1000 / 800 N m s/rad, a presliding damping a static map
    cannot carry) it stays below 8x while the full friction goes beyond: there the bristles decide."""
    recipe = str(ROOT / "recipes" / "tracking_lv.yaml")
    red = {}
    for j in ("j1", "j2"):
        m = true_model("direct_drive", j)
        m.sigma0 = None
        by = compensation_runs({j: m}, recipe, str(PLANTS / "direct_drive.yaml"), seed=6, duration_scale=0.5)[j]
        none, static, true = (by[k].metrics for k in ("none", "model", "true"))
        red[j] = (none.rms_error / static.rms_error, none.rms_error / true.rms_error)
        if j == "j2":
            assert none.stick_slip_episodes > 0 and static.stick_slip_episodes == 0
    assert red["j2"][0] > 8 and red["j1"][0] < 8 < red["j1"][1], red


def test_the_error_after_a_warm_up_needs_the_thermal_law():
    """tracking_warm on the geared joint (thermal6 warm-up): after the duty cycles, the feed-forward of the
    plant's own friction with its thermal law (heat balance from the ambient) tracks better than the same
    map without it (the cold friction, too high once warm); metrics_from(0) is the whole run's."""
    recipe = str(ROOT / "recipes" / "tracking_warm.yaml")
    plant = str(PLANTS / "geared_industrial.yaml")
    warm = true_model("geared_industrial", "j2")
    cold = true_model("geared_industrial", "j2")
    cold.thermal = None
    after = {}
    for name, m in (("warm", warm), ("cold", cold)):
        runs = compensation_runs({"j2": m}, recipe, plant, seed=7, duration_scale=0.2)["j2"]
        run = runs["model"]
        assert run.metrics_from(0) == run.metrics
        assert set(np.unique(run.part)) == {0, 1, 2}
        after[name] = run.metrics_from(1).rms_error
    T = runs["none"].T
    assert T[runs["none"].part >= 1].mean() > T[0] + 5.0     # the duty cycles warmed the joint
    assert after["warm"] < 0.5 * after["cold"], after


def test_measured_velocity_feedforward_is_the_models_map_at_the_filtered_velocity():
    """The kernel's feed-forward from the measured velocity (``_measured_map``) against the model's own
    friction: its first-order filter by hand, and g(wf) sgn(wf) + f(wf) equal to FrictionModel.friction
    at the filtered velocity, both signs and at zero."""
    from frictid.plant.kernel import _branch, _measured_map
    m = true_model("direct_drive", "j1")   # per-sign Stribeck map: both branches checked
    m.sigma0 = None
    cp, dp = _branch(np.asarray(m.c_pos, float), np.asarray(m.c_pos, float))
    cn, dn = _branch(np.asarray(m.c_neg, float), np.asarray(m.c_neg, float))
    h, band = 1e-3, 30.0
    for w, wf0 in ((0.02, 0.0), (-0.3, 0.1), (1.5, 1.4), (0.0, 0.0)):
        F, wf = _measured_map(w, wf0, h, band, cp, cn, dp, dn)
        assert wf == pytest.approx(w + (wf0 - w) * np.exp(-band * h), rel=1e-12, abs=1e-15)
        assert F == pytest.approx(float(m.friction(np.array([wf]))[0]), rel=1e-9, abs=1e-12)


def test_measured_velocity_feedforward_reduces_the_error():
    """The plant's own static map fed forward from the measured velocity on the direct drive's joint 2:
    the error falls to under a third of the uncompensated one (the reference's feed-forward of the same
    map does likewise); the true friction along the reference stays the best."""
    m = true_model("direct_drive", "j2")
    m.sigma0 = None
    runs = compensation_runs({"j2": m}, RECIPE, str(PLANTS / "direct_drive.yaml"), seed=4, duration_scale=0.3)["j2"]
    none, meas, true = (runs[k].metrics.rms_error for k in ("none", "measured", "true"))
    assert true < meas < none / 3
    assert np.all(runs["measured"].ff == 0.0) and np.all(np.isfinite(runs["measured"].q))
