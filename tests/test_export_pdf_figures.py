"""The trial card's two figures drawn straight into the PDF (maps.export.pdfmap, pdfstates), the
route shared by every export of a plan, and the PNG figures' sizes."""

from __future__ import annotations

import json
import pickle
import shutil
import subprocess

import numpy as np
import pytest

from maps.export._testing import synthetic_plan
from maps.export.chart import embed_chart, plan_chart
from maps.export.plots import STATES_DPI, states_size_in
from maps.plan import Plan

START = "2026-06-01T08:00:00Z"


def _square(lon: float, lat: float, d: float) -> dict:
    return {"type": "Polygon", "coordinates": [[[lon, lat], [lon + d, lat], [lon + d, lat + d], [lon, lat + d], [lon, lat]]]}


@pytest.fixture(scope="module")
def charted() -> Plan:
    """The synthetic azimuth plan with land, a restricted patch and two depth areas around it."""
    plan = synthetic_plan("full-scale")
    lon, lat = plan.lonlat[:, 0], plan.lonlat[:, 1]
    fc = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "properties": {"kind": "land"}, "geometry": _square(lon.max() + 0.0005, lat.min(), 0.001)},
            {"type": "Feature", "properties": {"kind": "restricted"}, "geometry": _square(lon.min() - 0.0008, lat.min(), 0.0004)},
            {"type": "Feature", "properties": {"kind": "depth_area", "min_depth_m": 30.0}, "geometry": _square(24.9, 60.1, 0.1)},
            {
                "type": "Feature",
                "properties": {"kind": "depth_area", "min_depth_m": 10.0},
                "geometry": _square(float(lon.mean()), float(lat.mean()), 0.0005),
            },
        ],
    }
    plan = Plan.from_dict(json.loads(plan.to_json()))
    embed_chart(plan, fc)
    return plan


def _pdf_with_map(plan: Plan):
    from fpdf import FPDF

    from maps.export.cardpdf import _Card
    from maps.export.pdfmap import MapWriter, map_frame

    doc = _Card()
    doc.page()
    w = MapWriter(doc.pdf, "DejaVu Sans", plan, plan_chart(plan), map_frame(plan, (60.0, 170.0, 500.0, 500.0)))
    w.draw()
    w.draw_legend()
    assert isinstance(doc.pdf, FPDF)
    return w


def test_pdf_map_legend_lists_what_the_matplotlib_map_lists(charted):
    """Same layers, same order: land, shallow/restricted (hatched), depth areas, sea room, track
    segments, start and end, as draw_map's legend."""
    import matplotlib.pyplot as plt

    from maps.export.mapplot import draw_map

    fig, ax = plt.subplots()
    try:
        draw_map(ax, charted)
        want = ax.get_legend_handles_labels()[1]
    finally:
        plt.close(fig)
    got = [e["label"] for e in _pdf_with_map(charted).legend]
    assert got == want
    assert {"land", "shallow / restricted (no-go)", "start", "end"} <= set(got)
    assert any(lab.startswith("depth areas 10-30 m") for lab in got)


def test_pdf_map_frame_keeps_the_chart_aspect(charted):
    """The map's box has matplotlib's fixed aspect: a metre north is as long as a metre east."""
    from maps.export.pdfmap import map_frame

    f = map_frame(charted, (0.0, 0.0, 500.0, 700.0))
    m_lon, m_lat = f.m_per_deg
    lat0 = float(np.mean(charted.lonlat[:, 1]))
    assert m_lon == pytest.approx(111_320.0 * np.cos(np.radians(0.5 * (f.y0 + f.y1))))
    per_pt_east = (f.x1 - f.x0) * 111_320.0 * np.cos(np.radians(lat0)) / f.width
    per_pt_north = (f.y1 - f.y0) * m_lat / f.height
    assert per_pt_east == pytest.approx(per_pt_north, rel=1e-9)
    assert f.width <= 500.0 + 1e-9 and f.height <= 700.0 + 1e-9 and max(f.width / 500.0, f.height / 700.0) == pytest.approx(1.0)


