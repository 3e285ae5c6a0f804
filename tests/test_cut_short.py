"""A recording cut short inside its last row (a truncated download, a logger stopped mid-write) is read
without that row and says so, in every recording reader of diagnose, steering, yawid, mass and detect (stop 60's
leftover: before, a number cut short in the last cell was read as another number, "0.0123" as "0.01")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cli.app import _run
from diagnose.recording import load_recording, read_marin_dat, write_csv
from identify.detect.api import load_runs, simulated_recording
from identify.detect.vessel import Vessel
from identify.rollmass.recording import read_roll_csv
from identify.steering.recording import read_records
from identify.yawid.api import simulate_file
from identify.yawid.model import MODELS
from identify.yawid.recording import read_yaw_csv
from primitives.ship import load_profile
from tests.physics import basin_truth as bt
from tests.physics import sea_splendour as ss

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"


def _diagnose_csv(path: Path) -> Path:
    return write_csv(read_marin_dat(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat"), path)


def _marin_dat(path: Path) -> Path:
    path.write_bytes((DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat").read_bytes())
    return path


def _steering_csv(path: Path) -> Path:
    ss.write_csv(ss.simulate(ss.EXPERIMENT_1, 0), path)
    return path


def _yaw_csv(path: Path) -> Path:
    return simulate_file(path, seed=1, noise_scale=0.5)


def _mass_csv(path: Path) -> Path:
    ship, data = bt.simulate_runs("base", 1, 4, length=0.1, quiet=True)
    return bt.write_csv(bt.case_recordings(ship, data, "case1", 0)[0], path)


def _detect_csv(path: Path) -> Path:
    return write_csv(simulated_recording(Vessel(), 60, seed=3, measured_moment=True), path)


def _mass_read(path):
    rec, _ = read_roll_csv(path)
    return np.column_stack([rec.delta, rec.p, rec.a_s, rec.r, rec.phi, rec.u]), rec.notes


def _detect_read(path):
    notes: list[str] = []
    (rec,) = load_runs([path], "full", notes)
    return np.column_stack([rec.t, rec.y]), notes


def _diagnose_read(path):
    rec = load_recording(path)[0]
    return np.column_stack([rec.t, rec.y]), rec.notes


def _steering_read(path):
    (rec,), _, notes = read_records(path)
    return np.column_stack([rec.t, rec.y]), notes


def _yaw_read(path):
    data = read_yaw_csv(path, MODELS["full"], load_profile("naval-vessel"))
    return np.column_stack([data.t, *data.signals.values()]), list(getattr(data, "notes", ()))


READERS = {
    "diagnose csv": (_diagnose_csv, "run.csv", _diagnose_read),
    "MARIN dat": (_marin_dat, "run.dat", _diagnose_read),
    "steering csv": (_steering_csv, "run.csv", _steering_read),
    "yawid csv": (_yaw_csv, "run.csv", _yaw_read),
    "mass csv": (_mass_csv, "run.csv", _mass_read),
    "detect csv": (_detect_csv, "run.csv", _detect_read),
}


def _cut(text: str) -> str:
    """The file cut inside its last row's last cell: every field there, the last number one character long (a MARIN
    .dat file ends in lines of tabs: cut inside its last row of numbers)."""
    body = text.rstrip()
    last = body.rsplit("\n", 1)[1]
    sep = max(last.rfind(","), last.rfind("\t"), last.rfind(" "))
    return body[: len(body) - len(last) + sep + 2]


@pytest.mark.parametrize("kind", list(READERS))
def test_a_last_row_cut_short_is_left_out_with_a_note(tmp_path, kind):
    make, name, read = READERS[kind]
    (tmp_path / "whole").mkdir()
    whole = make(tmp_path / "whole" / name)
    text = whole.read_text(encoding="latin-1")
    assert text.endswith("\n")
    full, notes = read(whole)
    assert not any("cut short" in n for n in notes)
    shorter = tmp_path / f"shorter{whole.suffix}"
    shorter.write_text(text[: text.rstrip().rfind("\n") + 1], encoding="latin-1")  # the last row deleted by hand
    expect, _ = read(shorter)
    cut = tmp_path / f"cut{whole.suffix}"
    cut.write_text(_cut(text), encoding="latin-1")
    got, notes = read(cut)
    np.testing.assert_array_equal(got, expect)  # before: the cut number was read (the last row 0.0123 -> 0.0)
    said = [n for n in notes if "cut short" in n]
    assert len(said) == 1 and "left out" in said[0] and "end it with a line break" in said[0], notes


def test_yawid_says_the_row_it_left_out(tmp_path, capsys):
    path = _yaw_csv(tmp_path / "run.csv")
    path.write_text(_cut(path.read_text()))
    assert _run(["yawid", str(path), "--model", "simplified"]) == 0
    out = capsys.readouterr().out
    assert f"note: {path}: the last line" in out and "cut short" in out


@pytest.mark.parametrize("kind", ["diagnose csv", "yawid csv"])
def test_a_last_comment_without_a_line_break_is_no_cut_row(tmp_path, kind):
    """A comment line ends some loggers' files (``# end of run``); without a line break it holds no sample: the rows
    are all read and no "cut short" note is given."""
    make, name, read = READERS[kind]
    whole = make(tmp_path / name)
    full, _ = read(whole)
    whole.write_text(whole.read_text() + "# end of run")
    got, notes = read(whole)
    np.testing.assert_array_equal(got, full)
    assert not any("cut short" in n for n in notes), notes


def test_mass_says_the_row_it_left_out(tmp_path, capsys, monkeypatch):
    """`mass` reads its three runs through the shared edge and prints the note (the fit replaced by a fixed
    estimate: the reading and the notes are what is tested; before, the cut nominal run was refused over its 'u')."""
    from identify.rollmass import api
    from identify.rollmass.estimate import MassEstimate

    ship, data = bt.simulate_runs("base", 1, 4, length=0.35, quiet=True)
    paths = [bt.write_csv(r, tmp_path / f"{r.role}.csv") for r in bt.case_recordings(ship, data, "case1", 0)]
    paths[0].write_text(_cut(paths[0].read_text()))
    monkeypatch.setattr(api, "estimate", lambda *a, **k: MassEstimate("oe", {}, 0.2, -0.2, m_sd=0.01, zbar_m_sd=0.004, corr=0.9))
    assert _run(["mass", *map(str, paths)]) == 0
    out = capsys.readouterr().out
    assert f"note: {paths[0]}: the last line" in out and "cut short" in out, out


def test_detect_prior_says_the_row_it_left_out(tmp_path, capsys):
    """`detect-prior` (and `detect`, through the same :func:`identify.detect.api.load_runs`) prints the note."""
    path = _detect_csv(tmp_path / "run.csv")
    path.write_text(_cut(path.read_text()))
    assert _run(["detect-prior", str(path), "--out", str(tmp_path / "p.json"), "--bootstrap", "0"]) == 0
    err = capsys.readouterr().err
    assert f"note: {path}: the last line" in err and "cut short" in err, err
