"""The oe fit's band-limited objective (identify/rollmass/band.py, stop 61; an experiment, not the default): the
filter is the project's forward-backward Butterworth in steady state, the Jacobian stays the filtered residual's
exact derivative, a noise-free recording's load is recovered through the band, and with no band the fit never
touches the filter."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from identify.rollmass import band as band_mod
from identify.rollmass import output_error as oe
from identify.rollmass.band import Band, parse_band
from identify.rollmass.estimate import estimate
from identify.rollmass.model import Load, load_profile
from identify.rollmass.output_error import start_values
from identify.rollmass.restoring import heel_gain
from identify.rollmass.sandwich import central_jacobian
from identify.rollmass.simulate import Noise, simulate_case
from primitives.iir import butter, filtfilt

PROF = load_profile()
CAL = Load(0.2, -0.256)
ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("spec", ["lowpass:0.7", "bandstop:0.8-1.7", "bandpass:0.2-0.5"])
def test_the_gain_is_the_butterworth_designs_squared(spec):
    """The closed-form |H|^2 against scipy's design of the same Butterworth in second-order sections (well
    conditioned, unlike the direct form: 4e-4 off on the band-pass), to 1e-9."""
    import scipy.signal as ss

    b, T, N = parse_band(spec), 0.02, 4096
    sos = ss.butter(b.order, b.freqs[0] if b.kind == "lowpass" else b.freqs, b.kind, fs=1 / T, output="sos")
    f = np.fft.rfftfreq(N, T)[:-1]
    _, h = ss.sosfreqz(sos, worN=f, fs=1 / T)
    assert np.abs(band_mod._gain(b, N, T)[:-1] - np.abs(h) ** 2).max() < 1e-9


@pytest.mark.parametrize("spec", ["lowpass:0.7", "bandstop:0.8-1.7"])
def test_the_band_is_the_forward_backward_butterworth_away_from_the_ends(spec):
    """Band.apply against primitives.iir.filtfilt of the same design: equal to 1e-6 of the signal's peak once the
    ends' transients (the two pads differ there) have decayed, and zero-phase (a sine in the pass band keeps its phase)."""
    b = parse_band(spec)
    T, n = 0.02, 12000
    x = np.random.default_rng(1).standard_normal((n, 2))
    ba = butter(b.order, b.freqs[0] if b.kind == "lowpass" else b.freqs, b.kind, fs=1 / T)
    ref = filtfilt(*ba, x, axis=0)
    got = b.apply(x, T)
    inner = slice(4000, n - 4000)  # 80 s from the ends: the slowest pole's transient (bandpass) has decayed
    assert np.abs(got[inner] - ref[inner]).max() < 1e-6 * np.abs(x).max()
    t = np.arange(n) * T
    f = 0.3 if b.kind != "bandstop" else 3.0
    s = np.sin(2 * np.pi * f * t)
    assert np.abs(b.apply(s, T)[inner] - s[inner]).max() < 0.05  # passed, in phase


def test_a_band_is_refused_in_one_line_naming_the_forms():
    for bad in ("lowpass", "lowpass:0.5-0.7", "bandstop:1.7-0.8", "notch:0.8-1.7", "bandpass:a-b", "lowpass:-1"):
        with pytest.raises(ValueError, match="lowpass:F, bandpass:LO-HI or bandstop:LO-HI"):
            parse_band(bad)
    assert parse_band("bandstop:0.80-1.7").label() == "bandstop:0.8-1.7"


@pytest.mark.parametrize("spec", ["lowpass:0.7", "bandstop:0.8-1.7"])
def test_the_jacobian_is_the_band_limited_residuals_derivative(spec):
    """Every column against central differences of the whole band-limited residual (whitened, weighted, projected,
    prior rows): within 1e-5 of the column, as tests/test_rollmass_oe_jacobian.py holds the full band's. The
    sandwich takes this residual and Jacobian, so its scores are the filtered ones. Fails if the band is left out
    of the Jacobian's basis or columns (checked: 0.3-1.0 off)."""
    ds = simulate_case(PROF, "case2", Noise.from_profile(PROF), seed=3, length_factor=0.3)
    kn = PROF.known
    free = oe.SHARED + ("kappa", "z_f", "m", "zbar_m")
    w = np.array([1.0 / oe._measured(d).std(axis=0) for d in ds])
    v = {**start_values(PROF), "K_v": 0.1, "n_p": 0.01, "e_y": 0.01, "t_imu": 0.003}
    x = np.array([v[k] for k in oe.SHARED] + [1.2 * heel_gain(kn), kn.z_f_prior, 0.4, -0.268])
    rng = np.random.default_rng(0)
    ar = [[np.r_[1.0, 0.1 * rng.standard_normal(12)] for _ in range(3)] for _ in ds]
    prob = oe._Problem(ds, kn, CAL, kn.z_f_prior, free, w, ar, kn.z_f_prior_sd, band=parse_band(spec))
    J, ref = prob.jacobian(x), central_jacobian(prob.residual, x)
    err = np.linalg.norm(J - ref, axis=0) / np.linalg.norm(ref, axis=0)
    assert np.all(err < 1e-5), dict(zip(prob.free, err))
    full = oe._Problem(ds, kn, CAL, kn.z_f_prior, free, w, ar, kn.z_f_prior_sd)
    assert not np.allclose(prob.residual(x), full.residual(x))  # the band does cut the residual