def test_card_pdf_pages_render_with_the_map_and_states_drawn(charted, tmp_path):
    """Every page renders; page 1 shows land (tan), no-go water (blue-grey) and the start
    (green) inside the map; the last page has the states figure's size and its words as text."""
    from maps.export.card import write_card_pdf

    path = write_card_pdf(charted, tmp_path / "card.pdf", start=START)
    pdf = path.read_bytes()
    w_in, h_in = states_size_in(charted)
    assert f"/MediaBox [0 0 {w_in * 72:.2f} {h_in * 72:.2f}]".encode() in pdf
    if not shutil.which("pdftoppm") or not shutil.which("pdftotext"):
        pytest.skip("poppler-utils not installed: pages not rendered")
    pages = int(
        next(
            ln.split()[-1]
            for ln in subprocess.run(["pdfinfo", str(path)], capture_output=True, text=True, check=True).stdout.splitlines()
            if ln.startswith("Pages:")
        )
    )
    subprocess.run(["pdftoppm", "-png", "-r", "40", str(path), str(tmp_path / "p")], check=True)
    pngs = sorted(tmp_path.glob("p-*.png"))
    assert len(pngs) == pages >= 4
    from PIL import Image

    page1 = np.asarray(Image.open(pngs[0]).convert("RGB")).reshape(-1, 3).astype(int)

    def has(hex_colour: str, tol: int = 12) -> bool:
        c = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)])
        return bool((np.abs(page1 - c).max(axis=1) <= tol).sum() >= 3)

    assert has("#c8b88a") and has("#8fb3c9") and has("#008000", 40)  # land, no-go, start marker
    text = subprocess.run(
        ["pdftotext", "-f", str(pages), "-l", str(pages), str(path), "-"], capture_output=True, text=True, check=True
    ).stdout
    assert "time from start [min]" in text and "speed over ground [kn]" in text and "heading [°]" in text


def test_one_route_per_plan_and_chart_even_across_a_pickle(charted):
    """The exports of one plan share one route (for one chart object); the route travels with
    the plan to the drawing process; another chart gets its own route."""
    from maps.export.route import build_route

    chart = plan_chart(charted)
    r = build_route(charted, chart)
    assert build_route(charted, chart) is r
    other = build_route(charted, plan_chart(charted))
    assert other is not r and [p.name for p in other.points] == [p.name for p in r.points]
    job = pickle.loads(pickle.dumps({"plan": charted, "chart": chart}))
    build_route(job["plan"], job["chart"])  # primes the memo for this chart again
    again = pickle.loads(pickle.dumps({"plan": job["plan"], "chart": job["chart"]}))
    assert build_route(again["plan"], again["chart"]) is again["plan"].__dict__["_route_memo"][-1]
    assert "_route_memo" not in json.loads(charted.to_json())
    # a value the route is built from changed on the same plan: built afresh, never the stale one
    charted.stats["turning_radius_m"] = 2.0 * (charted.stats.get("turning_radius_m") or 100.0)
    turned = build_route(charted, chart)
    assert turned is not r and build_route(charted, chart) is turned


def test_png_figures_have_their_sizes(charted, tmp_path):
    """The states PNG is the figure's size at its dpi; the track PNG ends where its map and
    legend do (no blank margin round an equal-aspect map)."""
    from PIL import Image

    from maps.export.plots import plot_states, plot_track

    s = Image.open(plot_states(charted, tmp_path / "s.png"))
    w_in, h_in = states_size_in(charted)
    assert abs(s.size[0] - w_in * STATES_DPI) <= 1 and abs(s.size[1] - h_in * STATES_DPI) <= 1
    t = np.asarray(Image.open(plot_track(charted, tmp_path / "t.png")).convert("L"))
    assert t.shape[0] > 300 and t.shape[1] > 300
    ink_cols = np.flatnonzero((t < 250).any(axis=0))
    ink_rows = np.flatnonzero((t < 250).any(axis=1))
    assert ink_cols[-1] > 0.97 * t.shape[1] and ink_rows[-1] > 0.9 * t.shape[0]  # nothing much blank right or below


def test_one_sea_room_per_plan_even_across_a_pickle(charted):
    """The overlay, the track figure and the card's map share the plan's sea room, also in the
    drawing process; a different margin is another sea room."""
    from dataclasses import replace

    from maps.export.geojson import sea_room_lonlat

    room = sea_room_lonlat(charted)
    assert room is not None and sea_room_lonlat(charted) is room
    sent = pickle.loads(pickle.dumps(charted))
    assert sea_room_lonlat(sent) is sent.__dict__["_sea_room_memo"][1] and sea_room_lonlat(sent).equals(room)
    wider = replace(charted, margin_m=charted.margin_m + 50.0)
    assert sea_room_lonlat(wider).area > room.area


