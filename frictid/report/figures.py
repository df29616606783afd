"""The report's figures: matplotlib (Agg, object API, no pyplot, no display) rendered to inline SVG, or to
PNG when a figure would draw too many points for a light SVG.

matplotlib is imported inside the functions only (the imports left inside functions here are all
matplotlib's), so importing :mod:`frictid.report` does not load it and the numerics layers never do. Every axis carries its unit. Colours are the Okabe-Ito palette (safe for
the common colour-vision deficiencies) and every series that colour tells apart is also told apart by line
style or marker, so the figures survive greyscale printing.

Figures downsample what they *draw* (min/max per pixel column for time series, a stride for short curves);
the numbers behind them are never touched.
"""
from __future__ import annotations

import base64
import functools
import gc
import io
import math
import re
from dataclasses import dataclass

import numpy as np

from frictid.segments.runs import paint, runs

#: Okabe-Ito colours (Wong 2011, Nature Methods 8:441); yellow is left out (too light on white paper).
BLACK, ORANGE, SKY, GREEN, BLUE, VERMILLION, PURPLE, GREY = (
    "#000000", "#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7", "#8C8C8C")

#: (colour, line style, marker) of the n-th model: distinct in colour *and* in dash pattern.
SERIES = (
    (BLUE, "-", "o"), (VERMILLION, (0, (6, 2)), "s"), (GREEN, (0, (1, 1.5)), "^"),
    (PURPLE, (0, (6, 2, 1, 2)), "D"), (ORANGE, (0, (3, 1.5)), "v"), (SKY, (0, (8, 2, 1, 2, 1, 2)), "P"),
    (BLACK, (0, (2, 3)), "X"), (GREY, (0, (10, 3)), "*"), (VERMILLION, (0, (1, 3)), "h"),
    (BLUE, (0, (4, 1, 1, 1, 1, 1)), "<"),
)

#: Segment kinds: colour and label; the timeline also gives every kind its own row.
KIND_STYLE = {
    "constant_velocity": (BLUE, "constant velocity"),
    "ramp_presliding": (ORANGE, "ramp (presliding)"),
    "step": (VERMILLION, "step"),
    "duty_cycle": (GREEN, "duty cycle"),
    "rest": (GREY, "rest"),
    "other": (SKY, "other"),
}
#: Kinds shaded behind the signals (rest and other only get their ribbon row).
SHADED = ("constant_velocity", "ramp_presliding", "step", "duty_cycle")

#: Width of the figures [in] and their resolution [px/in]: 1000 px, the columns of the decimation.
WIDTH_IN = 10.0
DPI = 100
COLUMNS = int(WIDTH_IN * DPI)
#: Above this many drawn points a figure is written as PNG instead of SVG.
PNG_ABOVE = 40000
#: A point drawn with error bars in both directions costs about as many SVG bytes as this many points of
#: a line (marker, two bars, four caps: some 700 bytes against about 15 per line vertex).
ERRORBAR_POINTS = 50
#: An SVG larger than this [bytes] is written as PNG instead (a safety net for figures the point count
#: underestimates).
SVG_MAX_BYTES = 400_000

RC = {
    "svg.fonttype": "none",  # text stays text: smaller files, selectable, printed by the browser's font
    "font.family": ["DejaVu Sans"],
    "font.size": 9.0,
    "axes.titlesize": 9.5,
    # titles at a fixed height above the axes (no axes has tick labels or a label on top): matplotlib's
    # automatic placement measured every x axis's ticks again at each draw (about 8 % of the figures' time)
    "axes.titley": 1.0,
    "axes.labelsize": 9.0,
    "legend.fontsize": 8.0,
    "axes.grid": True,
    "grid.color": "#d9d9d9",
    "grid.linewidth": 0.6,
    "axes.axisbelow": True,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "lines.linewidth": 1.3,
    "errorbar.capsize": 1.5,
    "path.simplify": True,
    "path.simplify_threshold": 0.2,
    "figure.dpi": DPI,
    "savefig.dpi": DPI,
    "figure.facecolor": "white",
    "axes.formatter.useoffset": False,
    "axes.formatter.limits": (-4, 5),
}


#: SVG text keeps matplotlib's font first and falls back on fonts of similar width, then any sans-serif.
FONT_STACK = "font-family: 'DejaVu Sans', Verdana, 'Bitstream Vera Sans', Arial, sans-serif"


@dataclass
class Rendered:
    """A rendered figure: ``kind`` "svg" (``data`` is the markup) or "png" (``data`` is base64)."""

    kind: str
    data: str
    alt: str
    width: int
    height: int
    points: int = 0
    axes: list = None  # (x label, y label, x tick labels shown) per axes, for checks

    @property
    def nbytes(self) -> int:
        return len(self.data)


