"""`shiptrial mass` with files in the wrong roles and no role headers, and a header speed in knots: refused
before the fit (identify/rollmass/roles.py, api.default_speed_warnings). Recordings from the independent
basin truth (tests/physics/basin_truth.py); the refusals come before the fit, so these tests are fast."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from cli.app import _run
from identify.rollmass import roles
from identify.rollmass.api import default_speed_warnings, order_warnings
from identify.rollmass.model import Load, load_profile
from identify.rollmass.recording import read_roll_csv
from primitives.errors import UserError
from tests.physics import basin_truth as bt

CAL = "0.2@-0.256"


@pytest.fixture(scope="module")
def bare(tmp_path_factory) -> list[Path]:
    """Case 2 (nominal, 0.2 kg, 0.4 kg) of one basin-truth run, written without the role and load headers
    (a logger that does not know them): only the order says which file is which."""
    d = tmp_path_factory.mktemp("massroles")
    ship, data = bt.simulate_runs("base", 1, 4, length=0.6)
    out = []
    for r in bt.case_recordings(ship, data, "case2", 0):
        r.meta = {k: v for k, v in r.meta.items() if k not in ("role", "load_kg", "load_z_m")}
        out.append(bt.write_csv(r, d / f"{r.name}.csv"))
    return out


def _error(capsys, argv: list) -> str:
    assert _run(["mass", *map(str, argv)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize("order", [(1, 0, 2), (0, 2, 1), (2, 0, 1), (2, 1, 0)])
def test_files_in_the_wrong_order_without_role_headers_are_refused(bare, capsys, order):
    # on main these fitted: N L C to 0.097 kg for 0.2 kg without a warning, C N L and L N C for 190-200 s CPU each
    # to a fit that did not converge (base run 0, stop 52)
    files = [bare[i] for i in order]
    msg = _error(capsys, [*files, "--known-load", CAL])
    assert "wrong roles" in msg and "NOMINAL CALIBRATION LOADED" in msg and str(files[1]) in msg


def _checked(files: list[Path], cal: Load, role_headers: bool = False) -> list[str]:
    read = [read_roll_csv(p) for p in files]
    metas = [dict(m, role=role) if role_headers else m for (_, m), role in zip(read, ("nominal", "calibration", "loaded"))]
    prof = load_profile()
    prof = replace(prof, known=replace(prof.known, U=float(metas[0]["speed_m_s"])))
    return order_warnings([r for r, _ in read], files, metas, prof, cal)


def test_the_right_order_passes_the_check(bare):
    assert _checked(bare, Load(0.2, -0.256)) == []


def test_the_nominal_run_given_last_is_warned(bare):
    # C L N: the calibration check holds (0.2 -> 0.4 kg changes the roll as 0 -> 0.2 kg does), the loaded run rolls
    # faster than the nominal: on main a negative mass with the generic interval warning only
    (w,) = _checked([bare[1], bare[2], bare[0]], Load(0.2, -0.256))
    assert "rolls faster" in w and "wrong roles" in w and "below the roll centre" in w


def test_role_headers_that_confirm_the_order_turn_the_refusal_into_a_warning_on_the_known_load(bare):
    (w,) = _checked([bare[0], bare[2], bare[1]], Load(0.2, -0.256), role_headers=True)
    assert "check the known load" in w and "wrong roles" not in w


def test_a_load_too_small_to_change_the_roll_is_not_judged(bare):
    rc = roles.measure_roles([read_roll_csv(p)[0] for p in bare], load_profile(), Load(0.05, -0.03))
    assert abs(rc.predicted) < roles.MIN_PREDICTED and roles.role_message(rc, bare, Load(0.05, -0.03)) is None


def test_the_predicted_change_has_the_physical_sign():
    prof = load_profile()
    assert roles.predicted_change(prof, Load(0.2, -0.256)) < -0.1  # a load on deck: lower GM, more inertia
    assert roles.predicted_change(prof, Load(0.2, 0.1)) > 0  # ballast below the roll centre stiffens the roll


def test_a_header_speed_in_knots_is_refused_before_the_fit(bare, capsys, tmp_path):
    # stops 50-51: '# speed_m_s: 0.97' (0.5 m/s in knots) with the default profile was warned after a full fit
    # without the u column, which would name the contradiction first (its mean 0.5 m/s against the header)
    files = []
    for p in bare:
        lines = [
            "# speed_m_s: 0.97" if ln.startswith("# speed_m_s:") else ln if ln.startswith("#") else ln.rsplit(",", 1)[0]
            for ln in p.read_text().splitlines()
        ]
        assert lines[len(lines) - len([ln for ln in lines if not ln.startswith("#")])] == "t,delta,p,a_s,r,phi"
        (tmp_path / p.name).write_text("\n".join(lines) + "\n")
        files.append(tmp_path / p.name)
    msg = _error(capsys, [*files, "--known-load", CAL])
    assert str(files[0]) in msg and "speed_m_s: 0.97" in msg and "knots" in msg and "m/s" in msg


def test_a_header_speed_far_from_the_default_profile_but_not_knots_is_warned():
    prof, paths = load_profile(), [Path("a.csv")] * 3
    metas = [{"speed_m_s": "1.5"}] * 3
    fast = replace(prof, known=replace(prof.known, U=1.5))
    (w,) = default_speed_warnings(prof, fast, True, paths, metas)
    assert "speed_m_s 1.5" in w and "200 % off" in w
    knots = replace(prof, known=replace(prof.known, U=0.97))
    with pytest.raises(UserError, match="reads as knots"):
        default_speed_warnings(prof, knots, True, paths, [{"speed_m_s": "0.97"}] * 3)
    assert default_speed_warnings(prof, knots, False, paths, metas) == []  # a given profile is refused earlier


def _header(files: list[Path], dst: Path, old: str, new: str | None) -> list[Path]:
    """``files`` copied into ``dst`` with the header line starting ``# old:`` replaced by ``new`` (None: dropped)."""
    out = []
    for p in files:
        lines = [(new if ln.startswith(f"# {old}:") else ln) for ln in p.read_text().splitlines()]
        (dst / p.name).write_text("\n".join(ln for ln in lines if ln is not None) + "\n")
        out.append(dst / p.name)
    return out


