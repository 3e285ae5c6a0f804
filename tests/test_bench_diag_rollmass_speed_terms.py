"""benchmarks/rollmass_surge_speed.py and benchmarks/diag_rollmass_speed_terms.py (stop 62): the surge equation's
speed (S2) recovers a speed made by (S1) where the 0.2 Hz low-pass rounds its kinks, the candidate keeps
``followed_speed``'s decision (a constant speed stays held), and a bad switch or an unwritable --dump is one stderr
line, exit 2, before any simulation (no fits here)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np

from benchmarks import diag_rollmass_speed_terms as diag
from benchmarks import rollmass_surge_speed as surge
from identify.rollmass.simulate import RollRecording
from identify.rollmass.speed import followed_speed
from primitives.iir import filtfilt, lfilter
from primitives.zerophase import lowpass

SCRIPT = Path(diag.__file__).resolve()


def _slowing(n: int = 6000, T: float = 0.02) -> tuple[RollRecording, np.ndarray]:
    """A ship slowing in joystick turns by (S1): rudder steps of 1-6 s, the speed a lag of the drag ``delta^2``
    and of ``r^2`` (the quasi-steady ``v r``), at a time constant on the candidate's grid."""
    rng = np.random.default_rng(62)
    delta = np.zeros(n)
    i = 0
    while i < n:
        hold = int(rng.uniform(1.0, 6.0) / T)
        delta[i : i + hold] = rng.choice([-1, 0, 1]) * np.deg2rad(rng.uniform(8, 28))
        i += hold
    delta = lfilter([1 - np.exp(-T / 0.3)], [1, -np.exp(-T / 0.3)], delta)  # the servo's rate
    r = lfilter([1 - np.exp(-T / 1.5)], [1, -np.exp(-T / 1.5)], 0.6 * delta)  # the ship's yaw response
    a = np.exp(-T / float(surge.TAU_GRID[10]))
    drag = 1.0 - 0.9 * delta**2 - 1.5 * r**2
    s = lfilter([1 - a], [1, -a], drag - drag[0]) + drag[0]
    u = 0.5 * s
    rec = RollRecording("x", T, delta, np.zeros(n), np.zeros(n), r, U=float(np.mean(u)), u=u)
    return rec, u / np.mean(u)


def test_the_surge_speed_recovers_a_speed_the_low_pass_rounds():
    rec, want = _slowing()
    got = surge.followed(rec)
    assert got is not None and followed_speed(rec) is not None
    low = filtfilt(*lowpass(2, 0.2, 1.0 / rec.T), want, padtype="even")
    mid = slice(250, -250)
    err_surge, err_low = np.std(got[mid] - want[mid]), np.std(low[mid] - want[mid])
    assert err_surge < 1e-6 and err_low > 1e-3, (err_surge, err_low)  # measured: about 1e-13 and 3e-3


def test_a_constant_speed_stays_held():
    rec, _ = _slowing()
    held = dataclasses.replace(rec, u=np.full(rec.n, 0.5) + 0.002 * np.random.default_rng(1).standard_normal(rec.n))
    assert followed_speed(held) is None and surge.followed(held) is None
    assert surge.followed(dataclasses.replace(rec, u=None)) is None


def _run(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, cwd=tmp_path, timeout=120)


def test_a_bad_switch_or_dump_is_one_line_and_exit_2_before_simulating(tmp_path):
    dump = tmp_path / "d.jsonl"
    for args in (["--switches", "main,lp1", "--dump", str(dump)], ["--dump", str(tmp_path / "no" / "d.jsonl")]):
        p = _run(tmp_path, *args)
        assert p.returncode == 2 and p.stdout == "", p
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and "fix:" in lines[0] and "Traceback" not in p.stderr, p.stderr
    assert not dump.exists()