def preload() -> None:
    """Import what rendering needs (matplotlib's figure, Agg and SVG backends, its font list) ahead of
    forking workers, so that they inherit it instead of importing it each."""
    from matplotlib.backends import backend_agg, backend_svg  # noqa: F401
    from matplotlib.figure import Figure  # noqa: F401
    from matplotlib.font_manager import fontManager  # noqa: F401


def new_figure(height_in: float):
    """A matplotlib Figure on the Agg canvas (no pyplot, no global figure manager)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(WIDTH_IN, height_in), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


#: Fixed margins [in] of every figure: room for the y tick labels and label (left), the x tick labels and
#: label (bottom) and the title (top). A fixed layout instead of matplotlib's constrained layout, which
#: measured every text of a figure twice and took about 45 % of the figures' time.
LEFT_IN, RIGHT_IN, TOP_IN, BOTTOM_IN = 0.95, 0.2, 0.32, 0.55
#: Gap [in] between stacked axes sharing their x axis, and between axes that each have a title and an
#: x label.
TIGHT_GAP_IN, TITLED_GAP_IN, SIDE_GAP_IN = 0.12, 0.85, 0.95


def place(fig, rows: int = 1, cols: int = 1, *, left: float = LEFT_IN, bottom: float = BOTTOM_IN,
          top: float = TOP_IN, hgap: float = TIGHT_GAP_IN, wgap: float = SIDE_GAP_IN, right: float = RIGHT_IN) -> dict:
    """``subplots_adjust`` arguments of a fixed layout given in inches: margins and the gaps between
    ``rows`` x ``cols`` axes (matplotlib takes the gaps as fractions of the mean axes size)."""
    w, h = fig.get_size_inches()
    ah = max((h - top - bottom - (rows - 1) * hgap) / rows, 0.1)
    aw = max((w - left - right - (cols - 1) * wgap) / cols, 0.1)
    return {"left": left / w, "right": 1 - right / w, "top": 1 - top / h, "bottom": bottom / h,
            "hspace": hgap / ah, "wspace": wgap / aw}


#: Height [in] of one row of a legend drawn under the axes (outside the data).
LEGEND_ROW_IN = 0.2


def legend_below(fig, handles, ncol: int) -> None:
    """The figure's legend in its bottom margin, centred, outside every axes (the caller leaves
    ``LEGEND_ROW_IN`` per row of room under the x label)."""
    if handles:
        fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=max(1, ncol),
                   frameon=False)


def log_ticks(axis, lo: float, hi: float) -> None:
    """Readable ticks on a logarithmic axis from ``lo`` to ``hi``: labelled at 1, 2, 5 per decade over
    less than two decades, at the decades otherwise, as plain numbers; minor ticks unlabelled (matplotlib
    labels them on short ranges, where they overlap)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    decades = math.log10(hi / lo) if lo > 0 and hi > lo else 1.0
    axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0) if decades < 2 else (1.0,), numticks=12))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def rc_context(salt: str = "frictid"):
    """matplotlib settings of the report; ``salt`` makes the SVG element ids unique per figure."""
    import matplotlib

    rc = dict(RC)
    rc["svg.hashsalt"] = salt
    return matplotlib.rc_context(rc)


_SVG_HEAD = re.compile(r"^.*?(<svg\b)", re.S)
_SVG_SIZE = re.compile(r'\s(width|height)="[^"]*"')


def render(fig, alt: str, salt: str, points: int = 0, png_above: int = PNG_ABOVE) -> Rendered:
    """Render a figure: inline SVG (XML prologue dropped, sized by CSS) or, above ``png_above`` drawn
    points or :data:`SVG_MAX_BYTES` of SVG, a PNG. ``alt`` describes the figure for screen readers and
    when images are off."""
    w, h = (int(round(x * DPI)) for x in fig.get_size_inches())
    _ticks_in_view(fig)
    buf = io.BytesIO()
    if points > png_above:
        fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
        return Rendered("png", base64.b64encode(buf.getvalue()).decode("ascii"), alt, w, h, points, _labels(fig))
    fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
    if buf.tell() > SVG_MAX_BYTES:
        return render(fig, alt, salt, points, png_above=-1)
    axes = _labels(fig)
    svg = buf.getvalue().decode("utf-8")
    svg = _SVG_HEAD.sub(r"\1", svg, count=1)
    head_end = svg.index(">")
    head = _SVG_SIZE.sub("", svg[:head_end])
    svg = (head + f' class="fig" role="img" aria-label="{_attr(alt)}" preserveAspectRatio="xMidYMid meet"'
           + svg[head_end:])
    svg = re.sub(r"<metadata>.*?</metadata>\s*", "", svg, count=1, flags=re.S)
    svg = svg.replace("font-family: 'DejaVu Sans'", FONT_STACK)
    svg = _prefix_ids(svg, re.sub(r"[^A-Za-z0-9_-]", "-", salt) + "-")
    return Rendered("svg", svg, alt, w, h, points, axes)


