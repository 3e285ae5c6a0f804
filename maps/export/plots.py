"""Figures of a plan: the track on the map (drawn by :func:`maps.export.mapplot.draw_map`) and
the simulated states over time (speed, heading, inputs), as PNG (or PDF/SVG by suffix), each
drawn once per plan (:class:`PlanFigures`).

``sea_map``: see :mod:`maps.export.mapplot`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402

from maps.export._common import KN_PER_MPS, step_slice  # noqa: E402
from maps.export.figures import STATES_DPI, TRACK_DPI, PlanFigures  # noqa: E402
from maps.export.mapplot import annotate_steps, draw_map, lon_ticks, primitive_colours, step_colour  # noqa: E402
from maps.plan import Plan  # noqa: E402


def state_series(plan: Plan) -> list[tuple[str, np.ndarray]]:
    """(label, values) of each panel of the states figure: speed (kn), heading (deg, NaN where
    it wraps round), then each commanded input (angles in deg)."""
    heading = np.degrees(plan.track[:, 2]) % 360.0
    heading[1:][np.abs(np.diff(heading)) > 180] = np.nan  # no line across the wrap
    series = [("speed over ground [kn]", plan.speed * KN_PER_MPS), ("heading [°]", heading)]
    for j, nm in enumerate(plan.input_names):
        v = plan.inputs[:, j] if plan.inputs.ndim == 2 and plan.inputs.shape[1] > j else np.zeros_like(plan.t)
        series.append(input_series(nm, v))
    return series


def input_series(name: str, values: np.ndarray) -> tuple[str, np.ndarray]:
    """A commanded input as the states figure plots it, in the units of the orders: angles in
    degrees, shaft speeds (rev/s in the plan) in rpm; other inputs as they are."""
    base, num = name.rstrip("0123456789"), name[len(name.rstrip("0123456789")) :]
    if base == "alpha":
        return f"azimuth {num} angle [°]", np.degrees(values)
    if base == "delta":
        return ("rudder [°]" if not num else f"pod {num} angle [°]"), np.degrees(values)
    if base == "n":
        return ("propeller [rpm]" if not num else f"propeller {num} [rpm]"), 60.0 * np.asarray(values, float)
    return name, np.asarray(values, float)


def state_limits(lo: float, hi: float) -> tuple[float, float]:
    """The y range of a states panel with data from ``lo`` to ``hi``: matplotlib's autoscaling
    (non-singular, 5 % margins), except that a series constant to 1e-9 of its size (a steady
    speed) is shown as constant, not as rounding noise around an offset."""
    from matplotlib.ticker import MaxNLocator

    if hi - lo <= 1e-9 * max(abs(lo), abs(hi), 1.0):
        lo = hi = 0.5 * (lo + hi)
    lo, hi = MaxNLocator().nonsingular(lo, hi)
    d = 0.05 * (hi - lo)
    return lo - d, hi + d


def states_size_in(plan: Plan) -> tuple[float, float]:
    """Width and height (inches) of the states figure: A4 wide, 1.5 in a panel plus 1 in."""
    return 8.27, 1.5 * (2 + len(plan.input_names)) + 1.0


def draw_states(axes: list, plan: Plan) -> None:
    """Speed (kn), heading (deg) and each commanded input over time (minutes) on ``axes``
    (len 2 + number of inputs); the manoeuvre numbers along the top are
    :func:`draw_step_numbers`' (drawn once the layout is final)."""
    t_min = (plan.t - plan.t[0]) / 60.0
    colours = primitive_colours(plan)
    series = state_series(plan)
    from matplotlib.collections import PolyCollection

    spans, span_colours = [], []
    for st in plan.steps:
        sl = step_slice(plan, st)
        a, b = t_min[sl.start], t_min[sl.stop - 1]
        spans.append([(a, 0.0), (a, 1.0), (b, 1.0), (b, 0.0)])
        span_colours.append(step_colour(plan, st, colours))
    for ax, (label, y) in zip(axes, series):
        # each step's span as axvspan shades it (full height, 12 % colour), all in one collection: one artist, not a patch a step
        ax.add_collection(
            PolyCollection(spans, facecolors=span_colours, alpha=0.12, linewidths=0, transform=ax.get_xaxis_transform()),
            autolim=False,
        )
        ax.plot(t_min[: len(y)], y, color="k", lw=0.9)
        finite = y[np.isfinite(y)]
        if len(finite):
            ax.set_ylim(*state_limits(float(finite.min()), float(finite.max())))
        ax.set_ylabel(label, fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time from start [min]", fontsize=8)


def step_label_centres(plan: Plan) -> np.ndarray:
    """Time (minutes from the start) of the middle of each step: where its number goes on top."""
    t_min = (plan.t - plan.t[0]) / 60.0
    return np.array([0.5 * (t_min[sl.start] + t_min[sl.stop - 1]) for sl in (step_slice(plan, st) for st in plan.steps)])


STEP_LABEL_GAP_EM = 0.4  # blank between two step numbers, in font sizes


def thin_labels(centres: np.ndarray, widths: np.ndarray, gap: float) -> list[int]:
    """Indices of the centred labels (positions ``centres``, ``widths``, same units) to show so
    that no two are closer than ``gap``: left to right, a label is kept when it clears the last
    kept one; the last label is always kept (the kept ones it would touch give way), and so is
    the first, unless the first and last themselves collide (then only the first)."""
    n = len(centres)
    if n == 0:
        return []
    lo, hi = np.asarray(centres) - 0.5 * np.asarray(widths), np.asarray(centres) + 0.5 * np.asarray(widths)
    kept = [0]
    for i in range(1, n):
        if lo[i] >= hi[kept[-1]] + gap:
            kept.append(i)
    if kept[-1] != n - 1:
        while len(kept) > 1 and lo[n - 1] < hi[kept[-1]] + gap:
            kept.pop()
        if lo[n - 1] >= hi[kept[-1]] + gap:
            kept.append(n - 1)
    return kept


def draw_step_numbers(fig: Any, ax: Any, plan: Plan, fontsize: float = 7.0) -> None:
    """The step numbers over ``ax`` (laid out: its width is final), in their primitives'
    colours, thinned by :func:`thin_labels` to what the axes' width holds without overlap."""
    from matplotlib.font_manager import FontProperties

    r = fig.canvas.get_renderer()
    prop = FontProperties(size=fontsize, weight="bold")
    px_per_pt = fig.dpi / 72.0
    labels = [str(st.index + 1) for st in plan.steps]
    widths = np.array([r.get_text_width_height_descent(s, prop, ismath=False)[0] / px_per_pt for s in labels])
    centres = step_label_centres(plan)
    x0, x1 = ax.get_xlim()
    pos = ax.get_position()
    width_pt = pos.width * fig.get_size_inches()[0] * 72.0
    colours = primitive_colours(plan)
    for i in thin_labels((centres - x0) / (x1 - x0) * width_pt, widths, STEP_LABEL_GAP_EM * fontsize):
        st = plan.steps[i]
        ax.text(
            centres[i],
            1.02,
            labels[i],
            transform=ax.get_xaxis_transform(),
            ha="center",
            va="bottom",
            fontsize=fontsize,
            fontweight="bold",
            color=step_colour(plan, st, colours),
        )


# Margins in inches (what tight_layout found for the bundled ships, rounded up; the left one grows
# with the y tick labels, :func:`states_left_in`): a layout pass measures every tick label of every
# axes, which cost as much CPU as drawing the figure.
STATES_MARGINS_IN = {"left": 0.72, "right": 0.15, "top": 0.56, "bottom": 0.52}
STATES_HSPACE = 0.15


def states_left_in(label_width_pt: float, fontsize: float = 7.0) -> float:
    """Left margin (inches) of the states figure whose widest y tick label is ``label_width_pt``
    wide: the tick (3.5 pt), its pad (3.5 pt), the label, the y label's pad (4 pt) and its line,
    never less than :data:`STATES_MARGINS_IN`'s (so the bundled ships' figures keep their layout)
    but wide enough that a profile with large values (forces in N) is not cut at the edge."""
    need_pt = 3.5 + 3.5 + label_width_pt + 4.0 + 1.2 * fontsize + 3.0
    return max(STATES_MARGINS_IN["left"], need_pt / 72.0)


def ytick_label_width_pt(fig: Any, ax: Any, fontsize: float = 7.0) -> float:
    """Width in points of the widest y tick label ``ax`` will draw (its locator and formatter at
    its current size and limits; no layout pass over the figure)."""
    from matplotlib.font_manager import FontProperties

    lo, hi = sorted(ax.get_ylim())
    locs = [v for v in ax.yaxis.get_major_locator()() if lo - 1e-9 * (hi - lo) <= v <= hi + 1e-9 * (hi - lo)]
    labels = ax.yaxis.get_major_formatter().format_ticks(locs)
    r, prop = fig.canvas.get_renderer(), FontProperties(size=fontsize)
    return max((r.get_text_width_height_descent(s, prop, ismath="$" in s)[0] for s in labels if s), default=0.0) * 72.0 / fig.dpi


def fixed_margins(fig: Any, left: float, right: float, top: float, bottom: float, **kw: float) -> None:
    """``fig.subplots_adjust`` with the margins given in inches (``kw``: hspace, wspace)."""
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=left / w, right=1.0 - right / w, top=1.0 - top / h, bottom=bottom / h, **kw)


