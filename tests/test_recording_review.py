"""A reviewer's bad recordings (issue 13 "Recordings"): each refused in one line naming the file,
the field and the fix, exit 2, nothing written; legitimate runs pass.

The bad files are the MARIN 20/20 zig-zag written as a project CSV with one thing broken, as the
reviewer made them: u, v in knots, rudder in degrees, shaft speed in rpm, r in deg/s, phi in
degrees, a sign flipped, a model-scale run without its header, a header in other conventions,
the same run twice.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from cli.app import _run
from diagnose.recording import RecordingError, load_recording, read_csv, write_csv
from diagnose.recording_checks import conform
from primitives.ship import load_profile

DATA = Path(__file__).resolve().parents[1] / "diagnose" / "data"


@pytest.fixture(scope="module")
def ship():
    return load_profile("kvlcc2-linear")


@pytest.fixture(scope="module")
def marin(tmp_path_factory):
    """(run, path of its CSV, path of another run's CSV): MARIN zig-zags 20/20 and -20/-20."""
    tmp = tmp_path_factory.mktemp("marin")
    zz = load_recording(DATA / "MARIN_FREE_KVLCC2_zz_20_m.dat")[0]
    other = load_recording(DATA / "MARIN_FREE_KVLCC2_zz_-20_m.dat")[0]
    return zz, write_csv(zz, tmp / "zz_20.csv"), write_csv(other, tmp / "zz_-20.csv")


def _variant(rec, path: Path, meta: dict | None = None, drop_meta: tuple[str, ...] = (), **cols) -> Path:
    rec = dataclasses.replace(
        rec,
        channels=dict(rec.channels),
        y=rec.y.copy(),
        pos=rec.pos.copy(),
        t=rec.t.copy(),
        meta={k: v for k, v in rec.meta.items() if k not in drop_meta},
    )
    for k, v in cols.items():
        if k in ("u", "v", "r"):
            rec.y[:, "uvr".index(k)] = v
        elif k == "pos":
            rec.pos = v
        elif k == "t":
            rec.t = v
        else:
            rec.channels[k] = v
    return write_csv(rec, path, meta=meta)


def _refused(path: Path, ship, needles: tuple[str, ...], **kw) -> str:
    with pytest.raises(RecordingError) as exc:
        conform(load_recording(path), ship, **kw)
    msg = str(exc.value)
    assert "\n" not in msg and path.name in msg, msg
    for n in needles:
        assert n in msg, msg
    return msg


def test_legitimate_marin_runs_pass_every_check(ship):
    for p in sorted(DATA.glob("*.dat")):
        for prof in (ship, load_profile("kvlcc2")):
            assert conform(load_recording(p), prof)


def test_velocities_in_knots_are_refused_and_named(marin, ship, tmp_path):
    zz, _, _ = marin
    p = _variant(zz, tmp_path / "knots.csv", u=zz.y[:, 0] * 1.9438, v=zz.y[:, 1] * 1.9438)
    _refused(p, ship, ("'u', 'v'", "knots", "m/s"))


@pytest.mark.parametrize(
    "col,factor,needles",
    [
        ("delta", np.degrees(1.0), ("'delta'", "35 deg", "deg?", "give rad")),
        ("n", 60.0, ("'n'", "2 rev/s", "rpm?", "give rev/s")),
    ],
)
def test_inputs_in_degrees_or_rpm_are_named_not_blamed_on_the_model(marin, ship, tmp_path, col, factor, needles):
    zz, _, _ = marin
    p = _variant(zz, tmp_path / f"{col}.csv", **{col: zz.channels[col] * factor})
    _refused(p, ship, needles)


@pytest.mark.parametrize(
    "name,change,needles",
    [
        ("deg_r", lambda z: {"r": np.degrees(z.y[:, 2])}, ("'r'", "deg/s", "rad/s")),
        ("deg_phi", lambda z: {"phi": np.degrees(z.channels["phi"])}, ("'p'", "phi in degrees", "radians")),
        ("r_flip", lambda z: {"r": -z.y[:, 2]}, ("'r'", "opposite sign", "flip its sign")),
        ("v_flip", lambda z: {"v": -z.y[:, 1]}, ("'v'", "opposite sign", "starboard", "flip its sign")),
        ("u_flip", lambda z: {"u": -z.y[:, 0]}, ("'u'", "opposite sign", "flip its sign")),
        ("xy_swap", lambda z: {"pos": z.pos[:, ::-1].copy()}, ("'u', 'v'", "x and y look swapped")),
        (
            "delta_flip",
            lambda z: {"delta": -z.channels["delta"]},
            ("'delta'", "the other way", "flip the sign of delta", "positive delta turns to port"),
        ),
    ],
)
def test_rates_in_degrees_and_flipped_signs_are_refused(marin, ship, tmp_path, name, change, needles):
    zz, _, _ = marin
    _refused(_variant(zz, tmp_path / f"{name}.csv", **change(zz)), ship, needles)


def test_model_scale_run_without_its_header_is_refused_with_the_likely_cause(marin, ship, tmp_path):
    zz, _, _ = marin
    lam = 45.7
    s = np.sqrt(lam)
    p = _variant(
        zz,
        tmp_path / "model_noheader.csv",
        drop_meta=("scale", "scale_factor"),
        meta={"sample_time": f"{1 / s:.9g}"},
        t=zz.t / s,
        pos=zz.pos / lam,
        u=zz.y[:, 0] / s,
        v=zz.y[:, 1] / s,
        r=zz.y[:, 2] * s,
        n=zz.channels["n"] * s,
        p=zz.channels["p"] * s,
    )
    msg = _refused(p, ship, ("0.15 x", "7.97 m/s service speed", "# scale: model"), resample=True)
    assert "Froude scale ~4" in msg  # ~46, from the speeds alone
    # the same file with its header is Froude-scaled and accepted
    ok = _variant(
        zz,
        tmp_path / "model_header.csv",
        meta={"sample_time": f"{1 / s:.9g}", "scale": "model", "scale_factor": f"{lam:g}"},
        t=zz.t / s,
        pos=zz.pos / lam,
        u=zz.y[:, 0] / s,
        v=zz.y[:, 1] / s,
        r=zz.y[:, 2] * s,
        n=zz.channels["n"] * s,
        p=zz.channels["p"] * s,
    )
    assert conform(load_recording(ok), ship, resample=True)


@pytest.mark.parametrize(
    "name,text,needles",
    [
        ("semicolon", lambda h, rows: [h.replace(",", ";")] + [r.replace(",", ";") for r in rows], ("semicolons", "commas")),
        ("units", lambda h, rows: [",".join(f"{c} [x]" for c in h.split(","))] + rows, ("'t [x]'", "name it exactly 't'")),
        ("upper", lambda h, rows: [h.upper()] + rows, ("'T'", "name it exactly 't'")),
        ("dup", lambda h, rows: [h + ",r"] + [r + "," + r.split(",")[6] for r in rows], ("'r' appears twice",)),
        ("extra", lambda h, rows: [h] + rows[:6] + [rows[6] + ",1.0"] + rows[7:], ("row 8", "fields", "11 columns")),
        ("no_t", lambda h, rows: [h.replace("t,", "time,", 1)] + rows, ("missing required column(s) 't'", "header read")),
    ],
)
def test_header_mistakes_are_named_with_the_header_read(marin, tmp_path, name, text, needles):
    _, good, _ = marin
    lines = good.read_text().splitlines()
    meta = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if not ln.startswith("#")]
    p = tmp_path / f"{name}.csv"
    p.write_text("\n".join(meta + text(body[0], body[1:])) + "\n")
    with pytest.raises(RecordingError) as exc:
        read_csv(p)
    msg = str(exc.value)
    assert "\n" not in msg and p.name in msg
    for n in needles:
        assert n in msg, msg


