"""The trial card as the bridge reads it (issue 29): every step label visible, propeller speeds
in the unit of the orders, no step split across PDF pages, knots and helm/engine words only."""

from __future__ import annotations

import re

import numpy as np
import pytest

from maps.export._testing import synthetic_plan
from maps.plan import Plan

START = "2026-06-01T08:00Z"
# spot turns and short moves crowd many entry points into a few hundred metres
CROWDED = (
    "straight",
    "spot_turn_s",
    "spot_turn_s",
    "tau12",
    "spot_turn_p",
    "spot_turn_p",
    "straight",
    "tau16",
    "spot_turn_s",
    "straight",
)


@pytest.fixture(scope="module")
def crowded() -> Plan:
    return synthetic_plan("full-scale", CROWDED, run_in=True)


def _check_circles(centres: np.ndarray, radii: np.ndarray, track: np.ndarray) -> None:
    from maps.export.labels import segment_distances

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
    from maps.export.plots import state_series
    from maps.export.wording import step_orders

    series = dict(state_series(crowded))
    rpm = series["propeller 1 [rpm]"]
    tau12 = next(st for st in crowded.steps if st.primitive == "tau12")
    ordered = [float(m) for o in step_orders(crowded, tau12) for m in re.findall(r"(\d+) rpm", o)]
    assert ordered and max(ordered) == pytest.approx(np.nanmax(rpm), rel=0.01)
    assert np.nanmax(rpm) == pytest.approx(60.0 * np.nanmax(crowded.inputs[:, 0]))
    assert not any("n1" in label or "alpha" in label for label in series)


# -- the PDF: a step's orders never split across pages -------------------------------------------

_HEAD = re.compile(r"^(\d+)\. (EXECUTE|manoeuvre|run-in:|stop:|transit:) ")


def _pages(path) -> list[str]:
    import shutil
    import subprocess

    if not shutil.which("pdftotext"):
        pytest.skip("pdftotext (poppler-utils) not installed")
    text = subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True, check=True).stdout
    return text.split("\f")


def test_pdf_never_splits_a_step_across_pages(tmp_path):
    """Per page of the orders: the page starts with a step's heading and holds whole steps (each
    heading's last line, the wind abort, on the same page); every step is there once."""
    from maps.export import export_plan

    names = ("straight", "tau17", "spot_turn_s", "tau19", "tau12", "spot_turn_p", "tau17", "tau16", "tau20", "tau13", "tau18")
    plan = synthetic_plan("full-scale", names, run_in=True)
    pages = _pages(export_plan(plan, "card", tmp_path / "card.pdf", start=START)[0])
    orders = [p for p in pages if "orders per step in sailing order" in p]
    assert len(orders) >= 2  # enough steps for several pages
    seen = []
    for page in orders:
        body = [ln.strip() for ln in page.splitlines()[1:] if ln.strip()]
        assert _HEAD.match(body[0]), f"a page of orders starts mid-step: {body[0]!r}"
        heads = [int(m[1]) for ln in body if (m := _HEAD.match(ln))]
        ends = [ln for ln in body if ln.startswith("Abort if wind above")]
        assert len(heads) == len(ends), f"steps {heads}: a step runs over the page"
        seen += heads
    assert seen == list(range(1, len(plan.steps) + 1))


# -- words: knots, helm/engine or azimuth terms, names a master knows ----------------------------

_ENGINEERING = re.compile(r"m/s|\btau_[xyn]\b|side force|turning moment|\bnu\b|\bdeg\b|speed < 0\.0|steady course and speed")


def _bridge_texts(plan: Plan, tmp_path) -> dict[str, str]:
    """The card (HTML text without its images, the PDF's text), the GPX and the RTZ of ``plan``."""
    from maps.export import export_all

    paths = export_all(plan, tmp_path, start=START)
    html = re.sub(r'src="data:image/png;base64,[^"]+"', "", paths["card"].read_text(encoding="utf-8"))
    return {
        "html": html,
        "pdf": "".join(_pages(paths["card_pdf"])),
        "gpx": paths["gpx"].read_text(encoding="utf-8"),
        "rtz": paths["rtz"].read_text(encoding="utf-8"),
    }


