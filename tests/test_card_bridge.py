"""The trial card as the bridge reads it (issue 29): every step label visible, propeller speeds
in the unit of the orders, no step split across PDF pages, knots and helm/engine words only."""

from __future__ import annotations

import re

import numpy as np
import pytest

from maps.export._testing import synthetic_plan
from maps.export.labels import segment_distances
from maps.plan import Plan

START = "2026-06-01T08:00Z"
# spot turns and short moves crowd many entry points into a few hundred metres
CROWDED = ("straight", "spot_turn_s", "spot_turn_s", "tau12", "spot_turn_p", "spot_turn_p", "straight", "tau16", "spot_turn_s",
           "straight")


@pytest.fixture(scope="module")
def crowded() -> Plan:
    return synthetic_plan("full-scale", CROWDED, run_in=True)


def _check_circles(centres: np.ndarray, radii: np.ndarray, track: np.ndarray) -> None:
    n = len(centres)
    for i in range(n):
        for j in range(i + 1, n):
            gap = np.hypot(*(centres[i] - centres[j])) - radii[i] - radii[j]
            assert gap >= 0.0, f"labels {i + 1} and {j + 1} overlap by {-gap:.1f} pt"
    d = segment_distances(centres, track[:-1], track[1:])
    assert np.all(d >= radii), f"labels {np.flatnonzero(d < radii) + 1} lie on the track"


def test_pdf_map_labels_every_step_none_overlapping_or_on_the_track(crowded):
    from maps.export.pdfmap import map_frame, step_labels

    f = map_frame(crowded, (60.0, 170.0, 500.0, 400.0))
    labels = step_labels(crowded, f, lambda s: 4.5 * len(s))
    assert [lab.text for _, lab in labels] == [str(k + 1) for k in range(len(crowded.steps))]
    centres = np.array([[lab.x, lab.y] for _, lab in labels])
    _check_circles(centres, np.array([lab.r for _, lab in labels]), f.xy(crowded.lonlat))
    assert any(lab.moved for _, lab in labels)  # crowded: some are set aside (with a leader line)


def test_png_map_labels_every_step_none_overlapping_or_on_the_track(crowded):
    """The drawn annotations' boxes in the track figure (the HTML card's map)."""
    from maps.export.plots import track_figure

    fig = track_figure(crowded)
    try:
        fig.canvas.draw()  # the label boxes are laid out when drawn
        r = fig.canvas.get_renderer()
        ax = fig.axes[0]
        anns = sorted((a for a in ax.texts if (a.get_gid() or "").startswith("step-label-")), key=lambda a: int(a.get_text()))
        assert [a.get_text() for a in anns] == [str(k + 1) for k in range(len(crowded.steps))]
        boxes = [a.get_bbox_patch().get_window_extent(r) for a in anns]
        centres = np.array([[0.5 * (b.x0 + b.x1), 0.5 * (b.y0 + b.y1)] for b in boxes])
        radii = np.array([0.5 * min(b.width, b.height) for b in boxes])
        _check_circles(centres, radii, ax.transData.transform(crowded.lonlat[:, :2]))
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_states_figure_plots_propeller_speed_in_rpm_as_the_orders_say(crowded):
    from maps.export._common import step_orders
    from maps.export.plots import state_series

    series = dict(state_series(crowded))
    rpm = series["propeller 1 [rpm]"]
    tau12 = next(st for st in crowded.steps if st.primitive == "tau12")
    ordered = [float(m) for o in step_orders(crowded, tau12) for m in re.findall(r"(\d+) rpm", o)]
    assert ordered and max(ordered) == pytest.approx(np.nanmax(rpm), rel=0.01)
    assert np.nanmax(rpm) == pytest.approx(60.0 * np.nanmax(crowded.inputs[:, 0]))
    assert not any("n1" in label or "alpha" in label for label in series)
