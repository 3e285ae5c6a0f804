"""The wall-sided roll restoring of the mass / CoG estimator (identify/rollmass/restoring.py): the
righting arm it adds, the hull's BM from the profile, and the load it gives on the independent basin
truth's ``restoring`` variant (tests/physics/basin_truth.py), whose hull has that nonlinearity."""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np
import pytest

from identify.rollmass.api import estimate_from_files, heel_notes
from identify.rollmass.model import DEFAULT_PROFILE, Load, load_profile, metacentric_radius
from identify.rollmass.recording import read_roll_csv
from identify.rollmass.restoring import heel_gain, heel_signal, referenced_heel
from identify.rollmass.simulate import RollRecording
from primitives.errors import UserError
from primitives.ship import ProfileError
from tests.physics import basin_truth as bt

PROF = load_profile()


def test_the_linear_restoring_plus_the_heel_moment_is_the_wall_sided_righting_moment():
    """``C phi + kappa w(phi)`` with ``C = M g GM`` is ``M g sin(phi) (GM + BM/2 tan^2 phi)`` at every
    heel, and nothing is added without a BM."""
    kn = PROF.known
    phi = np.linspace(-0.4, 0.4, 17)
    got = kn.M * kn.g * kn.GM * phi + heel_gain(kn) * heel_signal(phi, kn)
    want = kn.M * kn.g * np.sin(phi) * (kn.GM + kn.BM / 2 * np.tan(phi) ** 2)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    assert not np.any(heel_signal(phi, dataclasses.replace(kn, BM=0.0)))


def test_bm_comes_from_the_profile_or_from_table_1_hydrostatics(tmp_path):
    """Our Lass II: KG + GM_T - KB with Morrish's KB at C_B 0.60 (0.083 m; a box's KB = T/2 would give
    0.092 m); a given BM_T is taken as it is; one in the wrong unit is refused."""
    ship = PROF.raw["ship"]
    assert PROF.known.BM == pytest.approx(0.0833, abs=5e-4)
    assert metacentric_radius({**ship, "BM_T": 0.05}) == 0.05
    assert metacentric_radius({k: v for k, v in ship.items() if k != "KG"}) == 0.0
    bad = tmp_path / "ship.toml"
    bad.write_text(DEFAULT_PROFILE.read_text().replace("GM_T = 0.018", "GM_T = 0.018\nBM_T = 92.0"))
    with pytest.raises(ProfileError, match="BM_T"):
        load_profile(bad)


def test_the_truths_wall_sided_hull_no_longer_reads_as_load():
    """Noise-free independent basin truth, ``restoring`` variant (a box-like hull with the cubic restoring
    ``C phi (1 + BM/(2 GM) phi^2)``), half length, case 2 (0.4 kg at z = -0.268 m), through the files as
    ``shiptrial mass`` reads them. Without the heel term (main at 8b60977) the load came out +5.2 % /
    +4.8 mm; with it +0.22 % / +0.2 mm (fitted kappa)."""
    ship, data = bt.simulate_runs("restoring", 1, 3015, length=0.5, quiet=True)
    m_true, z_true = bt.truth_load("case2")
    with tempfile.TemporaryDirectory() as d:
        paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in bt.case_recordings(ship, data, "case2", 0)]
        e = estimate_from_files(*paths)
    assert e.converged
    assert abs(e.m / m_true - 1) < 0.02 and abs(e.zbar_m - z_true) < 0.003, (e.m, e.zbar_m)


def test_a_roll_angle_in_some_runs_only_is_dropped_from_all_and_said():
    """The heel moment in one run and not the others would read as load: phi is used in all three or none."""
    z = np.zeros(10)
    recs = [RollRecording(f"r{i}", 0.01, z, z, z, z, phi=z if i != 1 else None) for i in range(3)]
    paths = [Path(f"run{i}.csv") for i in range(3)]
    out, notes = heel_notes(recs, paths)
    assert all(r.phi is None for r in out)
    assert len(notes) == 1 and "run0.csv, run2.csv only" in notes[0]
    same, none = heel_notes([dataclasses.replace(r, phi=z) for r in recs], paths)
    assert none == [] and all(r.phi is not None for r in same)


