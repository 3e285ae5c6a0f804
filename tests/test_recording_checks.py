"""Recordings a user brings from elsewhere: scale, sample time, frame and units are checked and
said, never silently assumed (issue 13 "Recordings", issue 15)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cli.app import _run
from diagnose.battery import scenario
from diagnose.recording import RecordingError, load_recording, read_csv, write_csv
from diagnose.recording_checks import check_inputs, check_sample_time, conform, froude_scale
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def ship():
    return load_profile("model-ship")


@pytest.fixture(scope="module")
def run():
    """A model-ship run of the project's simulator, body-frame u, v, r (0.125 s)."""
    return scenario((), 17, n_prims=2).diagnose[0]


def _with(rec, tmp_path, name="r.csv", meta=None, **cols):
    """Write ``rec`` with columns replaced (u=..., v=..., tau_x=...) and read it back's path."""
    rec = dataclasses.replace(rec, channels=dict(rec.channels), y=rec.y.copy())
    for k, v in cols.items():
        if k in ("u", "v", "r"):
            rec.y[:, "uvr".index(k)] = v
        else:
            rec.channels[k] = v
    return write_csv(rec, tmp_path / name, meta=meta)


def test_body_frame_run_loads_and_conforms_unchanged(run, ship, tmp_path):
    rec = read_csv(_with(run, tmp_path))[0]
    out = conform([rec], ship)[0]
    assert out.sample_time == pytest.approx(ship.sample_time)
    np.testing.assert_allclose(out.y, run.y, atol=1e-6)


def test_earth_frame_velocities_are_refused(run, tmp_path):
    c, s = np.cos(run.psi), np.sin(run.psi)
    xd, yd = c * run.y[:, 0] - s * run.y[:, 1], s * run.y[:, 0] + c * run.y[:, 1]
    assert np.ptp(run.psi) > 1.0  # the run turns: earth and body frame differ
    with pytest.raises(RecordingError, match="earth-frame"):
        read_csv(_with(run, tmp_path, u=xd, v=yd))


def test_velocities_in_knots_are_refused(run, tmp_path):
    with pytest.raises(RecordingError, match="knots"):
        read_csv(_with(run, tmp_path, u=run.y[:, 0] * 1.9438, v=run.y[:, 1] * 1.9438))


def test_marin_dat_still_rotated_and_says_why():
    from pathlib import Path

    rec = load_recording(Path(__file__).resolve().parents[1] / "diagnose/data/MARIN_FREE_KVLCC2_tc_35_m.dat")[0]
    assert any("earth-frame" in n and "MARIN" in n for n in rec.notes)
    assert rec.scale == "full"


def test_all_zeros_recording_is_one_clear_line(tmp_path):
    t = np.arange(100) * 0.125
    lines = ["t,x,y,psi,u,v,r,tau_x,tau_y,tau_n"] + [f"{x},0,0,0,0,0,0,0,0,0" for x in t]
    p = tmp_path / "zeros.csv"
    p.write_text("\n".join(lines))
    with pytest.raises(RecordingError, match="does not move"):
        read_csv(p)


def test_a_track_standing_still_beside_a_moving_u_loads_without_a_traceback(tmp_path):
    """A position that never changes (a constant lat/lon, no noise) while u says 1 m/s: the frame
    check has no track speed to compare with and gives no verdict; it divided by the zero track
    speed (ZeroDivisionError, found by the loaders' fuzz test)."""
    t = np.arange(50) * 0.5
    lines = ["t,x,psi,u,lat,lon,v"] + [f"{a},{a + 0.5},{0.01 * i},1.0,1.0,1.0,0.0" for i, a in enumerate(t)]
    p = tmp_path / "still.csv"
    p.write_text("\n".join(lines) + "\n")
    try:
        read_csv(p)
    except RecordingError:
        pass


def test_absurd_speed_is_refused_not_hung(run, tmp_path):
    u = run.y[:, 0].copy()
    u[10] = 1e308
    with pytest.raises(RecordingError, match=r"column 'u'.*beyond any ship"):
        read_csv(_with(run, tmp_path, u=u))


def test_inputs_scaled_by_a_million_are_refused(run, ship, tmp_path):
    rec = read_csv(_with(run, tmp_path, tau_x=run.channels["tau_x"] * 1e6))[0]
    with pytest.raises(RecordingError, match=r"'tau_x'.*units"):
        check_inputs(rec, ship)


