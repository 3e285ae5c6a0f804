"""Recordings: the BRIEF section 7 CSV and the MARIN KVLCC2 .dat files as published."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from diagnose.recording import RecordingError, _plain_numbers, load_recording, read_csv, read_marin_dat, write_csv

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"


def _csv(path: Path, header: str, rows: list[list[float]], meta: str = "") -> Path:
    lines = [meta] if meta else []
    lines.append(header)
    lines += [",".join("" if np.isnan(float(x)) else repr(float(x)) for x in r) for r in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _circle(n: int = 200, ts: float = 0.5, speed: float = 2.0, rate: float = 0.05):
    t = np.arange(n) * ts
    psi = rate * t
    x = speed / rate * np.sin(psi)
    y = speed / rate * (1 - np.cos(psi))
    return t, x, y, psi


def test_csv_round_trip_keeps_signals_and_metadata(tmp_path):
    t, x, y, psi = _circle()
    rows = [[t[i], x[i], y[i], psi[i], 2.0, 0.0, 0.05, 100.0, 0.0, 5.0] for i in range(len(t))]
    p = _csv(tmp_path / "a.csv", "t,x,y,psi,u,v,r,tau_x,tau_y,tau_n", rows, "# ship: model-ship\n# sample_time: 0.5")
    rec = read_csv(p)[0]
    assert rec.meta["ship"] == "model-ship"
    assert rec.sample_time == pytest.approx(0.5)
    assert rec.inputs_for(["tau_x", "tau_y", "tau_n"]).shape == (200, 3)
    write_csv(rec, tmp_path / "b.csv")
    back = read_csv(tmp_path / "b.csv")[0]
    np.testing.assert_allclose(back.y, rec.y)
    np.testing.assert_allclose(back.psi, rec.psi)


def test_velocities_are_derived_from_track_when_missing(tmp_path):
    t, x, y, psi = _circle()
    rows = [[t[i], x[i], y[i], psi[i], 1.0] for i in range(len(t))]
    rec = read_csv(_csv(tmp_path / "c.csv", "t,x,y,psi,tau_x", rows))[0]
    inner = slice(2, -2)
    np.testing.assert_allclose(rec.y[inner, 0], 2.0, rtol=2e-3)
    np.testing.assert_allclose(rec.y[inner, 1], 0.0, atol=5e-3)
    np.testing.assert_allclose(rec.y[inner, 2], 0.05, rtol=1e-6)
    assert any("derived" in n for n in rec.notes)


def test_repeated_and_irregular_stamps_are_averaged_and_resampled(tmp_path):
    t, x, y, psi = _circle(n=300, ts=0.2)
    t_rep = np.round(t)  # 1 s resolution: stamps repeat five times
    rows = [[t_rep[i], x[i], y[i], psi[i], 2.0, 0.0, 0.05, 1.0] for i in range(len(t))]
    rec = read_csv(_csv(tmp_path / "d.csv", "t,x,y,psi,u,v,r,tau_x", rows), sample_time=1.0)[0]
    assert rec.sample_time == pytest.approx(1.0)
    assert np.all(np.diff(rec.t) == pytest.approx(1.0))
    assert any("repeated time stamps" in n for n in rec.notes)


def test_short_gap_bridged_and_reported_long_gap_splits(tmp_path):
    t, x, y, psi = _circle(n=400, ts=0.5)
    rows = [[t[i], x[i], y[i], psi[i], 2.0, 0.0, 0.05, 1.0] for i in range(len(t))]
    for i in range(100, 104):  # 2 s of NaN: bridged
        rows[i][1] = float("nan")
    rec = read_csv(_csv(tmp_path / "e.csv", "t,x,y,psi,u,v,r,tau_x", rows))
    assert len(rec) == 1 and any("bridged" in n for n in rec[0].notes)
    for i in range(200, 240):  # 20 s of NaN: never interpolated over, the run is split
        rows[i][1] = float("nan")
    pieces = read_csv(_csv(tmp_path / "f.csv", "t,x,y,psi,u,v,r,tau_x", rows))
    assert len(pieces) == 2
    assert pieces[0].t[-1] < 100.0 < pieces[1].t[0]
    assert any("split" in n for n in pieces[0].notes)


@pytest.mark.parametrize(
    "header,mutate,needle",
    [
        ("t,x,y,u,v,r", None, "'psi'"),
        ("t,psi,u,v,r", None, "'x', 'y'"),
        ("t,x,y,psi,u,v,r", "degrees", "degrees"),
        ("t,x,y,psi,u,v,r", "latlon", "latitude/longitude"),
        ("t,x,y,psi,u,v,r", "short", "too short"),
        ("t,x,y,psi,u,v,r", "backwards", "decreases"),
    ],
)
def test_bad_recordings_give_one_line_errors_naming_file_and_field(tmp_path, header, mutate, needle):
    t, x, y, psi = _circle()
    if mutate == "degrees":
        psi = np.degrees(psi)
    if mutate == "latlon":
        x, y = 57.7 + x * 1e-7, 11.9 + y * 1e-7
    if mutate == "short":
        t, x, y, psi = t[:20], x[:20], y[:20], psi[:20]
    if mutate == "backwards":
        t = t.copy()
        t[50] = t[10]
    cols = {"t": t, "x": x, "y": y, "psi": psi, "u": np.full_like(t, 2.0), "v": 0 * t, "r": np.full_like(t, 0.05)}
    names = header.split(",")
    rows = [[float(cols[n][i]) for n in names] for i in range(len(t))]
    p = _csv(tmp_path / "bad.csv", header, rows)
    with pytest.raises(RecordingError) as exc:
        read_csv(p)
    msg = str(exc.value)
    assert "bad.csv" in msg and needle in msg and "\n" not in msg


def test_missing_input_column_names_the_ship_inputs(tmp_path):
    t, x, y, psi = _circle()
    rec = read_csv(_csv(tmp_path / "g.csv", "t,x,y,psi", [[t[i], x[i], y[i], psi[i]] for i in range(len(t))]))[0]
    with pytest.raises(RecordingError, match="tau_x"):
        rec.inputs_for(["tau_x", "tau_y", "tau_n"])


def test_unknown_suffix_is_rejected(tmp_path):
    p = tmp_path / "run.xlsx"
    p.write_text("x")
    with pytest.raises(RecordingError, match="unknown recording format"):
        load_recording(p)


def test_kvlcc2_dat_read_as_published():
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat")
    assert rec.sample_time == pytest.approx(1.0)
    assert 500 <= rec.n_samples <= 530  # 0 .. 520 s
    assert np.degrees(rec.channels["delta"][0]) == pytest.approx(-0.82, abs=0.02)  # neutral rudder angle
    assert rec.channels["n"][0] == pytest.approx(91.5 / 60, rel=1e-3)  # rpm -> rev/s
    assert np.abs(rec.y[:, 2]).max() < 0.02  # yaw rate in rad/s
    assert abs(np.degrees(rec.psi).min() + 19.5) < 1.0  # first overshoot near -19.5 deg


def test_kvlcc2_turning_circle_velocities_rotated_into_body_frame():
    rec = read_marin_dat(DATA / "MARIN_FREE_KVLCC2_tc_35_m.dat")
    assert any("earth-frame" in n for n in rec.notes)
    assert rec.y[:, 0].min() > 2.0  # body surge stays positive all round the circle
    assert np.ptp(rec.psi) > 2 * np.pi  # more than a full turn kept before the 10 s stamps
    assert rec.duration_s <= 1000.0


def _cells(n: int = 200) -> list[list[str]]:
    """Cells of a turning circle written at 17 significant digits and in other plain spellings."""
    t, x, y, psi = _circle(n)
    spell = [repr, lambda v: f"{v:.17g}", lambda v: f"{v:.6e}", lambda v: f" {v!r} "]
    return [
        [spell[(i + j) % 4](float(v)) for j, v in enumerate((t[i], x[i], y[i], psi[i], 2.0, -0.0, 0.05, 100.0))] for i in range(n)
    ]


def test_plain_number_cells_are_read_as_pythons_float_reads_them(tmp_path):
    """The whole-table reader (every cell a plain number) gives each cell's float() bits, as the
    cell-by-cell reader does; a cell it cannot take (empty, a comment sign, quoted) goes to that
    reader, which reads an empty cell as NaN and names a bad one."""
    cells = _cells()
    header = "t,x,y,psi,u,v,r,tau_x"
    p = tmp_path / "plain.csv"
    p.write_text("# sample_time: 0.5\n" + header + "\n" + "\n".join(",".join(r) for r in cells) + "\n", encoding="utf-8")
    rec = read_csv(p)[0]
    body = p.read_text(encoding="utf-8").splitlines()[1:]
    assert _plain_numbers(header.split(","), body) is not None  # the whole-table reader read it
    for j in range(3):  # u, v, r
        want = np.array([float(r[4 + j]) for r in cells])
        assert np.array_equal(rec.y[:, j], want) and np.array_equal(np.signbit(rec.y[:, j]), np.signbit(want))
    assert np.array_equal(rec.psi, np.array([float(r[3]) for r in cells]))
    quoted = [list(r) for r in cells]
    quoted[5][7] = '"100.0"'  # csv unquotes it: the same recording
    q = tmp_path / "quoted.csv"
    q.write_text(header + "\n" + "\n".join(",".join(r) for r in quoted) + "\n", encoding="utf-8")
    assert np.array_equal(read_csv(q, sample_time=0.5)[0].inputs_for(["tau_x"]), rec.inputs_for(["tau_x"]))
    bad = [list(r) for r in cells]
    bad[7][4] = "2.0 # note"  # not a comment: a bad cell, said
    b = tmp_path / "bad.csv"
    b.write_text(header + "\n" + "\n".join(",".join(r) for r in bad) + "\n", encoding="utf-8")
    with pytest.raises(RecordingError, match=r"row 9, column 'u'"):
        read_csv(b, sample_time=0.5)
