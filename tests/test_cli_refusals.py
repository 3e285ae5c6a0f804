"""Refusals that say what to do next (issue 29): an output path without its format's extension,
a trial length with a unit, every missing recording column at once, a map too small for the ship."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from cli.app import _run
from maps.export._testing import synthetic_plan

ROOT = Path(__file__).resolve().parents[1]


def test_export_without_the_formats_extension_is_refused_with_the_name_to_give(tmp_path, capsys):
    """`export --format card --out exp-card` wrote HTML into a file without extension."""
    plan = tmp_path / "plan.json"
    plan.write_text(synthetic_plan("model-ship").to_json())
    out = tmp_path / "exp-card"
    assert _run(["export", str(plan), "--format", "card", "--out", str(out), "--no-pdf"]) == 2
    err = capsys.readouterr().err
    assert f"give {out}.html" in err and not out.exists(), err
    assert _run(["export", str(plan), "--format", "gpx", "--out", str(tmp_path / "route")]) == 2
    assert f"give {tmp_path / 'route'}.gpx" in capsys.readouterr().err


@pytest.mark.parametrize(
    "text,seconds",
    [("1800", 1800.0), ("30min", 1800.0), ("30 min", 1800.0), ("0.5h", 1800.0), ("1800s", 1800.0), ("30 minutes", 1800.0)],
)
def test_trial_length_takes_a_unit(text, seconds):
    from cli.options import duration_s

    assert duration_s(text, "--trial-length") == seconds


def test_trial_length_in_an_unknown_form_names_the_forms_it_takes(capsys):
    """'--trial-length 30min' got click's generic "is not a valid float"."""
    assert _run(["plan", "--trial-length", "half an hour", "--out", "x"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --trial-length 'half an hour': give the duration in seconds (e.g. 1800) or with a unit"), err


def test_every_missing_recording_column_is_named_at_once(tmp_path, capsys):
    """They were reported one group at a time (t, then psi, then x/y, then the ship's inputs)."""
    rec = tmp_path / "run.csv"
    rec.write_text("t,u,v,r\n" + "".join(f"{i * 0.125},1,0,0\n" for i in range(100)))
    assert _run(["diagnose", str(rec), "--ship", "kvlcc2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for col in (
        "'psi' (heading, rad)",
        "'x', 'y' (north, east, m) or 'lat', 'lon' (deg)",
        "'delta'",
        "'n'",
        "choose the matching --ship",
    ):
        assert col in err, (col, err)


def test_a_map_too_small_says_what_would_help_and_the_open_sea_map_ships():
    """kvlcc2 on the bundled map said why, not what would help."""
    from maps.geo import bundled_map_path, load_map
    from maps.trialdesign import _what_helps

    text = _what_helps({"zigzag_10_10_s": (6200.0, 2100.0), "turning_circle_35_s": (9000.0, 9000.0)})
    assert "at least 6.2 km x 2.1 km of open water" in text and text.endswith("--map open-sea")
    # a move that fits the water's extent but has no reachable placement (issue 28): it needs more than that
    from maps.sizing import Needs

    assert "more than 6.2 km x 2.1 km of open water" in _what_helps({"zigzag_10_10_s": Needs(6200.0, 2100.0, reach=True)})
    sea = load_map("open-sea")  # the name given as --map loads the shipped map
    assert sea.source == str(bundled_map_path("open-sea"))
    assert sea.start is not None and sea.goal is not None
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["maps"]
    assert "data/*.geojson" in data


def test_a_map_name_that_is_neither_a_file_nor_bundled_names_the_bundled_maps(tmp_path, monkeypatch):
    from maps.geo import MapError, load_map

    monkeypatch.chdir(tmp_path)
    with pytest.raises(MapError, match="no such map file.*bundled map's name: helsinki, open-sea"):
        load_map("open-seas")
