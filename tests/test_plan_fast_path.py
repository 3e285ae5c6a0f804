"""The fast path of ``plan-trial`` (dedicated design solver, figures drawn once) changes no output.

The default plan (full-scale ship, bundled map) is made once with the design's convex step on
the dedicated Frank-Wolfe solver (what plan-trial uses) and once on cvxpy/Clarabel (the
reference path): the plan and every crew file must be the same, byte for byte, except the
timings in plan.json and the continuous design weights (the non-convex step ends within 1e-6
of the same point from a start 1e-6 away). The shared figures give the same PNG bytes as
figures drawn on their own.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import maps.trialdesign as trialdesign
from maps.export import export_all, export_plan
from maps.export.plots import plot_states, plot_track
from maps.geo import load_map
from maps.output import write_outputs
from maps.planner import plan_with_design
from primitives.ship import load_profile

START = "2026-06-01T08:00Z"
CREW = ("geojson", "gpx", "rtz", "csv")
TIMINGS = {"plan_time_s", "expansions_per_s", "setup_time_s", "design_time_s", "total_time_s", "search_s"}


@pytest.fixture(scope="module")
def sea():
    return load_map(None, draught_m=load_profile("full-scale").draught_m)


@pytest.fixture(scope="module")
def fast(sea):
    return _plan(sea, trialdesign.SOLVERS)


def _plan(sea, solvers):
    old = trialdesign.SOLVERS
    trialdesign.SOLVERS = solvers
    try:
        plan, td = plan_with_design(sea, profile="full-scale")
    finally:
        trialdesign.SOLVERS = old
    plan.stats["start_utc"] = START
    return plan, td


def _without(d, keys):
    if isinstance(d, dict):
        return {k: _without(v, keys) for k, v in d.items() if k not in keys}
    if isinstance(d, list):
        return [_without(v, keys) for v in d]
    return d


def _files(plan, sea, out):
    files = write_outputs(plan, sea, out)
    for fmt in CREW:
        files[fmt] = export_plan(plan, fmt, out / f"t.{fmt}", sea_map=sea, start=START)[0]
    return files


def test_dedicated_solver_gives_the_reference_plan_and_files(sea, fast, tmp_path):
    fast, td_fast = fast
    ref, td_ref = _plan(sea, ("CLARABEL", "SCS"))
    assert td_fast.design.solver_notes[0] == "convex: frank-wolfe" and td_ref.design.solver_notes[0] == "convex: CLARABEL"
    assert fast.counts == ref.counts and fast.design["counts"] == ref.design["counts"]
    for name, w in ref.design["weights"].items():
        assert fast.design["weights"][name] == pytest.approx(w, abs=1e-6)
    assert fast.design["d_efficiency"] == pytest.approx(ref.design["d_efficiency"], abs=1e-9)
    np.testing.assert_array_equal(fast.track, ref.track)
    a, b = _files(fast, sea, tmp_path / "fast"), _files(ref, sea, tmp_path / "ref")
    for key in CREW + ("trajectory_geojson", "plot"):
        assert a[key].read_bytes() == b[key].read_bytes(), key
    ja, jb = (json.loads(f["plan_json"].read_text()) for f in (a, b))
    design = {"weights", "d_efficiency", "efficiency", "digest"}  # compared to tolerance above (and so its digest)
    assert _without(ja, TIMINGS | design) == _without(jb, TIMINGS | design)


def test_shared_figures_give_the_same_pngs(sea, fast, tmp_path):
    plan = fast[0]
    files = export_all(plan, tmp_path / "all", sea_map=sea, start=START)
    assert files["states_png"].read_bytes() == plot_states(plan, tmp_path / "s.png").read_bytes()
    assert files["track_png"].read_bytes() == plot_track(plan, tmp_path / "t.png", sea).read_bytes()
    html = files["card"].read_text()
    assert html.count("data:image/png;base64,") == 2


def test_pdf_card_written_beside_the_other_outputs(tmp_path, capsys, monkeypatch):
    """plan-trial writes the PDF card in a forked child: it is there and complete on success, and
    a failure there is the command's one-line error with nothing written."""
    from cli.app import _run

    counts = "steep_zigzag_surge=1"
    out = tmp_path / "ok"
    assert _run(["plan", "--counts", counts, "--out", str(out), "--start-time", START]) == 0
    pdf = (out / "full-scale-trial.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and pdf.rstrip().endswith(b"%%EOF")
    capsys.readouterr()

    import maps.export.card as card

    def broken(*a, **k):
        raise RuntimeError("no room on the page")

    monkeypatch.setattr(card, "write_card_pdf", broken)
    bad = tmp_path / "bad"
    assert _run(["plan", "--counts", counts, "--out", str(bad), "--start-time", START]) == 2
    err = capsys.readouterr().err
    assert "error: full-scale-trial.pdf: writing the PDF trial card failed: RuntimeError: no room on the page" in err
    assert not bad.exists()


def test_planning_leaves_the_callers_options_alone(sea):
    """solve() may switch smoothing off after a failed shortcut: on the lattice's own copy of the
    options, never on the caller's object (which may plan again)."""
    from maps.chain import PlanOptions, build_lattice
    from maps.motionset import resolve_primitives
    from maps.planner import solve

    prof = load_profile("full-scale")
    opts = PlanOptions()
    counts = {"steep_zigzag_surge": 1}
    lat = build_lattice(sea, prof, resolve_primitives(prof, counts, None), counts, options=opts)
    assert lat.options == opts and lat.options is not opts
    lat.options.smooth = False  # what solve() does after a shortcut broke the margin
    plan = solve(lat)
    assert plan.feasible and opts.smooth and opts == PlanOptions()


def test_endpoints_found_before_the_design_are_the_lattices_and_a_bad_one_is_said_by_build_lattice(sea):
    """prepare_basic_moves finds the start and goal while the design is computed elsewhere; the
    lattice built afterwards has the same start and goal as one built without it, and a start
    on land is still refused by build_lattice (where it would be without the early step)."""
    from maps.chain import PlanOptions, build_lattice, prepare_basic_moves
    from maps.geo import MapError
    from maps.motionset import resolve_primitives

    prof = load_profile("full-scale")
    counts = {"steep_zigzag_surge": 1}
    prims = resolve_primitives(prof, counts, None)
    cache: dict = {}
    prepare_basic_moves(sea, prof, PlanOptions(), cache)
    assert "endpoints" in cache
    early = build_lattice(sea, prof, prims, counts, options=PlanOptions(), cache=cache)
    plain = build_lattice(sea, prof, prims, counts, options=PlanOptions())
    assert (early.start, early.start_cell, early.goal_cell, early.goal_h) == (
        plain.start,
        plain.start_cell,
        plain.goal_cell,
        plain.goal_h,
    )
    land = (60.1699, 24.9384, 0.0)  # Helsinki city centre
    bad: dict = {}
    prepare_basic_moves(sea, prof, PlanOptions(), bad, start=land)
    assert "endpoints" not in bad
    with pytest.raises(MapError, match="start .* is on land"):
        build_lattice(sea, prof, prims, counts, start=land, options=PlanOptions(), cache=bad)
