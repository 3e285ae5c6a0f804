"""benchmarks/diag_rollmass_truth_terms.py (stop 56; the review's draft, adapted): zeroing every term a variant adds
gives base's ship on the same draw, only the named terms change (in a copy: a fresh draw is untouched), the
draw-patch is restored, and each bad option or an unwritable --dump is one stderr line, exit 2, no traceback and no
dump, before any simulation (no fits here)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks import diag_rollmass_truth_terms as diag
from tests.physics import basin_truth as bt

SCRIPT = Path(diag.__file__).resolve()


def _fields(ship: bt.Ship) -> dict:
    return {f.name: getattr(ship, f.name) for f in dataclasses.fields(ship)}


@pytest.mark.parametrize(
    "variant,terms", [("sway_roll", ["Yp", "Yphi", "Kv", "Np", "Ypd"]), ("imu_mount", ["x_imu", "eps0", "eps1", "eps2"])]
)
def test_every_term_of_a_variant_zeroed_is_base_on_the_same_draw(variant, terms):
    got, base = _fields(diag.zeroed(bt.draw_ships(5, variant, 7), terms)), _fields(bt.draw_ships(5, "base", 7))
    assert [k for k in got if not np.array_equal(got[k], base[k])] == []


def test_only_the_named_terms_change_and_a_fresh_draw_is_untouched():
    before = _fields(bt.draw_ships(5, "sway_roll", 7))
    got = _fields(diag.zeroed(bt.draw_ships(5, "sway_roll", 7), ["Yp", "eps1"]))
    assert [k for k in got if not np.array_equal(got[k], before[k])] == ["Yp"]  # sway_roll has no misalignment
    im = _fields(diag.zeroed(bt.draw_ships(5, "imu_mount", 7), ["eps1"]))
    ref = _fields(bt.draw_ships(5, "imu_mount", 7))
    assert np.all(ref["eps"][:, 1] != 0) and np.all(im["eps"][:, 1] == 0)
    assert np.array_equal(im["eps"][:, [0, 2]], ref["eps"][:, [0, 2]])
    assert np.array_equal(_fields(bt.draw_ships(5, "sway_roll", 7))["Yp"], before["Yp"])


def test_the_draw_patch_zeroes_inside_and_is_restored_after():
    real = bt.draw_ships
    with diag.zeroed_draws(["Yp"]):
        assert np.all(bt.draw_ships(3, "sway_roll", 7).Yp == 0)
    assert bt.draw_ships is real and np.all(bt.draw_ships(3, "sway_roll", 7).Yp != 0)


@pytest.mark.parametrize(
    "bad,option",
    [
        (["--zero", "Yq"], "--zero"),
        (["--zero", "Yp,Yp"], "--zero"),
        (["--zero", "x_imu"], "--zero"),  # already zero on sway_roll: the dump would name a term that changed nothing
        (["--cases", "case4"], "--cases"),
        (["--cases", "case2,case2"], "--cases"),
        (["--last", "30"], "--last"),
        (["--last", "-1"], "--last"),
        (["--oracle", "--quiet"], "--quiet"),
        (["--oracle", "--cases", "case2"], "--cases"),
        (["--dump-in-missing-folder"], "--dump"),
    ],
)
def test_bad_option_is_one_line_naming_it_exit_2_no_dump(bad, option, tmp_path):
    dump = tmp_path / "d.jsonl"
    if bad == ["--dump-in-missing-folder"]:
        dump, bad = tmp_path / "no" / "d.jsonl", []
    p = subprocess.run(
        [sys.executable, str(SCRIPT), "--variant", "sway_roll", "--dump", str(dump), *bad],
        capture_output=True,
        text=True,
        timeout=60,  # the check comes before the 30-run simulation
    )
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
    assert f"error: {option}" in p.stderr and "fix:" in p.stderr and "Traceback" not in p.stderr
    assert not dump.exists() and p.stdout == ""
