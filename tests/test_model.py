"""The one evaluator of an identified model: :class:`frictid.FrictionModel`.

Its friction along constant-velocity plateaus (where no stick law plays a part) equals what the replay
computes along the log, for every model kind the parameter files hold; the feed-forward example of
docs/model.md runs; evaluations outside the identified ranges warn.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import frictid
from frictid.io.logs import read_logs
from frictid.io.params import write_params
from frictid.model import FrictionModel, ValidityWarning
from frictid.models import static as sm
from frictid.replay import STICK_NOISE, replay
from frictid.result import JointFit, ModelFit, ParamEstimate
from frictid.segments import derivatives, estimate_scales

from conftest import ROOT

SAMPLES = ROOT / "sample_logs"


def plateau_index(log, trim: float = 0.3) -> np.ndarray:
    """Samples in the middle of each constant-velocity plateau (the plant's truth labels), or, in a log
    without plateaus, the samples well outside a static model's stick zone."""
    lab = np.asarray(log.truth["segment"]).astype(str) == "constant_velocity"
    edges = np.flatnonzero(np.diff(np.r_[0, lab.astype(int), 0]))
    idx = []
    for i0, i1 in zip(edges[::2], edges[1::2]):
        k = int(trim * (i1 - i0))
        idx.append(np.arange(i0 + k, i1 - k))
    if idx:
        return np.concatenate(idx)
    w, _ = derivatives(log)
    return np.flatnonzero(np.abs(w) > 4 * STICK_NOISE * estimate_scales(log).sigma_w)


def object_friction(m: FrictionModel, log, rep, idx) -> np.ndarray:
    """``m.friction`` at the plateau samples, given what the replay read from the log there."""
    q = None if log.q is None else log.q[idx]
    payload = log.channels.get("payload")
    G = m.gravity(q, None if payload is None else payload[idx]) - m.offset if q is not None else 0.0
    load = np.abs(m.J * rep.a[idx] + G)
    T = rep.T[idx] if m.thermal else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        return m.friction(rep.w[idx], T=T, q=q, load=load, payload=None if payload is None else payload[idx],
                          t=log.t[idx])


@pytest.fixture(scope="module")
def fitted():
    out = []
    for files in (["hydraulic_sweep.csv"], ["direct_drive_sweep.parquet", "direct_drive_presliding.parquet"], ["geared_duty_cycle.parquet"]):
        paths = [str(SAMPLES / f) for f in files]
        res = frictid.fit(paths)
        out.append((read_logs(paths[0])[0], res))
    return out


def test_friction_equals_the_replay_on_plateaus_for_every_model(fitted):
    kinds = set()
    for log, res in fitted:
        jf = res[log.joint]
        idx = plateau_index(log)
        has_plateaus = "constant_velocity" in set(np.asarray(log.truth["segment"]).astype(str))
        for name in jf.models:
            try:
                m = jf.friction_model(name)
            except frictid.errors.ConfigError:
                continue
            if m.sigma0 is not None and not has_plateaus:
                continue  # LuGre's state equals its steady state only on plateaus
            rep = replay(log, m)
            ok = idx[np.isfinite(rep.w[idx]) & np.isfinite(rep.a[idx]) & np.isfinite(rep.F_model[idx])]
            assert ok.size > 100, (log.source, name, ok.size)
            got = object_friction(m, log, rep, ok)
            ref = rep.F_model[ok]
            err = np.max(np.abs(got - ref)) / np.max(np.abs(ref))
            # LuGre's state follows the noisy measured velocity over a bristle length: on plateaus it is the
            # steady state to its lag, not to round-off (the bristles from the reversals, fit step 7)
            assert err < (2e-2 if m.sigma0 is not None else 1e-9), (log.source, name, err)
            kinds.add("lugre" if m.sigma0 is not None else m.thermal["law"] if m.thermal else "static")
    assert {"static", "thermal4", "thermal6"} <= kinds, kinds


def extended(jf: JointFit, base: str, name: str, values: dict, extensions=()) -> JointFit:
    """A copy of ``jf`` with one more model: ``base`` plus the parameters ``values`` (as the diagnosis
    writes them: extension parameters beside the map's)."""
    import copy

    jf = copy.deepcopy(jf)
    mf = copy.deepcopy(jf.models[base])
    unit = {"sigma0": "N m/rad", "sigma1": "N m s/rad"}
    mf.params.update({k: ParamEstimate(k, v, 0.0, unit.get(k, ""), True) for k, v in values.items()})
    mf.name, mf.extra = name, dict(mf.extra or {}, extensions=list(extensions))
    jf.models[name] = mf
    return jf


@pytest.mark.parametrize("kind", ["lugre", "extensions"])
def test_friction_equals_the_replay_with_dynamics_and_extensions(fitted, kind):
    """LuGre (bristle state settled on plateaus) and every extension at once (position, load, drift, torque
    offset, an added Stribeck drop) on the hydraulic sweep."""
    log, res = fitted[0]
    jf = res[log.joint]
    if kind == "lugre":
        jf = extended(jf, jf.selected, "lugre_x", {"sigma0": 1e7, "sigma1": 2e3})
    else:
        jf = extended(jf, "polynomial", "poly_x", {
            "pos_amp": 0.1, "pos_period": 0.37, "pos_phase": 0.4, "load_torque": 2e-3, "load_gravity": 1e-3,
            "drift_per_hour": -0.3, "drift_t0": 0.0, "tau_offset": 3.0, "str_amp": 40.0, "str_vs": 0.07},
            extensions=["position", "load", "drift", "offset", "stribeck"])
    m = jf.friction_model(list(jf.models)[-1])
    assert (m.sigma0 is not None) == (kind == "lugre")
    idx = plateau_index(log)
    w, a = derivatives(log)
    if kind == "lugre":  # the bristles settle exactly only where the velocity is exactly constant
        w = w.copy()
        lab = np.asarray(log.truth["segment"]).astype(str) == "constant_velocity"
        edges = np.flatnonzero(np.diff(np.r_[0, lab.astype(int), 0]))
        for i0, i1 in zip(edges[::2], edges[1::2]):
            w[i0:i1] = np.nanmean(w[i0:i1])
    rep = replay(log, m, w=w, a=a)
    idx = idx[np.isfinite(rep.w[idx]) & np.isfinite(rep.a[idx])]
    got, ref = object_friction(m, log, rep, idx), rep.F_model[idx]
    assert np.max(np.abs(got - ref)) / np.max(np.abs(ref)) < 1e-9
    if kind == "extensions":  # each input moves the friction: none is silently ignored
        base = object_friction(m, log, rep, idx)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            assert not np.allclose(m.friction(rep.w[idx]), base, rtol=1e-3)


def test_missing_input_and_out_of_range_warn(fitted):
    log, res = fitted[0]
    jf = extended(res[log.joint], "polynomial", "poly_pos", {"pos_amp": 0.1, "pos_period": 0.5},
                  extensions=["position"])
    jf.validity = {"speed": [0.01, 0.95], "position": [-1.0, 1.0]}
    m = jf.friction_model("poly_pos")
    with pytest.warns(ValidityWarning, match="without q"):
        m.friction([0.5])
    with pytest.warns(ValidityWarning, match="speed .* outside"):
        m.friction([3.0], q=[0.0])
    with pytest.warns(ValidityWarning, match="position .* outside"):
        m.friction([0.5], q=[4.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        F = m.friction(np.array([[-0.5, 0.0], [0.2, 0.9]]), q=0.3)  # inside: silent, shape kept
    assert F.shape == (2, 2) and F[0, 0] < 0 < F[1, 0]


def test_load_gives_the_model_and_params_reload(fitted, tmp_path):
    log, res = fitted[0]
    p = tmp_path / "params.yaml"
    write_params(res, p)
    m = frictid.load(p)
    assert isinstance(m, FrictionModel) and m.name == res[log.joint].selected
    assert m.to_dict()["params"] == {k: v.to_dict() for k, v in res[log.joint].selected_fit.params.items()}
    assert all(m.params[k].bounds == p.bounds for k, p in res[log.joint].selected_fit.params.items())
    w = np.linspace(-0.9, 0.9, 41)
    assert np.array_equal(m.friction(w), res[log.joint].model.friction(w))
    with pytest.raises(frictid.errors.ConfigError, match="no joint"):
        frictid.load(p, joint="nope")


def test_the_examples_of_docs_model_md_run(tmp_path, monkeypatch):
    """Every python block of docs/model.md, in order, in a folder with the sample logs."""
    import re

    text = (ROOT / "docs" / "model.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 2
    (tmp_path / "sample_logs").symlink_to(SAMPLES)
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)
        for code in blocks:
            exec(compile(code, "docs/model.md", "exec"), ns)
    tau_ff, m = ns["tau_ff"], ns["m"]
    assert tau_ff.shape == ns["t"].shape and np.all(np.isfinite(tau_ff))
    # the friction part of the feed-forward has the sign of the motion wherever the joint moves
    F = tau_ff - m.J * ns["qdd_ref"] - m.gravity(ns["q_ref"])
    moving = np.abs(ns["qd_ref"]) > 0.05
    assert np.all(np.sign(F[moving]) == np.sign(ns["qd_ref"][moving]))


def test_params_carry_the_fits_bounds(fitted):
    """lmfit-like parameters: every static-map parameter of the chosen model has the optimiser's bounds,
    the value lies within them, and they survive the parameter file."""
    log, res = fitted[0]
    m = res[log.joint].model
    static = {q.name for q in sm.param_table(m.map)}
    for name, p in m.params.items():
        if p.value is None or (name not in static and p.bounds is None):  # rigid terms: least squares
            continue
        assert p.bounds is not None, name
        lo, hi = p.bounds
        assert lo <= p.value <= hi, (name, p.value, p.bounds)
