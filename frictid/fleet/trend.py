"""Each joint's friction over time, from a trend store: normalisation, change points, limits.

Per joint the store's runs are ordered by the dataset's time key (``date``, ...). The quantities are the
parameters of the joint's most frequent selected model and ``F_ref``, the friction level at a reference
speed (half the median speed the logs reached) evaluated by each run's :class:`frictid.FrictionModel`.

- **Temperature and load.** Where the model has a thermal law, ``F_ref`` is evaluated at the joint's
  reference temperature (the median of its runs' mean temperatures) and a load extension at no load, so a
  warm day is not wear. Where it has none, the day-to-day differences of a quantity are regressed on those
  of the run's mean temperature (robust, soft-L1, with an intercept that absorbs steady wear and a loss
  that ignores the one difference a step makes); a slope more than 3 standard errors from zero is removed.
- **Uncertainty.** Each run's ``F_ref`` carries its standard error (delta method from the selected model's
  covariance, which the store keeps: :mod:`.level`); parameters carry theirs from the fit.
- **Changes.** Any number of steps and wear episodes, dated (:mod:`.changes`): penalised segmentation
  (``ruptures.Dynp``, the choice between explanations by chi^2 + 2 p ln n) with each run weighted by its
  standard error combined with the series' own scatter.
- **Limits.** ``Fc=+20%`` (rise only), ``Fc=-10%`` (fall only), ``F_ref=15%`` (either way), ``sigma2=0.5``
  (in its unit): the fitted change from the first run to the last is compared with the limit.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from ..io.params import read_params
from ..compare import parse_tolerances
from ..errors import FrictidInputError
from .changes import changes_of, design_fit, segment
from .level import covariance_from_json, level_with_stderr
from .dataset import KeySpec, check_keys, time_key
from .store import COLUMNS, TrendStore

#: The quantity the joint's verdict is taken from.
LEVEL = "F_ref"
#: Fewest runs for a verdict.
MIN_RUNS = 6


@dataclass
class Limit:
    name: str
    value: float
    relative: bool
    sign: int  # +1 rise only, -1 fall only, 0 either

    def covers(self, quantity: str) -> bool:
        return self.name in ("*", quantity) or quantity.removesuffix("_pos").removesuffix("_neg") == self.name

    def crossed(self, base: float, last: float) -> float | None:
        """The change (relative or in the unit) when it crosses the limit, else None."""
        d = last - base
        amount = d / abs(base) if self.relative else d
        if self.relative and base == 0:
            return None
        if (self.sign >= 0 and amount > self.value) or (self.sign <= 0 and amount < -self.value):
            return amount
        return None

    def __str__(self) -> str:
        s = {1: "+", -1: "-", 0: ""}[self.sign]
        return f"{self.name}={s}{self.value * 100 if self.relative else self.value:g}{'%' if self.relative else ''}"


def parse_limits(text: str | None) -> list[Limit]:
    """``"Fc=+20%,F_ref=15%,sigma2=0.5"`` -> limits (a sign: that direction only)."""
    out = []
    for item in (text or "").split(","):
        if not item.strip():
            continue
        m = re.fullmatch(r"\s*([^=\s]+)\s*=\s*([+-]?)(.*)", item)
        if not m:
            raise FrictidInputError(f"--limit: {item!r} is not NAME=LIMIT (e.g. Fc=+20% or F_ref=15%)")
        try:
            (tol,) = parse_tolerances(f"{m.group(1)}={m.group(3)}")
        except FrictidInputError as exc:
            raise FrictidInputError(str(exc).replace("--tol", "--limit")) from None
        out.append(Limit(tol.pattern, tol.limit, tol.relative, {"+": 1, "-": -1, "": 0}[m.group(2)]))
    return out


@dataclass
class SeriesTrend:
    """One quantity of one joint over its runs, and the explanation chosen for it."""

    quantity: str
    unit: str
    dates: list[str]
    y: np.ndarray
    stderr: np.ndarray
    temp: np.ndarray
    normalised: str = "none"  # model | regression | none
    temp_coeff: float = 0.0
    sigma: float = math.nan
    kind: str = "steady"  # steady | step | wear | too few runs
    index: int | None = None
    fitted: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scores: dict = field(default_factory=dict)
    #: the values after the temperature regression (equal to ``y`` when none was needed)
    y_norm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: every change found, in order: kind (step | wear), index and date of its run, size [unit]
    changes: list = field(default_factory=list)

    @property
    def date(self) -> str | None:
        return self.dates[self.index] if self.index is not None else None

    @property
    def change(self) -> float:
        return float(self.fitted[-1] - self.fitted[0]) if len(self.fitted) else math.nan

    @property
    def change_rel(self) -> float:
        base = self.fitted[0] if len(self.fitted) else math.nan
        return self.change / abs(base) if base else math.nan

    def to_dict(self) -> dict:
        return {"quantity": self.quantity, "unit": self.unit, "kind": self.kind, "date": self.date,
                "change": self.change, "change_rel": self.change_rel, "sigma": self.sigma,
                "normalised": self.normalised, "temp_coeff": self.temp_coeff, "scores": self.scores,
                "changes": self.changes,
                "runs": [{"date": d, "value": v, "normalised": n, "stderr": s, "temp": t, "fitted": f}
                         for d, v, n, s, t, f in zip(self.dates, self.y, self.y_norm, self.stderr, self.temp,
                                                     self.fitted)]}


def temperature_slope(y: np.ndarray, temp: np.ndarray) -> float:
    """A first estimate of d y / d T from the day-to-day differences (robust, soft-L1, with an intercept
    that takes up steady wear; the one difference a step makes hardly bends it); 0 with fewer than 5."""
    dy, dT = np.diff(y), np.diff(temp)
    ok = np.isfinite(dy) & np.isfinite(dT)
    dy, dT = dy[ok], dT[ok]
    if len(dy) < 5 or not np.ptp(dT):
        return 0.0
    scale = 1.4826 * np.median(np.abs(dy - np.median(dy))) or np.std(dy) or 1.0
    fit = least_squares(lambda p: p[0] + p[1] * dT - dy, [np.median(dy), 0.0], loss="soft_l1", f_scale=scale)
    return float(fit.x[1])


def explain(st: SeriesTrend) -> SeriesTrend:
    """Find the series' changes (:mod:`.changes`), with its temperature term fitted alongside when the
    model did not normalise it: none (steady), or steps and wear episodes, each dated; ``kind`` names
    them in order (``wear+step``)."""
    y = st.y.astype(float)
    if len(y) < MIN_RUNS:
        st.kind, st.fitted, st.y_norm = "too few runs", np.full(len(y), np.nanmean(y) if len(y) else np.nan), y
        return st
    tc = None
    if st.normalised != "model" and np.isfinite(st.temp).all() and np.ptp(st.temp) > 0:
        tc = st.temp - np.median(st.temp)
    seg, s, steady = segment(y, st.stderr, tc, temperature_slope(y, st.temp) if tc is not None else 0.0)
    if tc is not None:  # the term is c tc times the level: its effect at the median level is c tc
        st.normalised, st.temp_coeff = "regression", float(seg.coef[-1])
        effect = seg.fitted - design_fit(seg)
    st.y_norm = y - effect if tc is not None else y
    st.fitted = seg.fitted - effect if tc is not None else seg.fitted
    st.sigma = float(np.median(s))
    st.changes = changes_of(seg)
    for c in st.changes:
        c["date"] = st.dates[c["index"]]
    st.scores = {"steady": steady.score, "chosen": seg.score}
    if st.changes:
        st.kind = "+".join(c["kind"] for c in st.changes)
        st.index = max(st.changes, key=lambda c: abs(c["size"]))["index"]
    else:
        st.kind, st.index = "steady", None
    return st


@dataclass
class JointTrend:
    joint: str
    keys: dict
    series: dict[str, SeriesTrend]
    crossings: list[dict] = field(default_factory=list)
    failed: list[dict] = field(default_factory=list)

    @property
    def level(self) -> SeriesTrend | None:
        return self.series.get(LEVEL)

    @property
    def kind(self) -> str:
        return self.level.kind if self.level else "no level"

    @property
    def score(self) -> float:
        """How much the joint changed: the level's largest departure from its first run, in noise units
        (a fault that maintenance undid counts too)."""
        lv = self.level
        if not lv or not lv.sigma or not np.isfinite(lv.sigma) or not len(lv.fitted):
            return 0.0
        return float(np.max(np.abs(lv.fitted - lv.fitted[0]))) / lv.sigma

    def to_dict(self) -> dict:
        lv = self.level
        return {"joint": self.joint, "keys": self.keys, "kind": self.kind, "date": lv.date if lv else None,
                "change_rel": lv.change_rel if lv else None, "score": self.score, "crossings": self.crossings,
                "failed_runs": self.failed, "quantities": {q: s.to_dict() for q, s in self.series.items()}}


def reference_level(path: Path, joint: str, w_ref: float, T_ref: float, cov_json) -> dict:
    """F_ref of a parameter file's selected model at +-w_ref (mean of the magnitudes), at T_ref where the
    model has a thermal law, load and position neutral, with its standard error from the covariance the
    store kept (:func:`.level.level_with_stderr`)."""
    jf = read_params(path).joints[str(joint)]
    return level_with_stderr(jf, jf.selected, w_ref, T_ref, covariance_from_json(cov_json))


@dataclass
class FleetTrend:
    """Every joint's trend, most changed first, and the store's failed partitions."""

    store: str
    time_key: str | None
    joints: list[JointTrend]
    failed: list[dict]
    limits: list[Limit]

    @property
    def crossings(self) -> list[dict]:
        return [dict(c, joint=j.joint) for j in self.joints for c in j.crossings]

    def to_dict(self) -> dict:
        kinds = {}
        for j in self.joints:
            kinds[j.kind] = kinds.get(j.kind, 0) + 1
        return {"store": self.store, "time_key": self.time_key, "limits": [str(x) for x in self.limits],
                "summary": {"joints": len(self.joints), "kinds": kinds, "crossings": len(self.crossings),
                            "failed_partitions": len(self.failed)},
                "joints": [j.to_dict() for j in self.joints], "failed": self.failed}


def _sort_key(s: pd.Series) -> pd.Series:
    num = pd.to_numeric(s, errors="coerce")
    return num if num.notna().all() else s.astype(str)


def _level_series(runs: pd.DataFrame, root: Path, joint: str, tk: str, unit: str) -> SeriesTrend:
    w_ref = 0.5 * float(np.nanmedian(runs["speed_hi"]))
    T_ref = float(np.nanmedian(runs["temp_mean"])) if runs["temp_mean"].notna().any() else 25.0
    levels = [reference_level(root / f, joint, w_ref, T_ref, c) for f, c in zip(runs["params_file"], runs["cov"])]
    by_model = bool(levels) and all(lv["thermal"] for lv in levels)
    return SeriesTrend(LEVEL, unit, runs[tk].astype(str).tolist(), np.array([lv["value"] for lv in levels]),
                       np.array([lv["stderr"] for lv in levels]), runs["temp_mean"].to_numpy(float),
                       normalised="model" if by_model else "none")


def _param_series(rows: pd.DataFrame, tk: str) -> dict[str, SeriesTrend]:
    out = {}
    model = rows["model"].mode().iloc[0]
    for name, g in rows[rows["model"] == model].groupby("param", sort=True):
        g = g[g["identifiable"].astype(bool) & np.isfinite(g["value"].to_numpy(float))]
        g = g.sort_values(tk, key=_sort_key)
        if len(g) >= MIN_RUNS and np.ptp(g["value"].to_numpy(float)) > 0:  # a fixed parameter has no trend
            out[str(name)] = SeriesTrend(str(name), str(g["unit"].iloc[0]), g[tk].astype(str).tolist(),
                                         g["value"].to_numpy(float), g["stderr"].to_numpy(float),
                                         g["temp_mean"].to_numpy(float))
    return out


def joint_trend(rows: pd.DataFrame, root: Path, tk: str, keys: dict, limits: list[Limit]) -> JointTrend:
    """The trend of one joint from its rows of the store."""
    joint = str(rows["log_joint"].iloc[0])
    runs = rows.drop_duplicates("partition").sort_values(tk, key=_sort_key)
    runs = runs[runs["params_file"].astype(bool) & runs["model"].notna()]
    units = rows.loc[rows["param"].astype(str).str.startswith("F"), "unit"]
    series = {LEVEL: _level_series(runs, root, joint, tk, str(units.iloc[0]) if len(units) else "")}
    series.update(_param_series(rows[rows["param"].notna()], tk))
    jt = JointTrend("/".join(f"{k}={v}" for k, v in keys.items()) + (f"#{joint}" if keys.get("joint") != joint else ""),
                    keys, {q: explain(s) for q, s in series.items()})
    for lim in limits:
        for q, s in jt.series.items():
            amount = lim.crossed(float(s.fitted[0]), float(s.fitted[-1])) if len(s.fitted) and lim.covers(q) else None
            if amount is not None:
                jt.crossings.append({"quantity": q, "limit": str(lim), "change": amount,
                                     "from": float(s.fitted[0]), "to": float(s.fitted[-1]), "date": s.date})
    return jt


def trend_fleet(store: str, limits: list[Limit] = (), keys: KeySpec | None = None) -> FleetTrend:
    """Every joint's trend in a store (``frictid trend STORE``). ``keys``: which of the store's dataset
    keys name a joint and which orders its runs (default: the time key by :func:`time_key`, the other keys
    name the joint)."""
    st = TrendStore(store)
    if not st.exists():
        raise FrictidInputError(f"{store}: not a trend store (make one with frictid fit DATASET --engine dask -o {store})")
    df = st.latest()
    if df.empty:
        raise FrictidInputError(f"{store}: the trend store has no rows")
    key_names = [c for c in df.columns if c not in COLUMNS]
    check_keys(keys, key_names, f"the store {store}")
    tk = keys.time if keys else time_key(key_names) or "partition"
    ident = list(keys.joint) if keys else [k for k in key_names if k != tk]
    bad = df[df["status"] != "ok"]
    failed = [{"partition": p, "kind": k, "reason": r}
              for p, k, r in zip(bad["partition"], bad["error_kind"], bad["reason"])]
    ok = df[df["status"] == "ok"]
    joints = []
    for vals, rows in ok.groupby(ident + ["log_joint"], sort=True, dropna=False):
        kv = dict(zip(ident, vals if isinstance(vals, tuple) else (vals,)))
        twice = rows.drop_duplicates("partition")[tk].duplicated()
        if twice.any():
            raise FrictidInputError(f"joint {'/'.join(f'{k}={v}' for k, v in kv.items())} ({vals[-1]}) has more than "
                                    f"one run at {tk}={rows.drop_duplicates('partition')[tk][twice].iloc[0]}: name the "
                                    f"keys that tell its joints apart with --keys (the store's keys: {', '.join(key_names)})")
        jt = joint_trend(rows, st.path, tk, kv, list(limits))
        mine = bad[np.logical_and.reduce([bad[k] == v for k, v in kv.items()])] if kv else bad
        jt.failed = [{"partition": p, "reason": r} for p, r in zip(mine["partition"], mine["reason"])]
        joints.append(jt)
    joints.sort(key=lambda j: -j.score)
    return FleetTrend(str(store), tk, joints, failed, list(limits))
