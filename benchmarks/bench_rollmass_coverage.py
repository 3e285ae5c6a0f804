"""Coverage of `shiptrial mass` (oe) intervals on the basin truth, measurable without refitting.

``fit`` runs the oe fits of :mod:`benchmarks.bench_rollmass_truth` (same seeds, so runs pair with it)
one process, one fit at a time, and stores per fit what the sandwich covariance needs: each dataset's
per-sample scores ``h_t = sum_channels J_t f_t`` (n x p), the residual per channel (n x 3), ``A = J^T J``,
the prior rows of ``J``, the estimate, its reported sd and the truth (one ``.npz`` per fit, so an
interrupted run keeps what it fitted). ``analyse`` re-evaluates covariance estimators on the stored fits
and prints per variant and case the z-scores ``(estimate - truth) / sd`` of mass and height, their
spread, and the 95 % coverage, for each estimator (:mod:`identify.rollmass.sandwich`).

    python benchmarks/bench_rollmass_coverage.py fit /tmp/cov --runs 4                      # stop 49: stopped after runs 0-1
    python benchmarks/bench_rollmass_coverage.py fit /tmp/quiet --runs 4 --quiet --like /tmp/cov   # the same fits, no noise
    python benchmarks/bench_rollmass_coverage.py analyse /tmp/cov --quiet-dir /tmp/quiet
    python benchmarks/bench_rollmass_coverage.py repeat --variant imu_mount --run 1 --case case2 --no-sensor-noise  # stop 50
    python benchmarks/bench_rollmass_coverage.py repeat --variant imu_mount --run 1 --case case2 --no-sensor-noise --store /tmp/s51/imu
    python benchmarks/bench_rollmass_coverage.py repeat --variant imu_mount --run 1 --case case2 --no-sensor-noise --store /tmp/s60c/cal --vary calibration  # stop 60: one dataset's sea
    python benchmarks/bench_rollmass_coverage.py sea_analyse /tmp/s51/imu   # stop 51: the spread against the meats

``repeat --store`` keeps each converged sea's Jacobian, residual and final point and the sea's own response in the
residual at the quiet fit's point; ``sea_analyse`` compares the load's spread over the seas with the sandwich from
the fitted residual, the leverage-corrected one the fit reports (:func:`identify.rollmass.sandwich.load_cov`) and
the one from that true response.

The ships of a run depend on ``--runs`` (the family is drawn at once), so a directory is resumed (fits already
stored are skipped) and paired only with the same ``--runs``.

This file holds ``fit`` and the command line; ``analyse`` is :mod:`benchmarks.rollmass_coverage_analysis`, ``repeat``
:mod:`benchmarks.rollmass_coverage_repeat`, ``sea_analyse`` and ``vary_analyse`` :mod:`benchmarks.rollmass_sea_analysis`,
and what a fit leaves (the captured covariance call, the stored scores, the truth's noise switches)
:mod:`benchmarks.rollmass_coverage_fits`.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, see bench_rollmass_truth.py

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.rollmass_coverage_analysis import analyse  # noqa: E402
from benchmarks.rollmass_coverage_fits import (  # noqa: E402
    capture,
    drop_column,
    load_fields,
    sea_scaled,
    sea_without_common,
    sensor_noise_off,
    store,
    waves_off,
)
from benchmarks.rollmass_coverage_repeat import ROLES, repeat  # noqa: E402
from benchmarks.rollmass_sea_analysis import sea_analyse, vary_analyse  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from primitives.errors import UserError  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

CONSTANT_SPEED = ("base", "sway_roll", "restoring", "imu_mount", "waves")


def fit(a: argparse.Namespace) -> None:
    if a.sea_scale != 1.0:
        sea_scaled(a.sea_scale)
    if a.own_sea:
        sea_without_common()
    if a.no_sensor_noise:
        sensor_noise_off()
    if a.no_waves:
        waves_off()
    outdir = Path(a.dir)
    outdir.mkdir(parents=True, exist_ok=True)
    seen = capture()
    sims = {}
    for variant in a.variants.split(","):
        seed = bt.variant_seed(a.seed, variant)  # as bench_rollmass_truth.py
        sims[variant] = bt.simulate_runs(variant, a.runs, seed, quiet=a.quiet)
    for run in range(a.runs):  # run-major: an interrupted run has about as many runs of every variant
        for variant, (ship, data) in sims.items():
            for case in a.cases.split(","):
                path = outdir / f"{variant}_{case}_run{run}.npz"
                if path.exists() or (a.like and not (Path(a.like) / path.name).exists()):
                    continue
                m_true, z_true = bt.truth_load(case)
                seen.clear()
                c0 = time.process_time()
                with tempfile.TemporaryDirectory() as d:
                    recs = bt.case_recordings(ship, data, case, run)
                    paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs]
                    if a.no_phi:  # no roll angle: no wall-sided heel input from the measured (sea-driven) roll
                        paths = [drop_column(p, "phi") for p in paths]
                    try:
                        e = estimate_from_files(*paths, method="oe")
                    except UserError as exc:
                        print(f"{path.name}: refused: {exc}", flush=True)
                        continue
                cpu = time.process_time() - c0
                if "J" not in seen:
                    print(f"{path.name}: no covariance ({'; '.join(e.warnings)[:80]})", flush=True)
                    continue
                keep = {"J": seen["J"]} if a.keep_jacobian else {}
                store(
                    seen,
                    path,
                    **load_fields(e, m_true, z_true),
                    converged=e.converged,
                    cpu=cpu,
                    rho=seen["rho"],
                    nu=seen["nu"],
                    **keep,
                )
                print(
                    f"{path.name}: m {e.m:.4f} ({m_true}) sd {e.m_sd:.4f}, z {e.zbar_m:.4f} ({z_true}) sd {e.zbar_m_sd:.4f}, "
                    f"conv {e.converged}, {cpu:.1f} s cpu",
                    flush=True,
                )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fit", help="run the fits and store what the covariance needs")
    f.add_argument("dir")
    f.add_argument("--runs", type=int, default=3, help="runs drawn per variant (fitted run-major; the ships depend on it)")
    f.add_argument("--variants", default=",".join(CONSTANT_SPEED))
    f.add_argument("--cases", default="case1,case2,case3")
    f.add_argument("--seed", type=int, default=2015)
    f.add_argument("--like", help="fit only the (variant, case, run) stored in this directory (pair a --quiet run)")
    f.add_argument("--no-sensor-noise", action="store_true", help="the waves kept, the IMU noise and bias off")
    f.add_argument("--sea-scale", type=float, default=1.0, help="the sea's forces times this")
    f.add_argument("--own-sea", action="store_true", help="the base disturbance without its component common to the DOFs")
    f.add_argument("--no-waves", action="store_true", help="the IMU noise and bias kept, the waves off")
    f.add_argument("--no-phi", action="store_true", help="the recordings without their roll angle column")
    f.add_argument("--quiet", action="store_true", help="no waves, no sensor noise (the same ships): the structure's bias")
    f.add_argument("--keep-jacobian", action="store_true", help="store the fit's whole Jacobian J too (about 4 MB a fit)")
    r = sub.add_parser("repeat", help="one ship and case on fresh seas: the interval's own calibration")
    r.add_argument("--variant", default="base")
    r.add_argument("--run", type=int, default=0)
    r.add_argument("--case", default="case1")
    r.add_argument("--realizations", type=int, default=16)
    r.add_argument("--runs", type=int, default=4, help="runs drawn per variant (the ships depend on it, as in `fit`)")
    r.add_argument("--seed", type=int, default=2015)
    r.add_argument("--sea-seed", type=int, default=777)
    r.add_argument("--sea-scale", type=float, default=1.0)
    r.add_argument("--no-sensor-noise", action="store_true", help="the sea alone")
    r.add_argument("--fresh-sensor", action="store_true", help="the IMU noise and bias drawn afresh on every sea too")
    r.add_argument("--store", help="keep each converged fit's Jacobian, residual and final point in this directory")
    r.add_argument("--vary", choices=("all",) + ROLES, default="all", help="a fresh sea for this role's dataset only")
    r.add_argument("--held-sea", type=int, default=0, help="with --vary ROLE: the other datasets' sea (this realization's)")
    r.add_argument("--freeze-noise", action="store_true", help="every fit on the held sea's fit's whiteners and weights")
    g = sub.add_parser("analyse", help="z-scores and coverage of covariance estimators on stored fits")
    g.add_argument("dir")
    g.add_argument("--quiet-dir", help="a `fit --quiet` of the same runs: split each error into bias and noise")
    g.add_argument("--part", action="append", help="NAME=DIR: fits with one noise source, against --quiet-dir")
    s = sub.add_parser("sea_analyse", help="a `repeat --store` directory: the spread against the sandwich's meats")
    s.add_argument("dir", help="a `repeat --store` directory, or several (comma-separated) of the same ship")
    v = sub.add_parser("vary_analyse", help="`repeat --vary` of each role and all: is the error a sum of the datasets' parts?")
    v.add_argument("prefix", help="the stores are PREFIX_nominal, PREFIX_calibration, PREFIX_loaded and PREFIX_all")
    a = ap.parse_args()
    {"fit": fit, "repeat": repeat, "analyse": analyse, "sea_analyse": sea_analyse, "vary_analyse": vary_analyse}[a.cmd](a)


if __name__ == "__main__":
    main()