def pin_layout(fig: Any) -> None:
    """Fix where matplotlib would put ``fig``'s axis labels without text, once the layout is final (the figure's
    size, margins, limits and ticks set), so that drawing it does not work them out again. Same pixels: an empty
    label draws nothing, yet matplotlib places every axis label clear of its tick labels at each draw, a second
    pass over that axis's ticks (0.01 s of CPU an axis).

    Precondition: nothing that changes the axis labels, limits or ticks may follow (a label given text after this
    would be drawn where the empty one was pinned, not under the tick labels). Titles are left to matplotlib: a
    pinned title loses its weight, pad and alignment and ignores twinned axes and offset texts (stop 54's review).
    """
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if not axis.get_label_text():
                x, y = axis.label.get_position()
                axis.set_label_coords(x, y, transform=axis.label.get_transform())


def legend_width_in(fig: Any, legend: Any) -> float:
    """Width of ``legend`` in inches (its texts laid out, nothing else of the figure)."""
    return legend.get_window_extent(fig.canvas.get_renderer()).width / fig.dpi


def states_figure(plan: Plan) -> Any:
    """A figure of :func:`draw_states`, laid out with :data:`STATES_MARGINS_IN` (the left one
    widened to the y tick labels by :func:`states_left_in`)."""
    n = 2 + len(plan.input_names)
    # made at the PNG's dpi: the layout's text measures (tick label widths, step numbers) are those of the
    # drawing, which then reuses them and their renderer (measured at 100 dpi, every text was laid out again
    # at 110: 0.79 -> 0.63 s CPU for the full-scale figure, the same pixels)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(n, 1, figsize=states_size_in(plan), sharex=True, dpi=STATES_DPI)
    draw_states(list(np.atleast_1d(axes)), plan)
    fig.suptitle(f"{plan.ship}: planned speed, heading and commanded inputs (manoeuvre numbers on top)", fontsize=9)
    fixed_margins(fig, **STATES_MARGINS_IN, hspace=STATES_HSPACE)
    left = states_left_in(max(ytick_label_width_pt(fig, ax) for ax in fig.axes))
    if left > STATES_MARGINS_IN["left"]:  # wide tick labels (large values): the axes give way, nothing is cut
        fixed_margins(fig, **{**STATES_MARGINS_IN, "left": left}, hspace=STATES_HSPACE)
    draw_step_numbers(fig, fig.axes[0], plan)
    pin_layout(fig)
    return fig


