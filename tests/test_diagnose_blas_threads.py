"""The diagnosis runs BLAS on one thread (diagnose.api.run): on a shared machine the refits' tall
Jacobian products spent up to 60 times their CPU on two threads, the second one spinning. The
thread count changes only the rounding of those products: the estimates stay within 1e-10
relative of a diagnosis on two threads (measured on the 13-run model test: 1.5e-12 in the
parameters, 4e-15 in the findings' figures; same findings)."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from diagnose import api
from diagnose.battery import scenario
from primitives.ship import load_profile


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_diagnosis_runs_blas_on_one_thread_with_the_same_estimates(monkeypatch):
    if not _blas_threads():
        pytest.skip("threadpoolctl finds no BLAS library in this process: there is no thread count to limit")
    ship = load_profile("model-ship")
    rec = scenario(("current", "actuator_delay"), 7, n_prims=9).diagnose[0].window(0, 801)
    seen = []
    with monkeypatch.context() as m:  # the thread count the diagnosis itself runs with
        m.setattr(api, "locate", lambda *a, f=api.locate, **k: seen.append(_blas_threads()) or f(*a, **k))
        one = api.run([rec], ship)
    assert seen and seen[0] and all(n == 1 for n in seen[0])
    with threadpool_limits(2, user_api="blas"):  # the undecorated diagnosis, on two threads
        two = api.run.__wrapped__([rec], ship)
    assert [f["effect"] for f in one.findings] == [f["effect"] for f in two.findings]
    np.testing.assert_allclose(one.P, two.P, rtol=1e-10, atol=0.0)
    for dof, v in two.fit_after.items():
        assert abs(one.fit_after[dof] - v) <= 1e-10 * abs(v)
