"""A parameter the instrument-mean subtraction makes unidentifiable is said, not designed over in
silence: with batchwise subtraction the surge force's instrument is constant within every
zig-zag, so X and Y Z^T of (7.52) cancel to rounding noise; the design, its report, the CLI and
the planner's design notes name the parameter, why, and what would help."""

from __future__ import annotations

import json

import numpy as np
import pytest

from expdesign.api import default_library, run_design
from expdesign.dopt import InfoSet, lost_to_mean_subtraction
from primitives.information import library_information
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def model_ship():
    prof = load_profile("model-ship")
    prims = [p for p in default_library(prof) if p.kind == "informative"]
    return prof, prims, InfoSet.from_infos(library_information(prof, prims))


def test_the_surge_force_is_lost_only_where_its_instrument_is_constant(model_ship):
    """In the zig-zags tau3-tau8 the surge force is held constant: batchwise subtraction leaves
    its information at rounding level (< 1e-9 of it, in fact ~1e-14); the spirals keep some."""
    prof, prims, info = model_ship
    xtau = prof.predictor_param_names.index("Xtau")
    zigzags = np.array([p.name in {"tau3", "tau4", "tau5", "tau6", "tau7", "tau8"} for p in prims], float)
    lost = lost_to_mean_subtraction(info, zigzags / zigzags.sum(), "batchwise")
    assert list(lost) == [xtau] and lost[xtau] < 1e-12
    assert lost_to_mean_subtraction(info, zigzags / zigzags.sum(), "none") == {}
    assert lost_to_mean_subtraction(info, np.full(len(prims), 1 / len(prims)), "batchwise") == {}


def test_the_design_warns_when_its_weights_lose_a_parameter(model_ship):
    prof, prims, info = model_ship
    d = run_design(prof, prims, mean_subtraction="batchwise", max_frac={"tau9": 0.0, "tau10": 0.0, "tau11": 0.0})
    assert len(d.warnings) == 1, d.warnings
    w = d.warnings[0]
    assert w.startswith("Xtau is not identifiable with batchwise instrument-mean subtraction")
    assert "in this design" in w and "tau9, tau10, tau11" in w and "--mean-subtraction none" in w
    assert d.to_dict()["warnings"] == d.warnings
    # the default design of the same library keeps it, and says nothing
    assert run_design(prof, prims, mean_subtraction="batchwise", infos=library_information(prof, prims)).warnings == []


def test_a_library_that_cannot_keep_the_parameter_is_named_in_the_cli(monkeypatch, capsys, tmp_path):
    """The full-scale thesis dictionary without tau12 (the only surge-force steps): no mix keeps
    Xtau under batchwise subtraction. The CLI prints one warning line on stderr, the JSON and the
    report carry it."""
    import expdesign.api
    from cli.app import _run

    real = expdesign.api.default_library
    monkeypatch.setattr(
        expdesign.api, "default_library", lambda prof, psi=None: [p for p in real(prof, psi) if p.name != "tau12"]
    )
    out = tmp_path / "out"
    code = _run(
        ["design", "--ship", "full-scale", "--mean-subtraction", "batchwise", "--monte-carlo", "0", "--json", "--out", str(out)]
    )
    assert code == 0
    cap = capsys.readouterr()
    warn = [line for line in cap.err.splitlines() if line.startswith("warning:")]
    assert len(warn) == 1 and "Xtau is not identifiable" in warn[0] and "in every mix of this library" in warn[0], cap.err
    assert json.loads(cap.out)["warnings"] == [warn[0][len("warning: ") :]]
    assert "**Warning:** Xtau is not identifiable" in (out / "report.md").read_text()


def test_the_planner_notes_carry_the_warning():
    from maps.trialdesign import design_counts

    prof = load_profile("full-scale")
    lib = [p for p in default_library(prof) if p.kind == "informative" and p.name != "tau12"]
    td = design_counts(prof, lib, mean_subtraction="batchwise")
    assert any(n.startswith("warning: Xtau is not identifiable") for n in td.notes), td.notes
    assert not any(n.startswith("warning:") for n in design_counts(prof, lib, mean_subtraction="complete").notes)
