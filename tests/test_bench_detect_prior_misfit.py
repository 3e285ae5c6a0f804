"""Stop 54's diagnostic (benchmarks/detect_prior_misfit.py): the candidate-term columns and the shares."""

from __future__ import annotations

import numpy as np

from benchmarks.detect_prior_misfit import (
    TERMS,
    Columns,
    band_pass,
    readings,
    sensitivity_columns,
    shares,
)
from identify.detect.yawmodel import NOMINAL, PARAMS, YawPrior, block_mean, simulate_r

DT = 0.1


def _prior() -> YawPrior:
    names = PARAMS["full-p"]
    return YawPrior("full-p", {k: NOMINAL[k] for k in names}, 1e-3, np.zeros((len(names), len(names))), dt=DT)


def _inputs(n: int = 3000, seed: int = 0) -> dict[str, np.ndarray]:
    t = np.arange(n) * DT
    rng = np.random.default_rng(seed)
    ph = rng.uniform(0, 2 * np.pi, 6)
    v = 0.3 * np.sin(2 * np.pi * t / 60 + ph[0])
    phi = 0.05 * np.sin(2 * np.pi * t / 8 + ph[1])
    return {
        "u": 5.0 + 0.5 * np.sin(2 * np.pi * t / 200 + ph[2]),
        "v": v,
        "v_dot": np.gradient(v, DT),
        "phi": phi,
        "p": np.gradient(phi, DT),
        "tau_r": 2e5 * np.sin(2 * np.pi * t / 40 + ph[3]) + 1e5 * np.sin(2 * np.pi * t / 17 + ph[4]),
    }


