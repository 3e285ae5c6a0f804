"""Fixtures shared by several test modules (each computed once per session)."""

import pytest


@pytest.fixture(autouse=True, scope="session")
def _no_user_caches():
    """No test reads or writes the user's plan cache (maps.plancache) or detect's noise cache
    (identify.detect.noisecache; its own variable too, which a user may have set and which would
    otherwise win over the planner's): an entry read from either would skip the code the test
    exercises. Session scope: set before any module or session fixture runs a command. The caches'
    own tests set a directory of their own."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SHIPTRIAL_CACHE_DIR", "")
        mp.setenv("SHIPTRIAL_DETECT_CACHE_DIR", "")
        yield


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
