"""frictid report: the HTML parses, every section is there for a log that supports it and explains itself
when absent, figures carry units and survive greyscale, nothing is fetched from outside, and the command's
exit codes and atomic output.

The scenario is one short plant log with every experiment kind (plateaus, ramps, steps, duty cycles) and a
real identification of it; the segments come from the plant's truth labels (tests may read them), so the
report is tested independently of how well the segmenter finds duty cycles.
"""
from __future__ import annotations

import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from html.parser import HTMLParser

import numpy as np
import pytest
import yaml

from frictid.data import JointLog, Segment

SECTION_KEYS = ("summary", "timeline", "friction-map", "presliding", "thermal", "models", "diagnosis",
                "provenance")

RECIPE = {
    "name": "report_all_kinds",
    "description": "every experiment kind on one joint, short (report tests)",
    "default_plant": "geared_industrial",
    "temp_env": 25.0,
    "start_rest": 0.5,
    "experiments": [
        {"kind": "constant_velocity", "velocities": {"min": 0.02, "max": 0.9, "count": 5, "spacing": "log"},
         "relative": True, "signs": "both", "plateau": 1.0, "min_plateau": 0.4, "accel": 0.5, "gap": 0.2,
         "rest": 0.5},
        {"kind": "ramp_presliding", "peaks": [0.3, 0.6], "relative": True, "signs": "both", "ramp_up": 1.0,
         "hold": 0.3, "ramp_down": 1.0, "settle": 0.5, "rest": 0.5},
        {"kind": "torque_steps", "levels": [0.3, 0.6], "relative": True, "signs": "both", "hold": 0.3,
         "release": 0.2, "settle": 0.3, "rest": 0.5},
        {"kind": "duty_cycle", "duty": 0.5, "cycles": 6, "cycle_time": 12.0, "slots": 4, "cold_start": True,
         "rest": 1.0},
    ],
}
#: Models fitted for the scenario (the rest of the fit's models only cost time here).
MODELS = "coulomb_viscous,stribeck,polynomial,lugre,thermal4"

FINDING = {"cause": "position dependence", "evidence": "the residual follows the position (test finding)",
           "statistic": {"F": 12.5, "p": 0.001},
           "extension": {"name": "position", "params": {"pos_amp": 0.02, "pos_period": 1.0, "pos_phase": 0.0}},
           "rms_before": 1.2, "rms_after": 0.9, "gain": 0.25, "heldout": True}


def truth_segments(log: JointLog) -> list[Segment]:
    """Segments from the plant's truth labels: one per run of (kind, cycle)."""
    lab = np.asarray(log.truth["segment"]).astype(str)
    cyc = np.asarray(log.truth.get("cycle", np.full(log.n, -1)))
    key = np.char.add(lab, cyc.astype(str))
    cut = np.flatnonzero(key[1:] != key[:-1]) + 1
    out = []
    for a, b in zip(np.r_[0, cut], np.r_[cut, log.n]):
        c = int(cyc[a])
        out.append(Segment(str(lab[a]), int(a), int(b), float(log.t[a]), float(log.t[b - 1]),
                           c if c >= 0 else None))
    return out


_SCENARIO: dict = {}


def build_scenario(tmp_path_factory) -> dict:
    """The scenario's files (log, parameter file with a diagnosis entry), built once per test session."""
    if _SCENARIO:
        return _SCENARIO
    import frictid
    from frictid.io.logs import write_logs
    from frictid.plant import simulate_recipe

    d = tmp_path_factory.mktemp("report")
    recipe = d / "recipe.yaml"
    recipe.write_text(yaml.safe_dump(RECIPE))
    log_path = d / "run.parquet"
    write_logs(simulate_recipe(str(recipe), seed=3), str(log_path))
    res = frictid.fit([str(log_path)], models=MODELS, segmenter=truth_segments)
    params = res.to_dict()
    joint = next(iter(params["joints"]))
    # the diagnosis' own findings (if any) and one more whose extension is given by its parameters
    params["joints"][joint]["diagnosis"] = list(params["joints"][joint].get("diagnosis") or []) + [dict(FINDING)]
    params_path = d / "params.yaml"
    params_path.write_text(yaml.safe_dump(params, sort_keys=False))
    _SCENARIO.update(dir=d, log=str(log_path), params=str(params_path), joint=joint)
    return _SCENARIO


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    return build_scenario(tmp_path_factory)


@pytest.fixture(scope="module")
def full_report(scenario):
    """(html, params dict, logs) of the scenario with every section."""
    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import build_report

    params = load_params_dict(scenario["params"])
    logs = read_many([scenario["log"]])
    html = build_report(params, logs, params_path=scenario["params"], command="frictid report (test)",
                        segmenter=truth_segments)
    return html, params, logs


# ---------------------------------------------------------------------------------------------------
# helpers


VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