def _truth_recordings(d: str, variant: str, seed: int, length: float, quiet: bool, case: str = "case2") -> list[Path]:
    ship, data = bt.simulate_runs(variant, 1, seed, length=length, quiet=quiet)
    return [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in bt.case_recordings(ship, data, case, 0)]


def test_the_accelerometer_reference_takes_the_ahrs_roll_error_out(monkeypatch, tmp_path):
    """Independent basin truth with sensor noise (``base``, 4 runs, 16 recordings): the recorded roll angle
    is off the true heel by the AHRS's error (here |mean| median 0.15 deg, up to 0.55 deg); referenced to
    the accelerometer's heel its mean error is at the accelerometer bias's level (median 0.08 deg, at most
    0.29 deg), and a further 0.5 deg added to ``phi`` changes nothing but through that constant's sine
    nonlinearity. (Each recording's mean taken out instead: median 0.50 deg, up to 2.5 deg, the true mean
    heel of its turns.)"""
    ship, data = bt.simulate_runs("base", 4, 21, length=0.6)
    monkeypatch.setattr(bt, "_ahrs_error", lambda R, n, s: np.zeros((R, n)))
    _, true = bt.simulate_runs("base", 4, 21, length=0.6)
    kn = PROF.known
    raw, ref = [], []  # |mean error| [deg] of the recorded and the referenced roll angle
    for name in bt.DATASETS:
        for run in range(4):
            cols = {k: data[name][k][run] for k in ("delta", "p", "a_s", "r", "phi", "u")}
            rec, _ = read_roll_csv(bt.write_csv(bt.Recording("nominal", name, 0.02, cols, {}), tmp_path / "x.csv"))
            t = true[name]["phi"][run]
            got = referenced_heel(rec, kn.g, float(rec.u.mean()))
            raw.append(np.rad2deg(abs((rec.phi - t).mean())))
            ref.append(np.rad2deg(abs((got - t).mean())))
            biased = referenced_heel(dataclasses.replace(rec, phi=rec.phi + np.deg2rad(0.5)), kn.g, float(rec.u.mean()))
            assert np.max(np.abs(biased - got)) < np.deg2rad(0.01)
            assert np.max(np.abs(referenced_heel(rec, kn.g, 0.5, "raw") - rec.phi)) == 0.0
    # what is left is the accelerometer's own bias (0.02 m/s^2 sd in the truth: 0.12 deg) and u times the yaw gyro's
    assert np.median(ref) < 0.1 and max(ref) < 0.35, (raw, ref)


def test_a_roll_angle_bias_does_not_read_as_load():
    """Noise-free ``restoring`` truth (half length, case 2) with the AHRS's roll angle 0.5 deg off in every
    run (the MTi-G's static accuracy): used as recorded (main at fad4f0a) the load moved from +0.18 % /
    +0.1 mm to -9.65 % / -13.8 mm; re-referenced to the accelerometer's heel it is +0.44 % / +0.5 mm with
    the bias and without it."""
    m_true, z_true = bt.truth_load("case2")
    with tempfile.TemporaryDirectory() as d:
        paths = _truth_recordings(d, "restoring", 3015, 0.5, True)
        for p in paths:  # the AHRS's roll angle 0.5 deg off, every other column as written
            lines = p.read_text().splitlines()
            k = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
            arr = np.loadtxt(lines[k + 1 :], delimiter=",")
            arr[:, lines[k].split(",").index("phi")] += np.deg2rad(0.5)
            rows = [",".join(f"{x:.9g}" for x in row) for row in arr]
            p.write_text("\n".join(lines[: k + 1] + rows) + "\n")
        e = estimate_from_files(*paths)
    assert e.converged
    assert abs(e.m / m_true - 1) < 0.01 and abs(e.zbar_m - z_true) < 0.002, (e.m, e.zbar_m)