@pytest.mark.parametrize("declared", [True, False])
def test_time_in_milliseconds_is_named(marin, ship, tmp_path, declared):
    zz, _, _ = marin
    p = _variant(
        zz,
        tmp_path / "ms.csv",
        t=zz.t * 1000.0,
        meta={"sample_time": "1"} if declared else None,
        drop_meta=() if declared else ("sample_time",),
    )
    if not declared:
        text = p.read_text().splitlines()
        p.write_text("\n".join(ln for ln in text if not ln.startswith("# sample_time")) + "\n")
    _refused(p, ship, ("milliseconds", "t in s" if not declared else "give t in seconds"))


def test_missing_rows_are_said_once_and_consistently(marin, tmp_path):
    zz, _, _ = marin
    r = zz.y[:, 2].copy()
    r[200:205] = np.nan  # 5 s of missing yaw rate: bridged, one note naming the column
    rec = read_csv(_variant(zz, tmp_path / "nan_r.csv", r=r))
    assert len(rec) == 1
    notes = [n for n in rec[0].notes if "bridged" in n]
    assert len(notes) == 1 and "5 row(s) missing r" in notes[0] and "t = 200 s" in notes[0]
    assert not any("split" in n for n in rec[0].notes)
    d = zz.channels["delta"].copy()
    d[300] = np.nan  # a single missing rudder angle is bridged and said
    rec = read_csv(_variant(zz, tmp_path / "nan_delta.csv", delta=d))
    assert any("missing delta" in n and "t = 300 s" in n for n in rec[0].notes)
    r[400:440] = np.nan  # 40 s: the run is split, each piece says which part it is, nothing says 'bridged' for it
    pieces = read_csv(_variant(zz, tmp_path / "gap_r.csv", r=r))
    assert len(pieces) == 2
    for i, piece in enumerate(pieces):
        assert any(f"piece {i + 1} of 2" in n for n in piece.notes)
        assert any("split" in n and "t = 399-440 s" in n for n in piece.notes), piece.notes
    assert any("5 row(s) missing r" in n for n in pieces[0].notes)
    assert not any("bridged" in n for n in pieces[1].notes)