class Balance(HTMLParser):
    """Checks that every element is closed in order (outside inline SVG, which is checked as XML)."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.sections: list[dict] = []
        self.ids: list[str] = []
        self.imgs = 0
        self.svgs = 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.append(a["id"])
        if tag == "section":
            self.sections.append(a)
        if tag == "img":
            self.imgs += 1
        if tag == "svg" and "svg" not in self.stack:
            self.svgs += 1
        if tag not in VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.append(a["id"])

    def handle_endtag(self, tag):
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1] if self.stack else 'nothing'}")
            if tag in self.stack:
                while self.stack and self.stack.pop() != tag:
                    pass
            return
        self.stack.pop()


def parse(html: str) -> Balance:
    p = Balance()
    p.feed(html)
    p.close()
    return p


def sections_of(html: str) -> dict[str, dict[str, str]]:
    """joint id -> section key -> data-present, from the section elements."""
    out: dict[str, dict[str, str]] = {}
    for a in parse(html).sections:
        key = a.get("data-section", "")
        if "part" in (a.get("class") or "").split() and a.get("id", "").endswith("-" + key):
            out.setdefault(a["id"][: -len(key) - 1], {})[key] = a.get("data-present")
    return out


def section_text(html: str, jid: str, key: str) -> str:
    m = re.search(rf'<section class="part[^"]*" id="{jid}-{key}".*?</section>', html, re.S)
    assert m, f"section {key} missing"
    return re.sub(r"<[^>]+>", " ", m.group(0))


# ---------------------------------------------------------------------------------------------------
# the report


def test_html_parses_and_inline_svg_is_well_formed_xml(full_report):
    html, _, _ = full_report
    assert html.startswith("<!DOCTYPE html>")
    p = parse(html)
    assert not p.errors, p.errors[:5]
    assert not p.stack, f"unclosed: {p.stack[:5]}"
    dup = {i for i in p.ids if p.ids.count(i) > 1}
    assert not dup, f"duplicate ids: {sorted(dup)[:5]}"
    svgs = re.findall(r"<svg\b.*?</svg>", html, re.S)
    assert len(svgs) == p.svgs >= 6
    for svg in svgs:
        root = ET.fromstring(svg)
        assert root.get("viewBox") and root.get("role") == "img" and root.get("aria-label")


def test_every_section_is_present_for_a_log_that_supports_it(full_report, scenario):
    html, params, _ = full_report
    secs = sections_of(html)
    jid = "j-" + scenario["joint"]
    assert set(secs[jid]) == set(SECTION_KEYS)
    assert all(v == "yes" for v in secs[jid].values()), secs[jid]
    jd = params["joints"][scenario["joint"]]
    # the summary names the chosen model, its parameters with errors and units, and the coverage
    summary = section_text(html, jid, "summary")
    assert f"Model: {jd['selected']}" in summary
    assert "±" in summary and "N m" in summary
    assert re.search(r"Velocity w &gt; 0: [0-9.]+ to [0-9.]+ rad/s over \d+ plateau points", summary)
    assert re.search(r"\d+ constant-velocity plateaus .*\d+ presliding ramps, \d+ steps, 6 duty cycles", summary)
    # every model of the file is in the comparison table, the chosen one marked
    models = section_text(html, jid, "models")
    for name in jd["models"]:
        assert name in models
    assert "chosen" in models
    # the diagnosis: the finding, its figure (before and after) and the replay
    diag = section_text(html, jid, "diagnosis")
    assert "position dependence" in diag and "25.0 %" in diag
    for f in jd["diagnosis"]:
        assert str(f["cause"]) in diag and f["evidence"][:40] in html.replace("&#39;", "'").replace("&#34;", '"')
    assert "Residual against position" in html
    assert re.search(r"after: [a-z_0-9+]+", html)
    assert "Replay of" in html
    # provenance: the hash of the log, the command, the YAML snippet of the chosen model that loads back
    from frictid.io.logs import file_sha256
    assert file_sha256(scenario["log"]) in html
    snippet = re.search(rf'<pre id="{jid}-yaml">(.*?)</pre>', html, re.S).group(1)
    import html as _html
    d = yaml.safe_load(_html.unescape(snippet))
    assert d["joints"][scenario["joint"]]["model"]["name"] == jd["selected"]


def test_plateau_points_are_the_fits(full_report, scenario):
    """The map draws exactly the plateaus the fit used (same segments, same friction torque)."""
    html, params, _ = full_report
    jd = params["joints"][scenario["joint"]]
    n_used = len(jd["segments_used"]["constant_velocity"])
    assert f"Friction against velocity: {n_used} plateau points" in html


def test_sections_explain_themselves_when_absent(scenario):
    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import build_report

    params = load_params_dict(scenario["params"])
    jid = "j-" + scenario["joint"]
    # no log: what needs the log says so; the rest comes from the parameter file
    html = build_report(params, [], params_path="p.yaml")
    secs = sections_of(html)[jid]
    assert secs["timeline"] == "no" and secs["summary"] == "yes" and secs["models"] == "yes"
    assert secs["friction-map"] == "yes"  # the model curves need no log
    for key in ("timeline", "presliding", "thermal"):
        assert "No log was given" in section_text(html, jid, key)
    # only the plateau part of the log: no ramps, steps or duty cycles, and each section says what it needs
    lg = read_many([scenario["log"]])[0]
    kinds = np.asarray(lg.truth["segment"]).astype(str)
    end = int(np.flatnonzero(kinds == "ramp_presliding")[0])
    part = JointLog(joint=lg.joint, t=lg.t[:end], tau=lg.tau[:end], q=lg.q[:end],
                    qd=None if lg.qd is None else lg.qd[:end],
                    channels={k: v[:end] for k, v in lg.channels.items()}, axis=lg.axis, meta=lg.meta,
                    source=lg.source, truth={"segment": kinds[:end], "cycle": np.asarray(lg.truth["cycle"])[:end]})
    html = build_report(params, [part], segmenter=truth_segments)
    secs = sections_of(html)[jid]
    assert secs["timeline"] == "yes" and secs["friction-map"] == "yes"
    assert secs["presliding"] == "no" and secs["thermal"] == "no"
    assert "recipes/ramp_presliding.yaml" in section_text(html, jid, "presliding")
    assert "recipes/duty_cycle.yaml" in section_text(html, jid, "thermal")
    assert "not among the files the fit read" not in html  # same file name as the fit's source


def test_several_joints_get_an_index(scenario):
    from frictid.io.params_load import load_params_dict
    from frictid.report import build_report

    params = load_params_dict(scenario["params"])
    j = scenario["joint"]
    params["joints"]["second joint"] = dict(params["joints"][j], diagnosis=[])
    html = build_report(params, [])
    assert '<nav id="index"' in html
    assert 'href="#j-second-joint"' in html and f'href="#j-{j}"' in html
    assert set(sections_of(html)) == {f"j-{j}", "j-second-joint"}
    single = load_params_dict(scenario["params"])
    assert '<nav id="index"' not in build_report(single, [])


def _two_joints(scenario):
    """The scenario's parameter file and log with a second joint (a copy of the first, same file)."""
    import dataclasses

    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict

    params = load_params_dict(scenario["params"])
    j = scenario["joint"]
    params["joints"]["second joint"] = params["joints"][j]
    lg = read_many([scenario["log"]])[0]
    return params, [lg, dataclasses.replace(lg, joint="second joint")]


