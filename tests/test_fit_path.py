"""identify.rollmass.fit_path.Counted (stop 61): the counting wrapper behaves as the problem it wraps under
``copy.copy``, ``copy.deepcopy``, pickling and attribute writes (its ``__getattr__`` proxy had recursed without end
when a copy looked up ``__setstate__`` before ``_prob`` was set)."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from identify.rollmass import output_error as oe
from identify.rollmass.fit_path import Counted, PathTally
from identify.rollmass.model import Load, load_profile
from identify.rollmass.simulate import Noise, simulate_case

PROF = load_profile()


@pytest.fixture(scope="module")
def problem() -> tuple[oe._Problem, np.ndarray]:
    datasets = simulate_case(PROF, "case2", Noise.from_profile(PROF, 0.05), seed=3, length_factor=0.3)
    kn = PROF.known
    free = oe.SHARED + ("m", "zbar_m")
    w = np.array([1.0 / oe._measured(d).std(axis=0) for d in datasets])
    start = oe.start_values(PROF)
    x = np.array([start[k] for k in oe.SHARED] + [0.4, -0.268])
    return oe._Problem(datasets, kn, Load(0.2, -0.256), kn.z_f_prior, free, w), x


def test_a_copy_is_a_problem_of_its_own_counted_in_the_same_tally(problem):
    """``copy.copy`` of a counted problem is a counted shallow copy of the problem: an attribute set on the copy
    (the coverage bench's other datasets) changes the copy's residual and not the original's, and the copy's
    evaluations add to the original's tally (the path's cost)."""
    prob, x = problem
    tally = PathTally()
    counted = Counted(prob, tally)
    q = copy.copy(counted)
    assert isinstance(q, Counted) and q.free == prob.free
    np.testing.assert_array_equal(q.residual(x), prob.residual(x))
    q.datasets = counted.datasets[:2]  # the first two datasets only: a shorter residual
    q.Y = [oe._measured(d, q.kn.g) for d in q.datasets]
    assert len(q.residual(x)) < len(counted.residual(x)) == len(prob.residual(x))
    assert prob.datasets is counted.datasets and len(prob.datasets) == 3  # the original untouched
    q.jacobian(x)
    assert (tally.residuals, tally.jacobians) == (3, 1)


def test_a_deep_copy_and_a_pickle_are_independent_problems_with_the_counts_so_far(problem):
    """``copy.deepcopy`` and a pickle round trip copy the problem and the tally: the copy's evaluations are counted in
    its own tally, which starts from the original's counts."""
    prob, x = problem
    tally = PathTally(residuals=5)
    counted = Counted(prob, tally)
    for q in (copy.deepcopy(counted), pickle.loads(pickle.dumps(counted))):
        np.testing.assert_array_equal(q.residual(x), prob.residual(x))
        assert q._tally.residuals == 6 and tally.residuals == 5
