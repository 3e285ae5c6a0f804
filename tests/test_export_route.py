"""The route a crew sails: RTZ leg speeds and ETAs, turn radii, land-free corridors, the chart
saved with the plan, the card's pages and fonts, the vessel name."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest
import shapely
from lxml import etree
from pyproj import Transformer

from cli.app import _run
from maps.export import export_plan
from maps.export._common import M_PER_NM
from maps.export._testing import synthetic_plan
from maps.export.chart import chart_of, embed_chart
from maps.export.route import build_route, turning_radius
from maps.export.rtz import RTZ_NS, plan_rtz, rtz_warnings, validate_rtz
from maps.plan import Plan

START = "2026-06-01T08:00:00Z"
NS = {"r": RTZ_NS}


@pytest.fixture(scope="module")
def azi_plan() -> Plan:
    return synthetic_plan("full-scale", margin_m=30.0)


@pytest.fixture(scope="module")
def tanker_plan() -> Plan:
    return synthetic_plan("kvlcc2", ("straight", "zigzag_10_10_s", "turn_s", "turning_circle_35_p", "straight"), run_in=True)


def _local(plan: Plan):
    """lon, lat -> (north, east) in the plan's metric frame."""
    tr = Transformer.from_crs("EPSG:4326", plan.projection["proj4"], always_xy=True)

    def f(lon, lat):
        e, n = tr.transform(lon, lat)
        return np.array([n, e])

    return f


def rtz_corridors(doc: bytes, plan: Plan) -> list[tuple[shapely.Polygon, int]]:
    """Each leg's corridor as written in the RTZ (positions and XTDs), in the plan's metric
    frame: an independent reading of the file, not the exporter's own polygons."""
    tree = etree.fromstring(doc)
    loc = _local(plan)
    wps = tree.findall("r:waypoints/r:waypoint", NS)
    out = []
    for i in range(1, len(wps)):
        pa, pb = (w.find("r:position", NS) for w in (wps[i - 1], wps[i]))
        a = loc(float(pa.get("lon")), float(pa.get("lat")))
        b = loc(float(pb.get("lon")), float(pb.get("lat")))
        leg = wps[i].find("r:leg", NS)
        s, p = float(leg.get("starboardXTD")) * M_PER_NM, float(leg.get("portsideXTD")) * M_PER_NM
        d = b - a
        n = np.array([-d[1], d[0]]) / np.hypot(*d)  # starboard of a -> b (x north, y east)
        out.append((shapely.Polygon([a - p * n, b - p * n, b + s * n, a + s * n]), i))
    return out


# -- speeds and ETAs ---------------------------------------------------------------------------


def test_rtz_legs_have_their_own_speeds_and_consistent_etas(azi_plan, tanker_plan, tmp_path):
    for plan in (azi_plan, tanker_plan):
        path = export_plan(plan, "rtz", tmp_path / f"{plan.ship}-trial.rtz", start=START)[0]
        assert validate_rtz(path) == []
        assert rtz_warnings(path) == []
    doc = plan_rtz(azi_plan, route_name="t", start=START)
    tree = etree.fromstring(doc)
    elems = tree.findall("r:schedules/r:schedule/r:calculated/r:scheduleElement", NS)
    wps = tree.findall("r:waypoints/r:waypoint", NS)
    # the leg into waypoint 3 is the 181 s zig-zag; its speed is its own (made good), not the next leg's
    for i in (1, 2, 3):
        leg = wps[i].find("r:leg", NS)
        assert float(leg.get("speedMin")) <= float(elems[i].get("speed")) <= float(leg.get("speedMax"))
    # the bug this replaces: each element carrying the speed of the leg out of its waypoint
    speeds = [e.get("speed") for e in elems]
    for e, sp in zip(elems, speeds[1:] + [None]):
        e.attrib.pop("speed", None)
        if sp:
            e.set("speed", sp)
    shifted = etree.tostring(tree)
    warns = rtz_warnings(shifted)
    assert any("first element" in w for w in warns) and any("takes" in w for w in warns)