def test_recorded_segments_are_reused_and_joints_built_in_parallel(scenario):
    """The report takes the segments the fit recorded (segment_list) when the file's hash and rows match:
    the same HTML as segmenting again, without calling the segmenter; joints built in two worker
    processes give the same HTML as one after another."""
    from frictid.report import build_report

    params, logs = _two_joints(scenario)
    assert all(e["rows"] == logs[0].n for e in params["joints"][scenario["joint"]]["segment_list"])
    calls = []

    def counting(log):
        calls.append(log.joint)
        return truth_segments(log)

    kw = dict(params_path="p.yaml", command="c", generated="2026-01-01 00:00 UTC")
    serial = build_report(params, logs, segmenter=counting, jobs=1, **kw)
    assert calls == [], "recorded segments were used"
    assert build_report(params, logs, segmenter=counting, jobs=2, **kw) == serial
    bare = {**params, "joints": {k: {n: v for n, v in jd.items() if n != "segment_list"}
                                 for k, jd in params["joints"].items()}}
    assert build_report(bare, logs, segmenter=counting, jobs=1, **kw) == serial
    assert sorted(calls) == sorted([scenario["joint"], "second joint"])
    # another file (hash) or another number of rows: segmented again
    other = {**params, "sources": [dict(params["sources"][0], sha256="0" * 64)]}
    jd = params["joints"][scenario["joint"]]
    from frictid.report import content as ct
    assert ct.recorded_segments(logs[0], jd, other["sources"], "0" * 64) is not None
    from frictid.io.logs import file_sha256
    assert ct.recorded_segments(logs[0], jd, other["sources"], file_sha256(scenario["log"])) is None
    short = dict(jd, segment_list=[dict(e, rows=e["rows"] - 1) for e in jd["segment_list"]])
    assert ct.recorded_segments(logs[0], short, params["sources"], file_sha256(scenario["log"])) is None


@pytest.mark.parametrize("joint", [
    {},
    {"selected": None, "models": {}, "diagnosis": ["a finding given as text"]},
    {"axis": "linear", "units": {"q": "m", "qd": "m/s", "tau": "N"}, "selected": "coulomb_viscous",
     "models": {"coulomb_viscous": {"map": "coulomb_viscous", "params": {
         "Fc": {"value": 3.0, "stderr": 0.1, "unit": "N"}, "sigma2": {"value": None, "stderr": None, "unit": "N s/m",
                                                                      "identifiable": False, "reason": "no data"}}}}},
])
def test_sparse_parameter_files_still_give_a_report(joint, scenario):
    """Keys the report reads may be missing (readers ignore what they do not know, and tolerate gaps)."""
    from frictid.io.logs import read_many
    from frictid.report import build_report

    for logs in ([], read_many([scenario["log"]])):
        params = {"schema": 1, "joints": {scenario["joint"]: joint}}
        html = build_report(params, logs, segmenter=truth_segments)
        p = parse(html)
        assert not p.errors and not p.stack
        assert set(sections_of(html)[f"j-{scenario['joint']}"]) == set(SECTION_KEYS)


def test_the_report_is_self_contained(full_report):
    html, _, _ = full_report
    for m in re.finditer(r'\b(?:src|href)\s*=\s*"([^"]*)"', html):
        assert m.group(1).startswith(("#", "data:")), m.group(0)
    for m in re.finditer(r"url\(([^)]*)\)", html):
        assert m.group(1).strip("'\"").startswith(("#", "data:")), m.group(0)
    low = html.lower()
    assert "<link" not in low and "@import" not in low and "@font-face" not in low
    assert not re.search(r"<script[^>]*\bsrc=", low)
    assert "default-src 'none'" in html  # the page may not fetch anything even if a figure tried


def test_report_size_is_modest(full_report):
    html, _, _ = full_report
    assert len(html.encode()) < 1_500_000


# ---------------------------------------------------------------------------------------------------
# figures


def test_every_axis_carries_its_unit(scenario):
    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import content as ct
    from frictid.report.build import joint_report
    from frictid.segments import derivatives

    params = load_params_dict(scenario["params"])
    jd = params["joints"][scenario["joint"]]
    datas = [ct.prepare_log(lg, jd, truth_segments, derivatives) for lg in read_many([scenario["log"]])]
    ctx = joint_report(scenario["joint"], jd, datas)
    figs = [f for s in ctx["sections"] for f in s.figures]
    figs += [r["figure"] for r in ctx["section"]["diagnosis"].data["findings"] if r["figure"] is not None]
    assert len(figs) >= 6
    unit = re.compile(r"\[[^\]]+\]")
    for f in figs:
        assert f.axes
        for xl, yl, x_shown in f.axes:
            assert yl == "segment kind" or unit.search(yl), (f.alt, yl)
            if x_shown:
                assert unit.search(xl), (f.alt, xl)


def test_series_are_told_apart_without_colour():
    from frictid.report.figures import KIND_STYLE, SERIES

    styles = [(str(ls), mk) for _, ls, mk in SERIES]
    assert len(set(s[0] for s in styles)) == len(styles)  # dash patterns alone separate the models
    assert len(set(s[1] for s in styles)) == len(styles)  # and so do the markers
    assert len({c for c, _ in KIND_STYLE.values()}) == len(KIND_STYLE)  # the timeline also has one row per kind
    assert "#F0E442" not in [c for c, _, _ in SERIES]  # Okabe-Ito yellow vanishes on paper


def test_minmax_decimation_keeps_every_extreme():
    from frictid.report.figures import minmax_decimate

    rng = np.random.default_rng(1)
    t = np.arange(100_003) * 1e-3
    y = np.cumsum(rng.standard_normal(t.size))
    y[777] = 1e6
    xd, yd = minmax_decimate(t, y, columns=500)
    assert xd.size <= 1000 and np.all(np.diff(xd) >= 0)
    assert yd.max() == 1e6 and yd.min() == y.min()
    k = int(np.ceil(t.size / 500))
    last = int(np.ceil(t.size / k)) - 1
    for c in (0, 123, last):  # each column's minimum and maximum are drawn
        blk = y[c * k:(c + 1) * k]
        assert blk.min() in yd and blk.max() in yd
    short = np.arange(10.0)
    assert np.array_equal(minmax_decimate(short, short)[1], short)


def test_kind_spans_are_bounded_by_the_pixels():
    from frictid.report.figures import kind_spans

    segs = [("step", i * 1.0, i * 1.0 + 0.2) for i in range(20_000)]
    spans = kind_spans(segs, 0.0, 20_000.0, columns=1000)
    assert 1 <= len(spans["step"]) <= 500
    assert kind_spans([("rest", 0.0, 10.0)], 0.0, 10.0, columns=100) == {"rest": [(0.0, 10.0)]}


def test_numbers_are_rounded_to_their_uncertainty():
    from frictid.report.build import fmt_num, fmt_pm

    assert fmt_pm(44.72235, 0.0643) == "44.722 ± 0.064"
    assert fmt_pm(1.5e7, 2e5) == "1.500e+07 ± 2.0e+05"
    assert fmt_pm({"value": 2.0, "stderr": None}, None) == "2"
    assert fmt_pm(None, 1.0) == "—"
    assert fmt_num(float("nan")) == "—"


