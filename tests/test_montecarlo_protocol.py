"""Monte Carlo protocol of seed 001 section 9.1.2: one continuous experiment per run, the
primitives back to back (in the library's order, one sequence as the thesis's optimized input, or
in a per-run random order), a minimum sub-experiment length, diverged runs counted apart from the
percentiles."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from expdesign.errors import DesignError
from expdesign.mc_result import MCResult, merge_results
from expdesign.montecarlo import MCConfig, block_lengths, prepare, run_segments, run_sequence
from primitives.library import model_ship_thesis
from primitives.ship import load_profile

DESIGN = {"tau1": 0.2, "tau6": 0.3, "tau8": 0.23, "tau11": 0.27}


@pytest.fixture(scope="module")
def ship():
    p = load_profile("model-ship")
    return p, model_ship_thesis(p)


def _layout(sh, design, run):
    seq = run_sequence(sh, design, run)
    return seq, run_segments(sh, seq)


@pytest.mark.parametrize("order", ["library", "random"])
def test_continuous_run_is_one_experiment_with_the_blocks_in_order(ship, order):
    p, lib = ship
    shuffled = {k: DESIGN[k] for k in ("tau8", "tau1", "tau11", "tau6")}  # the caller's order does not matter
    sh = prepare(p, {"opt": shuffled, "random": "random"}, MCConfig(runs=8, seed=4, order=order), lib)
    prims = {q.name: q for q in lib}
    orders = set()
    for run in range(8):
        seq, (segs, starts) = _layout(sh, "opt", run)
        assert Counter(k for k, _ in seq) == Counter(set(DESIGN)) and sum(n for _, n in seq) == 1000
        assert len(segs) == 1 and segs[0][0].shape == (1000, 3)  # one input signal for the whole run
        np.testing.assert_array_equal(segs[0][1], prims[seq[0][0]].nu0)  # starts where its first primitive starts
        k0, n0 = seq[0]
        np.testing.assert_array_equal(segs[0][0][:n0], np.resize(prims[k0].inputs, (n0, 3)))
        assert starts == list(np.cumsum([0] + [n for _, n in seq[:-1]]))
        orders.add(tuple(k for k, _ in seq))
        assert _layout(sh, "opt", run)[0] == seq  # the order depends on (seed, run) only
    assert orders == {("tau1", "tau6", "tau8", "tau11")} if order == "library" else len(orders) > 3
    rseq, (rsegs, _) = _layout(sh, "random", 0)
    assert len(rseq) == 5 and all(n == 200 for _, n in rseq) and rsegs[0][0].shape == (1000, 3)
    assert len({tuple(k for k, _ in _layout(sh, "random", run)[0]) for run in range(8)}) > 3  # drawn per run


def test_settling_gaps_hold_the_next_start_state(ship):
    p, lib = ship
    sh = prepare(p, {"opt": DESIGN}, MCConfig(runs=2, settle=8), lib)
    seq, (segs, starts) = _layout(sh, "opt", 0)
    inp = segs[0][0]
    assert inp.shape == (1000 + 8 * 3, 3)
    n0, k1 = seq[0][1], seq[1][0]
    np.testing.assert_array_equal(inp[n0 : n0 + 8], np.tile(sh.hold[k1], (8, 1)))
    assert starts[1] == n0


def test_piecewise_protocol_restarts_every_block_from_its_nominal_state(ship):
    p, lib = ship
    long = {"tau1": 0.2, "tau6": 0.45, "tau11": 0.35}
    sh = prepare(p, {"opt": long}, MCConfig(runs=2, protocol="piecewise"), lib)
    prims = {q.name: q for q in lib}
    seq, (segs, _) = _layout(sh, "opt", 0)
    assert len(segs) == len(seq) == 5  # 300-sample primitives: 450 and 350 samples become two pieces each
    for (k, n), (inp, nu0) in zip(seq, segs):
        assert 40 <= n <= prims[k].n_samples and inp.shape == (n, 3)
        np.testing.assert_array_equal(nu0, prims[k].nu0)


def test_no_sub_experiment_shorter_than_the_minimum():
    blocks, notes = block_lengths({"a": 0.5, "b": 0.46, "c": 0.01, "d": 0.03}, 1000, 40)
    lengths = dict(blocks)
    assert "c" not in lengths and lengths["d"] == 40 and sum(lengths.values()) == 1000
    assert min(lengths.values()) >= 40
    assert any("c dropped" in n for n in notes) and any("d raised" in n for n in notes)


def test_diverged_runs_are_counted_not_put_in_the_percentiles():
    theta0 = np.array([1.0, -2.0])
    theta = np.array([[1.1, -2.0], [1.0, -1.0], [np.nan, 0.0], [3e5, 1.0]])
    prm = np.array([0.07, 0.35, np.inf, 2e5])
    sim = np.array([[0.01, 0.0, 0.0], [0.2, 0.0, 0.0], [np.inf] * 3, [np.inf] * 3])
    r = MCResult("x", np.arange(4), theta, prm, sim, np.array([False, False, True, True]), 5, ["a", "b"], theta0)
    s = r.summary()
    assert s["diverged"] == 2 and s["runs"] == 4 and s["partial"] and s["runs_requested"] == 5
    assert s["param_rmse_p90"] < 0.4 and s["sim_rmse_p90"] <= 0.2  # not moved by the diverged runs
    assert s["frac_param_rmse_below_1_5"] == 0.5 and s["frac_sim_rmse_below_0_15"] == 0.25
    table = r.parameter_table()
    assert [t["parameter"] for t in table] == ["a", "b"]
    assert table[1]["bias"] == pytest.approx(0.25) and table[1]["frac_within_tolerance"] == 0.5
    # a reference estimate of the same runs is summarised beside, merged with its chunks, in the digest
    halves = [
        MCResult(
            "x",
            np.arange(4)[s],
            theta[s],
            prm[s],
            sim[s],
            r.diverged[s],
            5,
            ["a", "b"],
            theta0,
            [],
            "oe",
            MCResult("x", np.arange(4)[s], theta[s], prm[s], sim[s], r.diverged[s], 5, ["a", "b"], theta0, [], "iv"),
        )
        for s in (slice(2, 4), slice(0, 2))
    ]
    merged = merge_results([{"x": h} for h in halves])["x"]
    assert merged.reference.estimator == "iv" and np.array_equal(merged.reference.runs, np.arange(4))
    s2 = merged.summary()
    assert s2["estimator"] == "oe" and s2["reference"]["frac_sim_rmse_below_0_15"] == 0.25 and s2["digest"] != s["digest"]


def test_singular_solve_is_a_failed_run_not_a_number(ship):
    """tau3 and tau6 hold their surge force: with the instrument mean removed per block (7.19) the
    surge system is singular up to rounding. Every run is counted as diverged with a NaN estimate
    (the IV reference and the output-error result alike), none reports a number made of rounding."""
    from expdesign.montecarlo import evaluate_designs

    p, lib = ship
    r = evaluate_designs(
        p,
        {"d": {"tau3": 0.5, "tau6": 0.5}},
        runs=3,
        seed=1,
        n_samples=400,
        primitives=lib,
        mean_subtraction="batchwise",
        oe_iterations=2,
    )["d"]
    for res in (r, r.reference):
        assert res.diverged.all() and np.isnan(res.theta[:, :4]).all() and np.isinf(res.param_rmse).all()
        assert res.summary()["diverged"] == 3 and res.summary()["param_rmse_p50"] is None


def test_bad_protocol_settings_name_the_setting(ship):
    p, lib = ship
    with pytest.raises(DesignError, match="protocol"):
        prepare(p, {"x": DESIGN}, MCConfig(protocol="restart"), lib)
    with pytest.raises(DesignError, match="minimum sub-experiment"):
        prepare(p, {"x": DESIGN}, MCConfig(n_samples=100, min_block=40), lib)
    with pytest.raises(DesignError, match="unknown primitives"):
        prepare(p, {"x": {"tau42": 1.0}}, MCConfig(), lib)
    with pytest.raises(DesignError, match="'random'"):
        prepare(p, {"x": "best"}, MCConfig(), lib)
    with pytest.raises(DesignError, match="estimator must be one of"):
        prepare(p, {"x": DESIGN}, MCConfig(estimator="ml"), lib)
    with pytest.raises(DesignError, match="oe_iterations"):
        prepare(p, {"x": DESIGN}, MCConfig(oe_iterations=0), lib)
    for name, bad in (("n_segments", 0), ("min_block", 1), ("settle", -1), ("iv_iterations", -1), ("oe_iterations", 0)):
        with pytest.raises(DesignError, match=rf"^Monte Carlo {name} {bad} is below \d: give {name} >= \d$"):
            prepare(p, {"x": DESIGN}, MCConfig(**{name: bad}), lib)
