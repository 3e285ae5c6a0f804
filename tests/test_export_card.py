"""Trial card, plots, orders in sailor's words, export_all and the ``shiptrial export`` command."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest
from shapely.geometry import Polygon

from cli.app import _run
from maps.export import FORMATS, export_all
from maps.export._common import clock, describe_inputs, input_phases
from maps.export._testing import synthetic_plan
from maps.export.card import beaufort, card_html, step_sheets
from maps.export.mapplot import obstacle_geoms
from maps.export.plots import plot_states
from maps.plan import Plan

START = "2026-06-01T08:00:00Z"
ISLAND = Polygon([(24.953, 60.1215), (24.956, 60.1215), (24.956, 60.1225), (24.953, 60.1225)])


@pytest.fixture(scope="module")
def azi_plan() -> Plan:
    return synthetic_plan("full-scale")


@pytest.fixture(scope="module")
def model_plan() -> Plan:
    return synthetic_plan("model-ship", ("straight", "zigzag_20_20_p", "turn_s"))


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_orders_for_azimuth_ship_name_thrusters_rpm_and_directions(azi_plan):
    row = np.array([25.0, np.radians(90.0), 12.4, np.radians(-30.0)])  # the plan's shaft speeds are rev/s
    assert (
        describe_inputs(azi_plan, row)
        == "bow thruster 1500 rpm, thrust 90° to starboard; stern thruster 744 rpm, thrust 30° to port"
    )
    # tau14 (pure sway): both thrusters push to starboard, then both to port
    sway = next(st for st in azi_plan.steps if st.primitive == "tau14")
    phases = input_phases(azi_plan, sway)
    assert len(phases) == 2
    assert phases[0].startswith("at +0:00:") and phases[0].count("90° to starboard") == 2
    assert phases[1].startswith("at +1:40:") and phases[1].count("90° to port") == 2


def test_orders_for_generalized_force_ship(model_plan):
    zz = model_plan.steps[1]
    phases = input_phases(model_plan, zz)
    assert "turning moment 444 to port" in phases[0] and "turning moment 444 to starboard" in phases[1]


def test_step_sheets_carry_what_the_bridge_needs(azi_plan):
    sheets = step_sheets(azi_plan, START)
    assert len(sheets) == len(azi_plan.steps)
    s = sheets[1]
    assert s["position"] == "60°07.270'N 024°57.081'E"
    assert s["heading"] == "030°" and s["speed"].startswith("5.8 kn")
    assert s["orders"] == [f"at +{clock(o['t_s'])}: {o['text']}" for o in azi_plan.steps[1].orders] and s["duration"] == "3:01"
    assert s["start"] == "+0:50 (08:00:50 UTC)"
    assert any("to port" in a and "to starboard" in a for a in s["abort"])


def test_card_html_is_self_contained_and_complete(azi_plan, tmp_path):
    text = card_html(azi_plan, sea_map=[ISLAND], start=START)
    assert "http://" not in text and "https://" not in text
    imgs = re.findall(r'src="data:image/png;base64,([^"]+)"', text)
    assert len(imgs) == 2
    for b64 in imgs:
        w, h = _png_size(base64.b64decode(b64))
        assert w > 500 and h > 500
    for st in azi_plan.steps:
        assert st.primitive in text
    words = re.sub(r'src="data:image/png;base64,[^"]+"', "", text)
    assert "Beaufort 5" in words and "19 kn" in words and "m/s" not in words  # knots on the bridge (10 m/s wind)
    import html as _html

    for st in azi_plan.steps:  # every step's orders, in the ship's own terms
        assert st.orders and all(_html.escape(o["text"]) in text for o in st.orders)


def _page_sizes(path) -> list[tuple[float, float]]:
    """Width and height (points) of each page of a PDF, in page order (poppler's pdfinfo)."""
    import shutil
    import subprocess

    if not shutil.which("pdfinfo"):
        pytest.skip("poppler-utils not installed")
    out = subprocess.run(["pdfinfo", "-f", "1", "-l", "9999", str(path)], capture_output=True, text=True, check=True).stdout
    return [(float(w), float(h)) for w, h in re.findall(r"^Page +\d+ size: +([\d.]+) x ([\d.]+) pts", out, re.M)]


def test_card_pdf_has_every_page(azi_plan, tmp_path):
    """Page 1, the step table, the design table, the orders per step (as many pages as their
    lines need) and the states page: A4 portrait but the last, the states figure's size."""
    from maps.export.card import detail_pages
    from maps.export.plots import states_size_in

    paths = export_all(
        azi_plan,
        tmp_path,
        sea_map={
            "type": "FeatureCollection",
            "features": [{"type": "Feature", "properties": {"kind": "land"}, "geometry": ISLAND.__geo_interface__}],
        },
        start=START,
    )
    pdf = paths["card_pdf"].read_bytes()
    assert pdf.startswith(b"%PDF")
    sheets = step_sheets(azi_plan, START, [ISLAND])
    # page 1, one page of tables (the step table and the design table below it), the orders, the states
    want = 1 + 1 + len(detail_pages(sheets)) + 1
    sizes = _page_sizes(paths["card_pdf"])
    assert len(re.findall(rb"/Type\s*/Page\b", pdf)) == len(sizes) == want >= 4
    assert all(s == pytest.approx((72 * 8.27, 72 * 11.69), abs=0.01) for s in sizes[:-1])  # A4 portrait
    w_in, h_in = states_size_in(azi_plan)
    assert sizes[-1] == pytest.approx((72 * w_in, 72 * h_in), abs=0.01)


def test_card_pdf_is_reproducible(model_plan, tmp_path):
    """The same plan gives the same PDF bytes (no creation date in the file)."""
    from maps.export.card import write_card_pdf

    a = write_card_pdf(model_plan, tmp_path / "a.pdf", start=START).read_bytes()
    b = write_card_pdf(model_plan, tmp_path / "b.pdf", start=START).read_bytes()
    assert a == b and b"/CreationDate" not in a


def test_export_all_writes_every_format(model_plan, tmp_path):
    paths = export_all(model_plan, tmp_path / "out", start=START)
    assert set(FORMATS) | {"card_pdf", "track_png", "states_png"} == set(paths)
    for p in paths.values():
        assert p.exists() and p.stat().st_size > 500
    assert paths["rtz"].stem == "model-ship-trial"


def test_plot_states_png(azi_plan, tmp_path):
    w, h = _png_size(plot_states(azi_plan, tmp_path / "s.png").read_bytes())
    assert w > 600 and h > 600


def test_obstacle_inputs_accepted(tmp_path):
    fc = {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": ISLAND.__geo_interface__}]}
    f = tmp_path / "m.geojson"
    f.write_text(json.dumps(fc))
    for src in (ISLAND, [ISLAND], fc, f, str(f)):
        (g,) = obstacle_geoms(src)
        assert g.equals(ISLAND)
    assert obstacle_geoms(None) == []


def test_beaufort():
    assert [beaufort(v) for v in (0.1, 5.0, 10.0, 10.9, 33.0)] == [0, 3, 5, 6, 12]


# -- CLI -------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def plan_file(azi_plan, tmp_path_factory):
    p = tmp_path_factory.mktemp("cli") / "plan.json"
    p.write_text(azi_plan.to_json())
    return p


@pytest.mark.parametrize("fmt", ["gpx", "rtz", "geojson", "csv"])
def test_cli_export_one_format(plan_file, tmp_path, fmt, capsys):
    out = tmp_path / f"trial.{fmt}"
    assert _run(["export", str(plan_file), "--format", fmt, "--out", str(out), "--start", START]) == 0
    assert out.exists() and out.stat().st_size > 500
    assert f"wrote {out}" in capsys.readouterr().out


def test_cli_export_card_html_only(plan_file, tmp_path):
    out = tmp_path / "card.html"
    assert _run(["export", str(plan_file), "-f", "card", "-o", str(out), "--no-pdf"]) == 0
    assert out.exists() and not out.with_suffix(".pdf").exists()


@pytest.mark.parametrize(
    "content, needle",
    [
        (None, "no such plan file"),
        ("{not json", "not valid JSON"),
        ('{"format": "shiptrial-plan/1"}', "missing"),
        ('{"format": "something-else"}', "not a plan"),
        ("[1, 2]", "malformed plan"),
    ],
)
def test_cli_export_bad_plan_is_one_line_error_exit_2(tmp_path, capsys, content, needle):
    p = tmp_path / "plan.json"
    if content is not None:
        p.write_text(content)
    assert _run(["export", str(p), "--format", "gpx"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and needle in err and "\n" not in err and "Traceback" not in err


def test_cli_export_plan_without_steps_exit_2(azi_plan, tmp_path, capsys):
    p = tmp_path / "plan.json"
    p.write_text(json.dumps(json.loads(azi_plan.to_json()) | {"steps": []}))
    assert _run(["export", str(p), "--format", "rtz"]) == 2
    assert "steps" in capsys.readouterr().err


def test_cli_export_unknown_format_exit_2(plan_file, capsys):
    assert _run(["export", str(plan_file), "--format", "kml"]) == 2
    assert "kml" in capsys.readouterr().err


def test_sea_map_object_obstacles_come_back_in_lonlat(azi_plan, tmp_path):
    geo = pytest.importorskip("maps.geo")
    sea = geo.load_map()
    (g,) = obstacle_geoms(sea)
    lon0, lat0, lon1, lat1 = g.bounds
    assert 24.7 < lon0 < lon1 < 25.3 and 60.0 < lat0 < lat1 < 60.3
    # the card's page-1 map draws the bundled map's land around the synthetic track (placed in Helsinki)
    import shutil
    import subprocess

    from maps.export.card import write_card_pdf

    if not shutil.which("pdftoppm"):
        pytest.skip("poppler-utils not installed: page 1 not rendered")
    path = write_card_pdf(azi_plan, tmp_path / "card.pdf", sea, START)
    subprocess.run(["pdftoppm", "-png", "-r", "40", "-f", "1", "-l", "1", str(path), str(tmp_path / "p")], check=True)
    from PIL import Image

    (png,) = tmp_path.glob("p-*.png")
    page1 = np.asarray(Image.open(png).convert("RGB")).reshape(-1, 3).astype(int)
    assert (np.abs(page1 - [0xC8, 0xB8, 0x8A]).max(axis=1) <= 12).sum() > 200  # land (mapplot.LAND_COLOUR)


def test_geojson_sea_map_draws_only_what_the_hull_must_avoid():
    box = {"type": "Polygon", "coordinates": [[[24.9, 60.1], [25.0, 60.1], [25.0, 60.2], [24.9, 60.1]]]}
    fc = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "properties": {"kind": "trial_area"}, "geometry": box},
            {"type": "Feature", "properties": {"kind": "land"}, "geometry": ISLAND.__geo_interface__},
        ],
    }
    (g,) = obstacle_geoms(fc)
    assert g.equals(ISLAND)


def test_cli_card_uses_the_bundled_map_the_plan_names():
    from cli.export_cmd import resolve_sea_map

    pytest.importorskip("maps.geo")
    assert resolve_sea_map(None, "helsinki") is not None
    assert resolve_sea_map(None, "synthetic") is None


def test_design_table_lists_only_what_the_design_uses():
    """Primitives with no weight in the optimal design are named once as not used, never as rows with count 0."""
    from dataclasses import replace

    from maps.export.card import design_rows
    from maps.trialdesign import design_counts
    from primitives.ship import load_profile

    rec = design_counts(load_profile("full-scale")).record
    assert rec["not_used"] and not set(rec["not_used"]) & set(rec["weights"])
    plan = replace(synthetic_plan("full-scale"), design=rec)
    head, rows = design_rows(plan)
    codes = {re.fullmatch(r"(?:.* \[(\w+)\])|(\w+)", r[0]).group(1, 2) for r in rows}  # "name [code]" or "code"
    codes = {a or b for a, b in codes}
    assert codes == set(rec["counts"]) and all(int(r[2]) > 0 for r in rows)
    assert any(line.startswith("Not used") and all(n in line for n in rec["not_used"]) for line in head)
    # a plan.json written before the split (zero weights among the weights) reads the same way
    old = dict(rec, weights={**rec["weights"], **dict.fromkeys(rec["not_used"], 0.0)}, not_used=[])
    assert design_rows(replace(plan, design=old))[1] == rows


def test_abort_clearance_on_an_open_water_map_says_what_the_chart_shows():
    """On the open-sea map (no obstacle) the card's abort box read 'below 20 m (planned minimum
    none within the map)': a master reads a missing figure (stop 62's walk, the README's coaster)."""
    from types import SimpleNamespace

    from maps.export.card import abort_criteria

    open_water = abort_criteria(SimpleNamespace(max_wind_mps=10.0, min_clearance_m=float("inf"), margin_m=20.0))
    assert "below 20 m (the chart shows none near the track)" in open_water[1]
    assert "minimum none" not in open_water[1]
    charted = abort_criteria(SimpleNamespace(max_wind_mps=10.0, min_clearance_m=50.6, margin_m=20.0))
    assert "below 20 m (planned minimum 51 m)" in charted[1]


def test_step_table_says_heading_and_speed_are_at_the_start_waypoint(azi_plan):
    """The steps table's 'speed' column is the speed at the step's start waypoint: a run-in
    'steady approach at 2.2 kn' showed 'speed 5.8 kn', a spot turn 5.8 kn (stop 62's walk)."""
    html = card_html(azi_plan, start=START)
    after = html.split("<h2>Steps in sailing order</h2>", 1)[1]
    assert after.lstrip().startswith("<p>hdg and speed: the ship&#x27;s at the step&#x27;s start waypoint (WP).</p>")


def test_design_table_names_manoeuvres_as_the_steps_table_does(azi_plan):
    """The card's "Experiment design" rows listed codes only (tau12 ...): each row now names the manoeuvre as
    the steps table does (the name a master knows, the code in brackets), from the same source; a code the plan
    does not sail keeps its code alone (stop 62's walk-through)."""
    from dataclasses import replace

    from maps.export.card import _table_rows, design_rows
    from maps.trialdesign import design_counts
    from primitives.ship import load_profile

    plan = replace(azi_plan, design=design_counts(load_profile("full-scale")).record)
    _, rows = design_rows(plan)
    steps = {r[2] for r in _table_rows(step_sheets(plan, START))}
    sailed = {st.primitive for st in plan.steps if st.segment == "informative"}
    named = [r[0] for r in rows if r[0].endswith("]")]
    assert named and all(n in steps for n in named), (named, steps)
    assert {re.search(r"\[(\w+)\]$", n)[1] for n in named} == sailed & set(plan.design["counts"])
    assert all(r[0] in plan.design["counts"] for r in rows if not r[0].endswith("]"))  # not sailed: the code


def test_card_summary_line_has_separators_and_a_readable_duration(azi_plan):
    """The HTML summary read "Ship full-scale Area helsinki Start ..." (spaces collapse in HTML) and
    "duration 59:53 (h:)min:s": facts apart with "; ", the duration in h, min and s."""
    from dataclasses import replace

    page = card_html(replace(azi_plan, map_name="helsinki"), start=START)
    line = re.search(r"<p>(Ship [^<]*)</p>", page)[1]
    assert line == "Ship full-scale; area helsinki; start 2026-06-01 08:00 UTC", line
    assert "(h:)min:s" not in page
    m, sec = divmod(int(round(azi_plan.duration_s)), 60)
    h, m = divmod(m, 60)
    want = f"{h} h {m} min {sec} s" if h else f"{m} min {sec} s"
    assert f"duration {want}, " in page