def test_the_heel_reference_divides_by_cos_phi_before_its_low_pass():
    """A roll angle 0.5 deg off through 20 deg turns to both sides and straight stretches, the
    accelerometer reading the true heel: the offset ``sin(phi) - (a_s + u r)/g`` is ``cos(phi)`` times
    the bias, so it is divided by ``cos(phi)`` before the low-pass. The reference then recovers the
    true heel to 0.084 % of the bias at worst (asserted under 0.15 %); the low-passed offset divided by
    the instantaneous ``cos(phi)`` (stop 41's order) was off by up to 4.5 % of it, the turns' heel
    leaking into the slow part (both re-measured on this construction at stop 43)."""
    from scipy.signal import butter, filtfilt

    T, n, g, U = 0.02, 6000, 9.81, 0.5
    t = np.arange(n) * T
    turn = np.sign(np.sin(2 * np.pi * t / 8.0)) * (np.sin(2 * np.pi * t / 16.0) > -0.3)
    phi = np.deg2rad(20.0) * filtfilt(*butter(2, 0.5, fs=1 / T), turn)
    r = 0.1 * phi / np.deg2rad(20.0)
    b = np.deg2rad(0.5)
    rec = RollRecording("turns", T, np.zeros(n), np.gradient(phi, T), g * np.sin(phi) - U * r, r, phi=phi + b, U=U)
    err = (referenced_heel(rec, g, U) - phi) / b
    assert np.max(np.abs(err)) < 0.0015, np.max(np.abs(err))


def test_the_file_reader_passes_its_heel_reference_to_the_fit_and_refuses_an_unknown_one(monkeypatch, tmp_path):
    """``estimate_from_files(..., heel_reference=)`` reaches the oe fit (the truth bench's ``--heel-ref`` goes
    through it to every job), and a name outside ``HEEL_REFERENCES`` is a one-line user error."""
    from identify.rollmass import api

    seen = {}

    class Reached(Exception):
        pass

    def fake_estimate(*a, **k):
        seen.update(k)
        raise Reached

    paths = _truth_recordings(str(tmp_path), "base", 2015, 0.3, True)
    monkeypatch.setattr(api, "estimate", fake_estimate)
    with pytest.raises(Reached):
        api.estimate_from_files(*paths, heel_reference="raw")
    assert seen["heel_reference"] == "raw"
    with pytest.raises(UserError, match="heel reference 'level': choose one of raw, mean, acc, acc-lp"):
        api.estimate_from_files(*paths, heel_reference="level")


@pytest.mark.parametrize("bad", ["noise", "nan", "astern"])
def test_estimate_called_directly_holds_a_held_speed_in_the_heel_reference_too(monkeypatch, bad):
    """``estimate`` (not through the files) with a ``u`` the model holds (a constant speed with a positioning
    error, a NaN, a negative speed: ``speed.followed_speed`` is None) references the roll angle with
    the run's ``U`` in the centripetal ``u r``, as ``estimate_from_files`` does: the fit sees no trace of the
    column (before the review of stop 43 the raw ``u`` reached the heel reference here)."""
    from identify.rollmass import estimate as est_mod

    T, n, g, U = 0.02, 6000, PROF.known.g, 0.5
    t = np.arange(n) * T
    rng = np.random.default_rng(3)
    r = 0.3 * np.sin(2 * np.pi * t / 10.0)
    phi = np.deg2rad(5.0) * np.sin(2 * np.pi * t / 10.0)
    u = {"noise": U + 0.01 * rng.standard_normal(n), "nan": np.full(n, U), "astern": np.full(n, -U)}[bad]
    if bad == "nan":
        u[100] = np.nan
    rec = RollRecording("x", T, 0.1 * np.sin(t), np.gradient(phi, T), g * np.sin(phi) - U * r, r, phi=phi, U=U, u=u)
    seen = []

    def capture(datasets, *args, **kwargs):
        seen.extend(datasets)
        raise RuntimeError("captured")

    monkeypatch.setattr(est_mod, "fit_output_error", capture)
    with pytest.raises(RuntimeError, match="captured"):
        est_mod.estimate([rec] * 3, PROF.known, Load(0.2, -0.25), "oe", start={})
    want = referenced_heel(dataclasses.replace(rec, u=None), g, U)
    assert all(d.u is None and np.array_equal(d.phi, want) for d in seen)
