"""The podded-ship truth family (tests/physics/podded_truth.py) differs measurably from the
detector's yaw row (2.17) in every variant: it is an exam the detector was not built on."""

from __future__ import annotations

import numpy as np
import pytest

from identify.detect.priorfit import fit
from tests.physics.podded_truth import VARIANTS, draw_ship, nominal_ship, recordings

DUR, LEAD = 100.0, 30.0


@pytest.fixture(scope="module")
def clean():
    """Noise-free recordings (same manoeuvre, seed-drawn ship) of every variant."""
    return {v: recordings(v, 3, [31], duration_s=DUR, noise_scale=0.0, lead_in_s=LEAD)[0] for v in VARIANTS}


def _sig(c: dict) -> dict:
    return {"u": c["u"], "v": c["v"], "v_dot": c["v_dot"], "phi": c["phi"], "tau_r": c["tau_n"]}


def test_the_yaw_row_cannot_reproduce_any_variant(clean):
    # the product's own kernel is reproduced by (2.17) to rounding (test_detect: 1e-12 rad/s); on
    # every variant the best output-error fit on noise-free data misses r by more than 2e-4 rad/s
    # (2.7e-4 to 1.5e-3 measured on 150 s), and the prior it gives puts the lumped yaw inertia
    # I_r = I_z - N_rdot over 20 % away from the ship's (measured 0.59-0.67 of it, or diverged):
    # the fit absorbs the pod-hull interaction and the couplings it lacks
    for v, c in clean.items():
        ship = draw_ship(v, 3)
        p = fit("full", _sig(c), c["r"], 0.1, bootstrap=0)
        assert p.sigma > 2e-4, (v, p.sigma)
        assert abs(p.values["I_r"] / (ship.I_z - ship.N_rd) - 1) > 0.2, v


def test_each_variant_carries_its_structure(clean):
    nom = clean["nominal-mmg"]
    # strong roll: at least 1.5 times the roll of the nominal variant on the same manoeuvre
    assert np.abs(clean["strong-roll"]["phi"]).max() > 1.5 * np.abs(nom["phi"]).max()
    # steering lag: the recorded azimuth (setpoint) leads the moment the ship feels; the recorded
    # tau_n is the setpoint's, so it differs from the nominal variant's by a sizeable fraction
    lag, n0 = clean["steering-lag"]["tau_n"], nom["tau_n"]
    assert np.sqrt(np.mean((lag - n0) ** 2)) > 0.1 * np.sqrt(np.mean(n0**2))
    # pod-hull interaction (wake, thrust deduction, shadowing): slower on the same commands (6.6
    # against 7.2 m/s over 150 s of one manoeuvre) with another pod moment (21 % rms apart there)
    pod = clean["pod-interaction"]
    assert nominal_ship("pod-interaction").a_H > 2 * nominal_ship("nominal-mmg").a_H
    assert np.mean(pod["u"]) < 0.95 * np.mean(nom["u"])
    assert np.sqrt(np.mean((pod["tau_n"] - n0) ** 2)) > 0.1 * np.sqrt(np.mean(n0**2))
    # ships drawn from one variant differ (parameters scattered per seed)
    assert draw_ship("nominal-mmg", 1).N_rr != draw_ship("nominal-mmg", 2).N_rr


def test_coloured_noise_is_coloured_and_heavy_tailed(clean):
    noisy = recordings("coloured-noise", 3, [31], duration_s=DUR, lead_in_s=LEAD)[0]
    white = recordings("nominal-mmg", 3, [31], duration_s=DUR, lead_in_s=LEAD)[0]
    clean, clean_w = clean["coloured-noise"], clean["nominal-mmg"]
    e, w = noisy["u"] - clean["u"], white["u"] - clean_w["u"]
    lag = 10  # 1 s: the sensor low-pass (0.5 s) leaves white noise nearly uncorrelated there

    def rho(x: np.ndarray) -> float:
        return float(np.corrcoef(x[:-lag], x[lag:])[0, 1])

    assert rho(e) > 0.3 > rho(w)
    er = noisy["r"] - clean["r"] - np.mean(noisy["r"] - clean["r"])
    kurt = float(np.mean(er**4) / np.mean(er**2) ** 2)
    assert kurt > 3.0  # heavier than Gaussian tails survive the sensor filter, plus the gyro bias drift


def test_the_roll_rate_term_narrows_the_gap_without_closing_it(clean):
    # the prior's yaw row with N_p p (kind full-p, used when the recording has p) takes out most of
    # the strong-roll variant's misfit (1.55e-3 -> 4.3e-4 rad/s measured, I_r 0.60 -> 1.00 of the
    # ship's), yet no variant is reproduced: every fit still misses r by > 1.5e-4 rad/s on
    # noise-free data (2.0e-4 to 4.3e-4 measured), the interaction terms stay unmodelled
    fits = {}
    for v, c in clean.items():
        fits[v] = fit("full-p", _sig(c) | {"p": c["p"]}, c["r"], 0.1, bootstrap=0)
        assert fits[v].sigma > 1.5e-4, (v, fits[v].sigma)
    roll = clean["strong-roll"]
    without = fit("full", _sig(roll), roll["r"], 0.1, bootstrap=0)
    assert fits["strong-roll"].sigma < 0.5 * without.sigma
