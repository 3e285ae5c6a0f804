"""The measurement noise as white noise through a first-order low-pass (identify/detect/noiseread.py, stop 55;
read by noisespec since stop 57 retired the fourth-difference reader): drawn again as recorded, and the prior
keeps it (fit, file, no-change records); a prior file of the retired reader still loads."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import lfilter

from diagnose.recording import write_csv
from identify.detect import nullsim, priorfit
from identify.detect.api import fit_prior, simulated_recording
from identify.detect.inputs import signals
from identify.detect.noiseread import stationary_lowpass
from identify.detect.priorfit import white_noise_sd
from identify.detect.vessel import TABLE_4_1, Vessel
from identify.detect.yawmodel import NOMINAL, YawPrior
from primitives.errors import UserError

DT = 0.1


def test_stationary_lowpass_is_the_sensor_filter_started_in_its_steady_state():
    """The recursion e_k = a e_(k-1) + (1 - a) w_k to rounding (scipy's lfilter from the first sample),
    its first sample and its whole at the stationary sd sigma sqrt((1 - a) / (1 + a)); no filter, the draws."""
    a = math.exp(-DT / 0.3)
    w = np.random.default_rng(3).standard_normal((4000, 200))
    e = stationary_lowpass(w, 0.3, DT, axis=0)
    ref = lfilter([1 - a], [1, -a], w[1:], axis=0, zi=a * e[:1])[0]
    assert np.abs(ref - e[1:]).max() < 1e-12
    target = math.sqrt((1 - a) / (1 + a))
    assert abs(e.std() / target - 1) < 0.02
    # the first sample over 40000 columns: the sd's standard error is 0.35 %, so 2 % catches a start 4 % off
    first = stationary_lowpass(np.random.default_rng(4).standard_normal((3, 40000)), 0.3, DT, axis=0)[0]
    assert abs(first.std() / target - 1) < 0.02
    assert stationary_lowpass(w, 0.0, DT) is w


def test_the_bootstrap_s_noise_is_the_sensor_s():
    """priorfit._noise (the bootstrap refits' and the structural spread's draws): behind a 0.3 s corner the
    lag-1 autocorrelation is a = exp(-dt/tau) and the sd sigma sqrt((1 - a)/(1 + a)) (eq. N1); without a
    corner, main's white draws sd * N(0, 1), the same bits from the same generator."""
    prior = YawPrior("full", {}, 1.0, np.zeros((0, 0)), dt=DT, noise={"r": 2.0}, noise_tau={"r": 0.3})
    e = priorfit._noise(prior, "r", np.random.default_rng(0), (64, 5000))
    a = math.exp(-DT / 0.3)
    rho = np.mean(e[:, 1:] * e[:, :-1]) / np.mean(e * e)
    assert abs(rho - a) < 0.01 and abs(e.std() / (2.0 * math.sqrt((1 - a) / (1 + a))) - 1) < 0.01, (rho, e.std())
    white = replace(prior, noise_tau={})
    assert np.array_equal(
        priorfit._noise(white, "r", np.random.default_rng(0), (4, 50)), 2.0 * np.random.default_rng(0).standard_normal((4, 50))
    )


@pytest.fixture(scope="module")
def gyro_lowpassed(tmp_path_factory):
    """A product recording (measured moment) whose gyro's Table 4.1 noise went through a 0.3 s sensor
    low-pass (the noise alone: the same run without noise taken off, filtered, put back)."""
    noisy = simulated_recording(Vessel(), 400, seed=21, measured_moment=True)
    clean = simulated_recording(Vessel(), 400, seed=21, measured_moment=True, noise_scale=0.0)
    a = math.exp(-DT / 0.3)
    y = noisy.y.copy()
    y[:, 2] = clean.y[:, 2] + lfilter([1 - a], [1, -a], noisy.y[:, 2] - clean.y[:, 2])
    path = tmp_path_factory.mktemp("noiseread") / "nominal.csv"
    write_csv(replace(noisy, y=y), path)
    return path


@pytest.fixture(scope="module")
def spectral_prior(gyro_lowpassed):
    """(that recording, its prior fitted with ``noise_model="spectral"``)."""
    return gyro_lowpassed, fit_prior([gyro_lowpassed], "full", noise_model="spectral")


def test_the_spectral_prior_is_read_by_the_spectral_reader(gyro_lowpassed):
    """``fit_prior(..., noise_model="spectral")`` end to end (stop 56): the prior's noise is noisespec's reading of
    each sensed channel, exactly (the file /2, r behind a corner within 30 % of the 0.3 s and an sd within 25 % of
    Table 4.1's); stop 55's reader reads r otherwise here, so "spectral" sent to it fails this test."""
    from identify.detect.api import load_runs
    from identify.detect.noisespec import spectral_noise

    prior = fit_prior([gyro_lowpassed], "full", noise_model="spectral", bootstrap=0)
    assert prior.to_dict()["format"] == "shiptrial-yaw-prior/2", prior.to_dict()["format"]
    assert prior.to_dict()["noise_model"] == "spectral" and YawPrior.from_dict(prior.to_dict()).noise_model == "spectral"
    assert abs(prior.noise_tau["r"] / 0.3 - 1) < 0.30 and abs(prior.noise["r"] / TABLE_4_1["r"] - 1) < 0.25, prior
    sig, r = signals(load_runs([gyro_lowpassed])[0], prior.kind)
    for k, x in (sig | {"r": r}).items():
        sd, tau = spectral_noise(x, DT)
        assert prior.noise[k] == sd and prior.noise_tau.get(k, 0.0) == tau, (k, prior.noise, prior.noise_tau, sd, tau)


def test_the_prior_reads_a_low_passed_gyro_s_noise_and_keeps_it(spectral_prior):
    """With ``noise_model="spectral"`` (an option; the default stays the white reading) the prior's yaw-rate
    noise is the gyro's white sd (within 25 %) behind its 0.3 s corner (within 30 %), not the 0.19 of it the
    second difference sees (main before stop 55); the file keeps the corners, a file without them (written
    before) reads as white noise, and a negative corner is refused with the one-line "refit it" message."""
    _, prior = spectral_prior
    assert abs(prior.noise["r"] / TABLE_4_1["r"] - 1) < 0.25, prior.noise
    assert abs(prior.noise_tau["r"] / 0.3 - 1) < 0.30, prior.noise_tau
    back = YawPrior.from_dict(prior.to_dict())
    assert back.noise_tau == prior.noise_tau and back.noise == prior.noise
    old = prior.to_dict()
    del old["noise_tau"]
    assert YawPrior.from_dict(old).noise_tau == {}
    for tau in (-1.0, 1e9):  # negative, or beyond the corner noiseread can read (a > A_MAX)
        with pytest.raises(UserError, match="non-finite or non-physical values"):
            YawPrior.from_dict(prior.to_dict() | {"noise_tau": {"r": tau}})


def test_the_file_is_tagged_by_its_noise_model(spectral_prior):
    """A white prior's file is main's (format /1, no noise_tau key: byte for byte the file main writes); a
    low-pass one is /2, which main's reader refuses rather than draw its pre-filter sd as white noise."""
    _, prior = spectral_prior
    white = replace(prior, noise_tau={}).to_dict()
    assert white["format"] == "shiptrial-yaw-prior/1" and "noise_tau" not in white
    assert prior.to_dict()["format"] == "shiptrial-yaw-prior/2" and prior.to_dict()["noise_tau"] == prior.noise_tau
    assert prior.to_dict()["noise_model"] == "spectral" and "noise_model" not in white
    assert YawPrior.from_dict(white).noise_tau == {}
    with pytest.raises(UserError, match="not a yaw prior"):
        YawPrior.from_dict(white | {"format": "shiptrial-yaw-prior/3"})


def test_the_bootstrap_refits_see_the_sensor_s_noise(spectral_prior):
    """bootstrap_deviations: a white prior's noise gives the refits of no prior (each signal's white_noise_sd,
    main's path) bit for bit; a corner on r changes them."""
    path, prior = spectral_prior
    from identify.detect.api import load_runs

    sig, r = signals(load_runs([path])[0], prior.kind)
    x = np.array([prior.values[k] / NOMINAL[k] for k in prior.names])
    white = replace(prior, noise={k: white_noise_sd(v) for k, v in (sig | {"r": r}).items()}, noise_tau={})
    runs = [
        priorfit.bootstrap_deviations(prior.kind, sig, r, DT, x, 4, 3, prior=p)
        for p in (None, white, replace(white, noise_tau={"r": 0.3}))
    ]
    assert np.array_equal(runs[0], runs[1]) and not np.allclose(runs[1], runs[2]), runs


@pytest.mark.parametrize("path_kind", ["linear", "nonlinear"])
def test_the_no_change_records_carry_the_low_passed_noise(spectral_prior, path_kind):
    """The records' yaw-rate noise goes through the prior's corner, on the linear path (no ``derive``) and the
    nonlinear one (a ``derive`` without ``linear``): their second difference (the noise's: the prediction is
    smooth) is the filter's share of the white records' (0.19 behind 0.3 s at 10 Hz). One ``draws`` dict serves
    both calls, white first: the kept noise's key holds the corners, so the low-pass call is not served white."""
    path, prior = spectral_prior
    from identify.detect.api import load_runs

    rec = load_runs([path])[0]
    sig, r = signals(rec, prior.kind)
    only_r = {"r": 0.3}
    white = replace(prior, noise_tau={}, model_error=0.0)
    lp = replace(prior, noise_tau=only_r, model_error=0.0)
    derive = None if path_kind == "linear" else (lambda s, _r: s)
    draws: dict = {}
    d2 = [
        np.median(np.abs(np.diff(nullsim.null_records(p, sig, 8, seed=2, derive=derive, r0=float(r[0]), draws=draws), 2, axis=0)))
        for p in (white, lp)
    ]
    a = math.exp(-DT / 0.3)
    share = math.sqrt((6 - 8 * a + 2 * a * a) * (1 - a) / (1 + a) / 6)
    assert abs(d2[1] / d2[0] / share - 1) < 0.15, (d2, share)


def test_detect_prior_refuses_an_unknown_noise_model_before_reading_anything(tmp_path):
    """``--noise-model`` is checked with the other options: one line naming it and the choices; the API
    refuses it too before loading anything (the file named does not exist). "lowpass" (retired at stop 57) is
    refused in one line that names the two left."""
    from cli.options import validate_detect_prior_options

    with pytest.raises(UserError, match=r"^--noise-model 'pink': choose one of white, spectral$"):
        fit_prior([tmp_path / "missing.csv"], "full", noise_model="pink")

    with pytest.raises(UserError, match=r"^--noise-model 'pink': choose one of white, spectral$"):
        validate_detect_prior_options(out=tmp_path / "p.json", bootstrap=64, seed=0, noise_model="pink")
    for call in (
        lambda: fit_prior([tmp_path / "missing.csv"], "full", noise_model="lowpass"),
        lambda: validate_detect_prior_options(out=tmp_path / "p.json", bootstrap=64, seed=0, noise_model="lowpass"),
    ):
        with pytest.raises(UserError, match=r"^--noise-model 'lowpass': retired at stop 57 .*use spectral .* or white$"):
            call()
    validate_detect_prior_options(out=tmp_path / "p.json", bootstrap=64, seed=0, noise_model="spectral")


def test_a_prior_file_of_the_retired_lowpass_reader_still_loads(spectral_prior, tmp_path):
    """A /2 prior written by stop 55-56's ``--noise-model lowpass`` keeps its noise levels and corners when read
    (detect draws them as written), and tells its reader; a reader no version knows is refused in one line."""
    from identify.detect.api import load_prior

    _, prior = spectral_prior
    path = tmp_path / "lowpass.json"
    path.write_text(json.dumps(prior.to_dict() | {"noise_model": "lowpass"}))
    back = load_prior(path)
    assert back.noise_model == "lowpass" and back.noise == prior.noise and back.noise_tau == prior.noise_tau
    assert back.noise_tau, "the fixture's prior must hold a corner for this to test anything"
    path.write_text(json.dumps(prior.to_dict() | {"noise_model": "pink"}))
    with pytest.raises(UserError, match=r"lowpass.json: field noise_model 'pink' names no noise reader"):
        load_prior(path)


def test_the_refusal_of_an_unknown_noise_reader_names_the_real_path_and_no_retired_fix(tmp_path):
    """The one-line refusal gives the refit command with the prior's own path (not a placeholder) and offers only the
    readers ``detect-prior`` still fits (white, spectral), saying that lowpass files still load."""
    from identify.detect.api import load_prior
    from identify.detect.yawmodel import PARAMS

    names = PARAMS["full"]
    prior = YawPrior("full", {k: NOMINAL[k] for k in names}, 0.0025, 1e-6 * np.eye(len(names)), np.zeros(2), 0.001, 10, 0.1)
    path = tmp_path / "my-prior.json"
    path.write_text(json.dumps(replace(prior, noise_tau={"r": 0.3}, noise_model="pink").to_dict()))
    with pytest.raises(UserError) as e:
        load_prior(path)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: field noise_model 'pink' names no noise reader this version knows ")
    assert "(white, spectral; lowpass files of stops 55-56 still load)" in msg
    assert msg.endswith(f"refit it: shiptrial detect-prior NOMINAL.csv --out {path} --noise-model spectral")


def test_a_file_with_several_bad_fields_is_refused_naming_the_same_field_as_before():
    """YawPrior.from_dict reads values and cov before the other fields (as before stop 59 split it into _read and
    _check), so the refusal of a file without sigma and with no or a broken cov names the cov, not sigma."""
    d = {"format": "shiptrial-yaw-prior/1", "kind": "full", "values": dict.fromkeys(NOMINAL, 1.0), "ar": [0.5]}
    d |= {"sigma_w": 1.0, "block": 1, "dt": 0.1}
    with pytest.raises(UserError, match=r"\(field 'cov'\)"):
        YawPrior.from_dict(d)
    with pytest.raises(UserError, match=r"\(field cannot reshape array of size 2"):
        YawPrior.from_dict(d | {"cov": [1.0, 2.0]})
