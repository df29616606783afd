"""The report figures' shortcuts draw what matplotlib alone draws: ticks fixed at the locations inside the
view, ids prefixed by plain replacements, min/max decimation that finds non-finite samples from the picked
values, figure functions run with the garbage collector paused.
"""
from __future__ import annotations

import gc
import io
import re

import numpy as np
import pytest

from frictid.report import figures as fg


def _figure():
    """A figure with a linear axis whose locator gives ticks beyond the view, a log axis with minor ticks, and
    two axes sharing x."""
    fig = fg.new_figure(4.0)
    ax, axl = fig.subplots(1, 2, gridspec_kw=fg.place(fig, 1, 2))
    ax2 = ax.twinx()
    t = np.linspace(0.03, 59.99, 400)
    ax.plot(t, np.sin(t) * 2.6, marker="o", markevery=40)
    ax2.plot(t, np.cos(t) * 385)
    ax.set_xlim(t[0], t[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("torque [N m]")
    axl.set_xscale("log")
    axl.plot(t / 20, t ** 0.5)
    axl.set_xlim(0.0138, 3.09)
    axl.set_xlabel("|w| [rad/s], log scale")
    axl.set_ylabel("|F| [N m]")
    return fig


def test_ticks_in_view_draw_the_same_svg():
    def svg(fix):
        with fg.rc_context("ticks"):
            fig = _figure()
            if fix:
                fg._ticks_in_view(fig)
            buf = io.BytesIO()
            fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
            return fig, buf.getvalue()

    fig, fixed = svg(True)
    assert fixed == svg(False)[1]
    lo, hi = fig.axes[0].get_xlim()
    locs = fig.axes[0].xaxis.get_majorticklocs()
    assert locs.size and lo <= locs.min() and locs.max() <= hi  # no tick made beyond the limits
    assert fig.axes[1].xaxis.get_minorticklocs().size  # the log axis keeps its minor ticks


def test_prefixed_ids_are_unique_and_every_reference_resolves():
    with fg.rc_context("ids"):
        figs = [fg.render(_figure(), "a figure", salt) for salt in ("j-1-map-0", "j-2-map-0")]
    ids = [re.findall(r'\bid="([^"]+)"', f.data) for f in figs]
    for f, own, salt in zip(figs, ids, ("j-1-map-0-", "j-2-map-0-")):
        assert own and all(i.startswith(salt) for i in own)
        refs = re.findall(r'(?:href="#|url\(#)([^")]+)', f.data)
        assert refs and set(refs) <= set(own)
    assert not set(ids[0]) & set(ids[1])


def test_minmax_decimation_ignores_non_finite_samples():
    rng = np.random.default_rng(2)
    t = np.arange(50_000) * 1e-3
    y = np.cumsum(rng.standard_normal(t.size))
    y[rng.integers(0, t.size, 30)] = np.nan
    y[123] = np.inf
    y[4567] = -np.inf
    y[7000:7100] = np.nan  # a whole column
    xd, yd = fg.minmax_decimate(t, y, columns=500)
    k = int(np.ceil(t.size / 500))
    for c in range(500):
        blk = y[c * k:(c + 1) * k]
        fin = blk[np.isfinite(blk)]
        pair = yd[2 * c:2 * c + 2]
        if fin.size:
            assert sorted(pair) == [fin.min(), fin.max()]
        else:
            assert np.isnan(pair).all()


@pytest.mark.parametrize("enabled", [True, False])
def test_figure_functions_leave_the_garbage_collector_as_they_found_it(enabled):
    seen = []

    @fg._gc_paused
    def draw(fail):
        seen.append(gc.isenabled())
        if fail:
            raise ValueError("drawing failed")
        return "drawn"

    was = gc.isenabled()
    try:
        (gc.enable if enabled else gc.disable)()
        assert draw(False) == "drawn"
        with pytest.raises(ValueError):
            draw(True)
        assert gc.isenabled() == enabled
    finally:
        (gc.enable if was else gc.disable)()
    assert seen == [False, False]


def test_the_log_velocity_views_say_stribeck_only_where_the_chosen_model_drops():
    """The friction map's log-velocity views were titled "Stribeck region" whatever the chosen model did; a
    friction that rises from rest is no Stribeck drop (issue 19): the title says "Low-speed region" there."""
    v = np.geomspace(1e-3, 1.0, 50)
    drop = 1.0 + 0.5 * np.exp(-v / 0.05) + 0.2 * v
    rise = 1.5 - 0.5 * np.exp(-v / 0.05) + 0.2 * v
    curves = [{"selected": True, "pos": drop, "neg": rise}, {"selected": False, "pos": rise, "neg": drop}]
    assert fg._low_speed_title(curves, "pos") == "Stribeck region"
    assert fg._low_speed_title(curves, "neg") == "Low-speed region"
    assert fg._low_speed_title([{"selected": True, "pos": None, "neg": None}], "pos") == "Low-speed region"
    # a rise at low speed whose negative viscous slope ends below the value at rest still rises first
    v = np.geomspace(1e-3, 2.0, 80)
    rise_then_fall = 9.16 - 1.41 * np.exp(-(v / 0.354) ** 2) - 0.94 * v
    assert fg._low_speed_title([{"selected": True, "pos": rise_then_fall}], "pos") == "Low-speed region"