@pytest.mark.parametrize(
    "ship, names",
    [
        ("full-scale", ("straight", "tau12", "spot_turn_s", "tau16", "zigzag_10_10_s")),
        ("kvlcc2", ("straight", "zigzag_10_10_s", "turn_p", "stopping")),
    ],
)
def test_bridge_documents_speak_knots_and_the_ships_own_terms(ship, names, tmp_path):
    plan = synthetic_plan(ship, names, run_in=True)
    for doc, text in _bridge_texts(plan, tmp_path).items():
        bad = sorted({m[0] for m in _ENGINEERING.finditer(text)})
        assert not bad, f"{ship} {doc}: engineering words on a bridge document: {bad}"
        assert " kn" in text


def test_manoeuvres_are_named_as_a_master_knows_them(crowded):
    from maps.export.card import step_sheets

    sheets = {s["primitive"]: s for s in step_sheets(crowded, START) if s["segment"] == "EXECUTE"}
    assert re.fullmatch(r"acceleration 0 → 6\.\d kn, then thrusters stopped, coasting down", sheets["tau12"]["name"])
    assert re.fullmatch(r"crabbing at \d\.\d kn to starboard, then to port", sheets["tau16"]["name"])
    kv = synthetic_plan("kvlcc2", ("straight", "zigzag_10_10_s", "turn_p", "stopping"), run_in=True)
    named = {s["primitive"]: s["name"] for s in step_sheets(kv, START)}
    assert named["zigzag_10_10_s"] == "10/10 zig-zag to starboard"
    assert named["turn_p"] == "90° turn to port"
    assert re.fullmatch(r"engine stop from 1\d\.?\d* kn, coasting to \d+\.?\d* kn", named["stopping"])


def test_spot_turn_orders_give_times_thruster_angles_and_rpm(crowded):
    from maps.export.wording import step_orders
    from maps.plan import PlanStep

    # as the planner's lattice move carries it: its phases in words, no orders of its own
    st = next(st for st in crowded.steps if st.primitive == "spot_turn_s")
    spot = PlanStep(
        **{
            **st.__dict__,
            "orders": [],
            "commands": ["stop the ship", "turn on the spot 90° to starboard", "regain 5.8 kn on the new course"],
        }
    )
    lines = step_orders(crowded, spot)
    assert [
        re.match(r"at \+\d+:\d\d: (stop the ship|turn on the spot (89|90|91)° to starboard|on course \d{3}°, regain)", ln)
        is not None
        for ln in lines
    ] == [True, True, True]
    setting = r"(\d+ rpm, thrust (ahead|astern|\d+° to (starboard|port))|thruster stopped)"
    assert all(re.search(setting, ln) for ln in lines)
    assert re.search(r"\d+ rpm, thrust \d+° to starboard; stern thruster \d+ rpm, thrust \d+° to port", lines[1])


def test_abort_line_has_no_lower_speed_limit_for_a_manoeuvre_from_rest():
    from primitives.library import build_library
    from primitives.ship import load_profile

    lib = {p.name: p for p in build_library(load_profile("full-scale"))}
    assert lib["tau12"].abort_criteria().startswith("abort if speed above ")
    assert lib["tau17"].abort_criteria().startswith("abort if speed below ")


def test_a_run_in_that_stops_the_ship_is_called_a_stop():
    from maps.export.wording import manoeuvre_name, phase
    from maps.plan import PlanStep

    plan = synthetic_plan("full-scale", ("tau12",), run_in=True)
    st = plan.steps[0]
    assert st.segment == "run-in"
    stop = PlanStep(
        **{
            **st.__dict__,
            "description": "stop before tau12: come to rest and settle",
            "orders": [{"t_s": 0.0, "text": "stop engine(s) and come to rest, heading 117° for 67 s, then execute"}],
        }
    )
    assert phase(plan, stop) == "stop" and manoeuvre_name(plan, stop) == "stop and settle"
    assert phase(plan, st) == "run-in" and manoeuvre_name(plan, st).startswith("steady approach at 5.8 kn")


