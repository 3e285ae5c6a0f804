"""The stop-55 oracle (benchmarks/rollmass_oracle.py): on a noise-free truth recording it must recover the
recording's load, whatever that load is (a fit that returned the dataset's nominal load would fail the second)."""

import numpy as np
import pytest

from benchmarks import rollmass_oracle as ro

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")


@pytest.mark.parametrize("variant", ["base", "restoring"])
def test_oracle_recovers_noise_free_load(variant):
    lo = ro.loaded_recording(variant, "0.400kg-4", runs=2, length=0.2, quiet=True)
    assert lo.load == (0.4, -0.268)
    for f in ro.fit_runs(lo, np.arange(2)):
        assert f.converged
        assert abs(f.m / 0.4 - 1) < 1e-4 and abs(f.zm + 0.268) < 1e-5


def test_oracle_follows_a_changed_load():
    lo = ro.loaded_recording("base", "0.400kg-4", runs=2, length=0.2, quiet=True, load=(0.3, -0.2))
    for f in ro.fit_runs(lo, np.arange(2)):
        assert abs(f.m / 0.3 - 1) < 1e-4 and abs(f.zm + 0.2) < 1e-5
        assert abs(f.m - 0.4) > 0.05  # not the dataset's own load


def test_predict_is_the_truth_without_disturbance():
    """The oracle's model is basin_truth's: at the true load it reproduces a quiet recording to rounding."""
    lo = ro.loaded_recording("sway_roll", "0.200kg-2", runs=3, length=0.1, quiet=True)
    y = ro.predict(lo, np.arange(3), np.tile(np.array(lo.load), (3, 1)))
    assert np.abs(y - lo.rec).max() <= 1e-12 * np.abs(lo.rec).max()


def test_oracle_band_pass_recovers_noise_free_load():
    """The third, band-limited pass (a box frequency weighting) keeps the noise-free recording's load."""
    lo = ro.loaded_recording("base", "0.200kg-3", runs=1, length=0.3, quiet=True)
    (f,) = ro.fit_runs(lo, np.arange(1), band=(0.02, 0.5))
    assert f.converged and abs(f.m / 0.2 - 1) < 1e-4 and abs(f.zm + 0.256) < 1e-5
