"""Residual tests and cross-validation of ``shiptrial steering`` (Källström 1977, Figs. 3.3 c, d; Table 3.8)."""

from __future__ import annotations

import numpy as np

from identify.steering.crossval import cross_validate, split_record
from identify.steering.estimate import SteeringData
from identify.steering.residuals import rudder_correlation, whiteness
from tests.physics import sea_splendour as ss


def test_whiteness_passes_white_noise_and_fails_coloured():
    rng = np.random.default_rng(4)
    e = rng.normal(size=400)
    assert whiteness(e, 20).passed
    ar = np.zeros(400)
    for k in range(1, 400):
        ar[k] = 0.7 * ar[k - 1] + e[k]
    t = whiteness(ar, 20)
    assert not t.passed and t.values[0] > 0.6


def test_rudder_correlation_finds_a_delayed_rudder_in_the_residuals():
    rng = np.random.default_rng(5)
    u = np.sign(rng.normal(size=400))
    e = rng.normal(size=400)
    assert rudder_correlation(e, u, 20).passed
    leaked = e + 0.8 * np.roll(u, 3)
    t = rudder_correlation(leaked, u, 20)
    assert not t.passed and np.argmax(np.abs(t.values)) == 3


def test_cross_validation_holds_the_dynamics_and_refits_only_the_nuisance():
    run = ss.simulate(ss.EXPERIMENT_1, 0)
    d = SteeringData(run["t"], run["delta"], np.column_stack([run["r"], run["psi"]]), ("r", "psi"))
    p1, p2 = split_record(d, 1158.0, 1732.0)
    assert p1.t[-1] < 1158.0 <= 1732.0 <= p2.t[0] and len(p1.t) + len(p2.t) < len(d.t)
    fits, rows = cross_validate((p1, p2), ss.L, ss.V)
    assert len(rows) == 4 and all(r.fit is not None and r.fit.converged for r in rows)
    for r in rows:
        src = fits[(r.model_part, r.estimator)]
        for k in ("phi_1", "phi_2", "phi_4", "phi_5", "T_D"):
            assert r.fit.p[k] == src.p[k]
        assert set(r.fit.free) == {"delta_0", "rdot_0", "r_0", "psi_0", "b_r"}
        # its own part's start heading, not the other part's: the 20 deg course change lies between them
        assert abs(r.fit.p["psi_0"] - r.fit.records[0].y[0, 1]) < np.radians(2.0)