def test_the_planner_names_stops_recoveries_and_spot_turns_for_the_bridge():
    """The default Helsinki plan of the full-scale ship (tau12 starts from rest; spot turns
    reposition it): the run-in before tau12 stops the ship and says so, each manoeuvre ends with
    its recovery as a separate order, a spot turn gives each phase's thruster angles and rpm,
    and no step's commands or orders speak m/s."""
    from maps.export.wording import phase, step_orders
    from maps.planner import plan_trial
    from primitives.ship import load_profile

    plan = plan_trial(profile=load_profile("full-scale"))
    assert plan.feasible
    for st in plan.steps:
        words = " ".join([*st.commands, *(str(o.get("text", "")) for o in st.orders)])  # the description is the library's
        assert "m/s" not in words and "transit: transit" not in words
        if st.segment == "informative" and st.primitive == "tau12":
            before = plan.steps[st.index - 1]
            assert phase(plan, before) == "stop" and "steady course and speed" not in before.description
        if st.segment == "informative":
            rec = [o for o in st.orders if o.get("phase") == "recovery"]
            assert len(rec) == 1 and rec[0]["text"].startswith("manoeuvre complete; recovery: come to course")
            assert rec[0]["t_s"] > max(o["t_s"] for o in st.orders if o.get("phase") != "recovery")
    # a timed order reads "at +0:00: steer for ... at 5.8 kn", never "at +0:00: at 5.8 kn steer ..."
    assert not [ln for st in plan.steps for ln in step_orders(plan, st) if re.match(r"at \+[\d:]+: at ", ln)]
    spots = [st for st in plan.steps if st.primitive.startswith("spot_turn")]
    assert spots
    for st in spots:
        lines = step_orders(plan, st)
        assert len(lines) == 3 and all(re.search(r"\d+ rpm, thrust", ln) for ln in lines[:2])


# -- the map's legend and marks --------------------------------------------------------------------


def test_labels_keep_off_the_north_arrow_and_the_end_marker():
    """A step entered under the north arrow and one entered beside the end marker: their numbers
    go elsewhere, clear of both marks (the default place, up and right, would sit on them)."""
    from maps.export.labels import DEFAULT_OFFSET, map_marks, mark_room, place_labels

    frame = (0.0, 0.0, 400.0, 300.0)
    xn, yn = 0.95 * 400.0, 0.85 * 300.0  # the "N" of the north arrow
    track = np.array([[100.0, 100.0], [200.0, 100.0], [300.0, 150.0]])
    end = track[-1]
    anchors = np.array([[xn - DEFAULT_OFFSET[0], yn + 5.0 - DEFAULT_OFFSET[1]], end - np.array(DEFAULT_OFFSET) + [0.0, 2.0]])
    labels = place_labels(["7", "8"], anchors, [5.0, 5.0], track, frame)
    centres = np.array([[lab.x, lab.y] for lab in labels])
    room = mark_room(centres, map_marks(frame, tuple(end)))
    assert np.all(room >= 5.0), f"labels on the north arrow or the end marker: {room - 5.0}"
    assert all(lab.moved for lab in labels)


