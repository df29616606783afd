"""Issue 20's real-data line on the cheap logs (EMPS identification run, UR10e joints 1 and 2): each finding's
figure draws the number it states, no finding's stored model predicts worse than the model it was judged
against (on its figure's samples and on every moving sample), the load on UR10e joint 2 is found with its
held-out reduction, and UR10e joint 1's low-speed repair is named as the rise it is (issue 19: no
``stribeck`` with Fs < Fc).

The data are not copied into the repository: without ``../shared/realdata`` (or ``FRICTID_REALDATA``) these
tests fail, they do not skip (as tests/test_realdata.py). The table over every real log is
``python benchmarks/realdata.py --data ../shared/realdata --only findings`` (docs/realdata.md).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import frictid
from frictid.io.logs import read_logs
from frictid.report import content as ct
from frictid.segments import derivatives, find_segments

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("FRICTID_REALDATA", ROOT.parent / "shared" / "realdata"))
MAPS = ROOT / "recipes" / "realdata"
#: The figure's RMS before and after (in-sample, the same models on the same samples) within this of the
#: stated held-out RMS (benchmarks/realdata.py AGREE_TOL).
AGREE_TOL = 0.05


@pytest.fixture(autouse=True, scope="module")
def _realdata_present():
    """The real data are the final judge: without them these tests fail, they do not skip."""
    if not DATA.is_dir():
        pytest.fail(f"real-data sets not found at {DATA}: they are not copied into the repository; put the "
                    "shared folder beside the checkout (../shared/realdata) or set FRICTID_REALDATA", pytrace=False)


def _fitted(log: Path, mapping: Path) -> tuple[str, dict, list]:
    """One joint's parameter entry (as the file holds it, diagnosis run) and its logs prepared as the
    report prepares them."""
    logs = read_logs(str(log), str(mapping))
    params = frictid.fit(logs).to_dict()
    (jn, jd), = params["joints"].items()
    return jn, jd, [ct.prepare_log(lg, jd, find_segments, derivatives) for lg in logs]


@pytest.fixture(scope="module")
def emps():
    return _fitted(DATA / "emps" / "DATA_EMPS.mat", MAPS / "emps.yaml")


@pytest.fixture(scope="module")
def ur2():
    return _fitted(DATA / "ur10e_mamedov2020" / "jointwise_motion" / "ur-20_01_22-joint_2.csv",
                   MAPS / "ur10e_joint2.yaml")


@pytest.fixture(scope="module")
def ur1():
    return _fitted(DATA / "ur10e_mamedov2020" / "jointwise_motion" / "ur-20_01_22-joint_1.csv",
                   MAPS / "ur10e_joint1.yaml")


def _figures(case) -> list[tuple[dict, dict]]:
    """(finding, what the report's figure of it draws) for every finding of the joint; a finding judged
    off the sliding samples is replayed on the moving samples (the report does not draw it)."""
    jn, jd, datas = case
    entries = [f for f in jd.get("diagnosis") or [] if isinstance(f, dict)]
    rows = ct.diagnosis_samples(datas, jn, jd)
    out = []
    for f, before in zip(entries, ct.diagnosis_befores(jd, entries)):
        res = ct.diagnosis_residuals(datas, jn, jd, f, before=before,
                                     rows=rows if ct.on_sliding_samples(f) else None)
        assert res is not None, f
        out.append((f, res))
    return out


@pytest.mark.parametrize("case", ["emps", "ur2"])
def test_each_finding_figure_draws_its_number(case, request):
    """The figure of a finding drawn on the sliding samples shows the models and samples its held-out
    numbers come from: the RMS it draws before and after lie within 5 % of the stated ones. (EMPS's
    asymmetry drew the fit's coulomb_viscous with its -3.2 N offset, 1.75 N on those samples, against the
    diagnosis' base without it, 3.97 N.)"""
    figs = [(f, r) for f, r in _figures(request.getfixturevalue(case)) if ct.on_sliding_samples(f)]
    assert figs, "no finding drawn on the sliding samples"
    for f, res in figs:
        assert res["samples"] == "sliding"
        assert res["rms_before"] == pytest.approx(f["rms_before"], rel=AGREE_TOL), f["cause"]
        assert res["rms_after"] == pytest.approx(f["rms_after"], rel=AGREE_TOL), f["cause"]
        assert np.isfinite(res["before"]["mean"]).all() and np.isfinite(res["given"]["after"]).all()


@pytest.mark.parametrize("case", ["emps", "ur2", "ur1"])
def test_no_finding_model_predicts_worse_than_the_model_before_it(case, request):
    """Every finding states a held-out gain, and the extended model the file stores for it, replayed along
    the log, leaves less than the model it was judged against, on the samples its figure draws and on every
    moving sample (the fit's basis). (EMPS's presliding model carried the joint's offset twice, once in
    asym's per-sign levels and once as tau_offset: 3.64 N on the moving samples against 1.89 N before it.)"""
    fit = request.getfixturevalue(case)
    figs = _figures(fit)
    assert figs
    jn, jd, datas = fit
    entries = [f for f in jd.get("diagnosis") or [] if isinstance(f, dict)]
    for (f, res), before in zip(figs, ct.diagnosis_befores(jd, entries)):
        assert f["rms_after"] < f["rms_before"] and f["gain"] > 0, f["cause"]
        assert res["rms_after"] is not None and res["rms_after"] < res["rms_before"], (f["cause"], res["rms_before"],
                                                                                       res["rms_after"])
        mv = res if not ct.on_sliding_samples(f) else ct.diagnosis_residuals(datas, jn, jd, f, before=before)
        assert mv["samples"] == "moving" and mv["rms_after"] < mv["rms_before"], (f["cause"], mv["rms_before"],
                                                                                  mv["rms_after"])


def test_ur10e_joint1_low_speed_rise_is_not_named_stribeck(ur1):
    """UR10e joint 1's friction lies below its sliding level at low speed and rises to it: the diagnosis'
    low-speed repair has a negative amplitude (-5.05 N m in session 24, adopted as ``+stribeck``). Issue 19:
    no ``stribeck`` with Fs < Fc. It is a ``low_speed_rise`` in the repair, the model's name and the
    selected model, and no model of the file named as a Stribeck term carries a negative amplitude."""
    jn, jd, _ = ur1
    rep = [f for f in jd.get("diagnosis") or [] if f.get("kind") == "repair"]
    assert [(f["cause"], f["extension"]) for f in rep] == [("low_speed_rise", "low_speed_rise")], rep
    model = jd["models"][rep[0]["model"]]
    assert model["params"]["str_amp"]["value"] < 0
    assert "low_speed_rise" in rep[0]["model"].split("+") and "below the sliding level" in rep[0]["evidence"]
    assert "stribeck" not in str(jd["selected"]).split("+")[1:]
    for name, md in jd["models"].items():
        if "stribeck" in name.split("+")[1:]:
            assert all(v["value"] >= 0 for k, v in md["params"].items() if k in ("str_amp", "str_amp_neg")), name


def test_ur10e_joint2_load_is_found_and_adopted(ur2):
    """The load on UR10e joint 2 (its friction level grows with the gravity torque it carries): a plain load
    term cuts the held-out RMS of the sliding samples by at least a third (3.27 -> 1.93 N m in session 24),
    beats every other candidate of its step but its twin load_gravity, and the chosen model carries it."""
    jn, jd, _ = ur2
    load = [f for f in jd.get("diagnosis") or [] if f.get("cause") == "load"]
    assert len(load) == 1
    f = load[0]
    assert f["rms_after"] <= (2 / 3) * f["rms_before"]
    assert jd["selected"] == f["model"]
    step = next(s for s in jd["selection"]["diagnosis"]["steps"] if s.get("chosen") == f["extension"])
    others = [t["gain"] for t in step["tested"] if not t["extension"].startswith("load_")]
    assert max(others) < f["gain"]



def test_franka_joint2_selects_no_stribeck_map_that_rises():
    """Franka joint 2 (the Fourier trajectory, every model with a parameter not identifiable): the choice's
    fallback took ``stribeck_asym`` with Fs_pos 0 against Fc_pos 171 N m, a rise named as a Stribeck drop
    (issue 19: no ``stribeck`` with Fs < Fc). It now passes such a map over and says so."""
    from frictid.identify.select import rises

    logs = read_logs(str(DATA / "franka_panda_gaz2019"), str(MAPS / "franka_panda.yaml"))
    jf = frictid.fit([lg for lg in logs if lg.joint == "2"], diagnose=False)["2"]
    assert rises(jf.models["stribeck_asym"])
    assert not rises(jf.models[jf.selected]), jf.selected
    assert any(n.startswith("stribeck_asym:") and "Fs < Fc" in n for n in jf.selection.get("not_taken", [])), \
        jf.selection


def test_franka_joint3_selects_no_two_exponential_map_that_rises():
    """Franka joint 3 selected ``stribeck_2exp`` with alpha1 +179 and alpha2 +197 N m at 0.145 and 0.160
    rad/s: the amplitudes cancel, the level is 1.56 N m at rest and rises to 19.6 with no drop, a rise named
    for the drop of 001's form (issue 19). Its drop's amplitude and speed are now not identifiable with the
    reason, and the choice takes a map without that name."""
    from frictid.identify.select import rises
    from frictid.models.static import TWO_EXP_RISE

    logs = read_logs(str(DATA / "franka_panda_gaz2019"), str(MAPS / "franka_panda.yaml"))
    jf = frictid.fit([lg for lg in logs if lg.joint == "3"], diagnose=False)["3"]
    mf = jf.models["stribeck_2exp"]
    assert mf.params["alpha1"].value > 0 and TWO_EXP_RISE in (mf.params["alpha1"].reason or "")
    assert rises(mf) and not rises(jf.models[jf.selected]) and not jf.selected.startswith("stribeck_2exp"), \
        jf.selected
