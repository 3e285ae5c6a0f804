"""maps.export.plots.pin_layout: the empty axis labels it pins are where matplotlib's automatic placement puts
them (the same pixels, drawn without that placement's second pass over the ticks), it does pin them, titles are left
to matplotlib, and the real track and states figures have the same pixels with and without it;
maps.export.mapplot._draw_geom keeps the data limits add_patch gave."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from maps.export import plots  # noqa: E402
from maps.export.plots import pin_layout  # noqa: E402

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
            pin_layout(pinned)
            assert np.array_equal(_rgba(plain), _rgba(pinned))


def _label_positions(fig) -> list[tuple[float, float]]:
    return [p for ax in fig.axes for p in (ax.xaxis.label.get_position(), ax.yaxis.label.get_position())]


def test_empty_labels_are_pinned_and_labels_with_text_are_not():
    """The pin itself, by behaviour: drawing moves an automatically placed label below (or beside) its tick labels;
    a pinned one stays where it was when pinned. Fails if pin_layout does nothing or pins a label with text."""
    plain, pinned = _figure(1.0), _figure(1.0)  # x label empty, y label "y"
    before = _label_positions(pinned)
    pin_layout(pinned)
    plain.canvas.draw()
    pinned.canvas.draw()
    after_plain, after_pinned = _label_positions(plain), _label_positions(pinned)
    assert after_pinned[0] == before[0] != after_plain[0]  # the empty x label: pinned, not placed at the draw
    assert after_pinned[1] == after_plain[1] != before[1]  # the y label has text: placed by matplotlib as before
    # the ticks moved to the top after pinning: the plain label follows them, the pinned one stays
    for fig in (plain, pinned):
        fig.axes[0].xaxis.set_label_position("top")
        fig.axes[0].xaxis.tick_top()
        fig.canvas.draw()
    assert _label_positions(pinned)[0] == before[0] != _label_positions(plain)[0]
    plt.close(plain)
    plt.close(pinned)


def _titled(kind: str):
    fig = _figure(1e-3, y_offset=1e7) if kind == "offset" else _figure(1.0)
    ax = fig.axes[0]
    if kind == "bold":
        ax.set_title(TITLE, fontsize=9, fontweight="bold")
    elif kind == "pad0":
        ax.set_title(TITLE, fontsize=14, pad=0)
    elif kind == "pad12":
        ax.set_title(TITLE, fontsize=9, pad=12)
    elif kind == "twiny":
        ax.twiny().plot([0, 1], [0, 1])
    elif kind == "twinx-offset":
        ax.twinx().plot([0, 1, 2], 1e7 + 1e-3 * np.array([0.3, 1.7, 0.9]))
    elif kind == "ticks-top":
        ax.xaxis.tick_top()
    return fig


@pytest.mark.parametrize("kind", ["offset", "bold", "pad0", "pad12", "twiny", "twinx-offset", "ticks-top"])
def test_titles_are_left_to_matplotlib(kind):
    """The cases stop 54's review found a title pin to move (663-2,755 pixels): pin_layout leaves titles alone."""
    plain, pinned = _titled(kind), _titled(kind)
    pin_layout(pinned)
    assert np.array_equal(_rgba(plain), _rgba(pinned))


@pytest.fixture(scope="module")
def plan():
    from maps.export._testing import synthetic_plan

    return synthetic_plan("full-scale")


@pytest.mark.parametrize("name", ["track", "states"])
def test_real_figures_have_the_same_pixels_with_and_without_the_pin(plan, name, monkeypatch):
    """The figures the exports draw (their PNG bytes at the exported dpi), built with pin_layout and with it
    monkeypatched to nothing; at least one label of each is pinned (it stays put at the draw)."""
    from primitives.io import figure_png

    make = plots.track_figure if name == "track" else plots.states_figure
    dpi = plots.TRACK_DPI if name == "track" else plots.STATES_DPI
    pinned = make(plan)
    png_pinned, pos_pinned = figure_png(pinned, dpi), _label_positions(pinned)
    with monkeypatch.context() as m:
        m.setattr(plots, "pin_layout", lambda fig: None)
        plain = make(plan)
    png_plain, pos_plain = figure_png(plain, dpi), _label_positions(plain)
    plt.close(pinned)
    plt.close(plain)
    assert png_pinned == png_plain
    assert pos_pinned != pos_plain  # the pin took effect: an empty label not moved by the draw


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
