"""Legitimate recordings the recording checks must pass (a reviewer's false refusals of the checks
added for issue 13), and the mistakes they must still catch under the same conditions.

Synthetic runs with an exact track (x, y, psi integrated from u, v, r), GPS noise where said, and
the planner's own manoeuvres at both scales. Before the fixes each legitimate run here was refused:
slow, astern or stopped runs as "a model-scale recording without its header", astern and constant
rudders as "flip the sign of delta", a model's fast roll as p of the opposite sign, noisy slow
tracks as u, v in other units, an unused partly empty input column split the run, a coupled
(course) instability named as a damping sign, 2.6 rev/s hinted as rpm.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from diagnose.recording import MIN_SAMPLES, Recording, RecordingError, load_recording, write_csv
from diagnose.recording_checks import conform
from primitives.ship import PROFILE_DIR, load_profile

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"


def _run(path: Path, t, u, v, r, chans: dict, *, pos_noise: float = 0.0, seed: int = 0, meta: dict | None = None) -> Path:
    """A run whose track is u, v, r integrated (trapezoid) from the origin, heading north; positions
    with white noise of ``pos_noise`` m (GPS); psi wrapped at +-pi as a compass gives it."""
    ts = t[1] - t[0]
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * ts)])
    xd, yd = np.cos(psi) * u - np.sin(psi) * v, np.sin(psi) * u + np.cos(psi) * v
    pos = np.stack([np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * ts)]) for a in (xd, yd)], -1)
    pos = pos + pos_noise * np.random.default_rng(seed).standard_normal(pos.shape)
    wrapped = (psi + np.pi) % (2 * np.pi) - np.pi
    rec = Recording(path.stem, t, np.stack([u, v, r], -1), wrapped, pos, chans, None, dict(meta or {"scale": "full"}), [])
    return write_csv(rec, path)


def _nomoto(t, delta, u, sign: float = -1.0, T: float = 20.0, K: float = 0.2, L: float = 320.0):
    """Yaw rate of a first-order ship whose rudder force goes with u|u| (astern it reverses);
    sign -1: a positive delta turns to port (kvlcc2)."""
    r = np.zeros_like(t)
    ts = t[1] - t[0]
    for k in range(len(t) - 1):
        r[k + 1] = r[k] + ts * (-r[k] + sign * K * delta[k] * u[k] * abs(u[k]) / L) / T
    return r


T1 = np.arange(0.0, 600.0, 1.0)
ONE = np.ones(len(T1))
ZIGZAG = 0.35 * np.sign(np.sin(2 * np.pi * T1 / 120.0))


def _passes(path: Path, ship: str, **kw) -> list:
    prof = load_profile(ship)
    return conform(load_recording(path, inputs=prof.inputs), prof, **kw)


@pytest.mark.parametrize("name,speed,n", [("astern_2", -2.0, -1.0), ("astern_3", -3.0, -1.2), ("engine_stopped", 1.0, 0.0)])
def test_slow_astern_and_stopped_kvlcc2_runs_pass(tmp_path, name, speed, n):
    u = speed * ONE
    r = _nomoto(T1, ZIGZAG, u)
    assert _passes(_run(tmp_path / f"{name}.csv", T1, u, -6 * r, r, {"delta": ZIGZAG, "n": n * ONE}), "kvlcc2")


def test_a_constant_rudder_while_the_speed_changes_is_no_rudder_sign_verdict(tmp_path):
    """Rudder held at -0.02 rad, engine reduced, a slow yaw from wind: the old one-step fit read
    the speed change as the rudder's effect (t = +9.6) and refused 'flip the sign of delta'."""
    u = 7.97 - 3 * T1 / 600
    r = 2e-8 * T1**2 + 3e-6 * np.random.default_rng(0).standard_normal(len(T1))
    n = np.where(T1 < 100, 1.53, 1.0)
    assert _passes(_run(tmp_path / "const_rudder.csv", T1, u, 0 * ONE, r, {"delta": -0.02 * ONE, "n": n}), "kvlcc2")


def test_a_flipped_rudder_is_still_caught_when_the_run_goes_ahead(tmp_path):
    u = 7.97 * ONE
    r = _nomoto(T1, ZIGZAG, u)
    p = _run(tmp_path / "flip.csv", T1, u, -6 * r, r, {"delta": -ZIGZAG, "n": 1.53 * ONE})
    with pytest.raises(RecordingError, match="flip the sign of delta"):
        _passes(p, "kvlcc2")