@pytest.mark.parametrize(
    ("old", "new", "key"), [("imu_z_m", "# imu_z: -0.05", "imu_z_m"), ("speed_m_s", "# Speed_m_s: 0.5", "speed_m_s")]
)
def test_a_header_key_under_another_name_is_refused(bare, capsys, tmp_path, old, new, key):
    # stop 52's sweep: '# imu_z: -0.05' was ignored and the profile's IMU z -0.09 m used without a word
    files = _header(bare, tmp_path, old, new)
    msg = _error(capsys, [*files, "--known-load", CAL])
    assert str(files[0]) in msg and new in msg and f"'# {key}:'" in msg and "rename" in msg


def test_an_unknown_header_key_is_noted(bare, tmp_path):
    files = _header(bare, tmp_path, "dataset", "# operator: Linder")
    assert any("header '# operator:' is not read" in n for n in read_roll_csv(files[0])[0].notes)


@pytest.mark.parametrize("which", ["all", "one"])
def test_a_ship_header_the_profile_contradicts_is_refused(bare, capsys, tmp_path, which):
    # stop 52's sweep: '# ship: seed003_basin' with the default (Our Lass II) profile was read without a word
    files = _header(bare if which == "all" else bare[:1], tmp_path, "ship", "# ship: seed003_basin")
    files += bare[len(files) :]
    msg = _error(capsys, [*files, "--known-load", CAL])
    assert "seed003_basin" in msg and ("--profile" in msg if which == "all" else "one ship" in msg)


def test_a_yaw_rate_in_degrees_is_named_not_the_rudder(bare, capsys, tmp_path):
    # stop 52's sweep: r in deg/s was refused as "column 'delta' is 41 times the rudder angle ...: give delta in radians"
    files = []
    for p in bare:
        lines = p.read_text().splitlines()
        k = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
        j = lines[k].split(",").index("r")
        rows = [ln.split(",") for ln in lines[k + 1 :]]
        body = [",".join(r[:j] + [repr(57.2958 * float(r[j]))] + r[j + 1 :]) for r in rows]
        (tmp_path / p.name).write_text("\n".join(lines[: k + 1] + body) + "\n")
        files.append(tmp_path / p.name)
    msg = _error(capsys, [*files, "--known-load", CAL])
    assert "column 'r'" in msg and "rad/s" in msg and "column 'delta'" not in msg