TRACK_MARGINS_IN = {"left": 0.85, "top": 0.35, "bottom": 0.35}


def track_figure(plan: Plan, sea_map: Any = None) -> Any:
    """The numbered track coloured by primitive on the map, legend outside, titled; the axes
    take the figure less fixed margins and the legend's width (the PNG is cropped to what is
    drawn)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9.5, 7.5))
    draw_map(ax, plan, sea_map, numbers=False)
    leg = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), framealpha=0.9)  # outside: never hides the track
    ax.set_title(
        f"{plan.ship} trial{' on ' + plan.map_name if plan.map_name else ''}: manoeuvres numbered in sailing order",
        fontsize=9,
    )
    _fit_to_map(fig, ax, leg)
    annotate_steps(ax, plan)  # in the final layout: the labels are placed in points on the page
    pin_layout(fig)
    return fig


def _fit_to_map(fig: Any, ax: Any, legend: Any) -> None:
    """Size ``fig`` to the map (its aspect fixed by the latitude) plus fixed margins and the
    legend on the right: the figure ends where the drawing does, with no layout pass over the
    tick labels and no cropping draw when saved."""
    from matplotlib.ticker import FixedLocator

    r = fig.canvas.get_renderer()
    leg = legend.get_window_extent(r)
    leg_w, leg_h = leg.width / fig.dpi, leg.height / fig.dpi
    m = TRACK_MARGINS_IN
    fixed_margins(fig, right=leg_w + 0.2, **m)
    ax.apply_aspect()  # the axes shrink to the map's aspect inside the box the margins leave
    w, h = fig.get_size_inches()
    pos = ax.get_position()
    ax_w, ax_h = pos.width * w, pos.height * h
    # the title is centred over the map: a map narrower than its title gets the room on both sides
    over = max(0.0, 0.5 * (ax.title.get_window_extent(r).width / fig.dpi - ax_w) + 0.1)
    left = max(m["left"], over)
    right = max(0.01 * ax_w + leg_w + 0.15, over)  # the legend sits 1 % of the axes width right of the map
    fig.set_size_inches(left + ax_w + right, m["top"] + max(ax_h, leg_h) + m["bottom"])
    fixed_margins(fig, right=right, left=left, top=m["top"], bottom=m["bottom"] + max(0.0, leg_h - ax_h))
    x0, x1 = ax.get_xlim()
    ax.xaxis.set_major_locator(FixedLocator(lon_ticks(x0, x1, 72.0 * ax_w)))  # labels that do not overlap


def plot_states(plan: Plan, path: str | Path, dpi: int = STATES_DPI, figures: PlanFigures | None = None) -> Path:
    """The simulated states over time (speed, heading, inputs) as PNG (or PDF/SVG by suffix)."""
    if figures is not None:
        return figures.save("states", path, dpi)
    with PlanFigures(plan) as figs:
        return figs.save("states", path, dpi)


def plot_track(
    plan: Plan, path: str | Path, sea_map: Any = None, dpi: int = TRACK_DPI, figures: PlanFigures | None = None
) -> Path:
    """The numbered track coloured by primitive on the map, as PNG (or PDF/SVG by suffix)."""
    if figures is not None:
        return figures.save("track", path, dpi)
    with PlanFigures(plan, sea_map) as figs:
        return figs.save("track", path, dpi)
