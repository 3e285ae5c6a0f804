"""The kernel's ``positions=False`` mode (issue 14): callers that read only the velocities skip the
position rows of the time loop; the velocities must be bit-identical to a full simulation."""

import numpy as np
import pytest

from primitives.ship import load_profile
from primitives.simulate import Disturbances, simulate


def _inputs(profile, n, batch, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = np.array([profile.input_limits[k] for k in profile.inputs]).T
    return rng.uniform(0.2 * lo, 0.2 * hi, (batch, n, len(profile.inputs)))


@pytest.mark.parametrize("name", ["model-ship", "full-scale", "naval-vessel"])
@pytest.mark.parametrize("current", [False, True])
def test_velocities_identical_without_positions(name, current):
    p = load_profile(name)
    dist = Disturbances(current_ne=(0.1, -0.05), current_sample_std=0.05) if current else None
    nu0 = np.tile(np.r_[p.cruise_speed_mps, 0.0, 0.0, np.zeros(p.n_dof - 3)], (4, 1))
    kw = dict(nu0=nu0, disturbances=dist, batch=4, seed=3)
    full = simulate(p, _inputs(p, 200, 4), **kw)
    fast = simulate(p, _inputs(p, 200, 4), positions=False, **kw)
    assert np.array_equal(full.nu, fast.nu) and np.isfinite(full.nu).all()
    # positions are not integrated: NaN, never a silent zero
    assert np.isnan(fast.eta[:, 1:, :2]).all() and np.isnan(fast.pos_meas[:, 1:]).all()
    if current or p.n_dof == 4 or p.pods:  # the dynamics read the heading: it is integrated as in a full run
        assert np.array_equal(full.eta[..., 2:], fast.eta[..., 2:])
    else:
        assert np.isnan(fast.eta[:, 1:, 2]).all()


def test_positions_mode_keeps_the_heading_a_term_reads():
    from primitives.terms import TermSet

    p = load_profile("model-ship")
    terms = TermSet([list(p.model.terms[0]), list(p.model.terms[1]) + ["psi"], list(p.model.terms[2])])
    theta = np.r_[p.params(p.simulation_set)[:7], 1e-3, p.params(p.simulation_set)[7:]]
    inp = _inputs(p, 100, 2)
    full = simulate(p, inp, theta, terms=terms, nu0=(1.0, 0.0, 0.0), batch=2)
    fast = simulate(p, inp, theta, terms=terms, nu0=(1.0, 0.0, 0.0), batch=2, positions=False)
    assert np.array_equal(full.nu, fast.nu) and np.array_equal(full.eta[..., 2], fast.eta[..., 2])
