"""expdesign.runseeds makes each Monte Carlo run's generator as numpy's
default_rng(SeedSequence(seed, spawn_key=(run, stream))) makes it: the same seed words, the same
state and the same draws, for seeds of one to several 32-bit words and runs up to 2**32 - 1 (numpy's
own beyond)."""

from __future__ import annotations

import numpy as np
import pytest

from expdesign import runseeds

SEEDS = [0, 1, 3, 2**31, 2**32 - 1, 2**32, 2**40 + 5, 2**64 + 7, 2**128 + 3, 2**200 + 11]
RUNS = np.array([0, 1, 7, 249, 1999, 65_536, 2**31, 2**32 - 1])


def _numpy(seed, run, stream):
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(run), stream)))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("stream", [0, 1, 5, 2**32 - 1])
def test_the_seed_words_are_numpys(seed, stream):
    expected = [np.random.SeedSequence(seed, spawn_key=(int(r), stream)).generate_state(4, np.uint64) for r in RUNS]
    np.testing.assert_array_equal(runseeds.state_words(seed, RUNS, stream), np.stack(expected))


@pytest.mark.parametrize("seed,stream", [(0, 1), (3, 0), (2**64 + 7, 1)])
def test_the_generators_draw_numpys_numbers(seed, stream):
    runs = [5, 0, 1999, 2**32 - 1, 2**32, 2**40]  # the last two: numpy's own generators
    for g, r in zip(runseeds.run_rngs(seed, runs, stream), runs):
        ref = _numpy(seed, r, stream)
        assert g.bit_generator.state == ref.bit_generator.state
        np.testing.assert_array_equal(g.standard_normal(50), ref.standard_normal(50))
        np.testing.assert_array_equal(g.integers(0, 11, 5), ref.integers(0, 11, 5))
    assert runseeds.run_rngs(seed, [], stream) == []


def test_a_negative_seed_is_refused_as_numpy_refuses_it():
    with pytest.raises(ValueError):
        runseeds.run_rngs(-1, [0, 1], 1)
