"""No words from inside the project in what users read (issue 29): help texts and the diagnosis
report cite publications (author, year, equation), never "BRIEF", the source documents' seed numbers
or the notes' lesson numbers; every command's help, detect and mass included."""

from __future__ import annotations

import re

import pytest
import typer

from cli.app import _run, app

INTERNAL = re.compile(r"\bBRIEF\b|\bseed 0\d\d\b|\blesson \d+|\bseed00\d", re.IGNORECASE)
COMMANDS = list(typer.main.get_command(app).commands)


@pytest.mark.parametrize("command", ["", *COMMANDS])
def test_help_has_no_internal_words(command, capsys):
    rc = _run([command, "--help"] if command else ["--help"])
    out = capsys.readouterr().out
    assert rc == 0 and out.strip()
    hits = [ln.strip() for ln in out.splitlines() if INTERNAL.search(ln)]
    assert not hits, f"shiptrial {command} --help: {hits}"


def test_commands_cover_the_app():
    assert {
        "primitives",
        "design",
        "plan",
        "export",
        "diagnose",
        "sweep",
        "yawid",
        "yawid-sim",
        "detect",
        "detect-prior",
        "mass",
        "mass-sim",
    } <= set(COMMANDS)


def test_diagnosis_report_has_no_internal_words(damping_diagnosis):
    from diagnose.report import to_json, to_text

    _, d = damping_diagnosis
    text = to_text(d) + repr(to_json(d, None))
    assert not INTERNAL.findall(text), INTERNAL.findall(text)


def test_a_diverged_fit_is_explained_once_not_at_every_cell(damping_diagnosis):
    """'< -999 % (the model diverges from the run)' was printed 20+ times in one report."""
    from diagnose.perrun import fit_str
    from diagnose.report import to_text

    assert fit_str(-5000.0) == "< -999 %" and fit_str(float("nan")) == "n/a"
    text = to_text(damping_diagnosis[1])
    assert text.count("'< -999 %': the simulation diverges from the run") == 1