def test_track_figure_of_a_narrow_map_keeps_its_title_and_readable_ticks():
    """A map much taller than wide (a fjord): the figure is as wide as its title, and the
    longitude labels do not overlap (fewer ticks on a narrow map, in the PDF map too)."""
    import matplotlib.pyplot as plt

    from maps.export.mapplot import lon_ticks
    from maps.export.pdfmap import map_frame
    from maps.export.plots import track_figure

    plan = synthetic_plan("full-scale", ("straight",) * 40)
    lat0 = float(plan.lonlat[0, 1])
    plan.lonlat[:, 1] = lat0 + np.linspace(0.0, 0.1, len(plan.lonlat))  # 11 km north
    plan.lonlat[:, 0] = plan.lonlat[0, 0] + np.linspace(0.0, 0.002, len(plan.lonlat))  # 110 m east
    fig = track_figure(plan)
    try:
        r = fig.canvas.get_renderer()
        ax = fig.axes[0]
        title, whole = ax.title.get_window_extent(r), fig.bbox
        assert title.x0 >= whole.x0 - 1 and title.x1 <= whole.x1 + 1
        boxes = sorted(
            (t.get_window_extent(r) for t in ax.get_xticklabels() if t.get_text() and t.get_visible()), key=lambda b: b.x0
        )
        visible = [b for b in boxes if b.x1 >= ax.bbox.x0 - 1 and b.x0 <= ax.bbox.x1 + 1]
        assert all(a.x1 <= b.x0 for a, b in zip(visible, visible[1:]))
    finally:
        plt.close(fig)
    f = map_frame(plan, (0.0, 0.0, 500.0, 500.0))
    ticks = lon_ticks(f.x0, f.x1, f.width)
    assert ticks and all((b - a) / (f.x1 - f.x0) * f.width >= 60.0 for a, b in zip(ticks, ticks[1:]))
    assert len(lon_ticks(24.95, 25.02, 400.0)) >= 4  # a wide map keeps its four or five


def test_page1_summary_lines_fit_the_page(charted):
    """A design that leaves many manoeuvres unused: page 1's summary is wrapped, every line
    inside the page's width in the card's font, none lost."""
    from datetime import UTC, datetime

    from maps.export.card import page1_layout
    from maps.export.cardpdf import FONT, W, _Card

    plan = Plan.from_dict(json.loads(charted.to_json()))
    names = [f"zigzag_{k}_{k}_s" for k in range(10, 30)]
    plan.design = {
        "criterion": "D",
        "mean_subtraction": "complete",
        "d_efficiency": 0.99,
        "weights": {"straight": 1.0},
        "counts": {"straight": 1},
        "not_used": names,
    }
    lines, _, _, _ = page1_layout(plan, datetime(2026, 6, 1, 8, tzinfo=UTC), plan_chart(plan), "MS Test")
    doc = _Card()
    doc.pdf.set_font(FONT, "", 8.5)
    assert all(0.05 * W + doc.pdf.get_string_width(line) <= 0.97 * W for line in lines)
    assert all(n in " ".join(lines) for n in names)


def _boxes_apart(boxes: list[tuple[float, float]]) -> bool:
    """(x0, x1) boxes, sorted by x0, none overlapping the next."""
    boxes = sorted(boxes)
    return all(a[1] <= b[0] for a, b in zip(boxes, boxes[1:]))


@pytest.fixture(scope="module")
def long_plan() -> Plan:
    """80 steps: far more numbers than the states figure's width holds side by side."""
    return synthetic_plan("full-scale", ("straight", "turn_s") * 40)


def test_states_png_step_numbers_do_not_overlap(long_plan):
    """A long plan's step numbers are thinned to what the top axes hold: no two label boxes
    overlap, the first and last steps are always numbered, and a short plan keeps every number."""
    import matplotlib.pyplot as plt

    from maps.export.plots import states_figure

    for plan, every in ((long_plan, False), (synthetic_plan("full-scale"), True)):
        fig = states_figure(plan)
        try:
            r = fig.canvas.get_renderer()
            texts = [t for t in fig.axes[0].texts if t.get_text().isdigit()]
            shown = [t.get_text() for t in texts]
            boxes = [(b.x0, b.x1) for b in (t.get_window_extent(r) for t in texts)]
            assert _boxes_apart(boxes)
            assert shown[0] == "1" and shown[-1] == str(len(plan.steps))
            assert len(shown) == len(plan.steps) if every else 10 < len(shown) < len(plan.steps)
        finally:
            plt.close(fig)


