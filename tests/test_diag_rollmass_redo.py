"""benchmarks/diag_rollmass_redo.py's ``--valley`` analysis (stop 57): on a constructed flat valley, one of whose
columns is scaled by 1e3, it names the flat parameter as the weakest direction of the column-scaled Jacobian, the
condition number is the valley's, and the cost along the Gauss-Newton step is the model's where the residual is linear;
``--profile``'s held parameter is held and its column dropped, and its factors are of ``M + X_v``; the documented
``--geodesic`` command runs (the geodesic LM's own tests: tests/test_rollmass_geodesic.py, stop 59)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks.diag_rollmass_redo import _Fixed, _profile, _valley

FLAT = 1e-4  # the valley's flatness: the X_v column is the m column but for this


class _Valley:
    """A linear least-squares problem whose cost hardly changes along ``X_v - m`` (a long flat valley: their columns
    differ by :data:`FLAT` in one row)."""

    free = ("k", "X_v", "m", "zbar_m")
    A = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, FLAT, 0.0, 0.0], [0.0, 1.0, 1.0, 0.3], [0.0, 0.2, 0.2, 1.0], [0.5, 0.0, 0.0, 0.1]])
    A[:, 0] *= 1e3  # one badly scaled column: without the column scaling the condition would be about 1e3 / FLAT
    b = np.array([1.0, 2e-4, 0.5, -0.4, 0.2])

    def residual(self, x: np.ndarray) -> np.ndarray:
        return self.A @ x - self.b

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        return self.A.copy()


def test_the_valley_analysis_names_the_flat_direction_and_the_cost_along_the_step():
    end = SimpleNamespace(prob=_Valley(), x=np.zeros(4))
    out = _valley(end)
    lines = out.split("\n")
    cond = float(lines[0].split()[2])
    assert 0.1 / FLAT < cond < 10 / FLAT  # the column-scaled J's condition is the valley's flatness
    weak = [w[:3].rstrip("+-0123456789.") for w in lines[1].split()[1:3]]
    assert sorted(weak) == ["X_v", "m"]  # the weakest direction is the valley's, X_v against m
    # linear residual: the actual cost change at t = 1 is the Gauss-Newton model's, and the full step solves it
    t1 = [p for p in lines[-1].split("; ") if p.startswith("t=1:")][0]
    actual, model = float(t1.split()[1]), float(t1.split("GN ")[1].rstrip(")"))
    assert np.isclose(actual, model, rtol=1e-3)  # printed to 4 figures
    r_min = _Valley.A @ np.linalg.lstsq(_Valley.A, _Valley.b, rcond=None)[0] - _Valley.b
    assert np.isclose(actual, r_min @ r_min - _Valley.b @ _Valley.b, rtol=1e-3)  # the step reaches the minimum


def test_a_profile_point_holds_its_parameter_and_drops_its_column():
    prob = _Valley()
    fixed = _Fixed(prob, 1, 7.0)
    y = np.array([0.1, 0.2, 0.3])
    assert np.array_equal(fixed.full(y), [0.1, 7.0, 0.2, 0.3])
    assert np.array_equal(fixed.residual(y), prob.residual(np.array([0.1, 7.0, 0.2, 0.3])))
    assert np.array_equal(fixed.jacobian(y), np.delete(prob.A, 1, axis=1))


def test_a_profile_holds_the_sway_mass_at_factors_of_the_ends():
    class Held(_Valley):
        kn = SimpleNamespace(M=3.0)

    prob, x = Held(), np.array([0.1, 2.0, 0.3, 0.4])  # M + X_v = 5
    out = _profile(SimpleNamespace(prob=prob, x=x), 1.0, 0.0, (1.0, 2.0))
    lines = [q.strip() for q in out.split("\n")]
    assert lines[0].startswith("M+X_v x1 (2)") and lines[1].startswith("M+X_v x2 (7)")  # X_v = fac (M + X_v) - M


@pytest.mark.slow
def test_the_documented_geodesic_command_runs_on_a_stored_creeping_fit():
    """docs/mass-accuracy.md's `--valley --geodesic` command on imu_mount 6/1 (stop 57's table: the exact path stalls,
    the geodesic LM converged at -11.66 % / -31.1 mm; -11.715 % since stop 62's corrected innovation sd, which moves
    every oe answer by about 0.1 point); the merge of stop 57 once broke it with an AttributeError."""
    root = Path(__file__).resolve().parents[1]
    cmd = [sys.executable, "benchmarks/diag_rollmass_redo.py", "benchmarks/rollmass_redo_s56.jsonl", "--runs", "30"]
    cmd += ["--only", "imu_mount/6/case1", "--valley", "--geodesic", "300"]
    out = subprocess.run(cmd, cwd=root, capture_output=True, text=True, timeout=600, env={**os.environ, "PYTHONPATH": str(root)})
    assert out.returncode == 0, out.stderr[-2000:]
    line = next(ln for ln in out.stdout.splitlines() if "geodesic LM" in ln)
    assert "converged" in line and "fit conv True" in line
    m = float(line.split(" m ")[1].split()[0])
    assert abs(m - -11.715) < 0.05