def test_rtz_checker_flags_an_eta_that_does_not_match_the_leg(azi_plan):
    doc = plan_rtz(azi_plan, route_name="t", start=START)
    late = doc.replace(b'eta="2026-06-01T08:03:51Z"', b'eta="2026-06-01T08:05:51Z"', 1)
    assert late != doc and any("waypoint 3" in w and "takes" in w for w in rtz_warnings(late))


# -- turn radii --------------------------------------------------------------------------------


def test_turn_radius_is_the_ships_own_and_fits_the_legs(tanker_plan):
    r, source = turning_radius(tanker_plan)
    assert source.startswith("tightest turn")
    # independent: the tightest circle through three positions 5 s apart along the 35 deg
    # turning circle, from the track's geometry alone, while the ship is still at speed (80 %
    # of the plan's median speed: the tanker loses 60 % of its speed in the full turn)
    st = next(s for s in tanker_plan.steps if s.primitive == "turning_circle_35_p")
    idx = np.flatnonzero(tanker_plan.step_of_sample == st.index)
    sog = np.hypot(*np.diff(tanker_plan.track[:, :2], axis=0).T) / np.diff(tanker_plan.t)
    at_speed = sog >= 0.8 * np.median(sog)
    radii = []
    for k in range(0, len(idx) - 10):
        if not at_speed[idx[k] : idx[k + 10]].all():
            continue
        a, b, c = (tanker_plan.track[idx[j], :2] for j in (k, k + 5, k + 10))
        ab, bc, ca = np.hypot(*(b - a)), np.hypot(*(c - b)), np.hypot(*(a - c))
        area = 0.5 * abs((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0])
        radii.append(ab * bc * ca / (4 * area) if area > 0 else np.inf)
    assert r == pytest.approx(min(radii), rel=0.05)
    assert 0.5 * tanker_plan.hull[0] < r < 2.5 * tanker_plan.hull[0]  # within the IMO limit, tactical diameter <= 5 L
    tree = etree.fromstring(plan_rtz(tanker_plan, route_name="t", start=START))
    default = float(tree.find("r:waypoints/r:defaultWaypoint", NS).get("radius"))
    assert default == pytest.approx(r / M_PER_NM, abs=1e-3)
    route = build_route(tanker_plan)
    for i in range(1, len(route.points) - 1):
        assert route.points[i].radius_m <= r + 1e-9
        # the wheel-over arc fits in half of the shorter adjacent leg (tangent length R tan(dchi / 2))
        a, b, c = (tanker_plan.track[route.points[j].sample, :2] for j in (i - 1, i, i + 1))
        d1, d2 = b - a, c - b
        dchi = abs(np.arctan2(d1[0] * d2[1] - d1[1] * d2[0], d1 @ d2))
        shorter = min(route.legs[i].length_m, route.legs[i + 1].length_m)
        assert route.points[i].radius_m * np.tan(min(dchi, np.radians(179)) / 2) <= 0.5 * shorter + 1.0


def test_turn_radius_without_turns_falls_back_to_the_imo_limit():
    plan = synthetic_plan("kvlcc2", ("straight", "straight"))
    r, source = turning_radius(plan)
    assert source == "IMO limit 2.5 L" and r == pytest.approx(2.5 * 320.0)


# -- land-free corridors -----------------------------------------------------------------------