def test_north_arrow_goes_to_a_corner_the_track_keeps_clear_of():
    """The coaster card's "end" square sat on the north arrow (drawn top right whatever the track did): a track
    ending top right (the synthetic plan mirrored north-south; it starts top left) gets the arrow in a corner it
    keeps clear of, on the PNG map and as the labels' mark (stop 62's walk-through)."""
    from dataclasses import replace

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from maps.export.labels import segment_distances
    from maps.export.mapplot import draw_map, map_view

    plan = synthetic_plan("full-scale")
    x0, y0, x1, y1, _, _ = map_view(plan)
    ll = plan.lonlat.copy()
    ll[:, 1] = y0 + y1 - ll[:, 1]
    plan = replace(plan, lonlat=ll)
    frac = (ll[:, :2] - (x0, y0)) / (x1 - x0, y1 - y0)
    assert frac[-1, 0] > 0.85 and frac[-1, 1] > 0.75  # the track ends near the top-right corner
    fig, ax = plt.subplots(figsize=(6, 5))
    try:
        draw_map(ax, plan, numbers=False, sea_room=False)
        (north,) = [t for t in ax.texts if t.get_text() == "N"]
        (nx, ny0), (_, ny1) = north.xyann, north.xy
    finally:
        plt.close(fig)
    clear = segment_distances(frac, np.array([[nx, ny0]]), np.array([[nx, ny1]])).min()
    # 0.07: labels.NORTH_CLEAR, the "N" and the end square apart on a card-sized map
    assert clear >= 0.07, f"north arrow at {nx:.2f}, {ny0:.2f}-{ny1:.2f}: {clear:.3f} of the frame from the track"


def _check_marks(centres: np.ndarray, radii: np.ndarray, frame: tuple[float, float, float, float], track: np.ndarray) -> None:
    from maps.export.labels import map_marks, mark_room, north_place

    room = mark_room(centres, map_marks(frame, tuple(track[-1]), north_place(track, frame))) - radii
    assert np.all(room >= 0.0), f"labels {np.flatnonzero(room < 0) + 1} on the north arrow or the end marker"


def test_map_labels_clear_of_the_marks_in_both_maps(crowded):
    from maps.export.pdfmap import map_frame, step_labels
    from maps.export.plots import track_figure

    f = map_frame(crowded, (60.0, 170.0, 500.0, 400.0))
    labels = [lab for _, lab in step_labels(crowded, f, lambda s: 4.5 * len(s))]
    _check_marks(
        np.array([[lab.x, lab.y] for lab in labels]),
        np.array([lab.r for lab in labels]),
        (f.left, f.bottom, f.left + f.width, f.bottom + f.height),
        f.xy(crowded.lonlat),
    )
    fig = track_figure(crowded)
    try:
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        ax = fig.axes[0]
        boxes = [a.get_bbox_patch().get_window_extent(r) for a in ax.texts if (a.get_gid() or "").startswith("step-label-")]
        bb = ax.get_window_extent()
        _check_marks(
            np.array([[0.5 * (b.x0 + b.x1), 0.5 * (b.y0 + b.y1)] for b in boxes]),
            np.array([0.5 * min(b.width, b.height) for b in boxes]),
            (bb.x0, bb.y0, bb.x1, bb.y1),
            ax.transData.transform(crowded.lonlat[:, :2]),
        )
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_map_legend_names_manoeuvres_as_the_bridge_does_and_fits_the_page(crowded):
    """Both maps' legends give a manoeuvre's bridge name with its design code in brackets (never
    the bare code); the PDF legend takes fewer columns rather than run off the page."""
    from maps.export.cardpdf import FONT, W, _Card
    from maps.export.pdfmap import MapWriter, map_frame
    from maps.export.plots import track_figure
    from maps.export.wording import manoeuvre_name

    first = {}
    for st in crowded.steps:
        if st.segment == "informative":
            first.setdefault(st.primitive, f"{manoeuvre_name(crowded, st)} [{st.primitive}]")
    fig = track_figure(crowded)
    try:
        png = fig.axes[0].get_legend_handles_labels()[1]
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)
    doc = _Card()
    doc.page()
    w = MapWriter(doc.pdf, FONT, crowded, None, map_frame(crowded, (0.1 * W, 0.2 * 842.0, 0.85 * W, 0.5 * 842.0)))
    w.draw()
    boxes = []
    out = w.out
    w.out = lambda ops: (boxes.append(ops) if " re B Q" in ops else None, out(ops))[1]
    w.draw_legend()
    pdf = [e["label"] for e in w.legend]
    assert png == pdf
    assert [x for x in pdf if x.endswith("]")] == list(first.values()) and not set(first) & set(pdf)
    left, _, width = (float(v) for v in boxes[0].split()[-6:-3])
    assert left >= 0.0 and left + width <= W, f"the legend runs off the page: {left:.0f}..{left + width:.0f} pt"