def test_pdf_states_page_step_numbers_do_not_overlap(long_plan, tmp_path):
    """The PDF card's states page thins the step numbers likewise (word boxes from pdftotext)."""
    import re

    from maps.export.card import write_card_pdf

    if not shutil.which("pdftotext"):
        pytest.skip("poppler-utils not installed")
    path = write_card_pdf(long_plan, tmp_path / "card.pdf", start=START)
    html = subprocess.run(["pdftotext", "-bbox", "-f", "0", str(path), "-"], capture_output=True, text=True, check=True).stdout
    last = html.split("<page ")[-1]
    words = [
        (float(a), float(b), float(c), w)
        for a, b, c, w in re.findall(r'xMin="([\d.]+)" yMin="([\d.]+)" xMax="([\d.]+)" yMax="[\d.]+">([^<]*)<', last)
    ]
    title_y = next(y for _, y, _, w in words if w == "planned")  # the title, over the step numbers
    numbers = [(x0, x1, w) for x0, y, x1, w in words if w.isdigit() and title_y < y < title_y + 40]
    assert numbers[0][2] == "1" and numbers[-1][2] == str(len(long_plan.steps)) and 10 < len(numbers) < len(long_plan.steps)
    assert _boxes_apart([(a, b) for a, b, _ in numbers])


WIDE_SCALES = pytest.mark.parametrize("scale", [-500.0, -1.2e-7], ids=["MN", "tiny"])


def _wide_plan(scale: float) -> Plan:
    """A generalized-force ship whose surge force is scaled to tick labels of 8-9 characters:
    to -2.5e6 N (the PDF writes "-2.5e+06") or to -0.0006 (the PNG writes "-0.000575")."""
    plan = synthetic_plan("model-ship")
    plan.inputs[:, 0] *= scale
    return plan


@WIDE_SCALES
def test_states_png_margin_follows_wide_tick_labels(scale):
    """Nothing of the figure (tick labels, y labels) falls outside it (fails before: the y label
    was cut at the left edge); the bundled ships keep the fixed margin."""
    import matplotlib.pyplot as plt

    from maps.export.plots import STATES_MARGINS_IN, states_figure

    fig = states_figure(_wide_plan(scale))
    try:
        r = fig.canvas.get_renderer()
        fig.draw(r)
        drawn = fig.get_tightbbox(r)  # inches
        w_in, h_in = fig.get_size_inches()
        assert drawn.x0 >= 0.0 and drawn.x1 <= w_in and drawn.y0 >= 0.0 and drawn.y1 <= h_in
        for ax in fig.axes:
            assert ax.yaxis.label.get_window_extent(r).x0 >= 0.0
    finally:
        plt.close(fig)
    fig = states_figure(synthetic_plan("full-scale"))
    try:
        assert fig.axes[0].get_position().x0 * fig.get_size_inches()[0] == pytest.approx(STATES_MARGINS_IN["left"])
    finally:
        plt.close(fig)


@WIDE_SCALES
def test_pdf_states_page_margin_follows_wide_tick_labels(scale, tmp_path):
    """The PDF card's states page: every word (tick labels and the turned y labels) on the page."""
    import re

    from maps.export.card import write_card_pdf

    if not shutil.which("pdftotext"):
        pytest.skip("poppler-utils not installed")
    path = write_card_pdf(_wide_plan(scale), tmp_path / "card.pdf", start=START)
    html = subprocess.run(["pdftotext", "-bbox", str(path), "-"], capture_output=True, text=True, check=True).stdout
    last = html.split("<page ")[-1]
    page_w = float(re.search(r'width="([\d.]+)"', last).group(1))
    words = re.findall(r'xMin="(-?[\d.]+)" yMin="-?[\d.]+" xMax="(-?[\d.]+)" yMax="-?[\d.]+">([^<]*)<', last)
    assert "tau_x" in [w for _, _, w in words] and max(len(w) for _, _, w in words if w.startswith("\u2212")) >= 8
    assert all(float(a) >= 0.0 and float(b) <= page_w for a, b, _ in words)


