"""The kernel in calm water fills no array with a constant: without measurement noise the measured
velocities are the true ones (a read-only view, not a copy), and a current or wind without a
random part is a read-only broadcast of its mean, not a (B, N, 2) copy. The numbers are those of
the materialised arrays, bit for bit."""

import numpy as np
import pytest

from primitives.ship import load_profile
from primitives.simulate import Disturbances, simulate


@pytest.fixture(scope="module")
def ship():
    return load_profile("model-ship")


def _inputs(profile, n, batch, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = np.array([profile.input_limits[k] for k in profile.inputs]).T
    return rng.uniform(0.2 * lo, 0.2 * hi, (batch, n, len(profile.inputs)))


def test_calm_water_result_is_not_copied(ship):
    res = simulate(ship, _inputs(ship, 300, 8), nu0=(1.0, 0.0, 0.0), batch=8)
    assert np.shares_memory(res.y, res.nu) and np.array_equal(res.y, res.nu)
    with pytest.raises(ValueError):  # a write through the second name would change nu
        res.y[0, 0, 0] = 1.0
    for env in (res.current_ne, res.wind_ne):
        assert env.shape == (8, 300, 2) and not any(env.strides[:2]) and not np.any(env)


def test_mean_current_and_wind_without_noise_are_broadcasts(ship):
    dist = Disturbances(current_ne=(0.1, -0.05), wind_ne=(3.0, 1.0))
    res = simulate(ship, _inputs(ship, 200, 4), nu0=(1.0, 0.0, 0.0), disturbances=dist, batch=4)
    assert not any(res.current_ne.strides[:2]) and np.all(res.current_ne == (0.1, -0.05))
    assert not any(res.wind_ne.strides[:2]) and np.all(res.wind_ne == (3.0, 1.0))


@pytest.mark.parametrize("current", [(0.0, 0.0), (0.1, -0.05)])
def test_broadcast_environment_gives_the_numbers_of_a_full_array(ship, current):
    """The same trajectory, bit for bit, whether the current is a pair or a full (B, N, 2) array."""
    inp, b = _inputs(ship, 250, 3), 3
    full = np.array(np.broadcast_to(current, (b, 250, 2)))
    a = simulate(ship, inp, nu0=(1.0, 0.0, 0.0), batch=b, disturbances=Disturbances(current_ne=current))
    c = simulate(ship, inp, nu0=(1.0, 0.0, 0.0), batch=b, disturbances=Disturbances(current_ne=full))
    assert np.array_equal(a.nu, c.nu) and np.array_equal(a.eta, c.eta) and np.isfinite(a.nu).all()


def test_current_that_starts_at_zero_is_not_still_water(ship):
    """A current given per sample, zero at the first sample only, moves the ship (the still-water
    shortcut must look at every sample of an array that is not one constant)."""
    inp = _inputs(ship, 250, 2)
    cur = np.zeros((250, 2))
    cur[1:] = (0.2, 0.1)
    calm = simulate(ship, inp, nu0=(1.0, 0.0, 0.0), batch=2)
    moved = simulate(ship, inp, nu0=(1.0, 0.0, 0.0), batch=2, disturbances=Disturbances(current_ne=cur))
    assert not np.allclose(calm.nu, moved.nu)


def test_noisy_measurements_are_their_own_array(ship):
    dist = Disturbances(measurement_std=(0.01, 0.01, 0.001))
    res = simulate(ship, _inputs(ship, 100, 2), nu0=(1.0, 0.0, 0.0), disturbances=dist, batch=2, seed=1)
    assert not np.shares_memory(res.y, res.nu) and res.y.flags.writeable