def _land_beside_zigzag(plan: Plan) -> tuple[shapely.Polygon, dict]:
    """A strip of land to port of the zig-zag leg, beyond the hull's largest excursion but
    inside the corridor a plain "excursion + half beam + margin" rule would draw."""
    route = build_route(plan)
    i = next(k for k, p in enumerate(route.points) if p.step is not None and p.step.primitive == "zigzag_10_10_s") + 1
    leg = route.legs[i]
    a, b = (plan.track[route.points[j].sample, :2] for j in (i - 1, i))
    d = b - a
    n = -np.array([-d[1], d[0]]) / np.hypot(*d)  # port: the plan turns to starboard after the zig-zag
    half_beam = 0.5 * plan.hull[1]
    exc = leg.need_port_m - half_beam - plan.margin_m
    near = exc + half_beam + 0.5 * plan.margin_m  # clear of the hull by half the margin
    land = shapely.Polygon(
        [a + near * n + 0.1 * d, a + near * n + 0.9 * d, a + (near + 400) * n + 0.9 * d, a + (near + 400) * n + 0.1 * d]
    )
    hull = shapely.LineString(plan.track[:, :2]).buffer(half_beam + 0.25 * plan.margin_m)
    assert not hull.intersects(land)  # the planned track itself keeps clear of this land
    tr = Transformer.from_crs(plan.projection["proj4"], "EPSG:4326", always_xy=True)
    ll = shapely.transform(land, lambda c: np.column_stack(tr.transform(c[:, 1], c[:, 0])))
    fc = {
        "type": "FeatureCollection",
        "features": [{"type": "Feature", "properties": {"kind": "land"}, "geometry": shapely.geometry.mapping(ll)}],
    }
    return land, json.loads(json.dumps(fc))


def test_rtz_corridors_do_not_cover_land_and_hold_the_hull(azi_plan):
    land, fc = _land_beside_zigzag(azi_plan)
    # without the chart the corridor of the zig-zag leg covers the land: the check can fail
    naive = rtz_corridors(plan_rtz(azi_plan, route_name="t", start=START), azi_plan)
    assert any(poly.intersects(land) for poly, _ in naive)
    doc = plan_rtz(azi_plan, route_name="t", start=START, sea_map=fc)
    assert validate_rtz(doc, file_name="t.rtz") == [] and rtz_warnings(doc) == []
    corridors = rtz_corridors(doc, azi_plan)
    assert not any(poly.intersects(land) for poly, _ in corridors)
    # the hull (track +- half beam) stays within its leg's cross-track limits (what the ECDIS
    # alarm watches), to the file's 0.001 NM resolution
    route = build_route(azi_plan, chart_of(fc))
    tree = etree.fromstring(doc)
    wps = tree.findall("r:waypoints/r:waypoint", NS)
    hb, tol = 0.5 * azi_plan.hull[1], M_PER_NM * 1e-3
    for i in range(1, len(wps)):
        leg = wps[i].find("r:leg", NS)
        s, p = float(leg.get("starboardXTD")) * M_PER_NM, float(leg.get("portsideXTD")) * M_PER_NM
        ka, kb = route.points[i - 1].sample, route.points[i].sample
        a, b = azi_plan.track[ka, :2], azi_plan.track[kb, :2]
        d = b - a
        if np.hypot(*d) < 1e-6:
            continue
        n = np.array([-d[1], d[0]]) / np.hypot(*d)
        off = (azi_plan.track[ka : kb + 1, :2] - a) @ n
        assert off.max() + hb <= s + tol and -off.min() + hb <= p + tol, f"leg {i}"
    # the card names the same waypoints as the RTZ (via points included) and their limits
    from maps.export.card import step_sheets

    names = {w.get("name").split()[0]: w for w in wps}
    for sh in step_sheets(azi_plan, START, fc):
        assert sh["waypoint"] in names and names[sh["waypoint"]].get("name").endswith(sh["primitive"])
    # the GPX route has the very same points as the RTZ (one source of waypoints): names, positions, times
    import gpxpy

    from maps.export.gpx import plan_gpx

    (rte,) = gpxpy.parse(plan_gpx(azi_plan, start=START, sea_map=fc).decode()).routes
    assert [p.name for p in rte.points] == [w.get("name") for w in wps]
    for p, w in zip(rte.points, wps):
        pos = w.find("r:position", NS)
        assert p.latitude == pytest.approx(float(pos.get("lat")), abs=1e-6)
        assert p.longitude == pytest.approx(float(pos.get("lon")), abs=1e-6)