def test_gpx_counts_steps_and_manoeuvres_apart(crowded, tmp_path):
    """The GPX route's description counts manoeuvres, not run-ins and transits as manoeuvres."""
    from maps.export.gpx import plan_gpx

    n_man = sum(1 for st in crowded.steps if st.segment == "informative")
    assert 0 < n_man < len(crowded.steps)
    text = plan_gpx(crowded, start=START).decode("utf-8")
    assert f"{len(crowded.steps)} steps ({n_man} manoeuvres)" in text


def test_acceleration_name_gives_the_top_speed_sailed_not_the_nominal(crowded):
    """tau12's name takes its top speed from the planned track (a ship that tops at 3.4 kn where
    the library's description says 3.5 m/s is called 'acceleration 0 → 3.4 kn')."""
    from dataclasses import replace

    from maps.export._common import step_slice
    from maps.export.wording import manoeuvre_name

    st = next(st for st in crowded.steps if st.primitive == "tau12" and st.segment == "informative")
    speed = crowded.speed.copy()
    sl = step_slice(crowded, st)
    speed[sl] *= 0.5
    slow = replace(crowded, speed=speed)
    top = float(speed[sl].max()) * 3600.0 / 1852.0
    assert manoeuvre_name(slow, st).startswith(f"acceleration 0 → {top:.1f} kn")
    assert manoeuvre_name(crowded, st).startswith(f"acceleration 0 → {float(crowded.speed[sl].max()) * 3600.0 / 1852.0:.1f} kn")


def test_orders_read_from_the_inputs_name_thrusters_not_variables(crowded):
    """A step without orders or commands of its own (an older plan.json) is told its inputs as
    timed settings; a varying one ends with the inputs' ranges, by thruster names ("bow thruster
    angle -5°..5°"), never the model's variables (alpha1, n1)."""
    from maps.export._common import input_phases
    from maps.plan import PlanStep

    st = next(st for st in crowded.steps if st.primitive == "tau16" and st.segment == "informative")
    bare = PlanStep(**{**st.__dict__, "orders": [], "commands": []})
    lines = input_phases(crowded, bare, max_phases=1)
    assert lines[-1].startswith("then ") and "bow thruster angle" in lines[-1] and "rpm" in lines[-1]
    assert not re.search(r"\b(alpha|n)\d\b", " ".join(lines))


def test_segment_distances_are_the_bits_of_the_broadcast_form():
    """The label placement's distances, x and y apart, against the (n, m, 2) form they replace
    (same bits: the card's label positions and so its PDF bytes do not move)."""
    from maps.export.labels import segment_distances

    def broadcast(p, a, b):
        d = b - a
        dd = np.maximum((d * d).sum(axis=1), 1e-12)
        t = np.clip(((p[:, None, :] - a[None]) * d[None]).sum(axis=2) / dd[None], 0.0, 1.0)
        q = a[None] + t[..., None] * d[None]
        return np.sqrt(((p[:, None, :] - q) ** 2).sum(axis=2)).min(axis=1)

    rng = np.random.default_rng(4)
    for n, m in [(73, 500), (10, 3), (1, 1)]:
        p, a = rng.normal(size=(n, 2)) * 100, rng.normal(size=(m, 2)) * 100
        b = a + rng.normal(size=(m, 2)) * 10
        b[0] = a[0]  # a point (a zero-length segment), as the anchors are
        assert np.array_equal(segment_distances(p, a, b), broadcast(p, a, b))
    assert np.all(segment_distances(np.zeros((3, 2)), np.zeros((0, 2)), np.zeros((0, 2))) == np.inf)
