"""The truth family's seeds and ``--cache`` file names (benchmarks/bench_detect_truth.py's helpers): the
stored studies of earlier stops are found by these names, so they are pinned here to the literal names the
benches wrote by hand before stop 59."""

from __future__ import annotations

from benchmarks.bench_detect_truth import (
    BATCH,
    batch_name,
    nominal_seed,
    prior_name,
    run_seeds,
    screen_name,
    stored_recording,
)

FP = "0b77fdf7a61a"


def test_seeds_are_the_ships_thousands():
    assert nominal_seed(102) == 102000
    assert run_seeds(102, 4) == [102001, 102002, 102003, 102004]
    assert run_seeds(7, 0) == []


def test_file_names_are_those_the_stored_studies_hold():
    assert BATCH == 10
    assert batch_name("nominal-mmg", 102) == "nominal-mmg-102-nominal"
    assert batch_name("strong-roll", 7, 10, 10) == "strong-roll-7-10-10"
    nominal = stored_recording("nominal-mmg", 102, FP)
    assert nominal == f"nominal-mmg-102-nominal-{FP}-0.csv"
    assert prior_name(nominal, "K1") == f"nominal-mmg-102-nominal-{FP}-0-prior-K1.pkl"
    # run i of a study with 10 unchanged and 10 changed runs: batch 10 * (i // 10), i % 10 within it
    assert stored_recording("nominal-mmg", 102, FP, 10, 3) == f"nominal-mmg-102-10-0-{FP}-3.csv"
    run13 = stored_recording("nominal-mmg", 102, FP, 10, 13)
    assert run13 == f"nominal-mmg-102-10-10-{FP}-3.csv"
    assert screen_name(run13, "K1") == f"nominal-mmg-102-10-10-{FP}-3-screen-K1.pkl"
    assert screen_name(run13, "K1", roll_band=True) == f"nominal-mmg-102-10-10-{FP}-3-screen-rb-K1.pkl"
    # the globs the benches that read a study use ("*" for the fingerprint)
    glob = screen_name(stored_recording("strong-roll", 7, "*", 10, 14), "K1")
    assert glob == "strong-roll-7-10-10-*-4-screen-K1.pkl"
    assert prior_name(stored_recording("strong-roll", 7, "*"), "K1") == "strong-roll-7-nominal-*-0-prior-K1.pkl"


def test_noise_read_finds_the_nominal_recordings_by_these_names(tmp_path):
    """benchmarks/detect_noise_read.py reads each ship's nominal recording of a --cache folder, found by
    ``stored_recording``'s names (any truth fingerprint), not the runs, priors, screenings or other files beside
    it; the variant is the truth family's (``steering-lag-acting`` is not ``steering-lag``'s ship 'acting')."""
    from benchmarks.detect_noise_read import nominal_recordings

    nominal = [("steering-lag", 7, FP), ("steering-lag-acting", 7, FP), ("nominal-mmg", 102, "abc123def456")]
    names = [stored_recording(v, s, fp) for v, s, fp in nominal]
    beside = [
        stored_recording("nominal-mmg", 102, FP, 10, 3),  # a run of a study
        prior_name(names[0], "K1"),
        screen_name(names[1], "K1"),
        "not-a-variant-7-nominal-" + FP + "-0.csv",
        "nominal-mmg-x-nominal-" + FP + "-0.csv",
        f"nominal-mmg-102-nominal-{FP}-1.csv",  # a nominal batch's second recording: none is stored
    ]
    for n in names + beside:
        (tmp_path / n).write_text("")
    found = nominal_recordings(tmp_path)
    assert found == sorted(((v, tmp_path / n) for (v, _, _), n in zip(nominal, names)), key=lambda vp: vp[1].name)
