"""The oe interval's z_f term: the implicit-function sensitivity of the optimum against refits."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from identify.rollmass.model import Load, load_profile
from identify.rollmass.output_error import (
    SHARED,
    _Problem,
    central_jacobian,
    fit_output_error,
    start_values,
    z_f_sensitivity,
)
from identify.rollmass.simulate import Noise, simulate_case

CAL = Load(0.2, -0.256)
FREE = SHARED + ("m", "zbar_m")


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="since the load's buoyancy moved from the roll centre to the waterline (issue 25) z_f enters the load "
    "only through the inertia couplings: refit slope -0.044 kg/m, -0.072 m/m, sensitivity +0.052, +0.094 "
    "(opposite sign; 0.8 g and 1.4 mm at the prior's 15 mm sd). A case where z_f matters is needed (open).",
)
def test_z_f_sensitivity_matches_the_slope_of_converged_refits():
    """Case 1, seed 3, profile noise, 0.3 of the run length (~20 s CPU, hence slow). The load's
    d(m, zbar_m)/d z_f = -(J^T J)^-1 J^T dr/dz_f at a converged optimum must match the central slope
    of refits at z_f -+ 2 mm on the same noise model. Refits and optimum are polished by a
    central-difference trust-region fit: the oe fit's own stopping point is not stationary along
    the mass-height ridge (measured here: m 0.2087 there, 0.2011 converged). Measured: sensitivity
    -0.215 kg/m, -0.250 m/m; refit slope -0.303, -0.349 (the secant over 4 mm and the Gauss-Newton
    Hessian); 35 % holds them, a zero or sign-flipped sensitivity fails."""
    prof = load_profile()
    ds = simulate_case(prof, "case1", Noise.from_profile(prof), seed=3, length_factor=0.3)
    kn, z_f, h = prof.known, prof.known.z_f_prior, 2e-3
    f = fit_output_error(ds, kn, CAL, z_f, start_values(prof), with_cov=False)
    w, ar = f.noise
    x0 = np.array([f.values[k] for k in FREE])
    opt = {}
    for dz in (-h, 0.0, h):
        prob = _Problem(ds, kn, CAL, z_f + dz, FREE, w, ar)
        opt[dz] = least_squares(
            prob.residual, x0, jac="3-point", method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-10, max_nfev=100
        ).x
    prob = _Problem(ds, kn, CAL, z_f, FREE, w, ar)
    sens = z_f_sensitivity(prob, opt[0.0], central_jacobian(prob.residual, opt[0.0]))[-2:]
    slope = (opt[h] - opt[-h])[-2:] / (2 * h)
    assert np.all(np.abs(slope) > 0.1)  # the case has a z_f term worth propagating
    np.testing.assert_allclose(sens, slope, rtol=0.35)
