"""The terminal output of plan and design fits 80 columns without cutting a word (issue 29)."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from types import SimpleNamespace

import pytest

from maps.export._testing import synthetic_plan


@pytest.fixture
def narrow(monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setenv("TERM", "dumb")


def test_plan_summary_fits_80_columns_and_keeps_port_and_starboard(narrow, capsys):
    from cli.plan_summary import print_summary

    plan = synthetic_plan(
        "full-scale", ("straight", "zigzag_10_10_s", "turning_circle_35_p", "spot_turn_s", "tau16"), run_in=True
    )
    plan = replace(plan, min_clearance_m=math.inf)
    print_summary(plan, {}, {})
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 80
    assert "…" not in out  # nothing cut
    # the manoeuvre column, its wrapped lines joined
    rows = [ln.split("│") for ln in out.splitlines() if ln.startswith("│") and ln.count("│") == 7]
    col = re.sub(r"\s+", " ", " ".join(r[4] for r in rows))
    assert "10/10 zig-zag to starboard [zigzag_10_10_s]" in col and "turning circle to port, rudder 35°" in col
    assert "[turning_circle_35_p]" in col  # the design code, whole
    assert "inf m" not in out and "no land or obstacle within the map" in out
    assert "steps in sailing order" in out  # run-ins, stops and transits are steps, not manoeuvres


def test_design_summary_lists_every_primitive_the_rounding_uses(capsys):
    from cli.design_cmd import _echo_design

    d = SimpleNamespace(
        criterion="D",
        mean_subtraction="complete",
        weights={"tau12": 0.6, "turning_circle_35_s": 0.396, "tau17": 0.004},
        rounded={"tau12": 3, "turning_circle_35_s": 2, "tau17": 1},
        unit_s={"tau12": 200.0, "turning_circle_35_s": 300.0, "tau17": 200.0},
        efficiency_vs_uniform=1.2,
        efficiency_bound=0.99,
        references={},
    )
    _echo_design("full-scale", d)
    out = capsys.readouterr().out
    assert all(n in out for n in d.rounded)  # tau17 has under 0.5 % but is rounded to one run: design.json has it
    assert "turning_circle_35_s" in out and "…" not in out


def test_primitives_table_fits_80_columns_with_whole_names(narrow, capsys):
    from cli.app import _run

    assert _run(["primitives", "--ship", "kvlcc2"]) == 0
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 80 and "…" not in out
    assert "turning_circle_35_s" in out and "turning_circle_35_p" in out


def test_primitives_table_ranges_read_with_negative_bounds(narrow, capsys):
    """A surge range below zero reads "-1.31..3.00" (it read "-1.31-3.00"), and nothing that
    rounds to zero carries a minus sign ("-0.00", "-1,-0,-0")."""
    from cli.app import _run

    assert _run(["primitives", "--ship", "full-scale"]) == 0
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 80
    stop = next(ln for ln in out.splitlines() if ln.startswith("stopping "))
    assert re.search(r" -\d+\.\d\d\.\.\d+\.\d\d ", stop), stop
    assert not re.search(r"(?<![\d.])-0(?:\.0+)?(?![\d.])", out)  # "-0.50" is a value, "-0.00" and "-0," are not
