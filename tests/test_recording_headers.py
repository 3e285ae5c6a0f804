"""Recording header lines that say where and how a run was recorded (issue 26): ``# environment:``
(a basin or towing tank has no current and no wind) and ``# rudder_sign:`` (a recording in the
other rudder convention is converted on reading, not refused)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cli.app import _run
from diagnose.candidates import build_library
from diagnose.recording import RecordingError, load_recording, read_marin_dat, write_csv
from diagnose.recording_checks import conform
from primitives.ship import load_profile

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"


@pytest.fixture(scope="module")
def tc35():
    return read_marin_dat(DATA / "MARIN_FREE_KVLCC2_tc_35_m.dat")


def _environment_untestable(profile, recs) -> dict[str, str]:
    cands, untestable = build_library(profile, recs)
    assert not {c.effect for c in cands} & {"current", "wind"}
    return {u["effect"]: u["reason"] for u in untestable if u["effect"] in ("current", "wind")}


def test_marin_runs_are_basin_runs_and_get_no_current_candidate(tc35):
    """MARIN's free-running tests are basin runs: no current is offered (before, the turning circle
    offered one, and the 20/20 zig-zags named a 0.46 m/s current in tank data)."""
    p = load_profile("kvlcc2-linear")
    assert tc35.environment == "basin" and tc35.in_tank
    reasons = _environment_untestable(p, [tc35])
    assert "basin or towing tank" in reasons["current"] and "basin or towing tank" in reasons["wind"]
    # the same turning circle at sea with u, v measured over ground: a current is a candidate
    at_sea = dataclasses.replace(tc35, meta={**tc35.meta, "environment": "sea", "velocities": "recorded"})
    cands, _ = build_library(p, [at_sea])
    assert "current" in {c.effect for c in cands}


def test_a_current_is_not_inferred_from_a_track_alone_and_is_measured_with_a_log(tc35):
    """At sea, u, v derived from the track (MARIN's are: dx0/dt, dy0/dt) and no speed through the
    water: a current is not offered, the reason says it cannot be told from a model error (before,
    MARIN's zig-zags named a 0.46 m/s current). With a log's speed through the water the drift
    between the two measures it: 0.5 m/s toward 60 deg recovered; a log that agrees with the track
    rules a current out."""
    from diagnose.current_direct import measure

    p = load_profile("kvlcc2-linear")
    sea = dataclasses.replace(tc35, meta={**tc35.meta, "environment": "sea"})
    cands, untestable = build_library(p, [sea])
    assert "current" not in {c.effect for c in cands}
    why = next(u["reason"] for u in untestable if u["effect"] == "current")
    assert "derived from the track" in why and "cannot be told" in why
    c, s_ = np.cos(sea.psi), np.sin(sea.psi)
    cn, ce = 0.5 * np.cos(np.radians(60.0)), 0.5 * np.sin(np.radians(60.0))
    noise = np.random.default_rng(1).normal(0.0, 0.05, (2, len(sea.t)))
    logged = {"u_water": sea.y[:, 0] - (c * cn + s_ * ce) + noise[0], "v_water": sea.y[:, 1] - (-s_ * cn + c * ce) + noise[1]}
    with_log = dataclasses.replace(sea, channels={**sea.channels, **logged})
    m = measure([with_log])
    assert m.speed == pytest.approx(0.5, abs=0.02) and m.toward_deg == pytest.approx(60.0, abs=3.0) and 0 < m.std < 0.02
    cands, _ = build_library(p, [with_log])
    cur = next(c for c in cands if c.effect == "current")
    assert "measured from the track against the speed through the water" in cur.description
    agree = dataclasses.replace(sea, channels={**sea.channels, "u_water": sea.y[:, 0] + noise[0]})  # a one-axis log
    cands, untestable = build_library(p, [agree])
    assert "current" not in {c.effect for c in cands}
    assert "within 2 std of no current" in next(u["reason"] for u in untestable if u["effect"] == "current")


def test_environment_header_read_from_csv(tc35, tmp_path):
    path = write_csv(tc35, tmp_path / "tc.csv", meta={"environment": "sea"})
    rec = load_recording(path)[0]
    assert rec.environment == "sea" and not rec.in_tank
    path = write_csv(tc35, tmp_path / "tank.csv", meta={"environment": "towing-tank"})
    assert load_recording(path)[0].in_tank


@pytest.mark.parametrize(
    ("line", "words"),
    [
        ("# environment: lake", ["environment", "lake", "sea, basin, towing-tank"]),
        ("# rudder_sign: left", ["rudder_sign", "left", "port-positive, starboard-positive"]),
        ("# yaw_rate_sign: clockwise", ["yaw_rate_sign", "clockwise", "starboard-positive, port-positive"]),
    ],
)
def test_unknown_header_value_refused_in_one_line(tmp_path, capsys, line, words):
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat")
    meta = {k: v for k, v in rec.meta.items() if k not in ("environment", "rudder_sign")}
    rec = dataclasses.replace(rec, meta=meta)
    path = write_csv(rec, tmp_path / "run.csv")
    path.write_text(line + "\n" + path.read_text())
    with pytest.raises(RecordingError) as e:
        load_recording(path)
    assert all(w in str(e.value) for w in words), e.value
    out = tmp_path / "out"
    code = _run(["diagnose", str(path), "--ship", "kvlcc2-linear", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("error:") and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_option_values_refused_in_one_line(tmp_path, capsys):
    path = DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat"
    for opt in (["--environment", "lake"], ["--rudder-sign", "port"], ["--yaw-rate-sign", "cw"]):
        code = _run(["diagnose", str(path), "--ship", "kvlcc2-linear", *opt])
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.startswith(f"error: {opt[0]} {opt[1]}") and len(err.splitlines()) == 1


def test_starboard_positive_recording_converted_on_reading(tmp_path):
    """MMG's convention (starboard-positive) against the kvlcc2 profile's (port-positive): converted,
    said in the notes; the same file without the header is refused as before; a header naming the
    wrong convention is caught by the response check."""
    ship = load_profile("kvlcc2-linear")
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat")
    mmg = dataclasses.replace(rec, channels={**rec.channels, "delta": -rec.channels["delta"]})
    path = write_csv(mmg, tmp_path / "mmg.csv", meta={"rudder_sign": "starboard-positive"})
    got = conform(load_recording(path, inputs=ship.inputs), ship)[0]
    np.testing.assert_allclose(got.channels["delta"], rec.channels["delta"], atol=1e-9)
    assert any("converted from the file's starboard-positive" in n for n in got.notes), got.notes
    bare = write_csv(dataclasses.replace(mmg, meta={}), tmp_path / "bare.csv")
    with pytest.raises(RecordingError, match="rudder_sign: starboard-positive"):
        conform(load_recording(bare, inputs=ship.inputs), ship)
    wrong = write_csv(dataclasses.replace(mmg, meta={}), tmp_path / "wrong.csv", meta={"rudder_sign": "port-positive"})
    with pytest.raises(RecordingError, match="header's rudder_sign is wrong"):
        conform(load_recording(wrong, inputs=ship.inputs), ship)
    same = conform(load_recording(write_csv(rec, tmp_path / "same.csv"), inputs=ship.inputs), ship)[0]
    assert not any("converted" in n for n in same.notes)  # already in the ship's convention: unchanged


def _with_wind(rec, speed, frm, reference: str | None):
    n = rec.n_samples
    ch = {**rec.channels, "wind_speed": np.full(n, speed), "wind_dir": np.full(n, frm)}
    meta = {k: v for k, v in rec.meta.items() if k != "wind_reference"} | ({"wind_reference": reference} if reference else {})
    return dataclasses.replace(rec, channels=ch, meta=meta)


def test_wind_without_its_reference_or_in_knots_refused_in_one_line(tmp_path, capsys):
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat")
    bare = write_csv(_with_wind(rec, 9.0, 1.0, None), tmp_path / "bare.csv")
    with pytest.raises(RecordingError, match="wind_reference: true"):
        load_recording(bare)
    knots = write_csv(_with_wind(rec, 35.0, 1.0, "true"), tmp_path / "knots.csv")  # 18 m/s written in knots
    with pytest.raises(RecordingError, match="knots"):
        load_recording(knots)
    degrees = write_csv(_with_wind(rec, 9.0, 300.0, "true"), tmp_path / "deg.csv")  # from 300 deg, written in degrees
    with pytest.raises(RecordingError, match="wind_dir.*degrees"):
        load_recording(degrees)
    assert load_recording(write_csv(_with_wind(rec, 18.0, 1.0, "true"), tmp_path / "ok.csv"))[0].wind_ne is not None
    for path in (bare, knots, degrees):
        out = tmp_path / f"out-{path.stem}"
        code = _run(["diagnose", str(path), "--ship", "kvlcc2-linear", "--out", str(out)])
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.startswith("error:") and len(err.splitlines()) == 1, err
        assert not out.exists()  # nothing written


def test_relative_wind_in_knots_refused_against_the_ships_speed(tmp_path, capsys):
    """A relative wind in knots whose true wind stays below the storm limit (10 m/s, gusty, from
    300 deg): the true wind derived from it follows the ship's own velocity as it turns (factor
    1.944), refused in one line through the CLI, nothing written; the same in m/s is read."""
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_tc_35_m.dat")
    n = rec.n_samples
    rng = np.random.default_rng(3)
    gust = 1.0 + 0.15 * np.convolve(rng.standard_normal(n + 40), np.ones(40) / np.sqrt(40), "valid")[:n]
    frm = np.radians(300.0) + 0.1 * rng.standard_normal(n)
    wn, we = -10.0 * gust * np.cos(frm), -10.0 * gust * np.sin(frm)
    c, s = np.cos(rec.psi), np.sin(rec.psi)
    qa, qv = c * wn + s * we - rec.y[:, 0], -s * wn + c * we - rec.y[:, 1]  # the air relative to the ship
    for unit, k in (("mps", 1.0), ("kn", 1.9438)):
        rel = dataclasses.replace(
            rec,
            channels={**rec.channels, "wind_speed": k * np.hypot(qa, qv), "wind_dir": np.arctan2(-qv, -qa) % (2 * np.pi)},
            meta={**rec.meta, "wind_reference": "relative"},
        )
        path = write_csv(rel, tmp_path / f"rel-{unit}.csv")
        if unit == "mps":
            assert load_recording(path)[0].wind_ne is not None
            continue
        with pytest.raises(RecordingError, match="follows the ship's own velocity.*knots"):
            load_recording(path)
        out = tmp_path / "out"
        code = _run(["diagnose", str(path), "--ship", "kvlcc2-linear", "--out", str(out)])
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.startswith("error:") and len(err.splitlines()) == 1 and "knots" in err, err
        assert not out.exists()


def test_relative_wind_converted_to_the_true_wind(tmp_path):
    """The apparent wind on board of a ship turning through a steady true wind: read back as that
    true wind (18 m/s from 300 deg) on every sample."""
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_tc_35_m.dat")
    frm = np.radians(300.0)
    wn, we = -18.0 * np.cos(frm), -18.0 * np.sin(frm)  # air velocity toward, north/east
    c, s = np.cos(rec.psi), np.sin(rec.psi)
    ub, vb = c * wn + s * we, -s * wn + c * we  # in body axes
    qa, qv = ub - rec.y[:, 0], vb - rec.y[:, 1]  # the air relative to the ship
    rel = dataclasses.replace(
        rec,
        channels={**rec.channels, "wind_speed": np.hypot(qa, qv), "wind_dir": np.arctan2(-qv, -qa) % (2 * np.pi)},
        meta={**rec.meta, "wind_reference": "relative"},
    )
    got = load_recording(write_csv(rel, tmp_path / "rel.csv"))[0]
    np.testing.assert_allclose(got.wind_ne, np.tile([wn, we], (got.n_samples, 1)), atol=1e-4)
    assert any("relative wind" in n for n in got.notes)


def test_a_basin_says_its_recorded_wind_is_not_used(tc35):
    """A basin run with wind columns: no wind candidate, and the reason says the columns are not used."""
    windy = _with_wind(tc35, 5.0, 1.0, "true")
    reasons = _environment_untestable(load_profile("kvlcc2-linear"), [windy])
    assert "recorded wind columns" in reasons["wind"] and "recorded wind" not in reasons["current"], reasons


def test_environment_option_stands_for_the_header(tc35, tmp_path, capsys):
    """--environment basin on a file whose header says sea: no current is offered, and the report says why."""
    import json

    short = tc35.window(0, 200)  # the turn's first 200 s: the heading turns well past 45 deg
    assert np.ptp(short.psi) > np.radians(90.0)
    path = write_csv(short, tmp_path / "tc.csv", meta={"environment": "sea"})
    assert _run(["diagnose", str(path), "--ship", "kvlcc2-linear", "--environment", "basin", "--json"]) in (0, None)
    out = json.loads(capsys.readouterr().out)
    reasons = {u["effect"]: u["reason"] for u in out["untestable"]}
    assert "basin or towing tank" in reasons["current"], reasons
    assert not any(f["effect"] == "current" for f in out["findings"])


def test_yaw_rate_in_the_other_convention_converted_or_refused(tmp_path, capsys):
    """A log whose r is positive turning to port (the mathematical convention) loads unchanged with
    '# yaw_rate_sign: port-positive' or --yaw-rate-sign port-positive (r negated before it is
    checked against the heading, said in the notes); without either it is refused in one line that
    names the header, nothing written."""
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat")
    y = rec.y.copy()
    y[:, 2] = -y[:, 2]
    flipped = dataclasses.replace(rec, y=y)
    path = write_csv(flipped, tmp_path / "port.csv", meta={"yaw_rate_sign": "port-positive"})
    got = load_recording(path)[0]
    np.testing.assert_allclose(got.y[:, 2], rec.y[:, 2], atol=1e-6)
    assert any("yaw rate r converted from port-positive" in n for n in got.notes), got.notes
    bare = write_csv(flipped, tmp_path / "bare.csv")
    with pytest.raises(RecordingError, match="yaw_rate_sign: port-positive"):
        load_recording(bare)
    np.testing.assert_allclose(load_recording(bare, yaw_rate_sign="port-positive")[0].y[:, 2], rec.y[:, 2], atol=1e-6)
    out = tmp_path / "out"
    code = _run(["diagnose", str(bare), "--ship", "kvlcc2-linear", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("error:") and len(err.splitlines()) == 1 and "yaw_rate_sign" in err
    assert not out.exists()


def test_a_sideways_log_without_its_forward_part_refused_in_one_line(tc35, tmp_path, capsys):
    """v_water alone (no u_water) cannot measure a current and is not silently ignored: one line
    naming the file and both columns, exit 2, nothing written."""
    path = write_csv(dataclasses.replace(tc35, channels={**tc35.channels, "v_water": tc35.y[:, 1]}), tmp_path / "log.csv")
    out = tmp_path / "out"
    code = _run(["diagnose", str(path), "--ship", "kvlcc2-linear", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and str(path) in err
    assert "'v_water' without 'u_water'" in err and not out.exists()


def test_a_header_cannot_say_velocities_were_recorded_when_the_file_has_no_u_v(tc35, tmp_path):
    """Provenance of u, v comes from the columns: a file without u, v has them derived from the
    track whatever a '# velocities:' header says (else a current would be inferred from a track
    alone); a MARIN run written back to CSV keeps 'derived from the track'."""
    from diagnose.current_direct import from_track_alone

    back = load_recording(write_csv(tc35, tmp_path / "back.csv"))
    assert back[0].meta["velocities"] == "derived from the track" and from_track_alone(back)
    text = (tmp_path / "back.csv").read_text().splitlines()
    head = [ln for ln in text if ln.startswith("#") and "velocities" not in ln]
    rows = [ln for ln in text if not ln.startswith("#")]
    names = rows[0].split(",")
    keep = [i for i, n in enumerate(names) if n not in ("u", "v")]
    body = [",".join(r.split(",")[i] for i in keep) for r in rows]
    path = tmp_path / "track.csv"
    path.write_text("\n".join([*head, "# velocities: recorded", *body]) + "\n")
    got = load_recording(path)
    assert got[0].meta["velocities"] == "derived from the track" and from_track_alone(got)