def _extra(prior: YawPrior, w: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    r = simulate_r(prior.kind, prior.values, w, DT)
    return {"r": r, "a": w["tau_r"] / 1e7, "n": 60.0 + 0 * r}


def test_a_term_added_to_the_yaw_row_is_its_sensitivity_column():
    """r of the row with ``tau_r + c g`` less the prior's r_hat is c times the term's column (the model is
    linear in the moment but for r|r|: to 1 % at this size); the other columns are not that residual."""
    prior, w = _prior(), _inputs()
    extra = _extra(prior, w)
    G, names = sensitivity_columns(prior, w, extra, 0.0)
    j = names.index("v|v|")
    g = TERMS["v|v|"](w | extra, DT)
    g = (g - g.mean()) / g.std() * np.std(w["tau_r"])
    c = 0.01
    e = simulate_r(prior.kind, prior.values, w | {"tau_r": w["tau_r"] + c * g}, DT) - simulate_r(prior.kind, prior.values, w, DT)
    assert np.abs(e - c * G[:, j]).max() < 0.01 * np.abs(e).max()
    k = names.index("phi^3")
    assert abs(np.corrcoef(e, G[:, k])[0, 1]) < 0.9


def test_shares_find_a_missing_term_out_of_sample_and_not_noise():
    """A residual that is one candidate's column (plus a little noise) on the nominal and on a run: that
    candidate explains nearly all of it on the run with the nominal's coefficient, beyond the prior's own
    sensitivities; a candidate that is not in it explains next to nothing; on a run whose residual is noise
    the nominal's term only adds its own variance (a negative share: out of sample a term can cost)."""
    rng = np.random.default_rng(3)
    nb = 300
    cols = []
    for _ in range(2):  # a nominal and a run
        J = rng.standard_normal((nb, 3))
        G = rng.standard_normal((nb, 2))
        e = 2.0 * G[:, 0] + 0.1 * rng.standard_normal(nb)
        cols.append(Columns(e, J, G, ("a", "b"), rng.standard_normal((nb, 4)), (0.0, 0.5)))
    nom, run = cols
    assert shares(nom, run, [0], band=False) > 0.95
    assert abs(shares(nom, run, [1], band=False)) < 0.05
    noise = Columns(rng.standard_normal(nb), run.J, run.G, run.names, run.noise, run.band)
    assert shares(nom, noise, [0], band=False) < -1.0


def test_band_pass_keeps_the_band_only():
    t = np.arange(500)  # whole cycles: no leakage between bins
    inside = np.sin(2 * np.pi * 0.05 * t)
    outside = np.sin(2 * np.pi * 0.3 * t)
    y = band_pass(inside + outside + 1.0, (0.02, 0.1))
    assert np.abs(y - inside).max() < 0.05
    assert block_mean(np.ones(20), 10).shape == (2,)


def test_readings_are_the_change_along_each_signature():
    """A residual that is 2 % of the inertia signature (plus AR-coloured noise the prior's filter whitens) reads
    +2 % along yaw inertia, to 0.1 %."""
    rng = np.random.default_rng(5)
    nb = 500
    t = np.arange(nb)
    S = np.column_stack([np.sin(2 * np.pi * t / 40), np.sin(2 * np.pi * t / 90 + 1), np.cos(2 * np.pi * t / 25)])
    ar = np.array([0.5])
    w = 1e-4 * rng.standard_normal(nb)
    noise = np.empty(nb)
    noise[0] = w[0]
    for k in range(1, nb):
        noise[k] = 0.5 * noise[k - 1] + w[k]
    c = Columns(0.02 * S[:, 0] + noise, np.zeros((nb, 1)), np.zeros((nb, 1)), ("x",), np.zeros((nb, 1)), (0.0, 0.5), S, ar)
    assert abs(readings(c)[0] - 0.02) < 1e-3


def test_more_runs_than_the_stored_studies_unchanged_ones_are_refused_in_one_line():
    """Run 10 on of a stored study is a changed run: ``--runs 11`` would read it as an unchanged one (0e42d15 asked for
    a file that does not exist and ended in a traceback)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    for runs in ("11", "0"):
        cmd = [sys.executable, "benchmarks/detect_prior_misfit.py", "--cache", "/nonexistent:K:1:1", "--runs", runs]
        out = subprocess.run(cmd, cwd=root, capture_output=True, text=True, timeout=120, env=env)
        assert out.returncode == 2 and "Traceback" not in out.stderr
        assert (
            out.stderr.strip()
            .splitlines()[-1]
            .endswith(f"--runs {runs}: give 1 to 10 (the stored studies' unchanged runs per ship)")
        )


def test_a_cache_folder_spec_or_file_missing_is_refused_in_one_line_before_any_simulation(tmp_path, capsys):
    """``--cache`` on a missing folder (or a malformed spec, or a folder without the stored prior) ended in a
    traceback (FileNotFoundError, ValueError) at stop 59; each is now one line naming the spec and the file
    (bench_detect_truth's own names), exit 2."""
    import pytest

    from benchmarks.bench_detect_truth import prior_name, stored_recording
    from benchmarks.detect_prior_misfit import TRUTH_FP, main

    prior = tmp_path / prior_name(stored_recording("strong-roll", 7, TRUTH_FP), "K")
    cases = [
        (["--cache", f"{tmp_path}/none:K:1:1"], f"{tmp_path}/none: no such folder"),
        (["--cache", f"{tmp_path}:K"], "expected DIR:KEY:FIRSTSHIP:NSHIPS"),
        (["--cache", f"{tmp_path}:K:7:1", "--variants", "strong-roll"], f"{prior} is missing"),
        ([], "--cache: give at least one"),
        (["--load", f"{tmp_path}/none.pkl"], f"--load {tmp_path}/none.pkl: no such file"),
    ]
    for argv, said in cases:
        with pytest.raises(SystemExit) as stop:
            main(argv)
        err = capsys.readouterr().err
        assert stop.value.code == 2 and said in err.strip().splitlines()[-1] and "Traceback" not in err


def test_study_refuses_a_malformed_cache_spec_rather_than_reading_no_ship(tmp_path):
    """study() called without main's checks: a spec that is not DIR:KEY:FIRSTSHIP:NSHIPS raises, naming it, rather
    than giving an empty table (review of stop 60: it was read as zero ships)."""
    import pytest

    from benchmarks.detect_prior_misfit import study

    with pytest.raises(ValueError, match=f"--cache {tmp_path}:K: expected DIR:KEY:FIRSTSHIP:NSHIPS"):
        study([f"{tmp_path}:K"], ("strong-roll",), 1)