@pytest.mark.slow
def test_planned_route_on_the_bundled_map_has_land_free_corridors(tmp_path):
    from maps.geo import load_map

    out = tmp_path / "out"
    assert _run(["plan", "--out", str(out), "--start-time", START]) == 0
    plan = Plan.load(out / "plan.json")
    rtz = next(out.glob("*.rtz"))
    assert validate_rtz(rtz) == [] and rtz_warnings(rtz) == []
    sea = load_map()
    for poly, i in rtz_corridors(rtz.read_bytes(), plan):
        assert not poly.intersects(sea.obstacles), f"corridor of leg {i} covers land"


# -- the chart travels with the plan -----------------------------------------------------------


def test_plan_json_carries_the_chart_and_exports_the_same_without_the_map(azi_plan, tmp_path):
    from maps.geo import load_map
    from maps.output import write_outputs

    _, fc = _land_beside_zigzag(azi_plan)
    fc["features"].append(
        {
            "type": "Feature",
            "properties": {"kind": "depth_area", "min_depth_m": 2.0},
            "geometry": {
                "type": "Polygon",
                "coordinates": [[[24.93, 60.11], [24.935, 60.11], [24.935, 60.115], [24.93, 60.115], [24.93, 60.11]]],
            },
        }
    )
    (tmp_path / "m.geojson").write_text(json.dumps(fc))
    sea = load_map(tmp_path / "m.geojson", draught_m=5.0)
    plan = Plan.from_dict(json.loads(azi_plan.to_json()))
    files = write_outputs(plan, sea, tmp_path / "o")
    saved = Plan.load(files["plan_json"])
    assert saved.stats["chart"]["land"] and saved.stats["chart"]["no_go"]  # the shallow patch is no-go for 5 m draught
    with_map = plan_rtz(saved, route_name="t", start=START, sea_map=sea)
    assert plan_rtz(saved, route_name="t", start=START) == with_map
    # trajectory.geojson is the tagged track only; the crew's overlay adds points and corridors
    traj = json.loads(files["trajectory_geojson"].read_text())
    assert {f["properties"]["kind"] for f in traj["features"]} == {"track"}
    assert all(f["properties"]["segment"] in ("run-in", "informative", "transit") for f in traj["features"])


def test_card_map_draws_land_shallow_and_depth_areas(azi_plan, tmp_path):
    """Both ways the map is drawn: by matplotlib with its hatch pattern (PNG figures) and straight
    into the PDF card, with the hatching as line geometry and the same legend."""
    import matplotlib.pyplot as plt

    from maps.export.cardpdf import _Card
    from maps.export.chart import plan_chart
    from maps.export.mapplot import NO_GO_EDGE, NO_GO_LABEL, draw_map
    from maps.export.pdfdraw import col
    from maps.export.pdfmap import MapWriter, map_frame

    _, fc = _land_beside_zigzag(azi_plan)
    fc["features"] += [
        {
            "type": "Feature",
            "properties": {"kind": "depth_area", "min_depth_m": 30.0},
            "geometry": {
                "type": "Polygon",
                "coordinates": [[[24.9, 60.1], [25.0, 60.1], [25.0, 60.15], [24.9, 60.15], [24.9, 60.1]]],
            },
        },
        {
            "type": "Feature",
            "properties": {"kind": "restricted"},
            "geometry": {  # 55-80 m west of the start
                "type": "Polygon",
                "coordinates": [
                    [[24.9486, 60.1198], [24.9490, 60.1198], [24.9490, 60.1202], [24.9486, 60.1202], [24.9486, 60.1198]]
                ],
            },
        },
    ]
    plan = Plan.from_dict(json.loads(azi_plan.to_json()))
    embed_chart(plan, fc)
    fig, ax = plt.subplots()
    try:
        draw_map(ax, plan)  # from the plan's own chart
        labels = ax.get_legend_handles_labels()[1]
        hatched = [a for a in ax.patches if a.get_hatch()]
    finally:
        plt.close(fig)
    assert "land" in labels and NO_GO_LABEL in labels and hatched
    assert any(lab.startswith("depth areas 30-30 m") for lab in labels)
    assert "transit" in labels
    doc = _Card()
    doc.page()
    w = MapWriter(doc.pdf, "DejaVu Sans", plan, plan_chart(plan), map_frame(plan, (60.0, 170.0, 500.0, 500.0)))
    w.draw()
    drawn = doc.pdf.pages[doc.pdf.page].contents.decode("latin-1")
    assert [e["label"] for e in w.legend] == labels
    assert next(e for e in w.legend if e["label"] == NO_GO_LABEL)["kind"] == "hatch"
    assert f"{col(NO_GO_EDGE, 'RG')} 0.6 w 2 J" in drawn  # the hatch lines, in the no-go edge colour


