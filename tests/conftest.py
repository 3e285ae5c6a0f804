"""Fixtures shared by several test modules (each computed once per session)."""

import pytest


@pytest.fixture(scope="session")
def damping_diagnosis():
    """(scenario, diagnosis): the model-ship's quadratic yaw damping case diagnosed with its
    validation run; read (never changed) by the held-out and report-reading tests."""
    from diagnose.api import run
    from diagnose.battery import scenario
    from primitives.ship import load_profile

    sc = scenario(("quadratic_damping",), 41)
    return sc, run(sc.diagnose, load_profile("model-ship"), validate=sc.validate)


@pytest.fixture(scope="module")
def kvlcc2():
    """The bundled kvlcc2 profile, loaded once per test module (module scope: a test may edit it)."""
    from primitives.ship import load_profile

    return load_profile("kvlcc2")