@pytest.mark.parametrize("n_manoeuvres", [3, 8, 12])
def test_manoeuvre_colours_never_read_as_run_in_transit_or_chart(n_manoeuvres: int) -> None:
    """A plan's third manoeuvre was tab10's green, 40 (8-bit RGB) from the run-ins' dashed green,
    and its eighth tab10's grey, 9 from the transits': on the card's map and states page a master
    could not tell a zig-zag from its run-in (stop 62's walk through the README's Quick start)."""
    from types import SimpleNamespace

    from matplotlib.colors import to_rgb

    from maps.export.mapplot import LAND_COLOUR, RUN_IN_COLOUR, SEA_ROOM_COLOUR, TRANSIT_COLOUR, WATER_COLOUR, primitive_colours

    steps = [SimpleNamespace(primitive="runin", segment="run-in"), SimpleNamespace(primitive="transit", segment="transit")]
    steps += [SimpleNamespace(primitive=f"m{i}", segment="informative") for i in range(n_manoeuvres)]
    colours = primitive_colours(SimpleNamespace(steps=steps))
    reserved = np.array([to_rgb(c) for c in (RUN_IN_COLOUR, TRANSIT_COLOUR, SEA_ROOM_COLOUR, WATER_COLOUR, LAND_COLOUR)]) * 255.0
    drawn = np.array([to_rgb(colours[f"m{i}"]) for i in range(n_manoeuvres)]) * 255.0
    nearest = np.linalg.norm(drawn[:, None, :] - reserved[None, :, :], axis=2).min(axis=1)
    assert nearest.min() >= 50.0, f"manoeuvre colour {int(nearest.argmin())} is {nearest.min():.0f} from a reserved colour"
    assert len({tuple(np.round(c, 3)) for c in drawn}) == n_manoeuvres  # one colour per manoeuvre


def test_plan_png_draws_each_manoeuvre_in_the_cards_colour_never_the_run_ins():
    """plan.png (maps.output) drew its third manoeuvre in tab10's green beside the run-ins' dashed
    #1b7f3b, and by sorted name where the card colours by first appearance (stop 62's walk)."""
    from types import SimpleNamespace

    from matplotlib.colors import to_rgb

    from maps.export.mapplot import RUN_IN_COLOUR, primitive_colours
    from maps.output import _plan_track

    names = ["zz", "acc", "crab", "turn"]  # sailed in this order, not sorted
    steps = [SimpleNamespace(index=0, primitive="zz", segment="run-in", execute=False, entry_x=0.0, entry_y=0.0)]
    steps += [
        SimpleNamespace(index=i + 1, primitive=n, segment="informative", execute=True, entry_x=0.0, entry_y=0.0)
        for i, n in enumerate(names)
    ]
    plan = SimpleNamespace(steps=steps, step_of_sample=np.repeat(np.arange(5), 2), track=np.zeros((10, 3)))
    drawn: dict[str, tuple] = {}

    class Ax:
        def plot(self, *args, color=None, label=None, **kw):
            if label in names:
                drawn[label] = to_rgb(color)

    _plan_track(plan, Ax())
    card = primitive_colours(plan)
    assert {n: to_rgb(card[n]) for n in names} == drawn
    run_in = np.array(to_rgb(RUN_IN_COLOUR))
    assert min(np.linalg.norm(np.array(c) - run_in) * 255 for c in drawn.values()) >= 50


def test_a_plan_of_up_to_seven_manoeuvres_gets_no_colour_near_the_transit_or_run_in() -> None:
    """The states page draws each step as a 12 %-alpha band: tab10's brown (62 from the transit
    grey in 8-bit RGB) made a band CIELAB dE 2.6 from the transit's, so the Quick start's fifth
    manoeuvre (tau20, steps 16 and 19) read as a transit; main's green (40 from the run-in) the
    same for its third. Up to seven manoeuvres take only colours at least 65 away."""
    from types import SimpleNamespace

    from matplotlib.colors import to_rgb

    from maps.export.mapplot import RUN_IN_COLOUR, TRANSIT_COLOUR, primitive_colours

    steps = [SimpleNamespace(primitive=f"m{i}", segment="informative") for i in range(7)]
    colours = primitive_colours(SimpleNamespace(steps=steps))
    near = np.array([to_rgb(RUN_IN_COLOUR), to_rgb(TRANSIT_COLOUR)]) * 255.0
    for i in range(7):
        d = np.linalg.norm(near - np.array(to_rgb(colours[f"m{i}"])) * 255.0, axis=1).min()
        assert d >= 65.0, f"manoeuvre {i + 1} is {d:.0f} from the run-in or transit colour"
