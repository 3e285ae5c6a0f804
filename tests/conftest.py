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


@pytest.fixture(scope="session")
def detect_screening(tmp_path_factory):
    """(prior, recording, screening): a full-model prior fitted on a 400 s simulated nominal run (16
    bootstrap refits) and an unchanged 300 s run screened against it with 200 no-change records; read,
    never changed, by the detector's calibration tests."""
    from diagnose.recording import write_csv
    from identify.detect.api import fit_prior, hull_inertia, screen, simulated_recording
    from identify.detect.vessel import Vessel

    path = tmp_path_factory.mktemp("detect") / "nominal.csv"
    write_csv(simulated_recording(Vessel(), 400, seed=31, measured_moment=True), path)
    prior = fit_prior([path], "full", bootstrap=16)
    rec = simulated_recording(Vessel(), 300, seed=32, measured_moment=True)
    hull = dict(zip(("i_z", "n_rdot"), hull_inertia("naval-vessel")))
    return prior, rec, screen(rec, prior, null_runs=200, **hull)