def _ticks_in_view(fig) -> None:
    """Fix every axis's ticks at the locations its locators give inside the view limits, kept as a draw
    keeps them (in the axis's scale, within 1e-10 of the span): the same picture. matplotlib makes a tick
    (three lines, two texts) for every location a locator gives, also those beyond the limits that it does
    not draw (a quarter of the report's ticks), and it ran the locators again at every draw: about 10 % of
    the figures' time. Shared axes share their locators."""
    from matplotlib.ticker import FixedLocator, NullLocator

    done = set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if id(axis.major) in done:
                continue
            done.add(id(axis.major))
            tr = axis.get_transform()
            a, b = sorted(tr.transform(axis.get_view_interval()))
            tol = 1e-10 * (b - a)
            for ticker, locs, setter in ((axis.major, axis.get_majorticklocs, axis.set_major_locator),
                                         (axis.minor, axis.get_minorticklocs, axis.set_minor_locator)):
                if isinstance(ticker.locator, NullLocator):
                    continue
                locs = np.asarray(locs(), float)
                v = tr.transform(locs)
                setter(FixedLocator(locs[(v >= a - tol) & (v <= b + tol)]))


def _prefix_ids(svg: str, prefix: str) -> str:
    """Make the element ids of one inline SVG unique in the page (matplotlib numbers them per figure:
    axes_1, patch_1, ...) and keep its internal references (href="#...", url(#...)) pointing at them.

    Plain replacements: matplotlib writes every id as an attribute (' id="') and refers only to ids of the
    same SVG; regular expressions took about 5 % of the figures' time."""
    return (svg.replace(' id="', f' id="{prefix}').replace('href="#', f'href="#{prefix}')
            .replace("url(#", f"url(#{prefix}"))


def _labels(fig) -> list[tuple[str, str, bool]]:
    """(x label, y label, whether x tick labels are shown) of every axes of a drawn figure."""
    out = []
    for ax in fig.axes:
        shown = any(t.get_visible() and t.get_text() for t in ax.get_xticklabels())
        out.append((ax.get_xlabel(), ax.get_ylabel(), shown))
    return out


