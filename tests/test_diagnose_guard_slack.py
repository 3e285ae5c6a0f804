"""The per-run guard's slack on a validation channel (issue 26: the MMG battery's 0.0005 rad/s
gyro bias, named at 14-18 of its std with the validation runs' yaw fits 5-8 points better, was
dropped on noise seeds 3 and 5 because the 10/10 zig-zag's surge lost 1.1-1.2 points: a channel
spread over 8.3 noise units there, where that is 0.09 of the noise)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from diagnose import perrun
from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare
from primitives.ship import load_profile


def _row(loss: float, spread: float) -> dict:
    before = {"surge": 91.0, "sway": 95.0, "yaw": 80.0}
    after = {"surge": 91.0 - loss, "sway": 95.0, "yaw": 88.0}
    return {
        "run": "val.csv",
        "role": "validation",
        "before": before,
        "after": after,
        "weighted_misfit_before": 3.0,
        "weighted_misfit_after": 1.0,
        "noise_spread": {"surge": spread, "sway": 34.0, "yaw": 17.0},
    }


@pytest.mark.parametrize("spread,kept", [(8.3, True), (40.0, False)])
def test_a_fit_point_below_a_fifth_of_the_noise_does_not_drop_a_finding(monkeypatch, spread, kept):
    p = load_profile("model-ship")
    sc = scenario((), 7, n_prims=2)
    recs = sc.diagnose + sc.validate
    cands, _ = build_library(p, recs)
    model = AugmentedModel(p, p.params(), cands, n_rec=1)
    preps = [prepare(p, recs[0], 0)]
    val = [prepare(p, r) for r in recs[1:]]
    bias = next(c for c in cands if c.key == "sensor_bias:r")
    P = model.p0()
    P[model.slot_of[bias.key]] = 1e-4
    free = list(model.x0_params()) + list(model.slot_of[bias.key])
    table = [_row(1.2, spread)]
    monkeypatch.setattr(perrun, "per_run_fits", lambda *a, **k: (table, "validation runs, simulated"))
    w = np.ones(3) / np.array([0.01, 0.01, 1e-3])
    _P, _free, steps, _t, _m, dropped = perrun.guard(
        model, preps, val, w, model.p0(), P, free, [SimpleNamespace(candidate=bias)], []
    )
    assert (len(steps) == 1) is kept
    assert bool(dropped) is not kept


def test_the_slack_is_a_point_or_a_fifth_of_the_noise_in_points():
    """A fit is 100 (1 - |e| / |y - mean y|): a residual rising by d noise units costs 100 d / s
    points on a channel spread over s noise units."""
    sl = perrun.channel_slack(_row(0.0, 8.0))
    assert sl["surge"] == pytest.approx(2.5) and sl["sway"] == perrun.GUARD_SLACK and sl["yaw"] == pytest.approx(20 / 17)
    assert perrun.channel_slack({"before": {}, "after": {}}) == dict.fromkeys(("surge", "sway", "yaw"), perrun.GUARD_SLACK)
