"""The trial card's last page, speed, heading and commanded inputs over time, drawn straight into
the PDF with fpdf2 (:class:`maps.export.pdfdraw.Painter`).

The same panels as :func:`maps.export.plots.states_figure` (page size, margins, the
step spans shaded in their colours, the step numbers on top thinned alike, matplotlib's limits, tick positions
and tick labels) without drawing the figure with matplotlib, writing it as SVG and reading the SVG
back with fpdf2, which cost a third of the card's CPU.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from maps.export._common import step_slice
from maps.export.pdfdraw import LINE_HEIGHT, Painter, col, rgb, rings_ops
from maps.export.plots import (
    STATES_HSPACE,
    STATES_MARGINS_IN,
    STEP_LABEL_GAP_EM,
    primitive_colours,
    state_limits,
    state_series,
    states_left_in,
    states_size_in,
    step_colour,
    step_label_centres,
    thin_labels,
)
from maps.plan import Plan

PT = 72.0
FS = 7.0  # tick labels, y labels, step numbers (as the figure's)
GRID = tuple(0.3 * c + 0.7 for c in (0.69, 0.69, 0.69))  # matplotlib's grid (#b0b0b0, alpha 0.3) over white


def _ticks(lo: float, hi: float, length_pt: float, per_label: float) -> tuple[list[float], list[str]]:
    """matplotlib's AutoLocator ticks inside ``lo``..``hi`` on an axis ``length_pt`` long and their
    ScalarFormatter labels (labels ``per_label`` font sizes apart)."""
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    nbins = int(np.clip(math.floor(length_pt / (FS * per_label)), 1, 9))
    locs = [float(v) for v in MaxNLocator(nbins, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi) if lo <= v <= hi]
    fmt = ScalarFormatter()
    fmt.create_dummy_axis()
    fmt.axis.set_view_interval(lo, hi)
    labels = fmt.format_ticks(locs)
    off = fmt.get_offset()
    if off:  # an offset or a power of ten: say each value whole rather than as a separate offset text
        labels = [f"{v:.6g}".replace("-", "\u2212") for v in locs]
    return locs, labels


class StatesWriter(Painter):
    """Writes the states page (a page of its own size, added by the caller) of ``plan``."""

    def __init__(self, pdf: Any, font: str, plan: Plan) -> None:
        super().__init__(pdf, font)
        self.plan = plan
        self.t_min = (plan.t - plan.t[0]) / 60.0
        self.series = state_series(plan)
        w_in, h_in = states_size_in(plan)
        self.w, self.h = w_in * PT, h_in * PT
        m = STATES_MARGINS_IN
        n = len(self.series)
        top, bottom = self.h - m["top"] * PT, m["bottom"] * PT
        self.ax_h = (top - bottom) / (n + (n - 1) * STATES_HSPACE)
        self.yaxes = [self.y_axis(y) for _, y in self.series]  # (limits, ticks, labels) of each panel
        widest = max((self.text_width(s, FS) for _, _, labels in self.yaxes for s in labels), default=0.0)
        self.left, self.right = states_left_in(widest, FS) * PT, self.w - m["right"] * PT
        self.ax_bottoms = [top - (k + 1) * self.ax_h - k * STATES_HSPACE * self.ax_h for k in range(n)]
        self.xlim = state_limits(float(self.t_min[0]), float(self.t_min[-1]))
        colours = primitive_colours(plan)
        self.spans = [(self.t_min[step_slice(plan, st)], step_colour(plan, st, colours)) for st in plan.steps]

    def x(self, v: np.ndarray | float) -> np.ndarray | float:
        a, b = self.xlim
        return self.left + (np.asarray(v) - a) / (b - a) * (self.right - self.left)

    def draw(self) -> None:
        xt, xl = _ticks(*self.xlim, self.right - self.left, 3.0)
        for k, (label, y) in enumerate(self.series):
            self.panel(self.ax_bottoms[k], label, y, self.yaxes[k], xt, xl if k == len(self.series) - 1 else None)
        self.step_numbers()
        mid = 0.5 * (self.left + self.right)
        self.text(
            mid, self.ax_bottoms[-1] - 3.5 - 3.5 - LINE_HEIGHT * FS - 4.0, "time from start [min]", 8.0, ha="center", va="top"
        )
        self.text(
            0.5 * self.w,
            0.98 * self.h,
            f"{self.plan.ship}: planned speed, heading and commanded inputs (manoeuvre numbers on top)",
            9.0,
            ha="center",
            va="top",
        )

    def step_numbers(self) -> None:
        """The step numbers over the top panel, thinned as the PNG's (:func:`thin_labels`)."""
        top = self.ax_bottoms[0] + self.ax_h
        labels = [str(st.index + 1) for st in self.plan.steps]
        centres = np.asarray(self.x(step_label_centres(self.plan)), float)
        widths = np.array([self.text_width(s, FS, bold=True) for s in labels])
        for i in thin_labels(centres, widths, STEP_LABEL_GAP_EM * FS):
            colour = self.spans[i][1]
            self.text(
                float(centres[i]),
                top + 0.02 * self.ax_h,
                labels[i],
                FS,
                bold=True,
                ha="center",
                va="bottom",
                colour=tuple(round(255 * c) for c in rgb(colour)),
            )

    def y_axis(self, y: np.ndarray) -> tuple[tuple[float, float], list[float], list[str]]:
        """The y limits of a panel showing ``y``, its tick positions and tick labels."""
        finite = y[np.isfinite(y)]
        ylim = state_limits(float(finite.min()), float(finite.max())) if len(finite) else (-0.055, 0.055)
        return (ylim, *_ticks(*ylim, self.ax_h, 2.0))

    def panel(
        self,
        bottom: float,
        label: str,
        y: np.ndarray,
        yaxis: tuple[tuple[float, float], list[float], list[str]],
        xt: list[float],
        xl: list[str] | None,
    ) -> None:
        """One axes: shaded step spans, grid, the series, frame, ticks and labels."""
        left, right, h = self.left, self.right, self.ax_h
        ylim, yt, yl = yaxis

        def py(v: np.ndarray | float) -> np.ndarray | float:
            return bottom + (np.asarray(v) - ylim[0]) / (ylim[1] - ylim[0]) * h

        self.out(f"q {left:.2f} {bottom:.2f} {right - left:.2f} {h:.2f} re W n")
        for ts, colour in self.spans:  # axvspan at 12 % opacity over white
            r, g, b = (0.12 * c + 0.88 for c in rgb(colour))
            a, z = self.x(ts[0]), self.x(ts[-1])
            self.out(f"{r:.3f} {g:.3f} {b:.3f} rg {a:.2f} {bottom:.2f} {z - a:.2f} {h:.2f} re f")
        grid = [np.array([[self.x(v), bottom], [self.x(v), bottom + h]]) for v in xt]
        grid += [np.array([[left, py(v)], [right, py(v)]]) for v in yt]
        if grid:
            self.out(f"{col(GRID, 'RG')} 0.8 w 2 J [] 0 d\n" + rings_ops(grid, close=False) + " S")
        self.series_line(np.column_stack([self.x(self.t_min[: len(y)]), py(y)]))
        self.out("Q q")
        ticks = [np.array([[self.x(v), bottom], [self.x(v), bottom - 3.5]]) for v in xt]
        ticks += [np.array([[left, py(v)], [left - 3.5, py(v)]]) for v in yt]
        self.out(
            f"{col('k', 'RG')} 0.8 w 0 J 0 j [] 0 d {left:.2f} {bottom:.2f} {right - left:.2f} {h:.2f} re S\n"
            + rings_ops(ticks, close=False)
            + " S Q"
        )
        widths = [self.text(left - 7.0, float(py(v)), s, FS, ha="right", va="center") for v, s in zip(yt, yl)]
        if xl is not None:
            for v, s in zip(xt, xl):
                self.text(float(self.x(v)), bottom - 7.0, s, FS, ha="center", va="top")
        self.ylabel(left - 7.0 - max(widths, default=0.0) - 4.0, bottom + 0.5 * h, label)

    def series_line(self, xy: np.ndarray) -> None:
        """The black curve, broken at NaN (heading wrap-arounds), simplified to 0.05 pt."""
        from shapely import LineString

        ok = np.isfinite(xy[:, 1])
        runs, start = [], None
        for i, good in enumerate(np.append(ok, False)):
            if good and start is None:
                start = i
            elif not good and start is not None:
                if i - start >= 2:
                    runs.append(np.asarray(LineString(xy[start:i]).simplify(0.05).coords))
                start = None
        if runs:
            self.out(f"{col('k', 'RG')} 0.90 w 2 J 1 j [] 0 d\n" + rings_ops(runs, close=False) + " S")

    def ylabel(self, x_right: float, y_mid: float, s: str) -> None:
        """``s`` turned 90° (reading upwards), centred on ``y_mid``, its extent ending at ``x_right``."""
        p = self.pdf
        w = self.text_width(s, FS)
        bx, by = x_right - 0.24 * FS, self.page_h - y_mid  # baseline point (fpdf: y from the top)
        with p.rotation(90, bx, by):
            p.set_text_color(0, 0, 0)
            p.text(bx - 0.5 * w, by, s)


def draw_states_page(pdf: Any, font: str, plan: Plan) -> None:
    """Add the states page (the size of :func:`maps.export.plots.states_figure`) and draw it."""
    w_in, h_in = states_size_in(plan)
    pdf.add_page(format=(w_in * PT, h_in * PT))
    StatesWriter(pdf, font, plan).draw()