def _attr(s: str) -> str:
    return (s.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;").replace(">", "&gt;"))


# ---------------------------------------------------------------------------------------------------
# decimation of what is drawn


def minmax_decimate(x: np.ndarray, y: np.ndarray, columns: int = COLUMNS) -> tuple[np.ndarray, np.ndarray]:
    """At most ``2 * columns`` points that draw the same picture as (x, y) at ``columns`` pixels: the
    minimum and the maximum of y in each column of consecutive samples, in time order.

    x is assumed to advance roughly evenly (a log's time); non-finite y are ignored within a column.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    n = x.size
    if n <= 2 * columns:
        return x, y
    k = int(math.ceil(n / columns))
    m = int(math.ceil(n / k))
    pad = m * k - n
    yp = np.concatenate([y, np.full(pad, y[-1])]) if pad else y
    blocks = yp.reshape(m, k)
    lo, hi = np.argmin(blocks, axis=1), np.argmax(blocks, axis=1)
    rows = np.arange(m)
    # a NaN or an infinity in a column is what argmin or argmax picks there: the picked values tell whether
    # the series is finite without a pass over it (a third of the time; the common case: no masked copies)
    if not (np.isfinite(blocks[rows, lo]).all() and np.isfinite(blocks[rows, hi]).all()):
        finite = np.isfinite(blocks)
        lo = np.argmin(np.where(finite, blocks, np.inf), axis=1)
        hi = np.argmax(np.where(finite, blocks, -np.inf), axis=1)
    base = rows * k
    first = np.minimum(lo, hi) + base
    second = np.maximum(lo, hi) + base
    idx = np.empty(2 * m, dtype=np.int64)
    idx[0::2] = first
    idx[1::2] = second
    idx = np.minimum(idx, n - 1)
    return x[idx], y[idx]


def kind_spans(segments: list[tuple[str, float, float]], lo: float, hi: float, columns: int = COLUMNS
               ) -> dict[str, list[tuple[float, float]]]:
    """Segments (kind, t_start, t_end) merged per kind at the resolution of ``columns`` pixels:
    (start, width) rectangles, at most ``columns / 2`` per kind whatever the number of segments."""
    out: dict[str, list[tuple[float, float]]] = {}
    span = hi - lo
    if not segments or span <= 0:
        return out
    by_kind: dict[str, list[tuple[float, float]]] = {}
    for kind, a, b in segments:
        by_kind.setdefault(kind, []).append((a, b))
    px = span / columns
    for kind, rows in by_kind.items():
        a = np.array([r[0] for r in rows], float)
        b = np.array([r[1] for r in rows], float)
        c0 = np.clip(np.floor((a - lo) / px).astype(int), 0, columns - 1)
        c1 = np.clip(np.ceil((b - lo) / px).astype(int), 1, columns)
        c1 = np.maximum(c1, c0 + 1)
        cov = np.zeros(columns, dtype=bool)  # the pixel columns a segment of this kind covers
        paint(cov, c0, c1, True)
        out[kind] = [(lo + s * px, (e - s) * px) for s, e in zip(*runs(cov))]
    return out


def time_axis(span_s: float) -> tuple[float, str]:
    """Divisor and label of the time axis: seconds, or minutes for logs longer than 20 minutes."""
    return (60.0, "time [min]") if span_s > 1200 else (1.0, "time [s]")


def si_scale(values: np.ndarray, unit: str) -> tuple[float, str]:
    """A factor and unit with an SI prefix (m, µ, n) so that small displacements read well."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    top = float(np.max(np.abs(v))) if v.size else 1.0
    for f, p in ((1.0, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n")):
        if top >= f or f == 1e-9:
            return f, p + unit
    return 1.0, unit


def _finite_limits(arrays, pad: float = 0.08) -> tuple[float, float] | None:
    vals = [np.asarray(a, float).ravel() for a in arrays if a is not None and np.size(a)]
    if not vals:
        return None
    v = np.concatenate(vals)
    v = v[np.isfinite(v)]
    if not v.size:
        return None
    lo, hi = float(v.min()), float(v.max())
    d = hi - lo if hi > lo else max(abs(hi), 1.0)
    return lo - pad * d, hi + pad * d


# ---------------------------------------------------------------------------------------------------
# the figures


def _gc_paused(figure_function):
    """Run a figure function with Python's cyclic garbage collector paused (and resumed as it was).

    A figure is 5 000 to 25 000 objects alive until it is rendered: the collections its allocations
    triggered moved them to the oldest generation, whose collections then went through every object of the
    process (in the report, about 30 % of the figures' time). Paused, the dead figure is freed by the next
    collection of the youngest generation (about 5 ms)."""
    @functools.wraps(figure_function)
    def paused(*args, **kwargs):
        enabled = gc.isenabled()
        gc.disable()
        try:
            return figure_function(*args, **kwargs)
        finally:
            if enabled:
                gc.enable()
    return paused


@_gc_paused
def timeline(t, q, w, tau, segments, units: dict, title: str, salt: str) -> Rendered:
    """Position, velocity and torque over the whole log with the segment kinds: one ribbon row per kind
    (readable without colour) and the identification kinds shaded behind the signals."""
    t = np.asarray(t, float)
    lo, hi = float(t[0]), float(t[-1])
    div, tlabel = time_axis(hi - lo)
    spans = kind_spans(segments, lo, hi)
    rows = [("position", q, units["q"]), ("velocity", w, units["qd"]), ("torque", tau, units["tau"])]
    rows = [r for r in rows if r[1] is not None]
    with rc_context(salt):
        fig = new_figure(1.7 + 1.75 * len(rows))
        gs = fig.add_gridspec(len(rows) + 1, 1, height_ratios=[1.6] + [2.0] * len(rows),
                              **place(fig, len(rows) + 1, left=1.45))
        rib = fig.add_subplot(gs[0])
        axes = [fig.add_subplot(gs[i + 1], sharex=rib) for i in range(len(rows))]
        kinds = list(KIND_STYLE)
        points = 0
        for i, k in enumerate(kinds):
            colour, _ = KIND_STYLE[k]
            rects = [(a / div, b / div) for a, b in spans.get(k, [])]
            if rects:
                rib.broken_barh(rects, (len(kinds) - 1 - i - 0.4, 0.8), facecolors=colour, edgecolor="none")
        rib.set_yticks(range(len(kinds)))
        rib.set_yticklabels([KIND_STYLE[k][1] for k in reversed(kinds)], fontsize=7.5)
        rib.set_ylim(-0.6, len(kinds) - 0.4)
        rib.set_ylabel("segment kind", fontsize=8)
        rib.grid(False, axis="y")
        rib.tick_params(labelbottom=False)
        rib.set_title(title, loc="left")
        for ax, (name, y, unit) in zip(axes, rows):
            for k in SHADED:  # one collection per kind, spanning the axes' height
                rects = [(a / div, b / div) for a, b in spans.get(k, [])]
                if rects:
                    ax.broken_barh(rects, (0, 1), transform=ax.get_xaxis_transform(), facecolors=KIND_STYLE[k][0],
                                   alpha=0.13, edgecolor="none", zorder=0)
            xd, yd = minmax_decimate(t, np.asarray(y, float))
            points += xd.size
            ax.plot(xd / div, yd, color=BLACK, lw=0.7)
            ax.set_ylabel(f"{name} [{unit}]")
            ax.tick_params(labelbottom=False)
        axes[-1].tick_params(labelbottom=True)
        axes[-1].set_xlabel(tlabel)
        rib.set_xlim(lo / div, hi / div)
        counts = {k: sum(1 for s in segments if s[0] == k) for k in SHADED}
        found = ", ".join(f"{counts[k]} {KIND_STYLE[k][1]}" for k in SHADED if counts[k])
        alt = (f"{title}: position, velocity and torque against time with the segment kinds"
               + (f" ({found} segments)" if found else " (no identification segment found)"))
        return render(fig, alt, salt, points)


def _low_speed_title(curves: list[dict], key: str) -> str:
    """The title of a branch's log-velocity view: "Stribeck region" where the selected model's |F| first moves
    from its value at the lowest speed drawn downwards (by more than 1 % of its largest value there: a
    Stribeck drop), else "Low-speed region" (a friction that rises from rest is no Stribeck drop, issue 19;
    the direct-drive sample's low-speed rise, whose negative viscous slope brings |F| below its value at rest
    at the top speed, rises first)."""
    sel = [np.asarray(c[key], dtype=float) for c in curves if c["selected"] and c.get(key) is not None]
    f = sel[0][np.isfinite(sel[0])] if sel else np.zeros(0)
    moved = np.flatnonzero(np.abs(f - f[0]) > 0.01 * np.abs(f).max()) if f.size > 1 else []
    return "Stribeck region" if len(moved) and f[moved[0]] < f[0] else "Low-speed region"


@_gc_paused
def friction_map(pl, curves: list[dict], grids: dict, units: dict, salt: str) -> Rendered:
    """Friction against velocity: plateau points with error bars and every static model (top, both
    signs), and the low speeds on a logarithmic velocity axis for w > 0 and w < 0 (bottom; titled "Stribeck
    region" where the selected model's friction drops from the lowest speed, :func:`_low_speed_title`)."""
    F_u, w_u = units["tau"], units["qd"]
    with rc_context(salt):
        n_handles = sum(1 for c in curves if c["lin"] is not None) + (1 if len(pl) else 0)
        legend_rows = math.ceil(n_handles / 3)
        fig = new_figure(7.6 + 0.22 * legend_rows)
        gs = fig.add_gridspec(2, 2, height_ratios=[1.25, 1.0],
                              **place(fig, 2, 2, bottom=BOTTOM_IN + 0.1 + 0.22 * legend_rows, hgap=TITLED_GAP_IN))
        ax = fig.add_subplot(gs[0, :])
        axp = fig.add_subplot(gs[1, 0])
        axn = fig.add_subplot(gs[1, 1])
        handles = []
        for i, c in enumerate(curves):
            colour, ls, _ = SERIES[i % len(SERIES)]
            lw = 2.6 if c["selected"] else 1.3
            label = c.get("label") or c["name"]
            z = 5 if c["selected"] else 3
            if c["lin"] is not None:
                ln, = ax.plot(grids["lin"], c["lin"], color=colour, ls=ls, lw=lw, label=label, zorder=z)
                handles.append(ln)
            if c["pos"] is not None:
                axp.plot(grids["log"], c["pos"], color=colour, ls=ls, lw=lw, zorder=z)
            if c["neg"] is not None:
                axn.plot(grids["log"], c["neg"], color=colour, ls=ls, lw=lw, zorder=z)
        if len(pl):
            eb = ax.errorbar(pl.w, pl.F, yerr=pl.F_se, xerr=pl.w_se, fmt="o", ms=4.5, mfc="white",
                             mec=BLACK, ecolor=BLACK, elinewidth=0.8, zorder=6,
                             label="plateau mean ± 1 s.e.")
            handles.insert(0, eb)
            for axs, sgn in ((axp, 1), (axn, -1)):
                m = np.sign(pl.w) == sgn
                if m.any():
                    axs.errorbar(np.abs(pl.w[m]), np.abs(pl.F[m]), yerr=pl.F_se[m], xerr=pl.w_se[m], fmt="o",
                                 ms=4.5, mfc="white", mec=BLACK, ecolor=BLACK, elinewidth=0.8, zorder=6)
            lim = _finite_limits([pl.F - pl.F_se, pl.F + pl.F_se, [0.0]], pad=0.15)
            if lim:
                ax.set_ylim(*lim)
            for axs, sgn in ((axp, 1), (axn, -1)):
                m = np.sign(pl.w) == sgn
                lim = _finite_limits([np.abs(pl.F[m])], pad=0.3) if m.any() else None
                if lim:
                    axs.set_ylim(max(0.0, lim[0]), lim[1])
        else:
            sel = [c["lin"] for c in curves if c["selected"] and c["lin"] is not None]
            lim = _finite_limits(sel or [c["lin"] for c in curves], pad=0.15)
            if lim:
                ax.set_ylim(*lim)
        ax.axhline(0, color=GREY, lw=0.6)
        ax.axvline(0, color=GREY, lw=0.6)
        ax.set_xlim(grids["lin"][0], grids["lin"][-1])
        ax.set_xlabel(f"velocity w [{w_u}]")
        ax.set_ylabel(f"friction torque F [{F_u}]")
        ax.set_title("Friction-velocity map: plateau points and the fitted static models", loc="left")
        for axs, side, key in ((axp, "w > 0", "pos"), (axn, "w < 0", "neg")):
            axs.set_xscale("log")
            axs.set_xlim(grids["log"][0], grids["log"][-1])
            log_ticks(axs.xaxis, grids["log"][0], grids["log"][-1])
            axs.set_xlabel(f"|w| [{w_u}], log scale")
            axs.set_ylabel(f"|F| [{F_u}]")
            axs.set_title(f"{_low_speed_title(curves, key)}, {side}", loc="left")
        legend_below(fig, handles, min(3, len(handles)))
        alt = (f"Friction against velocity: {len(pl)} plateau points and {len(curves)} static models; "
               "log-velocity views of both signs")
        npts = len(pl) * 2 * ERRORBAR_POINTS + sum(len(grids["lin"]) + 2 * len(grids["log"]) for _ in curves)
        return render(fig, alt, salt, npts)


@_gc_paused
def presliding(ramps: list[dict], steps: list[dict], units: dict, sigma0_label: str, sigma1_label: str,
               salt: str) -> Rendered:
    """Presliding: torque against displacement on the ramps with LuGre's bristle path at the fitted
    sigma0, and the step transients measured (solid) against the model (dashed)."""
    from matplotlib.lines import Line2D  # matplotlib only where a figure is drawn

    panels = [p for p in (("ramps", ramps), ("steps", steps)) if p[1]]
    with rc_context(salt):
        fig = new_figure(4.4)
        axes = fig.subplots(1, len(panels), squeeze=False,
                            gridspec_kw=place(fig, 1, len(panels), bottom=BOTTOM_IN + 2 * LEGEND_ROW_IN + 0.1))[0]
        points = 0
        for ax, (kind, items) in zip(axes, panels):
            if kind == "ramps":
                f, xu = si_scale(np.concatenate([r["x"] for r in items]), units["q"])
                for i, r in enumerate(items):
                    colour, _, mk = SERIES[i % len(SERIES)]
                    ax.plot(r["x"] / f, r["F"], color=colour, lw=1.1, marker=mk, ms=3,
                            markevery=max(1, len(r["x"]) // 6))
                    points += len(r["x"])
                    if r["model"] is not None:
                        ax.plot(r["x"] / f, r["model"], color=BLACK, lw=1.4, ls=(0, (4, 2)))
                        points += len(r["x"])
                ax.set_xlabel(f"displacement from ramp start [{xu}]")
                ax.set_ylabel(f"friction torque [{units['tau']}]")
                ax.set_title("Ramps: torque against displacement", loc="left")
                hs = [Line2D([], [], color=GREY, lw=1.1, marker="o", ms=3, label="measured (one colour per ramp)")]
                if any(r["model"] is not None for r in items):
                    hs.append(Line2D([], [], color=BLACK, lw=1.4, ls=(0, (4, 2)), label=sigma0_label))
                ax.legend(handles=hs, loc="upper left", bbox_to_anchor=(0.0, -0.13), frameon=False)
            else:
                f, xu = si_scale(np.concatenate([s["x"] for s in items]), units["q"])
                for i, s in enumerate(items):
                    colour, _, mk = SERIES[i % len(SERIES)]
                    every = max(1, len(s["t"]) // 6)
                    ax.plot(s["t"] * 1e3, s["x"] / f, color=colour, lw=1.1, marker=mk, ms=3, markevery=every)
                    points += len(s["t"])
                    if s["model"] is not None:
                        ax.plot(s["t"] * 1e3, s["model"] / f, color=colour, lw=1.5, ls=(0, (4, 2)), marker=mk,
                                ms=4, mfc="white", markevery=(every // 2, every))
                        points += len(s["t"])
                ax.set_xlabel("time from step start [ms]")
                ax.set_ylabel(f"displacement [{xu}]")
                ax.set_title("Steps: transient measured and simulated", loc="left")
                hs = [Line2D([], [], color=GREY, lw=1.1, marker="o", ms=3, label="measured (one colour per step)")]
                if any(s["model"] is not None for s in items):
                    hs.append(Line2D([], [], color=GREY, lw=1.5, ls=(0, (4, 2)), marker="o", mfc="white", ms=4,
                                     label=sigma1_label + " (dashed, same colour)"))
                ax.legend(handles=hs, loc="upper left", bbox_to_anchor=(0.0, -0.13), frameon=False)
        alt = f"Presliding: {len(ramps)} ramps (torque against displacement) and {len(steps)} step transients"
        return render(fig, alt, salt, points)


@_gc_paused
def thermal(cycles: list[dict], models: list[dict], units: dict, salt: str) -> Rendered:
    """Friction per duty cycle against time with each thermal model (top) and the joint temperature each
    model estimates, with the ambient and any measured joint temperature (bottom)."""
    t = np.array([c["t"] for c in cycles], float)
    div, tlabel = time_axis(float(t.max() - t.min()) if t.size else 0.0)
    with rc_context(salt):
        fig = new_figure(6.0)
        ax, axT = fig.subplots(2, 1, sharex=True, gridspec_kw=place(fig, 2, 1, hgap=0.2, right=2.6))
        ax.plot(t / div, [c["F_rms"] for c in cycles], "o", ms=5, mfc="white", mec=BLACK, ls="none",
                label="measured (RMS over the cycle)", zorder=6)
        for i, m in enumerate(models):
            colour, ls, mk = SERIES[i % len(SERIES)]
            lw = 2.2 if m["selected"] else 1.3
            if np.any(np.isfinite(m["F_rms"])):
                ax.plot(t / div, m["F_rms"], color=colour, ls=ls, marker=mk, ms=4, lw=lw, label=m["name"])
            if np.any(np.isfinite(m["T"])):
                axT.plot(t / div, m["T"], color=colour, ls=ls, marker=mk, ms=4, lw=lw, label=f"{m['name']} (estimated)")
        te = np.array([c["temp_env"] for c in cycles], float)
        tj = np.array([c["temp_joint"] for c in cycles], float)
        if np.any(np.isfinite(te)):
            axT.plot(t / div, te, color=GREY, ls=(0, (1, 1.5)), lw=1.2, label="ambient (temp_env)")
        if np.any(np.isfinite(tj)):
            axT.plot(t / div, tj, "s", ms=4, mfc=BLACK, mec=BLACK, ls="none", label="measured (temp_joint)")
        ax.set_ylabel(f"friction per cycle, RMS [{units['tau']}]")
        ax.set_title("Thermal: friction per duty cycle and the thermal models", loc="left")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        axT.set_ylabel("joint temperature [degC]")
        axT.set_xlabel(tlabel + " (cycle midpoint)")
        axT.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        alt = f"Thermal: friction of {len(cycles)} duty cycles against time with {len(models)} thermal models"
        return render(fig, alt, salt, len(cycles) * (2 + 2 * len(models)))


@_gc_paused
def diagnosis(finding: dict, res: dict, units: dict, salt: str) -> Rendered:
    """Residual of the model a finding was measured against and of its extension against the finding's
    cause variable (binned mean ± 1 s.e.), on the samples the finding's numbers come from (the diagnosis'
    sliding samples, else the moving ones), each curve labelled with its residual's RMS over them."""
    b = res["before"]
    xdiv, xl = 1.0, res["label"]
    if xl.startswith("time ["):
        xdiv, xl = time_axis(float(np.ptp(b["x"])) if b["x"].size else 0.0)
    u = units["tau"]

    def rms(v):
        return "" if v is None else f", RMS {v:.3g} {u}"

    before = (res.get("before_model") or "chosen model") + {
        "refitted": " as the diagnosis' base (refitted on these samples, held out by fold)",
        "without offset": " without the fit's offset (the diagnosis' base)"}.get(res.get("before_base") or "", "")
    with rc_context(salt):
        fig = new_figure(3.4 + LEGEND_ROW_IN)
        ax = fig.subplots(gridspec_kw=place(fig, bottom=BOTTOM_IN + LEGEND_ROW_IN + 0.1))
        ax.axhline(0, color=GREY, lw=0.8)
        ax.errorbar(b["x"] / xdiv, b["mean"], yerr=b["se"], fmt="o-", ms=4, mfc="white", mec=BLACK,
                    color=BLACK, lw=1.0, ecolor=BLACK, label=f"before: {before}{rms(res.get('rms_before'))}")
        g = res.get("given")
        if g is not None:
            ext = finding.get("extension")
            name = g.get("model") or (ext.get("name") or ext.get("model") if isinstance(ext, dict) else ext)
            ax.plot(g["x"] / xdiv, g["after"], color=VERMILLION, ls=(0, (5, 2)), marker="s", ms=4, lw=1.6,
                    label=(f"after: {name or 'with the extension, as the diagnosis gives it'}"
                           f"{rms(res.get('rms_after') if g.get('model') else None)}"))
        ax.set_xlabel(xl)
        ax.set_ylabel(f"torque residual [{u}]")
        where = "sliding samples" if res.get("samples") == "sliding" else "moving samples"
        ax.set_title(f"Residual against {xl.split(' [')[0]} ({where}): {finding.get('cause', 'finding')}",
                     loc="left")
        legend_below(fig, ax.get_legend_handles_labels()[0], 1)
        alt = f"Diagnosis {finding.get('cause', '')}: residual against {xl} on the {where}"
        return render(fig, alt, salt, int(b["x"].size * 2))


@_gc_paused
def replay(t, tau, tau_model, units: dict, title: str, salt: str, q=None, q_model=None, source: str = "") -> Rendered:
    """Measured torque and the model's replay along the log and their difference; with a closed-loop
    re-simulation, the measured and simulated position and their difference too. ``source``: the log's
    name, for the caption (the title stays short enough for the figure's width)."""
    t = np.asarray(t, float)
    lo, hi = float(t[0]), float(t[-1])
    div, tlabel = time_axis(hi - lo)
    closed = q is not None and q_model is not None
    with rc_context(salt):
        fig = new_figure((7.6 if closed else 4.6) + LEGEND_ROW_IN)
        ratios = [2.0, 1.2] + ([2.0, 1.2] if closed else [])
        axes = fig.subplots(len(ratios), 1, sharex=True, height_ratios=ratios,
                            gridspec_kw=place(fig, len(ratios), bottom=BOTTOM_IN + LEGEND_ROW_IN + 0.1))
        pairs = [(axes[0], axes[1], tau, tau_model, "torque", units["tau"])]
        if closed:
            pairs.append((axes[2], axes[3], q, q_model, "position", units["q"]))
        points = 0
        for ax, axr, meas, model, name, unit in pairs:
            meas = np.asarray(meas, float)
            model = np.asarray(model, float)
            x1, y1 = minmax_decimate(t, meas)
            x2, y2 = minmax_decimate(t, model)
            x3, y3 = minmax_decimate(t, meas - model)
            points += x1.size + x2.size + x3.size
            ax.plot(x1 / div, y1, color=BLACK, lw=0.7, label="measured")
            ax.plot(x2 / div, y2, color=VERMILLION, lw=0.9, ls=(0, (4, 1.5)),
                    label="model" if name == "torque" else "simulated (closed loop)")
            axr.plot(x3 / div, y3, color=BLUE, lw=0.7)
            axr.axhline(0, color=GREY, lw=0.6)
            ax.set_ylabel(f"{name} [{unit}]")
            axr.set_ylabel(f"difference [{unit}]")
        handles = axes[0].get_legend_handles_labels()[0] + (axes[2].get_legend_handles_labels()[0][1:] if closed else [])
        legend_below(fig, handles, len(handles))
        axes[-1].set_xlabel(tlabel)
        axes[0].set_xlim(lo / div, hi / div)
        axes[0].set_title(title, loc="left")
        alt = (f"{title}{' along ' + source if source else ''}: measured and model torque against time and their "
               "difference"
               + ("; measured and simulated position in closed loop" if closed else ""))
        return render(fig, alt, salt, points)


@_gc_paused
def compensation(runs: dict, units: dict, salt: str) -> Rendered:
    """Tracking error against time of each compensation run (none, model, true), overlaid."""
    styles = {"none": (BLACK, "-"), "model": (VERMILLION, (0, (6, 2))), "true": (BLUE, (0, (1, 1.5)))}
    t_all = np.concatenate([np.asarray(r["t"], float) for r in runs.values()])
    div, tlabel = time_axis(float(np.ptp(t_all)) if t_all.size else 0.0)
    with rc_context(salt):
        fig = new_figure(3.6 + LEGEND_ROW_IN)
        ax = fig.subplots(gridspec_kw=place(fig, bottom=BOTTOM_IN + LEGEND_ROW_IN + 0.1))
        ax.axhline(0, color=GREY, lw=0.6)
        points = 0
        for name, r in runs.items():
            colour, ls = styles.get(name, (GREEN, (0, (3, 1.5))))
            x, y = minmax_decimate(np.asarray(r["t"], float), np.asarray(r["q_ref"], float) - np.asarray(r["q"], float))
            points += x.size
            ax.plot(x / div, y, color=colour, ls=ls, lw=0.9, label=r.get("label", name))
        ax.set_xlabel(tlabel)
        ax.set_ylabel(f"tracking error q_ref - q [{units.get('q', 'rad')}]")
        ax.set_title("Compensation what-if: tracking error of each run", loc="left")
        legend_below(fig, ax.get_legend_handles_labels()[0], len(runs))
        alt = "Tracking error against time with " + ", ".join(r.get("label", n) for n, r in runs.items())
        return render(fig, alt, salt, points)