def _cli(args: list[str], capsys) -> tuple[int, str]:
    rc = _run(args)
    return rc, capsys.readouterr().err.strip()


@pytest.mark.parametrize("how", ["RECORDING", "--fit-on", "--validate", "copy"])
def test_the_same_run_twice_is_refused_naming_both(marin, tmp_path, capsys, how):
    _, good, _ = marin
    other = good
    if how == "copy":
        other = tmp_path / "copy.csv"
        other.write_bytes(good.read_bytes())
    opt = [] if how == "RECORDING" else ["--validate" if how == "copy" else how]
    out = tmp_path / "out"
    rc, err = _cli(["diagnose", str(good), *opt, str(other), "--ship", "kvlcc2-linear", "--out", str(out)], capsys)
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert err.count(good.name) + err.count(other.name) >= 2 and "give each run once" in err
    assert ("identical content" if how == "copy" else "the same file") in err
    assert not out.exists()


def test_cli_refuses_a_bad_recording_in_one_line_and_writes_nothing(marin, tmp_path, capsys):
    zz, _, val = marin
    bad = _variant(zz, tmp_path / "deg_delta.csv", delta=np.degrees(zz.channels["delta"]))
    out = tmp_path / "out"
    rc, err = _cli(["diagnose", str(bad), "--ship", "kvlcc2-linear", "--validate", str(val), "--out", str(out)], capsys)
    assert rc == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert "deg_delta.csv" in err and "'delta'" in err and "deg?" in err and "cannot be simulated" not in err
    assert not out.exists()