def test_numerics_never_import_matplotlib():
    code = ("import sys; import frictid.models.static, frictid.identify.static, frictid.segments, frictid.report, "
            "frictid.report.content, frictid.report.build; "
            "assert 'matplotlib' not in sys.modules, 'matplotlib imported'")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-800:]


# ---------------------------------------------------------------------------------------------------
# the command


def test_cli_writes_the_report_atomically(scenario, cli, tmp_path):
    out = tmp_path / "report.html"
    r = cli("report", scenario["params"], scenario["log"], "-o", out)
    assert r.code == 0, r
    assert "wrote" in r.err and out.stat().st_size > 10_000
    html = out.read_text()
    assert not parse(html).errors
    assert f"frictid report {scenario['params']} {scenario['log']} -o {out}" in html
    # without logs, and to standard output
    r = cli("report", scenario["params"], "-o", "-")
    assert r.code == 0 and r.out.startswith("<!DOCTYPE html>")
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]  # no temporary file left


@pytest.mark.parametrize("case", ["no-params", "no-output", "missing-params", "output-is-input", "no-folder",
                                  "bad-log", "not-params"])
def test_cli_input_errors_exit_2_and_write_nothing(case, scenario, cli, tmp_path):
    out = tmp_path / "r.html"
    bad = tmp_path / "bad.csv"
    bad.write_text("t,tau\n0,1\nx,2\n")
    notp = tmp_path / "notp.yaml"
    notp.write_text("schema: 7\njoints: {}\n")
    args = {
        "no-params": ["report", "-o", out],
        "no-output": ["report", scenario["params"]],
        "missing-params": ["report", tmp_path / "nope.yaml", "-o", out],
        "output-is-input": ["report", scenario["params"], "-o", scenario["params"]],
        "no-folder": ["report", scenario["params"], "-o", tmp_path / "no" / "r.html"],
        "bad-log": ["report", scenario["params"], bad, "-o", out],
        "not-params": ["report", notp, "-o", out],
    }[case]
    r = cli(*args)
    assert r.code == 2, r
    assert "error" in r.err and "Traceback" not in r.err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv", "notp.yaml"]


def test_fit_writes_the_report_too(scenario, cli, tmp_path):
    params, rep = tmp_path / "p.yaml", tmp_path / "r.html"
    r = cli("fit", scenario["log"], "-o", params, "--models", "coulomb_viscous,stribeck", "--no-diagnose",
            "--report", rep)
    assert r.code == 0, r
    html = rep.read_text()
    assert params.exists() and not parse(html).errors
    assert f"--report {rep}" in html and "--no-diagnose" in html
    assert sections_of(html)[f"j-{scenario['joint']}"]["friction-map"] == "yes"
    # refused before any work: the report cannot be the parameter file, nor re-read standard input
    for args in (["fit", scenario["log"], "-o", params, "--report", params],
                 ["fit", "-", "-o", tmp_path / "q.yaml", "--report", tmp_path / "q.html"]):
        r = cli(*args)
        assert r.code == 2 and "--report" in r.err, r
    assert not (tmp_path / "q.yaml").exists() and not (tmp_path / "q.html").exists()