def _primitive_runs(ship: str, tmp: Path) -> list[Path]:
    """Every primitive of the planner's library for ``ship`` long enough to diagnose, as the ship
    would record it (nominal motion, the inputs held on the last sample)."""
    from primitives.library import build_library

    prof = load_profile(ship)
    out = []
    for prim in build_library(prof):
        if prim.n_samples + 1 < MIN_SAMPLES:
            continue
        t = np.arange(prim.n_samples + 1) * prof.sample_time
        inp = np.vstack([prim.inputs, prim.inputs[-1:]])
        rec = Recording(
            prim.name,
            t,
            prim.nu.copy(),
            prim.track[:, 2].copy(),
            prim.track[:, :2].copy(),
            {k: inp[:, i] for i, k in enumerate(prof.inputs)},
            None,
            {"scale": "full"},
            [],
        )
        out.append(write_csv(rec, tmp / f"{ship}_{prim.name}.csv"))
    return out


@pytest.mark.parametrize("ship", ["full-scale", "model-ship", "kvlcc2"])
def test_every_planner_manoeuvre_passes_at_both_scales(tmp_path, ship):
    """The planner's own primitives: crab and spot turns (u = v = 0), tau14 at 0.65 m/s,
    deceleration, the model ship's slow tau1 (before: 8 of them refused as model scale)."""
    runs = _primitive_runs(ship, tmp_path)
    assert len(runs) >= 14
    for p in runs:
        assert _passes(p, ship), p


def test_slow_and_station_keeping_runs_without_a_shaft_speed_pass(tmp_path):
    t = np.arange(0.0, 120.0, 0.125)
    one = np.ones(len(t))
    tau = {"tau_x": 300 * one, "tau_y": 0 * one, "tau_n": 50 * np.sign(np.sin(2 * np.pi * t / 30))}
    slow = _run(
        tmp_path / "ms_slow.csv", t, 0.25 * one, 0.02 * np.sin(2 * np.pi * t / 30), 0.05 * np.sin(2 * np.pi * t / 30), tau
    )
    dp = _run(
        tmp_path / "ms_dp.csv",
        t,
        0.01 * np.sin(2 * np.pi * t / 20),
        0.01 * np.cos(2 * np.pi * t / 25),
        0.01 * np.sin(2 * np.pi * t / 15),
        tau,
        pos_noise=0.002,
    )
    for p in (slow, dp):
        assert _passes(p, "model-ship")
    azi = {"n1": 10 * ONE, "alpha1": 1.57 * ONE, "n2": 10 * ONE, "alpha2": 1.57 * ONE}
    crab = _run(
        tmp_path / "fs_crab.csv",
        T1,
        0.05 * np.sin(2 * np.pi * T1 / 200),
        0.5 * np.sin(np.pi * T1 / 600),
        0.002 * np.sin(2 * np.pi * T1 / 100),
        azi,
    )
    assert _passes(crab, "full-scale")


@pytest.mark.parametrize("what,period", [("roll", 1.5), ("roll", 3.0), ("yaw", 4.0)])
def test_fast_roll_and_yaw_of_a_model_pass_and_degrees_are_still_caught(tmp_path, what, period):
    """At model scale a roll period of 1.5 s: r and p against dpsi/dt, dphi/dt differenced over
    2 s read p as of the opposite sign (1.5 s), 2.42 x (3 s), r as 1.58 x (4 s yaw)."""
    t = np.arange(0.0, 120.0, 0.125)
    one = np.ones(len(t))
    w = 2 * np.pi / period
    tau = {"tau_x": 1000 * one, "tau_y": 0 * one, "tau_n": 50 * np.sign(np.sin(2 * np.pi * t / 30))}
    if what == "roll":
        r, extra = 0.1 * np.sin(2 * np.pi * t / 30), {"phi": 0.05 * np.sin(w * t), "p": 0.05 * w * np.cos(w * t)}
    else:
        r, extra = 0.2 * np.cos(w * t), {}
    assert _passes(_run(tmp_path / "ok.csv", t, one, 0 * one, r, tau | extra), "model-ship")
    if what == "roll":
        bad = _run(tmp_path / "deg.csv", t, one, 0 * one, r, tau | extra | {"p": np.degrees(extra["p"])})
        needle = r"column 'p'.*(deg/s|units)"  # 57 x, or beyond any ship (12 rad/s at 1.5 s)
    else:
        bad = _run(tmp_path / "flip.csv", t, one, 0 * one, r, tau)
        text = bad.read_text().splitlines()
        head = text.index(next(ln for ln in text if ln.startswith("t,")))
        col = text[head].split(",").index("r")
        rows = [ln.split(",") for ln in text[head + 1 :]]
        for row in rows:
            row[col] = repr(-float(row[col]))
        bad.write_text("\n".join(text[: head + 1] + [",".join(row) for row in rows]) + "\n")
        needle = "'r' has the opposite sign"
    with pytest.raises(RecordingError, match=needle):
        load_recording(bad)


