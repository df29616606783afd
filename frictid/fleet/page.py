"""The trend page: one self-contained HTML file. A fleet overview (every joint, most changed first: its
verdict, the date, the change of its friction level, limits crossed) and per joint its quantities over
time (matplotlib SVG inline, as the report draws them): the values after normalisation with a band of
+-2 standard errors (or +-2 sigma of the scatter where a run has none), the chosen explanation, the date of
each step and each onset of wear."""
from __future__ import annotations

import html

import numpy as np

from ..io.atomic import atomic_open
from ..report.figures import new_figure, place, rc_context, render
from ..version import __version__
from .trend import FleetTrend, JointTrend

#: Quantities drawn per joint (the level first, then the model's parameters in order).
MAX_PANELS = 4

_CSS = """body{font:14px/1.4 system-ui,sans-serif;margin:1.5em auto;max-width:980px;color:#222}
table{border-collapse:collapse;margin:.5em 0}td,th{border-bottom:1px solid #ddd;padding:.2em .6em;text-align:left}
.fig{width:100%;height:auto}.step{color:#b35900}.wear{color:#b00020}.cross{font-weight:bold;color:#b00020}
h2{margin-top:1.6em}"""


def _figure(jt: JointTrend):
    series = list(jt.series.values())[:MAX_PANELS]
    fig = new_figure(1.6 + 1.5 * len(series))
    axes = fig.subplots(len(series), 1, sharex=True, squeeze=False)[:, 0]
    fig.subplots_adjust(**place(fig, rows=len(series)))
    dates = sorted({d for s in series for d in s.dates})  # a parameter may lack some runs: same x for all
    for ax, s in zip(axes, series):
        x = np.array([dates.index(d) for d in s.dates])
        band = np.where(np.isfinite(s.stderr), 2 * s.stderr, 2 * s.sigma if np.isfinite(s.sigma) else 0.0)
        y = s.y_norm if len(s.y_norm) else s.y
        ax.fill_between(x, y - band, y + band, color="#9ecae1", alpha=0.5, lw=0)
        ax.plot(x, y, "o", ms=3, color="#08519c", label="normalised" if s.normalised != "none" else "value")
        if s.normalised == "regression":
            ax.plot(x, s.y, ".", ms=2, color="#999999", label="as fitted")
        ax.plot(x, s.fitted, "-", color="#b00020", lw=1.2, label=s.kind)
        for c in s.changes:  # every change: a step dashed, the onset of wear dotted
            ax.axvline(x[c["index"]], color="#b35900", ls="--" if c["kind"] == "step" else ":", lw=0.8)
        ax.set_ylabel(f"{s.quantity} [{s.unit}]" if s.unit else s.quantity)
        ax.legend(loc="best", fontsize=7, frameon=False)
    ticks = np.unique(np.linspace(0, len(dates) - 1, min(6, len(dates))).astype(int))
    axes[-1].set_xticks(ticks, [dates[i] for i in ticks])
    axes[-1].set_xlabel("run")
    return fig


def joint_svg(jt: JointTrend) -> str:
    with rc_context(f"fleet-{jt.joint}"):
        fig = _figure(jt)
        return render(fig, f"{jt.joint}: friction quantities over time", f"fleet-{jt.joint}").data


def _row(jt: JointTrend) -> str:
    lv = jt.level
    rel = f"{lv.change_rel * 100:+.1f} %" if lv is not None and np.isfinite(lv.change_rel) else ""
    cross = ", ".join(f"{c['quantity']} {c['limit']}" for c in jt.crossings)
    return (f"<tr><td><a href='#{html.escape(jt.joint)}'>{html.escape(jt.joint)}</a></td>"
            f"<td class='{jt.kind.split('+')[0]}'>{jt.kind}</td><td>{html.escape(str(lv.date or '')) if lv else ''}</td>"
            f"<td>{rel}</td><td>{jt.score:.1f}</td><td class='cross'>{html.escape(cross)}</td>"
            f"<td>{len(jt.failed)}</td></tr>")


def build_page(ft: FleetTrend) -> str:
    """The page's HTML."""
    d = ft.to_dict()["summary"]
    parts = [f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>frictid trend</title>"
             f"<style>{_CSS}</style></head><body><h1>Friction trend of {d['joints']} joints</h1>",
             f"<p>Store <code>{html.escape(ft.store)}</code>, time key <code>{html.escape(str(ft.time_key))}</code>; "
             f"verdicts {html.escape(', '.join(f'{k}: {v}' for k, v in d['kinds'].items()))}; "
             f"{d['crossings']} limit crossing(s) ({html.escape(', '.join(map(str, ft.limits)) or 'no limits')}); "
             f"{d['failed_partitions']} failed partition(s). frictid {__version__}.</p>",
             "<h2>Fleet overview</h2><table><tr><th>joint</th><th>verdict</th><th>date</th><th>level change</th>"
             "<th>largest departure / sigma</th><th>limits crossed</th><th>failed runs</th></tr>",
             *(_row(j) for j in ft.joints), "</table>"]
    if ft.failed:
        parts.append("<h2>Failed partitions</h2><table><tr><th>partition</th><th>kind</th><th>reason</th></tr>"
                     + "".join(f"<tr><td>{html.escape(f['partition'])}</td><td>{html.escape(str(f['kind']))}</td>"
                               f"<td>{html.escape(str(f['reason']))}</td></tr>" for f in ft.failed) + "</table>")
    for jt in ft.joints:
        parts.append(f"<h2 id='{html.escape(jt.joint)}'>{html.escape(jt.joint)}: {jt.kind}</h2>")
        parts.append(joint_svg(jt) if jt.series else "<p>no runs with a model</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_page(ft: FleetTrend, path) -> None:
    """Write the page atomically."""
    text = build_page(ft)
    with atomic_open(path, "w") as fh:
        fh.write(text)
