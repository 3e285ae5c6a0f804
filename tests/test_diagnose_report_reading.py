"""The diagnosis report as a trials engineer reads it (reviewer's findings 7, 8 and 13): each
finding's own share of the held-out fit, the baseline refit's share apart, plain reasons for a
rejection, bounded fit percentages, the measures defined once, times from the run's start and
residual plots without edge artefacts."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from diagnose import plausible, report
from diagnose.evidence import evidence as _evidence
from diagnose.heldout import rejection_entry, verdict
from diagnose.locate import locate
from diagnose.report import per_run_lines, sentence, to_text
from primitives.ship import DOFS, load_profile


@pytest.fixture(scope="module")
def ship():
    return load_profile("model-ship")


@pytest.fixture(scope="module")
def damping(damping_diagnosis):
    return damping_diagnosis[1]


def _fits(s, w, y):
    return {"surge": s, "sway": w, "yaw": y}


def test_zero_delay_is_no_delay_found_not_an_implausible_one(ship):
    ok, why = plausible.check("actuator_delay", {"delay_s": 0.0}, ship)
    assert not ok and "no delay found" in why and "at most" not in why
    # the search records the failed check apart ("implausible"): the report says it without the prefix
    assert report.rejection({"reason": f"implausible estimate: {why}", "implausible": why}).startswith("no delay found")
    lim, _ = plausible.max_delay_s(ship)
    ok, why = plausible.check("actuator_delay", {"delay_s": 3 * lim}, ship)
    assert not ok and "at most" in why  # the upper bound, when that is the one violated


@pytest.mark.parametrize("name, says", [("model-ship", "1 m model ship"), ("kvlcc2", "KVLCC2 tanker")])
def test_rejected_wind_says_what_the_ship_is_from_its_profile(name, says):
    """A rejected steady wind names the ship as its profile does (its name, what its description says it is, its
    L, B, T): it read "as a loaded tanker of these main particulars would feel it" for the 1 m model ship too."""
    prof = load_profile(name)
    lim = plausible.MAX_WIND_REF_MPS * plausible.froude(prof)
    ok, why = plausible.check("wind", {"speed_mps": 2 * lim}, prof)
    assert not ok and "at most" in why
    assert f"'{name}'" in why and says in why and f"L {prof.length_m:g} m" in why, why
    # the ship is not called a tanker; the wind model's tanker coefficients are named as the model's
    assert "as a loaded tanker" not in why and "loaded tanker's wind coefficients" in why, why


def test_ship_words_of_a_made_profile_say_its_name_once():
    """`profile new` writes "coaster: 3-DOF model made from ..." as the description: the name is not said twice."""
    from dataclasses import replace

    prof = replace(load_profile("kvlcc2"), name="coaster", description="coaster: 3-DOF model made from main particulars (x)")
    assert plausible.ship_words(prof) == "'coaster', 3-DOF model made from main particulars,"


def _verdict(rss0, rss1, den=1e6, rows=1000, q=1):
    rss0, rss1 = np.array(rss0, float), np.array(rss1, float)
    return verdict(rss0, rss1, np.full_like(rss0, den), np.full(len(rss0), rows), q, 1.0)


# one real Verdict per held-out criterion: (verdict, criterion, what the report must say)
CRITERIA = [
    (lambda: _verdict([[1, 1, 1]], [[0.999] * 3], rows=100, q=5), "penalty", ["too small for the penalty", "+9.7"]),
    (lambda: _verdict(np.ones((3, 3)), [[0.1] * 3, [1.01] * 3, [1.01] * 3]), "too_few_improved", ["only 1 of 3"]),
    (lambda: _verdict([[1, 1, 1]], [[0.01, 0.01, 2.0]], den=4.0), "channel_much_worse", ["loses 20.7 points", "15 allowed"]),
    (
        lambda: _verdict(np.ones((3, 3)), [[0.5] * 3, [0.5] * 3, [1.05] * 3]),
        "run_misfit_rises",
        ["rises by 5.0 %", "2 % allowed"],
    ),
    (
        lambda: _verdict([[1, 0, 1], [0, 0, 200], [1, 0, 1]], [[0.5, 0, 1], [0, 0, 203], [0.5, 0, 1]], rows=100),
        "no_pooled_gain",
        ["pooled held-out misfit does not fall", "gain -0.98 %", "2/3"],
    ),
]


@pytest.mark.parametrize("make,criterion,words", CRITERIA, ids=[c[1] for c in CRITERIA])
def test_rejection_is_worded_from_the_verdicts_failed_criterion(make, criterion, words):
    """The search stores the failed criterion with its numbers (``heldout.rejection_entry``);
    the report words it from those fields, for validation runs and for refitted folds."""
    from diagnose.search import MUCH_WORSE

    v = make()
    assert not v.accepted(MUCH_WORSE) and v.failed_criterion(MUCH_WORSE)["criterion"] == criterion
    val = report.rejection(rejection_entry(v, MUCH_WORSE, validation=True))
    assert val.startswith("not confirmed on the validation runs: ") and "does not improve" not in val
    for w in words:
        assert w in val, (w, val)
    folds = report.rejection(rejection_entry(v, MUCH_WORSE, validation=False))
    assert folds.startswith("not confirmed on the held-out data (each left-out run or block refitted")
    assert "validation" not in folds and all(w in folds for w in words)


def test_an_accepted_verdict_is_no_rejection_and_other_reasons_pass_as_said():
    from diagnose.search import MUCH_WORSE

    v = _verdict(np.ones((3, 3)), np.full((3, 3), 0.5))
    assert v.accepted(MUCH_WORSE) and v.failed_criterion(MUCH_WORSE) is None
    assert rejection_entry(v, MUCH_WORSE, validation=True) is None
    assert report.rejection({"reason": "the refit diverged"}) == "the refit diverged"


def _finding(effect, dof="yaw", **p):
    return {"effect": effect, "dof": dof, "evidence": "e", "plausibility": "", "parameters": p}


def test_every_effect_states_its_interval_and_when_it_includes_no_effect():
    """MARIN's yaw inertia read scale 0.166 +- 0.244: the text printed "0.86 x the model's" with
    no +-. Each effect now carries its +- (the ratio's by the delta method) and one within 1 std
    of no effect says so."""
    from diagnose.describe import _inertia

    c, m = SimpleNamespace(key="k", dof=2), SimpleNamespace(slot_of={"k": [0]})
    p = _inertia(c, m, np.array([0.166]), np.array([[0.244**2]]), [0])
    assert p["inertia_ratio_std"] == pytest.approx(0.244 / 1.166**2)
    text = sentence(_finding("inertia_change", **p))
    assert "0.86 +- 0.18 x the model's" in text and "1.166 +- 0.244" in text and "includes no effect" in text
    cases = [
        (_finding("quadratic_damping", term="r*|r|", value=-0.02, value_std=0.005), "-0.02 +- 0.005"),
        (_finding("missing_coupling", term="v*r", value=0.3, value_std=0.5), "0.3 +- 0.5"),
        (
            _finding(
                "resistance_change",
                "surge",
                term="u*|u|",
                coefficient=-0.01,
                coefficient_std=0.002,
                resistance_change_pct=12.0,
                resistance_change_pct_std=2.4,
            ),
            "+12 +- 2 %",
        ),
        (
            _finding(
                "thrust_loss",
                "surge",
                term="tau_x",
                coefficient=-0.01,
                coefficient_std=0.002,
                loss_percent=8.0,
                loss_percent_std=1.6,
            ),
            "8 +- 1.6 %",
        ),
        (_finding("thrust_loss", "surge", term="u*tau_x", coefficient=-0.004, coefficient_std=0.001), "-0.004 +- 0.001"),
        (
            _finding("wind", "sway", wind_surge=0.5, wind_surge_std=0.1, wind_sway=0.1, wind_sway_std=0.2),
            "surge 0.5 +- 0.1, sway 0.1 +- 0.2",
        ),
        (  # the mean accelerations are printed apart from the scales, with their units
            _finding("wind", "sway", wind_surge=0.5, wind_surge_std=0.1, wind_accel_surge=-0.0012, wind_accel_surge_std=0.0001),
            "scaled per DOF by surge 0.5 +- 0.1; areas from the main particulars as a loaded tanker's); its mean "
            "acceleration of the ship over the diagnosed runs: surge -0.0012 +- 0.0001 m/s^2",
        ),
    ]
    for f, pm in cases:
        text = sentence(f)
        assert pm in text, (pm, text)
        weak = all(
            abs(f["parameters"][k]) < f["parameters"][f"{k}_std"]
            for k in f["parameters"]
            if f"{k}_std" in f["parameters"] and k in ("value", "coefficient", "loss_percent", "wind_surge", "wind_sway")
        )
        assert ("includes no effect" in text) == weak, text


def test_absurd_fit_percentages_print_bounded():
    assert "260211219909401792" not in report.heldout_change(-2.602112199094018e15)
    assert "diverges" in report.heldout_change(-2.6e15) and report.heldout_change(-0.69) == "held-out residual +69 %"
    d = SimpleNamespace(
        per_run_method="validation runs, simulated",
        per_run=[{"run": "a.csv", "before": _fits(-7840.0, 10.0, 20.0), "after": _fits(-2.6e17, 12.0, 25.0)}],
    )
    table = "\n".join(per_run_lines(d))
    assert "< -999" in table and "7840" not in table and "e+" not in table


def test_roll_coupling_is_named_for_a_human():
    f = {
        "effect": "roll_coupling",
        "dof": "sway",
        "evidence": "e",
        "plausibility": "",
        "parameters": {"phi_sway": -2.1, "phi_yaw": 0.00674, "phi_sway_std": 0.536, "phi_yaw_std": 0.00681},
    }
    text = sentence(f)
    assert "phi_sway" not in text and "_std" not in text
    assert "roll angle" in text and "sway motion" in text and "yaw motion" in text


def test_finding_states_its_own_share_not_the_whole_models():
    rows = [{"run": "/x/val.csv", "before": _fits(70.0, 58.0, 60.0), "after": _fits(71.0, 64.0, 50.0)}]
    f = {
        "dof": "sway",
        "effect": "roll_coupling",
        "rss_drop": 0.7,
        "f_statistic": 80.0,
        "p_value": 1e-18,
        "cv_gain": 0.6,
        "heldout_per_run": rows,
    }
    text = _evidence(f, {"conditions": {}}, _fits(-46, 39, 43), _fits(75, 65, 70), "validation")
    assert "58 % -> 64 % (yaw 60 % -> 50 %)" in text and "val.csv (simulated)" in text and "39 %" not in text
    f["heldout_per_run"] = []
    assert "whole model" in _evidence(f, {"conditions": {}}, _fits(-46, 39, 43), _fits(75, 65, 70), "validation")


def test_gain_sources_separate_the_baseline_refit_from_each_finding():
    a = {"key": "a", "heldout_per_run": [{"run": "/x/v.csv", "before": _fits(50, 50, 50), "after": _fits(60, 55, 50)}]}
    b = {"key": "b", "heldout_per_run": [{"run": "/x/v.csv", "before": _fits(60, 55, 50), "after": _fits(61, 65, 52)}]}
    d = SimpleNamespace(
        findings=[a, b],
        structure=[],
        per_run_method="validation runs, simulated",
        fit_on="validation",
        refit_parameters=["Xu"],
        magnitudes_refitted=False,
        per_run=[{"run": "/x/v.csv", "before": _fits(-46, 39, 43), "after": _fits(61, 65, 52)}],
    )
    line = report.gain_sources(d)[1]
    assert line.startswith("  v.csv: baseline as given -46.0/39.0/43.0 -> baseline refitted 50.0/50.0/50.0")
    assert "+ a 60.0/55.0/50.0 -> + b 61.0/65.0/52.0 -> final 61.0/65.0/52.0" in line
    d.magnitudes_refitted = True  # the final row is then not the search's estimates: said
    assert "-> final (magnitudes refitted by maximum likelihood) 61.0/65.0/52.0" in report.gain_sources(d)[1]
    d.refit_parameters = []
    assert "before the first finding (no baseline parameter refitted) 50.0" in report.gain_sources(d)[1]
    d.fit_on = "diagnosed"  # leave-one-out folds are scored linearised, the table by simulation: no chain
    assert report.gain_sources(d) == []


def test_running_mean_has_no_edge_jump():
    x = np.full(50, 2.0)
    np.testing.assert_allclose(report.running_mean(x, 5), 2.0)  # a zero-padded convolution gives 1.2 at the ends
    ramp = np.arange(20.0)
    np.testing.assert_allclose(report.running_mean(ramp, 5)[2:-2], ramp[2:-2])
    assert report.running_mean(ramp, 5)[0] == pytest.approx(1.0)  # the window shrinks to samples 0..2


def test_cusum_times_are_from_the_runs_start(ship):
    n = 400
    t = 1.7e9 + np.arange(n + 1.0)  # a logger's epoch stamps
    rng = np.random.default_rng(3)
    y = 0.01 * rng.standard_normal((n + 1, 3))
    rec = SimpleNamespace(t=t, segments=None, source="run.csv")
    prep = SimpleNamespace(
        rec=rec, psi=np.zeros(n + 1), y=y, inputs=rng.standard_normal((n + 1, len(ship.inputs))), wind_body=None
    )
    res = np.zeros((n + 1, 3))
    res[200:260, 0] = 5.0  # a misfit from 200 s after the start
    loc = locate(ship, [prep], [res], ship.params(None), np.ones(3))
    w = loc["cusum_windows"][0]
    assert w["dof"] == DOFS[0] and 190 <= w["t_start"] <= 200 and w["run_start_stamp"] == t[0]


def test_report_defines_its_measures_and_splits_the_gain(damping):
    text = to_text(damping)
    for term in (
        "fit % = NRMSE fit",
        "100 % is perfect",
        "residual = recorded - simulated",
        "residual / noise =",
        "CUSUM alarm (5.1) =",
        "'per sample' coefficient",
        "pooled fit =",
    ):
        assert text.count(term) == 1, term
    assert "its own share" in text and "Where the gain comes from" in text and "before the first finding" in text


def test_no_finding_line_says_where_the_screened_candidates_are():
    """'see the screened candidates in the JSON' after the README's KVLCC2 example, which asks for
    no JSON and writes no file: a new user cannot find that JSON (stop 62's walk)."""
    d = SimpleNamespace(
        cannot_tell="", explained=False, findings=[], structure=[], untestable=[],
        location={"rms_over_noise": {"surge": 9.0, "sway": 5.3, "yaw": 8.6}},
    )  # fmt: skip
    line = report.finding_lines(d)[0]
    assert "surge residual is 9 x the noise" in line
    assert "--json, or diagnosis.json with --out DIR" in line


def test_a_recordings_note_that_names_it_is_not_prefixed_twice_in_the_report(damping):
    """Stop 62: 'Recording run.csv: run.csv: header '# ship: model' ...' (the ship note names its recording, as
    on stderr). Now the recording is named once; the note itself is unchanged (stderr, diagnosis.json)."""
    import dataclasses

    from diagnose.recording_checks import ship_header_note

    prep = damping.preps[0]
    rec = dataclasses.replace(prep.rec, meta={**prep.rec.meta, "ship": "model"})
    note = ship_header_note(rec, load_profile("model-ship"))
    assert note.startswith(f"{rec.source}: header '# ship: model'")
    rec = dataclasses.replace(rec, notes=[note, "a note of its own"])
    text = to_text(dataclasses.replace(damping, preps=[dataclasses.replace(prep, rec=rec), *damping.preps[1:]]))
    (line,) = [ln for ln in text.splitlines() if ln.startswith(f"Recording {rec.source}:")]
    assert line == f"Recording {rec.source}: {note.removeprefix(rec.source + ': ')}; a note of its own."
    assert line.count(rec.source) == 1