def test_unstable_baseline_names_the_profile_and_parameter_not_the_recording(marin, tmp_path, capsys):
    """Reviewer item 11: kvlcc2-linear with a positive yaw damping Nur: the profile is at fault, and
    --fit-on (which simulates the given parameters first) is no way out."""
    from primitives.ship import PROFILE_DIR

    text = (PROFILE_DIR / "kvlcc2-linear.toml").read_text()
    nur = "yaw = [-0.017583188348917526,"
    assert nur in text
    prof = tmp_path / "unstable.toml"
    prof.write_text(text.replace(nur, "yaw = [0.0005,").replace('name = "kvlcc2-linear"', 'name = "kvlcc2-unstable"'))
    _, good, val = marin
    out = tmp_path / "out"
    rc, err = _cli(
        ["diagnose", str(good), "--ship", str(prof), "--fit-on", str(DATA / "MARIN_FREE_KVLCC2_zz_10_m.dat"), "--out", str(out)],
        capsys,
    )
    assert rc == 2 and len(err.splitlines()) == 1, err
    assert "'kvlcc2-unstable'" in err and "yaw motion is unstable" in err and "Nur = +0.0005" in err
    assert "refit it with --fit-on" not in err and not out.exists()


def test_without_out_nothing_is_left_in_the_temp_dir(tmp_path, monkeypatch, capsys):
    """Reviewer item 13: every run without --out left ~500 KB in /tmp/shiptrial-diagnose-*."""
    import tempfile

    from diagnose.battery import scenario

    rec = write_csv(scenario((), 17, n_prims=2).diagnose[0], tmp_path / "run.csv")
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.chdir(tmp_path)
    before = set(tmp_path.rglob("*"))
    rc = _run(["diagnose", str(rec), "--ship", "model-ship"])
    out = capsys.readouterr().out
    assert rc == 0 and "no files written: pass --out DIR" in out
    assert set(tmp_path.rglob("*")) == before


def _battery_runs(name: str, tmp: Path) -> list[Path]:
    from tests.physics import mmg_battery as battery

    paths = battery.write_case(battery.generate(battery.case(name)), tmp / name)
    return [p for role in ("calm", "diagnose", "validate") for p in paths[role]]


@pytest.mark.parametrize("name", ["current-0.7", "model-current-0.6"])
def test_mmg_battery_runs_pass_every_check_and_a_flipped_rudder_is_caught(tmp_path, name):
    """Independent physics (MMG, full and model scale): no check refuses a legitimate run; the same
    runs with the rudder's sign flipped are refused (the weakest legitimate case of the sweep: a
    turning circle in a current). The slow test below covers every case."""
    ship = load_profile("kvlcc2")
    for p in _battery_runs(name, tmp_path):
        rec = conform(load_recording(p), ship)[0]
        flipped = dataclasses.replace(rec, channels=rec.channels | {"delta": -rec.channels["delta"]})
        with pytest.raises(RecordingError, match="flip the sign of delta"):
            conform([flipped], ship)


def _case_passes_every_check(name: str, tmp: str) -> str:
    """The case's runs through every check with both KVLCC2 profiles ('' when all pass, else what failed)."""
    for p in _battery_runs(name, Path(tmp)):
        for prof in ("kvlcc2", "kvlcc2-linear"):
            try:
                if not conform(load_recording(p), load_profile(prof)):
                    return f"{name}: {p.name} with {prof}: nothing conformed"
            except RecordingError as exc:
                return f"{name}: {p.name} with {prof}: {exc}"
    return ""


@pytest.mark.slow
def test_every_mmg_battery_run_passes_every_check(tmp_path):
    """Every case of the battery, generated two at a time (generation is the cost; each case is seeded
    by its own definition, so the pool changes nothing but the wall time)."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from tests.physics import mmg_battery as battery

    names = [c.name for c in battery.CASES]
    with ProcessPoolExecutor(max_workers=2, mp_context=mp.get_context("spawn")) as pool:
        failed = [f for f in pool.map(_case_passes_every_check, names, [str(tmp_path)] * len(names)) if f]
    assert not failed, failed