def test_docs_examples_run(scenario, cli, monkeypatch):
    """docs/report.md: the command lines on the scenario's files, and the Python block as written."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "report.md").read_text()
    monkeypatch.chdir(scenario["dir"])
    bash = re.search(r"```bash\n(.*?)```", doc, re.S).group(1)
    lines = [ln.split("#")[0].strip() for ln in bash.splitlines()]
    for ln in lines[:2]:  # the two lines on params.yaml / run.parquet
        args = ln.split()
        assert args[:2] == ["frictid", "report"]
        r = cli(*args[1:])
        assert r.code == 0, (ln, r)
    code = re.search(r"```python\n(.*?)```", doc, re.S).group(1)
    exec(compile(code, "docs/report.md", "exec"), {})
    assert Path("report.html").stat().st_size > 10_000


def test_friction_is_computed_on_the_slices_read(scenario):
    """The friction torque and gravity computed on a slice (plateaus, ramps, steps, cycles) are the whole
    log's ``tau - J a - G`` cut to that slice."""
    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import content as ct
    from frictid.segments import derivatives

    params = load_params_dict(scenario["params"])
    jd = params["joints"][scenario["joint"]]
    lg = read_many([scenario["log"]])[0]
    d = ct.prepare_log(lg, jd, truth_segments, derivatives, segments=[])
    terms = ct.rigid_terms(jd)
    G = terms["Px"] * np.cos(lg.q) + terms["Py"] * np.sin(lg.q) + terms["offset"]
    F = lg.tau - terms["J"] * np.nan_to_num(d.a) - G
    assert abs(terms["Px"]) > 0 and terms["J"] > 0
    for i0, i1 in ((0, 10), (lg.n // 3, lg.n // 2), (lg.n - 7, lg.n), (5, 5)):
        np.testing.assert_allclose(d.F[i0:i1], F[i0:i1], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(d.G[i0:i1], G[i0:i1], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(d.F.full(), F, rtol=1e-12, atol=1e-9)
    assert d.F[lg.n - 3:].shape == (3,) and d.F[::2].shape == F[::2].shape


def test_cycle_rms_from_the_gram_matrix_is_the_polynomials():
    """A duty cycle's F_rms from the Gram matrix of its regressors equals the polynomial evaluated at
    every sample (two ways of computing the same number)."""
    from frictid.models.static import polynomial
    from frictid.report.content import _poly_basis, _quad_rms

    rng = np.random.default_rng(7)
    for _ in range(5):
        w = rng.normal(0.0, rng.uniform(0.1, 3.0), rng.integers(10, 5000))
        c = rng.normal(0.0, 20.0, 4)
        X = _poly_basis(w)
        assert _quad_rms(c, X.T @ X / len(w)) == pytest.approx(np.sqrt(np.mean(polynomial(w, *c) ** 2)), rel=1e-9)


def test_cycle_coefficients_from_the_normal_equations_fit_as_lstsq():
    """A duty cycle's polynomial from the fit's normal equations has the fitted values of ``lstsq`` on the
    samples, also when the regressors cannot be told apart (one speed: sgn, w, w|w|, w^3 collinear), and its
    Gram matrix is the regressors'."""
    from frictid.report.content import _cycle_polynomial, _poly_basis

    rng = np.random.default_rng(11)
    cases = [rng.normal(0.0, rng.uniform(0.05, 3.0), rng.integers(50, 20000)) for _ in range(6)]
    cases += [np.full(300, 0.7), np.r_[np.full(200, 0.4), np.full(100, -0.4)]]
    for w in cases:
        X = _poly_basis(w)
        F = 40.0 * np.sign(w) + 3.0 * w + rng.normal(0.0, 0.5, w.size)
        want = X @ np.linalg.lstsq(X, F, rcond=None)[0]
        coef, gram = _cycle_polynomial(w, F)
        np.testing.assert_allclose(X @ coef, want, rtol=1e-9, atol=1e-9 * np.abs(F).max())
        np.testing.assert_allclose(gram, X.T @ X / w.size, rtol=1e-12)


def test_report_reads_the_references_only_for_a_closed_loop(tmp_path, monkeypatch):
    """q_ref / qd_ref / tau_ref feed only the closed-loop replay: a log without controller gains is read
    without them, a log with gains (meta.control) with them, and read once (its metadata says so)."""
    import frictid.io.logs as io_logs
    from frictid.cli.report import read_report_logs
    from frictid.data import JointLog
    from frictid.io.logs import write_logs

    calls = []
    real = io_logs.read_logs
    monkeypatch.setattr(io_logs, "read_logs", lambda *a, **k: calls.append(a[0]) or real(*a, **k))

    t = np.arange(2000) * 1e-3
    q = 0.1 * np.sin(2 * np.pi * t)
    ch = {"q_ref": q, "qd_ref": np.gradient(q, t), "tau_ref": np.zeros_like(t)}
    for name, meta, expect in (("open", {}, set()), ("closed", {"control": {"kp": 400.0, "kd": 20.0}},
                                                     {"q_ref", "qd_ref", "tau_ref"})):
        path = tmp_path / f"{name}.parquet"
        write_logs([JointLog(joint="j", t=t, q=q, tau=np.cos(t), channels=dict(ch), meta=meta)], str(path))
        calls.clear()
        got = read_report_logs([str(path)])
        assert set(got[0].channels) & set(ch) == expect, name
        assert calls == [str(path)], name


def test_cli_jobs(scenario, cli, tmp_path):
    """``--jobs 1`` builds the joints one after another and is recorded in the command line."""
    out = tmp_path / "r.html"
    r = cli("report", scenario["params"], scenario["log"], "-o", out, "--jobs", "1")
    assert r.code == 0, r
    assert "--jobs 1" in out.read_text()
    assert cli("report", scenario["params"], scenario["log"], "-o", out, "--jobs", "-1").code == 2


def _two_joint_file(scenario, path, spoil=None):
    """The two joints of :func:`_two_joints` in one Parquet file (each joint one block of rows), with
    ``spoil(k, log)`` applied to copies of the logs; returns the parameter dict."""
    import dataclasses

    from frictid.io.logs import write_logs

    params, logs = _two_joints(scenario)
    logs = [dataclasses.replace(lg, tau=lg.tau.copy()) for lg in logs]
    for k, lg in enumerate(logs):
        if spoil:
            spoil(k, lg)
    write_logs(logs, str(path))
    return params


def test_joints_read_by_their_workers_give_the_same_report(scenario, tmp_path):
    """A Parquet log whose joints are blocks of rows is read joint by joint by the processes that draw
    them: the same HTML as reading it whole first, with one worker or two."""
    from frictid.cli.report import plan_report_logs, read_report_logs
    from frictid.report import build_report
    from frictid.report.build import DeferredLogs

    path = tmp_path / "two.parquet"
    params = _two_joint_file(scenario, path)
    planned = plan_report_logs([str(path)])
    assert [(type(x), x.joint) for x in planned] == [(DeferredLogs, scenario["joint"]),
                                                      (DeferredLogs, "second joint")]
    kw = dict(params_path="p.yaml", command="c", generated="2026-01-01 00:00 UTC", segmenter=truth_segments)
    whole = build_report(params, read_report_logs([str(path)]), jobs=1, **kw)
    assert build_report(params, planned, jobs=1, **kw) == whole
    assert build_report(params, planned, jobs=2, **kw) == whole


def test_references_dropped_only_from_the_logs_the_report_read(scenario, tmp_path, monkeypatch):
    """Once the closed loops have run, the references are dropped from the logs a worker read itself (the
    diagnosis' replays reuse that memory), never from the caller's logs; the HTML is the same either way."""
    from frictid.cli.report import plan_report_logs, read_report_logs
    from frictid.replay import REFERENCE_CHANNELS
    from frictid.report import build_report
    from frictid.report import content as ct

    def closed(k, lg):
        q = np.asarray(lg.q, float)
        lg.channels = {**lg.channels, "q_ref": q.copy(), "qd_ref": np.gradient(q, lg.t), "tau_ref": np.zeros_like(q)}
        lg.meta = {**lg.meta, "control": {"kp": 400.0, "kd": 40.0, "ki": 0.0}}

    path = tmp_path / "closed.parquet"
    params = _two_joint_file(scenario, path, spoil=closed)
    given = read_report_logs([str(path)])
    assert all(set(REFERENCE_CHANNELS) <= set(lg.channels) for lg in given)
    kw = dict(params_path="p.yaml", command="c", generated="2026-01-01 00:00 UTC", segmenter=truth_segments)
    import frictid.replay as rp

    loops, runs = [], []
    real, real_loop = ct.drop_reference_channels, rp.closed_loop
    monkeypatch.setattr(ct, "drop_reference_channels",
                        lambda datas: (loops.extend(d.own for d in datas), real(datas)))
    monkeypatch.setattr(rp, "closed_loop", lambda log, *a, **k: (
        runs.append(set(REFERENCE_CHANNELS) <= set(log.channels)), real_loop(log, *a, **k))[1])
    whole = build_report(params, given, jobs=1, **kw)
    assert all(set(REFERENCE_CHANNELS) <= set(lg.channels) for lg in given)  # the caller's: kept
    assert loops and not any(loops)
    loops.clear()
    assert build_report(params, plan_report_logs([str(path)]), jobs=1, **kw) == whole
    assert loops and all(loops)
    assert len(runs) == 4 and all(runs)  # each log's closed loop ran with its references, in both reports


def test_cli_problems_and_warnings_of_joints_read_by_workers(scenario, cli, tmp_path):
    """The joints' problems come together in one error (exit 2, the old report kept); a joint's read
    warnings reach standard error and the report."""
    def infinite(k, lg):
        lg.tau[100 + k] = np.inf

    def one_missing(k, lg):
        if k == 1:
            lg.tau[50] = np.nan

    out = tmp_path / "r.html"
    out.write_text("the old report")
    pfile = tmp_path / "p.yaml"
    for spoil, code in ((infinite, 2), (one_missing, 0)):
        path = tmp_path / f"{spoil.__name__}.parquet"
        params = _two_joint_file(scenario, path, spoil)
        pfile.write_text(yaml.safe_dump(params, sort_keys=False))
        r = cli("report", pfile, path, "-o", out)
        assert r.code == code, r
        assert "Traceback" not in r.err
        if code == 2:
            assert f"joint {scenario['joint']}: column 'tau': row 101 (line 102)" in r.err, r.err
            n = _two_joints(scenario)[1][0].n  # rows of the first joint: the second's rows follow them
            assert f"joint second joint: column 'tau': row {n + 102} (line {n + 103})" in r.err, r.err
            assert out.read_text() == "the old report"
        else:
            assert "joint second joint: dropped 1 rows with missing values" in r.err, r.err
            assert "dropped 1 rows with missing values" in out.read_text()


def test_the_fits_scales_are_reused(scenario):
    """The fit records each log's scales with its segments; the report's are the same numbers as
    measuring the log again (so its derivatives are the fit's)."""
    from frictid.io.logs import file_sha256, read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import content as ct
    from frictid.segments import estimate_scales

    params = load_params_dict(scenario["params"])
    jd = params["joints"][scenario["joint"]]
    assert all(isinstance(e.get("scales"), dict) for e in jd["segment_list"])
    lg = read_many([scenario["log"]])[0]
    got = ct.recorded_scales(lg, jd, params["sources"], file_sha256(scenario["log"]))
    want = estimate_scales(lg)
    assert got is not None and got.to_dict().keys() == want.to_dict().keys()
    for k, v in want.to_dict().items():
        assert got.to_dict()[k] == v or (v != v and got.to_dict()[k] != got.to_dict()[k]), k
    assert ct.recorded_scales(lg, jd, params["sources"], "0" * 64) is None  # another file: measured again


def test_models_without_heldout_error_are_explained(scenario):
    """A static map the fit gave no held-out error (not all identifiable, an identifiable one had one)
    shows "—" in the model table, and the table's note names it and says why; the note is absent when every
    model has its error."""
    from frictid.identify.select import NOT_HELDOUT
    from frictid.io.params_load import load_params_dict
    from frictid.report import build_report

    jid = "j-" + scenario["joint"]
    params = load_params_dict(scenario["params"])
    models = params["joints"][scenario["joint"]]["models"]
    skipped = [n for n, m in models.items() if NOT_HELDOUT in (m.get("notes") or [])]
    assert ("not computed (—)" in section_text(build_report(params, []), jid, "models")) == bool(skipped)
    for m in models.values():
        m["notes"] = [x for x in (m.get("notes") or []) if x != NOT_HELDOUT]
    assert "not computed (—)" not in section_text(build_report(params, []), jid, "models")
    name = next(n for n, m in models.items() if n != params["joints"][scenario["joint"]]["selected"]
                and "params" in m)
    models[name]["metrics"]["rms_heldout"] = None
    models[name]["notes"].append(NOT_HELDOUT)
    text = section_text(build_report(params, []), jid, "models")
    assert f"not computed (—) for {name}: their parameters are not all identifiable" in text


def test_diagnosis_replays_are_dropped_once_used_and_the_residuals_do_not_change(scenario):
    """The findings' replays stay in the cache only while a later finding needs them (each is arrays of the
    log's length); the binned residuals are the same as with every replay kept."""
    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import content as ct
    from frictid.segments import derivatives

    params = load_params_dict(scenario["params"])
    jd = params["joints"][scenario["joint"]]
    d = ct.prepare_log(read_many([scenario["log"]])[0], jd, truth_segments, derivatives, segments=[])
    sel, models = jd["selected"], list(jd["models"])
    other = next(m for m in models if m != sel and "+" not in m)
    named = {"cause": "velocity dependence", "extension": "stribeck", "model": sel}
    findings = [named, {"cause": "presliding", "extension": "lugre"}, dict(FINDING), dict(named)]
    jd2 = {**jd, "diagnosis": findings, "selection": {**jd.get("selection", {}), "diagnosis": {"base": other}}}
    befores = ct.diagnosis_befores(jd2, findings)
    assert befores == [other, sel, sel, sel]  # the base, then the model of the finding before
    assert ct.replayed_models(jd2, findings[1], sel) == set()  # judged on the ramps
    assert ct.replayed_models(jd2, findings[2], sel) == {sel}  # its extended model is a copy, never cached
    assert ct.replayed_models(jd2, named, other) == {other, sel}
    kept, dropped = {}, {}
    for i, (f, before) in enumerate(zip(findings, befores)):
        if not ct.on_sliding_samples(f):
            continue
        later = set().union(*(ct.replayed_models(jd2, g, b) for g, b in zip(findings[i + 1:], befores[i + 1:])))
        a = ct.diagnosis_residuals([d], scenario["joint"], jd2, f, before=before, cache=kept)
        b = ct.diagnosis_residuals([d], scenario["joint"], jd2, f, before=before, cache=dropped, keep=later)
        assert a is not None and b is not None
        for part in ("before", "given"):
            for key in ("x", "mean", "after"):
                if key in (a.get(part) or {}):
                    np.testing.assert_array_equal(a[part][key], b[part][key])
        assert {name for name, _, _ in dropped} <= later
    assert dropped == {} and len(kept) >= 3  # the last finding leaves nothing; without keep, all stay


# ---------------------------------------------------------------------------------------------------
# issue 21: what the report says agrees with the numbers behind it


_OFFSET: dict = {}


@pytest.fixture(scope="module")
def offset_asym(tmp_path_factory):
    """A joint with a hidden torque offset and asymmetry (the simulated hydraulic plant, no gravity,
    declared so), fitted with the diagnosis: the chosen model carries the asymmetry, whose per-sign levels
    take in the offset; the joint's ``offset`` entry is then evidence, not a term of the chosen model."""
    if not _OFFSET:
        import diag_synth as ds

        import frictid
        from frictid.io.logs import write_logs

        base = ds.null_plant("hydraulic")
        plant = ds.inject(base, "asymmetry", 0.1, "small")
        plant["joints"][0]["effects"].append({"kind": "torque_offset", "value": 0.06 * ds.friction_scale(base)})
        logs = ds.simulate(plant, "small", 5)
        ds.declare_horizontal(logs, base)
        d = tmp_path_factory.mktemp("offset")
        write_logs(logs, str(d / "run.parquet"))
        params = frictid.fit(logs, models="coulomb_viscous,stribeck").to_dict()
        _OFFSET.update(params=params, log=str(d / "run.parquet"), joint=str(logs[0].joint))
    return _OFFSET


def _prepared(case):
    import copy

    from frictid.io.logs import read_many
    from frictid.report import content as ct
    from frictid.segments import derivatives

    params = copy.deepcopy(case["params"])
    jd = params["joints"][case["joint"]]
    datas = [ct.prepare_log(lg, jd, truth_segments, derivatives) for lg in read_many([case["log"]])]
    return params, jd, datas


def _torque_from_snippet(head: dict, mapname: str, q, w, a) -> np.ndarray:
    """The joint torque as a user reads it off the snippet: its ``torque`` line evaluated with its
    ``rigid_body`` values and the friction ``F(w)`` of its parameters (the file's static map)."""
    from frictid.models.static import evaluate

    values = {n: p["value"] for n, p in head["params"].items()}
    F = evaluate(mapname, w, values)
    expr = head["torque"].split("=", 1)[1]
    expr = (expr.replace("tau_offset (in F)", "0").replace("J a", "J * a").replace("cos(q)", "* cos(q)")
            .replace("sin(q)", "* sin(q)").replace("F(w)", "F"))
    ns = dict(head["rigid_body"], a=a, q=q, F=F, cos=np.cos, sin=np.sin)
    return eval(expr, {"__builtins__": {}}, ns)


def test_offset_trap_snippet_torque_is_the_models(offset_asym):
    """The snippet is the parameter file's head: with the offset taken in by the per-sign levels its
    rigid_body offset is 0, and its torque line reproduces FrictionModel's torque within 1 %; adding the
    joint's offset estimate, as the old snippet listed it, would not."""
    import html as _html

    from frictid.report import build_report
    from frictid.report import content as ct

    params, jd, datas = _prepared(offset_asym)
    sel = jd["selected"]
    assert "+" in sel and "asym" in sel, sel  # the scenario's point: an extended, per-sign model
    html = build_report(params, [datas[0].log], segmenter=truth_segments)
    jid = "j-" + offset_asym["joint"]
    snippet = yaml.safe_load(_html.unescape(re.search(rf'<pre id="{jid}-yaml">(.*?)</pre>', html, re.S).group(1)))
    head = snippet["joints"][offset_asym["joint"]]["model"]
    m = ct.chosen_model(jd)
    assert head["name"] == sel and head["rigid_body"]["offset"] == m.offset == 0.0
    assert abs(jd["offset"]["value"]) > 10.0  # the joint's estimate: the hidden offset, not a term to add
    d = datas[0]
    mv = np.abs(d.w) > 0.05
    q, w, a = np.asarray(d.log.q, float)[mv], d.w[mv], np.nan_to_num(d.a[mv])
    want = m.J * a + m.gravity(q) + m.friction(w)
    got = _torque_from_snippet(head, jd["models"][sel]["map"], q, w, a)
    scale = np.sqrt(np.mean(want ** 2))
    assert np.sqrt(np.mean((got - want) ** 2)) < 0.01 * scale
    trap = got + jd["offset"]["value"]
    assert np.sqrt(np.mean((trap - want) ** 2)) > 0.05 * scale


def test_offset_trap_chosen_curve_passes_through_its_points(offset_asym):
    """Points and curves share the chosen model's convention: the chosen curve meets its plateau points
    (to within a fraction of the hidden offset), which the joint's convention would miss by the offset."""
    from frictid.report import content as ct

    _, jd, datas = _prepared(offset_asym)
    m = ct.chosen_model(jd)
    pl = ct.plateaus(datas, m)
    grids = ct.velocity_grids(pl, datas)
    curves, _ = ct.model_curves(jd, grids)
    chosen = next(c for c in curves if c["selected"])
    assert chosen["shift"] == 0.0
    on_grid = np.interp(pl.w, grids["lin"], chosen["lin"])
    off = abs(jd["offset"]["value"])
    miss = np.median(np.abs(pl.F - on_grid))
    assert miss < 0.15 * off, (miss, off)
    old = ct.plateaus(datas)  # the joint's convention: its offset removed from the points
    assert np.median(np.abs(old.F - on_grid)) > 0.7 * off
    assert len(curves) <= ct.MAX_CURVES
    assert len({(str(c["name"])) for c in curves}) == len(curves)


def test_findings_of_a_model_not_adopted_are_marked(offset_asym):
    """When the diagnosis' model is not the chosen one, its findings are listed as not adopted, never as
    what the chosen model found; a warning about kept evidence is not shown without findings."""
    import copy

    from frictid.report import build_report

    params = copy.deepcopy(offset_asym["params"])
    j = offset_asym["joint"]
    jd = params["joints"][j]
    diag_model = jd["selected"]
    base = jd["models"][diag_model]["base"]
    jd["selected"] = base
    jd["selection"]["diagnosis_check"] = {"model": diag_model, "kept": base, "fit_choice": base,
                                          "rms_heldout": 6.66, "rms_heldout_fit_choice": 1.95}
    jd["warnings"] = [f"joint {j}: joint {j}: the diagnosis' model {diag_model} predicts the torque of held-out "
                      f"plateau means worse (RMS 6.66) than the fit's choice {base} (1.95): {base} stays selected; "
                      "the findings are kept as evidence"]
    html = build_report(params, [])
    jid = "j-" + j
    summary = section_text(html, jid, "summary")
    assert "Found " not in summary and "not adopted" in summary and "6.66" in summary
    diag = section_text(html, jid, "diagnosis")
    assert "Not adopted: evidence only" in diag and "not adopted" in diag
    assert f"joint {j}: joint {j}:" not in html and f"joint {j}: the diagnosis" not in summary
    assert "findings are kept as evidence" in summary  # with findings the warning stays, once
    jd["diagnosis"] = []
    html = build_report(params, [])
    summary = section_text(html, jid, "summary")
    assert "findings are kept as evidence" not in summary
    assert "No finding: the diagnosis tested" in summary


def test_labels_agree_between_the_tables(offset_asym):
    """A parameter has one verdict wherever it is shown: the shape parameters the extended model holds at
    its base model's values are "held" (not "identified" without an error), the rigid-body terms carry the
    chosen model's own entries, every held-out RMS names its basis and the chosen model is not marked as not
    identifiable unless a parameter of its table is."""
    from frictid.report import build
    from frictid.report import content as ct

    params, jd, datas = _prepared(offset_asym)
    sel = jd["selected"]
    rows = {r["name"]: r for r in build.model_param_rows(jd, sel)}
    base = jd["models"][jd["models"][sel]["base"]]["params"]
    for name, p in jd["models"][sel]["params"].items():
        plain = re.sub(r"_(pos|neg)$", "", name)
        if p.get("stderr") is None and plain in base:
            assert rows[name]["status"] == "held" and "base model" in rows[name]["reason"], rows[name]
        if rows[name]["status"] == "identified":
            assert p.get("stderr") is not None and p.get("identifiable", True)
    ctx = build.joint_report(offset_asym["joint"], jd, datas)
    summary = ctx["section"]["summary"].data
    model_rows = {r["name"]: r for r in ctx["section"]["models"].data["rows"]}
    shown = {r["name"]: r["status"] for r in summary["key_params"]}
    assert all(shown[n] == rows[n]["status"] for n in shown)
    assert set(model_rows[sel]["not_identifiable"]) <= {n for n, r in rows.items() if r["status"] == "not identifiable"}
    for r in summary["rigid"]:
        key = r["name"].split(" ")[0]
        if key in jd["models"][sel]["params"]:
            assert r["status"] == rows[key]["status"]
    offset_row = next(r for r in summary["rigid"] if r["name"] == "offset")
    assert offset_row["value"] == "0" and offset_row["status"] == "held"  # its reason says why
    assert all(r["basis"] in ("plateau means", "sliding samples", "moving samples", "duty cycles")
               for r in model_rows.values())
    assert model_rows[sel]["basis"] == "sliding samples" and "on sliding samples" in summary["heldout"]
    assert all(r["aic"] != "—" or r["aic_why"] for r in model_rows.values())
    assert ct.chosen_model(jd) is not None


def test_warnings_are_cleaned_of_what_the_report_knows_better():
    from frictid.report.content import clean_warnings

    w = ["joint j1: joint j1: dropped 3 rows", "log joint j1: dropped 1 rows with missing values",
         "the diagnosis' model stribeck predicts the torque of held-out moving samples (duty cycles included) "
         "worse (RMS 3) than the fit's choice x (2): x stays selected; the findings are kept as evidence"]
    assert clean_warnings("j1", w, 0, 0) == ["dropped 3 rows", "log dropped 1 rows with missing values"]
    kept = clean_warnings("j1", w, 1, 0)[2]
    assert "duty cycles included" not in kept and "kept as evidence" in kept
    assert "duty cycles included" in clean_warnings("j1", w, 1, 3)[2]


def test_replay_headline_is_robust_to_reversal_spikes(full_report):
    """The replay's headline is the median absolute residual, beside its 95th percentile and RMS: spikes
    at a few samples move the RMS, not the headline."""
    from frictid.report.content import residual_stats

    rng = np.random.default_rng(4)
    r = rng.normal(0.0, 2.0, 10_000)
    r[::100] = 500.0
    st = residual_stats(r)
    assert st["median_abs"] == pytest.approx(np.median(np.abs(r))) and st["median_abs"] < 2.0
    assert st["rms"] > 40.0 and st["p95_abs"] < 5.0 and st["n"] == r.size
    html, _, _ = full_report
    assert re.search(r"median \|residual\| [0-9.]+ N m \(95 % below [0-9.]+, RMS [0-9.]+\)", html)


def test_screened_rows_of_the_tested_table_say_so(offset_asym):
    """A candidate the long-log screen did not try on all samples carries the stride's numbers: its row in
    the tested table is marked and a footnote says what those numbers are; a row tried on all samples is
    not marked and without a screened row there is no footnote."""
    import copy

    from frictid.report import build_report

    params = copy.deepcopy(offset_asym["params"])
    j = offset_asym["joint"]
    jid = "j-" + j
    steps = params["joints"][j]["selection"]["diagnosis"]["steps"]
    tested = [c for s in steps for c in s["tested"]]
    assert len(tested) >= 2
    diag = section_text(build_report(params, []), jid, "diagnosis")
    assert "screened" not in diag
    tested[-1]["screened"] = {"stride": 7, "samples": 52000, "explained_bound": 0.4, "explained_min": 1.2}
    html = build_report(params, [])
    diag = section_text(html, jid, "diagnosis")
    assert diag.count("screened*") == 1 and "every 7th sample" in diag and "not on all of them" in diag
    rows = [r for r in re.findall(r"<tr>(.*?)</tr>", html, re.S) if "<td class=\"num\">" in r and "screened" in r]
    assert len(rows) == 1 and tested[-1]["extension"] in rows[0]


def test_each_finding_figure_draws_its_number_on_the_direct_drive_sample():
    """The figure of each finding of the shipped direct-drive sweep draws, on the diagnosis' sliding samples,
    the RMS its held-out numbers state (within 5 %), and each extended model leaves less than the model
    before it. Its second finding (asymmetry on the stribeck repair) replayed at 0.708 N m against 0.668
    before it while stating 0.675 -> 0.646: the per-sign Stribeck amplitudes were stored as their mean."""
    from pathlib import Path

    import frictid
    from frictid.io.logs import read_logs
    from frictid.report import content as ct
    from frictid.segments import derivatives, find_segments

    logs = read_logs(str(Path(__file__).resolve().parents[1] / "sample_logs" / "direct_drive_sweep.parquet"))
    (jn, jd), = frictid.fit(logs).to_dict()["joints"].items()
    datas = [ct.prepare_log(lg, jd, find_segments, derivatives) for lg in logs]
    rows = ct.diagnosis_samples(datas, jn, jd)
    entries = [f for f in jd.get("diagnosis") or [] if isinstance(f, dict)]
    assert len(entries) >= 2
    for f, before in zip(entries, ct.diagnosis_befores(jd, entries)):
        res = ct.diagnosis_residuals(datas, jn, jd, f, before=before, rows=rows)
        assert res["samples"] == "sliding"
        assert res["rms_before"] == pytest.approx(f["rms_before"], rel=0.05), f["cause"]
        assert res["rms_after"] == pytest.approx(f["rms_after"], rel=0.05), f["cause"]
        assert res["rms_after"] < res["rms_before"], f["cause"]