@pytest.mark.parametrize("speed,noise", [(0.5, 1.0), (1.0, 2.0), (2.0, 3.0)])
def test_slow_runs_with_gps_noise_pass_and_knots_are_still_caught(tmp_path, speed, noise):
    """A 2 s difference of a noisy track reads it faster than it is: 0.5 m/s with 1 m GPS noise
    was refused as u, v 0.55 x the track's speed."""
    azi = {"n1": 5 * ONE, "alpha1": 0 * ONE, "n2": 5 * ONE, "alpha2": 0 * ONE}
    r = 0.002 * np.sin(2 * np.pi * T1 / 100)
    for seed in range(3):
        p = _run(tmp_path / f"ok{seed}.csv", T1, speed * ONE, 0 * ONE, r, azi, pos_noise=noise, seed=seed)
        assert load_recording(p)
    rec = load_recording(p)[0]
    knots = write_csv(dataclasses.replace(rec, y=rec.y * np.array([1.9438, 1.9438, 1.0])), tmp_path / "knots.csv")
    with pytest.raises(RecordingError, match="knots"):
        load_recording(knots)


@pytest.mark.parametrize("noise", [0.1, 0.5, 1.0])
def test_a_dp_run_within_the_gps_noise_passes(tmp_path, noise):
    azi = {"n1": 5 * ONE, "alpha1": 1.0 * ONE, "n2": 5 * ONE, "alpha2": -1.0 * ONE}
    p = _run(
        tmp_path / "dp.csv",
        T1,
        0.05 * np.sin(2 * np.pi * T1 / 200),
        0.05 * np.cos(2 * np.pi * T1 / 150),
        0.001 * np.sin(2 * np.pi * T1 / 100),
        azi,
        pos_noise=noise,
    )
    assert load_recording(p)


def test_a_partly_empty_input_column_the_ship_does_not_use_does_not_split_the_run(tmp_path):
    u = 7.97 * ONE
    r = _nomoto(T1, ZIGZAG, u)
    tau_n = np.where((T1 > 200) & (T1 < 300), np.nan, 0.0)
    p = _run(tmp_path / "tau_n.csv", T1, u, -6 * r, r, {"delta": ZIGZAG, "n": 1.53 * ONE, "tau_n": tau_n})
    (rec,) = _passes(p, "kvlcc2")
    assert rec.n_samples == len(T1) and any("column 'tau_n'" in n and "bridged" in n for n in rec.notes)
    assert len(load_recording(p)) == 2  # without the ship's inputs every input column counts, as before


@pytest.mark.parametrize("col,value,limit", [("n", 2.6, "2 rev/s"), ("delta", 0.8, "0.6109 rad")])
def test_an_overrun_is_not_blamed_on_a_unit_it_cannot_be_in(tmp_path, col, value, limit):
    """2.6 rev/s is not 2.6 rpm (0.04 rev/s), 0.8 rad is not 0.8 deg: the message names the limit and
    the ship, and no unit (following the hint would corrupt a correct column)."""
    u = 7.97 * ONE
    r = _nomoto(T1, ZIGZAG, u)
    chans = {"delta": ZIGZAG, "n": 1.53 * ONE}
    chans[col] = chans[col] / np.max(np.abs(chans[col])) * value
    with pytest.raises(RecordingError) as exc:
        _passes(_run(tmp_path / f"{col}.csv", T1, u, -6 * r, r, chans), "kvlcc2")
    msg = str(exc.value)
    assert f"exceeds the {limit}" in msg and "'kvlcc2'" in msg and "rpm?" not in msg and "deg?" not in msg, msg


def test_a_coupled_course_instability_is_worded_as_such(tmp_path):
    """kvlcc2-linear with Nuv = -3e-4: every damping stable, the sway-yaw coupling makes the course
    unstable (|lambda| 1.045): not 'Nuv ... its damping must be negative'."""
    from diagnose.stability import check_baseline

    text = (PROFILE_DIR / "kvlcc2-linear.toml").read_text()
    nuv = "-9.47657621319453e-05"
    assert nuv in text
    path = tmp_path / "coupled.toml"
    path.write_text(text.replace(nuv, "-3e-4").replace('name = "kvlcc2-linear"', 'name = "kv-coupled"'))
    prof = load_profile(str(path))
    recs = conform(load_recording(DATA / "MARIN_FREE_KVLCC2_zz_20_m.dat"), prof)
    with pytest.raises(RecordingError) as exc:
        check_baseline(prof, prof.params(), recs, str(path))
    msg = str(exc.value)
    assert "sway-yaw motion is unstable through their coupling (course instability)" in msg, msg
    assert "Nuv = -0.0003" in msg and "not a damping sign" in msg and "damping must be negative" not in msg