def test_a_noise_free_recording_gives_its_load_through_the_band():
    """The estimator's own simulator, waves and IMU noise off: the 0.7 Hz low-pass fit reads the load within the
    oe tests' 0.03 kg and 30 mm (tests/test_rollmass.py) and converges, with a finite interval holding it."""
    prof = load_profile()
    for k in ("wave_roll_sd", "wave_sway_sd", "wave_yaw_sd"):
        prof.raw["experiment"][k] = 0.0
    ds = simulate_case(prof, "case1", Noise.from_profile(prof, 0.0), seed=7, length_factor=0.3)
    e = estimate(ds, prof.known, CAL, "oe", with_ci=True, start=start_values(prof), band=parse_band("lowpass:0.7"))
    assert e.converged
    assert abs(e.m - 0.2) < 0.03 and abs(e.zbar_m + 0.256) < 0.03, (e.m, e.zbar_m)
    assert np.isfinite(e.m_sd) and e.m_sd > 0


def test_without_a_band_the_fit_never_touches_the_filter(monkeypatch):
    """band None (the default): main's fit; the filter is never called (its apply raises here) and the answer is
    the default call's, bit for bit."""
    ds = simulate_case(PROF, "case2", Noise.from_profile(PROF, 0.05), seed=3, length_factor=0.3)
    ref = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=start_values(PROF))

    def boom(self: Band, x: np.ndarray, T: float) -> np.ndarray:
        raise AssertionError("the band filter ran without a band")

    monkeypatch.setattr(band_mod.Band, "apply", boom)
    got = estimate(ds, PROF.known, CAL, "oe", with_ci=True, start=start_values(PROF), band=None)
    assert (got.m, got.zbar_m, got.m_sd, got.zbar_m_sd) == (ref.m, ref.zbar_m, ref.m_sd, ref.zbar_m_sd)


def test_the_bench_records_the_band_and_the_table_refuses_to_pool_it(tmp_path):
    """bench_rollmass_truth --band: its rows' settings name the band (a full-band run's do not: its settings stay
    the earlier dumps'), and rollmass_family_table refuses a band dump pooled with a full-band one, in one line."""
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    bench = [sys.executable, str(ROOT / "benchmarks/bench_rollmass_truth.py"), "--runs", "1", "--variants", "base"]
    bench += ["--workers", "1"]
    dumps = {}
    for name, extra in (("band", ["--band", "lowpass:0.70", "--cases", "case2"]), ("full", ["--cases", "case3"])):
        dumps[name] = tmp_path / f"{name}.jsonl"
        subprocess.run(bench + extra + ["--dump", str(dumps[name])], env=env, check=True, capture_output=True, cwd=ROOT)
    row = json.loads(dumps["band"].read_text().splitlines()[0])
    assert row[7]["family"]["band"] == "lowpass:0.7" and "band" not in json.loads(dumps["full"].read_text())[7]["family"]
    table = [sys.executable, str(ROOT / "benchmarks/rollmass_family_table.py"), str(dumps["full"]), str(dumps["band"])]
    out = subprocess.run(table, env=env, capture_output=True, text=True, cwd=ROOT)
    assert out.returncode != 0 and "family settings" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    bad = subprocess.run(
        bench + ["--band", "lowpass", "--dump", str(tmp_path / "x.jsonl")], env=env, capture_output=True, text=True, cwd=ROOT
    )
    assert bad.returncode == 2 and "lowpass:F" in bad.stderr and not (tmp_path / "x.jsonl").exists()
