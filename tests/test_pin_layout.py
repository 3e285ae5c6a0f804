"""maps.export.plots.pin_layout: the titles and empty axis labels it pins are where matplotlib's automatic
placement puts them (the same pixels, drawn without that placement's second pass over the ticks), and a title
that matplotlib would move (over a y-axis offset text) is left to matplotlib; maps.export.mapplot._draw_geom
keeps the data limits add_patch gave."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from maps.export.plots import _title_stays, pin_layout  # noqa: E402

TITLE = "a title as wide as the axes ä°"  # wide: over the y axis's offset text, when there is one


def _figure(y_scale: float, y_offset: float = 0.0, xlabel: str = "", panels: int = 1):
    fig, axes = plt.subplots(panels, 1, figsize=(3.3, 2.6), sharex=True, squeeze=False)
    axes = axes[:, 0]
    for ax in axes:
        ax.plot([0, 1, 2], y_offset + y_scale * np.array([0.3, 1.7, 0.9]), lw=1.5, label="line")
        ax.set_ylabel("y")
    axes[0].set_title(TITLE, fontsize=9)
    axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set_xlabel(xlabel)
    fig.subplots_adjust(left=0.25, right=0.7, top=0.85)
    return fig


def _rgba(fig) -> np.ndarray:
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=110)
    plt.close(fig)
    return np.frombuffer(buf.getvalue(), np.uint8)


def test_pinned_figure_has_the_same_pixels():
    for xlabel in ("", "time [min]"):
        for panels in (1, 2):  # 2: the top panel's time axis has no label (and no tick labels: shared)
            plain, pinned = _figure(1.0, xlabel=xlabel, panels=panels), _figure(1.0, xlabel=xlabel, panels=panels)
            assert _title_stays(pinned.axes[0]) == (panels == 1)  # a shared axis's hidden labels: left to matplotlib
            pin_layout(pinned)
            assert np.array_equal(_rgba(plain), _rgba(pinned))


def test_title_over_an_offset_text_is_left_to_matplotlib():
    fig = _figure(1e-3, y_offset=1e7)  # ticks such as 10000000.0005: the y axis shows an offset text
    assert not _title_stays(fig.axes[0])
    auto, pinned = _figure(1e-3, y_offset=1e7), _figure(1e-3, y_offset=1e7)
    pin_layout(pinned)
    assert np.array_equal(_rgba(auto), _rgba(pinned))
    # what pinning it would have done: the title stays on the offset text, other pixels
    forced = _figure(1e-3, y_offset=1e7)
    forced.axes[0].set_title(TITLE, fontsize=9, y=1.0)
    assert not np.array_equal(_rgba(_figure(1e-3, y_offset=1e7)), _rgba(forced))
    plt.close(fig)


def test_title_with_ticks_on_top_is_left_to_matplotlib():
    fig = _figure(1.0)
    fig.axes[0].xaxis.tick_top()
    assert not _title_stays(fig.axes[0])
    plt.close(fig)


def test_draw_geom_gives_add_patchs_data_limits():
    from shapely.geometry import Polygon, box

    from maps.export.mapplot import _draw_geom

    geom = Polygon([(0.0, 0.0), (3.0, 0.5), (2.0, 4.0)], [[(1.0, 1.0), (2.0, 1.2), (1.8, 2.0)]]).union(box(5, 5, 6, 7))
    fig, ax = plt.subplots()
    assert _draw_geom(ax, geom, box(-1, -1, 10, 10), facecolor="tan")
    ax.autoscale_view()
    fig2, ax2 = plt.subplots()
    from matplotlib.patches import PathPatch

    ax2.add_patch(PathPatch(ax.patches[0].get_path() if ax.patches else ax.artists[0].get_path()))
    ax2.autoscale_view()
    assert np.allclose(ax.dataLim.bounds, ax2.dataLim.bounds, rtol=0, atol=1e-12)
    assert ax.get_xlim() == ax2.get_xlim() and ax.get_ylim() == ax2.get_ylim()
    plt.close(fig)
    plt.close(fig2)