@pytest.mark.parametrize("kind", ["latin1", "binary", "directory"])
def test_unreadable_files_are_one_line(tmp_path, kind):
    p = tmp_path / "bad.csv"
    if kind == "directory":
        p.mkdir()
    else:
        p.write_bytes("t,x,y,psi\n0,1,2,caf\xe9\n".encode("latin-1") if kind == "latin1" else bytes(range(256)))
    with pytest.raises(RecordingError, match="directory|UTF-8") as exc:
        load_recording(p)
    assert "\n" not in str(exc.value)


def test_scale_header_parsed_and_froude_scaling_says_so(run, tmp_path):
    rec = read_csv(_with(run, tmp_path, meta={"scale": "model", "scale_factor": "45.7"}))[0]
    assert rec.scale == "model" and rec.scale_factor == pytest.approx(45.7)
    full, note = froude_scale(rec)
    lam, s = 45.7, np.sqrt(45.7)
    assert "Froude" in note and note in full.notes
    assert full.sample_time == pytest.approx(rec.sample_time * s)
    np.testing.assert_allclose(full.pos, rec.pos * lam)
    np.testing.assert_allclose(full.y[:, :2], rec.y[:, :2] * s)
    np.testing.assert_allclose(full.y[:, 2], rec.y[:, 2] / s)
    np.testing.assert_allclose(full.psi, rec.psi)
    np.testing.assert_allclose(full.channels["tau_x"], rec.channels["tau_x"] * lam**3)
    np.testing.assert_allclose(full.channels["tau_n"], rec.channels["tau_n"] * lam**4)
    assert full.scale == "full"


@pytest.mark.parametrize(
    "meta,needle",
    [
        ({"scale": "half"}, "model' or 'full"),
        ({"scale": "model"}, "scale_factor"),
        ({"sample_time": "abc"}, "sample_time"),
        ({"scale_factor": "-2"}, "scale_factor"),
    ],
)
def test_bad_scale_headers_are_refused(run, tmp_path, meta, needle):
    with pytest.raises(RecordingError, match=needle):
        read_csv(_with(run, tmp_path, meta=meta))


def test_sample_time_differing_from_the_profile_is_refused_or_resampled(run, ship, tmp_path):
    coarse = run.window(0, len(run.t), "")
    coarse = dataclasses.replace(
        coarse,
        t=run.t[::2],
        y=run.y[::2],
        psi=run.psi[::2],
        pos=run.pos[::2],
        channels={k: v[::2] for k, v in run.channels.items()},
        segments=None,
    )
    with pytest.raises(RecordingError, match=r"0\.25 s.*0\.125 s.*--resample"):
        check_sample_time(coarse, ship, resample=False)
    fine = check_sample_time(coarse, ship, resample=True)
    assert fine.sample_time == pytest.approx(0.125)
    assert any("resampled" in n for n in fine.notes)
    np.testing.assert_allclose(fine.y[::2], coarse.y[: len(fine.y[::2])], atol=1e-9)


def test_cli_refuses_other_sample_time_unless_resample(run, tmp_path, capsys):
    coarse = dataclasses.replace(
        run,
        t=run.t[::2],
        y=run.y[::2],
        psi=run.psi[::2],
        pos=run.pos[::2],
        channels={k: v[::2] for k, v in run.channels.items()},
        segments=None,
        meta={},
    )
    p = write_csv(coarse, tmp_path / "coarse.csv")
    assert _run(["diagnose", str(p), "--ship", "model-ship"]) == 2
    assert "--resample" in capsys.readouterr().err


def test_conform_froude_scales_a_model_scale_header_and_says_so(run, ship, tmp_path):
    """A recording whose header says model scale reaches the (full-scale) profile scaled, with a note."""
    lam = 4.0  # the model run of the ship at 1/4 scale: times / 2, lengths / 4, forces / 64, moments / 256
    model = dataclasses.replace(
        run,
        t=run.t / 2,
        pos=run.pos / lam,
        y=run.y * [0.5, 0.5, 2.0],
        meta={},
        channels={
            "tau_x": run.channels["tau_x"] / lam**3,
            "tau_y": run.channels["tau_y"] / lam**3,
            "tau_n": run.channels["tau_n"] / lam**4,
        },
    )
    rec = read_csv(_with(model, tmp_path, meta={"scale": "model", "scale_factor": str(lam)}))[0]
    out = conform([rec], ship)[0]
    assert out.sample_time == pytest.approx(ship.sample_time)
    assert any("Froude-scaled" in n for n in out.notes)
    np.testing.assert_allclose(out.pos, run.pos, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(out.y, run.y, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(out.channels["tau_n"], run.channels["tau_n"], rtol=1e-6)
