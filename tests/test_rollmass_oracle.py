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
    """Off the start grid (0.31 kg, -0.213 m: neither on GRID_M nor GRID_Z), so LM must carry the grid's best
    point to the load; fails with the LM step's sign flipped (checked at stop 55's mend)."""
    lo = ro.loaded_recording("base", "0.400kg-4", runs=2, length=0.2, quiet=True, load=(0.31, -0.213))
    assert np.abs(ro.GRID_M - 0.31).min() > 0.005 and np.abs(ro.GRID_Z + 0.213).min() > 0.005
    for f in ro.fit_runs(lo, np.arange(2)):
        assert f.converged
        assert abs(f.m / 0.31 - 1) < 1e-4 and abs(f.zm + 0.213) < 1e-5
        assert abs(f.m - 0.4) > 0.05  # not the dataset's own load


def test_oracle_removes_channel_offsets():
    """A constant per channel (1 deg/s on p and r, 0.02 m/s^2 on a_s, 0.5 deg on phi: sensor biases) added to a
    noise-free recording must leave the load: the offsets are projected out (_center), not fitted as load."""
    lo = ro.loaded_recording("base", "0.400kg-4", runs=2, length=0.2, quiet=True, load=(0.31, -0.213))
    bias = np.array([np.deg2rad(1.0), 0.02, np.deg2rad(1.0), np.deg2rad(0.5)])
    lo.rec = lo.rec + bias[None, :, None]
    for f in ro.fit_runs(lo, np.arange(2)):
        assert f.converged
        assert abs(f.m / 0.31 - 1) < 1e-4 and abs(f.zm + 0.213) < 1e-5


def test_parts_add_up_to_the_recording():
    """--parts splits the recording with the same draws: sea + sensor - the noise-free truth = the recording
    (guards basin_truth.simulate_parts against simulate's step order changing)."""
    kw = dict(runs=2, length=0.1)
    rec = ro.loaded_recording("base", "0.200kg-3", **kw)
    sea = ro.loaded_recording("base", "0.200kg-3", parts="sea", **kw).rec
    sensor = ro.loaded_recording("base", "0.200kg-3", parts="sensor", **kw).rec
    clean = ro.predict(rec, np.arange(2), np.tile(np.array(rec.load), (2, 1)))
    assert np.abs(sea - clean).max() > 0 and np.abs(sensor - clean).max() > 0  # both parts carry something
    assert np.abs(sea + sensor - clean - rec.rec).max() <= 1e-12 * np.abs(rec.rec).max()


def test_misspelt_option_is_refused():
    with pytest.raises(TypeError):
        ro.loaded_recording("base", "0.400kg-4", runs=2, lenght=0.2)


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
