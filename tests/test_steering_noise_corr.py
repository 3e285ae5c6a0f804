"""Källström's R1 with cross-correlation: the process noise of the two rate equations correlated,
R1(1,2) = sqrt(R1(1,1) R1(2,2)) rho (his sin theta_20; here rho = tanh(atanh_rho_q)), estimated by maximum
likelihood with the heading's variance fixed (the scale ambiguity). The truth is the simulated Sea Splendour
(tests/physics/sea_splendour.py, sharing no code with the estimator) whose sea force and moment are correlated:
its mass matrix is diagonal, so the correlation of the sway and yaw accelerations' noise is the sea's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from identify.steering.api import fit_model
from identify.steering.estimate import SteeringData
from identify.steering.models import RHO, Structure
from tests.physics import sea_splendour as ss

CHANNELS = ("v", "r", "psi")


def _record(sea_corr: float, seed: int) -> SteeringData:
    """Experiment 2 (15 s, 30 min, 20 deg course change, seven lost readings) in a sea six times the default,
    so that the process noise dominates the sensors' and its correlation shows in the innovations."""
    run = ss.simulate(dataclasses.replace(ss.EXPERIMENT_2, sea=6.0, sea_corr=sea_corr), seed)
    return SteeringData(run["t"], run["delta"], np.column_stack([run[c] for c in CHANNELS]), CHANNELS)


def _rho_interval(f) -> tuple[float, float]:
    z, sd = f.p[RHO], f.std[RHO]
    assert np.isfinite(sd) and sd > 0, sd
    return float(np.tanh(z - 1.96 * sd)), float(np.tanh(z + 1.96 * sd))


@pytest.mark.parametrize("model", ["state-space", "nomoto2"])
def test_the_model_carries_the_correlation_into_its_continuous_noise_covariance(model):
    st = Structure(model, ss.L, ss.V, ("r", "psi"), noise_corr=True)
    q1, q2 = ("ln_q_v" if model == "state-space" else "ln_q_x"), "ln_q_r"
    assert {q1, q2, RHO} <= set(st.names)
    p = {k.name: 0.0 for k in st.params} | {q1: 0.3, q2: -0.4, RHO: np.arctanh(-0.6)}
    if model == "nomoto2":
        p |= {"phi_1": 3.0, "phi_2": 0.5, "phi_4": -1.0, "phi_5": -0.4}
    Qc = st.system(p)[5]
    assert Qc[0, 1] == Qc[1, 0] == pytest.approx(-0.6 * np.sqrt(Qc[0, 0] * Qc[1, 1]))
    assert Qc[0, 0] > 0 and Qc[1, 1] > 0 and not Qc[2].any()
    with pytest.raises(ValueError, match="two noisy states"):
        Structure("nomoto1", ss.L, ss.V, ("r", "psi"), noise_corr=True)


def test_maximum_likelihood_recovers_a_correlated_sea_and_aic_prefers_the_correlation():
    """Sea force and moment correlated at 0.8: the estimate's 95 % interval holds 0.8 and not zero, and AIC
    prefers the fit with the correlation by more than 10 (seed 1: rho 0.80, interval 0.60-0.90, AIC 98 lower)."""
    d = _record(0.8, 1)
    f = fit_model(d, ss.L, ss.V, "state-space", "ml", noise_corr=True)
    assert f.ok, f.undetermined
    lo, hi = _rho_interval(f)
    assert lo < 0.8 < hi and lo > 0.0, (lo, hi)
    assert f.aic < fit_model(d, ss.L, ss.V, "state-space", "ml").aic - 10


def test_without_a_correlated_sea_the_correlation_interval_holds_zero():
    f = fit_model(_record(0.0, 1), ss.L, ss.V, "state-space", "ml", noise_corr=True)
    assert f.ok, f.undetermined
    lo, hi = _rho_interval(f)
    assert lo < 0.0 < hi, (lo, hi)
    assert hi - lo < 1.0  # informative: not the whole of (-1, 1)


def test_identify_records_passes_the_correlation_to_the_second_order_ml_fits_only():
    """``--noise-corr``: the nomoto2 ML fit carries R1(1,2); nomoto1 (one noisy state) and OE fits run without it."""
    from identify.steering.api import identify_records

    run = ss.simulate(ss.EXPERIMENT_2, 3)
    d = SteeringData(run["t"], run["delta"], np.column_stack([run["r"], run["psi"]]), ("r", "psi"))
    res = identify_records([d], ss.L, ss.V, "nomoto2", "ml", noise_corr=True)
    fits = {(r.model, r.estimator): r.fit for r in res.results}
    assert all(f is not None and f.converged for f in fits.values())
    assert RHO in fits["nomoto2", "ml"].free
    assert RHO in fits["nomoto2", "oe"].structure.names and RHO not in fits["nomoto2", "oe"].free
    assert RHO not in fits["nomoto1", "ml"].structure.names
    assert any("--noise-corr" in n for n in res.notes)
    from identify.steering.report import text

    assert "process-noise correlation rho" in text(res)