# -- the card: every row, embedded TrueType fonts ----------------------------------------------


def test_card_pdf_prints_every_row_and_embeds_truetype_fonts(tmp_path):
    plan = synthetic_plan("full-scale", ("straight",) * 50)
    pdf = export_plan(plan, "card", tmp_path / "card.pdf", start=START)[0].read_bytes()
    assert b"/FontFile2" in pdf and b"/Type3" not in pdf  # TrueType (pdf.fonttype 42), no Type 3 bitmaps
    if shutil.which("pdffonts"):
        lines = subprocess.run(["pdffonts", str(tmp_path / "card.pdf")], capture_output=True, text=True, check=True).stdout
        fonts = lines.splitlines()[2:]
        assert fonts and all("TrueType" in f and " yes " in f for f in fonts)
    if not shutil.which("pdftotext"):
        pytest.skip("pdftotext (poppler-utils) not installed: rows not checked")
    text = subprocess.run(
        ["pdftotext", "-layout", str(tmp_path / "card.pdf"), "-"], capture_output=True, text=True, check=True
    ).stdout
    assert "rows 1-44 of 50" in text and "rows 45-50 of 50 (page 3)" in text.replace("(continued), ", "")
    rows = [int(m) for m in re.findall(r"^\s*(\d+)\s+transit\s", text, flags=re.M)]
    assert sorted(set(rows)) == list(range(1, 51))
    # the figures' words are text in the embedded fonts too (map ticks, states axes), not outlines
    assert "time from start [min]" in text and "speed over ground [kn]" in text and re.search(r"60°0\d\.\d{3}′N", text)


# -- vessel name -------------------------------------------------------------------------------


def test_vessel_name_from_option_plan_or_profile(azi_plan, tmp_path, capsys):
    doc = etree.fromstring(plan_rtz(azi_plan, route_name="t", start=START))
    assert doc.find("r:routeInfo", NS).get("vesselName") == (azi_plan.vessel_name or azi_plan.ship)
    p = tmp_path / "plan.json"
    p.write_text(azi_plan.to_json())
    out = tmp_path / "t.rtz"
    assert _run(["export", str(p), "-f", "rtz", "-o", str(out), "--vessel-name", "MS Trial Ship"]) == 0
    assert etree.parse(str(out)).find("r:routeInfo", NS).get("vesselName") == "MS Trial Ship"
    capsys.readouterr()
    assert _run(["export", str(p), "-f", "rtz", "-o", str(tmp_path / "u.rtz"), "--vessel-name", "x" * 40]) == 2
    err = capsys.readouterr().err
    assert "--vessel-name" in err and "32" in err and not (tmp_path / "u.rtz").exists()
    assert _run(["export", str(p), "-f", "rtz", "-o", str(tmp_path / "v.rtz"), "--vessel-name", "  "]) == 2
    assert "--vessel-name is empty" in capsys.readouterr().err and not (tmp_path / "v.rtz").exists()
