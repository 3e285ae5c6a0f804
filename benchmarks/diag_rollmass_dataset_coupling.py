"""Stop 51's check (docs/mass-accuracy.md): does the correlation over the seas of the datasets' load score sums
(``sea_analyse``'s per-dataset line) survive one fixed whitener and weights (sea 0's fit) for every sea? If it
vanished, the whiteners and weights each sea's stages estimate from all three datasets would couple them; it stays.
Needs the ``repeat --store`` directories of imu_mount run 1 case 2 (sea seeds 777, 778, 779) under ``--root``:

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_dataset_coupling.py --root /tmp/s51
"""

from __future__ import annotations

import argparse
import copy
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.rollmass_coverage_fits import capture, sensor_noise_off  # noqa: E402
from benchmarks.rollmass_coverage_repeat import fresh_sea  # noqa: E402
from benchmarks.rollmass_sea_analysis import score_sums  # noqa: E402
from identify.rollmass import oe_fit  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

V, RUN, CASE = "imu_mount", 1, "case2"
SEED = bt.variant_seed(2015, V)
STORES = (("imu1c2b", 777), ("imu1c2_s778", 778), ("imu1c2_s779", 779))


class _Got(Exception):
    pass


def _grab(datasets, *a, **k):
    raise _Got(datasets)


def _recordings(d: str) -> list[Path]:
    ship, data = bt.simulate_runs(V, 4, SEED)
    return [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in bt.case_recordings(ship, data, CASE, RUN)]


def datasets_for(scale: float, key: list[int]):
    """The datasets the fit reads for one sea (``scale`` of the truth's base disturbance, its stream ``key``),
    stopped before any fitting."""
    fresh_sea(scale, key)
    orig = oe_fit._best_start
    oe_fit._best_start = _grab
    try:
        with tempfile.TemporaryDirectory() as d:
            estimate_from_files(*_recordings(d), method="oe")
    except _Got as g:
        return g.args[0]
    finally:
        oe_fit._best_start = orig
    raise RuntimeError("the fit did not reach its first problem")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", type=Path, default=Path("/tmp/s51"), help="where the repeat --store directories are")
    args = ap.parse_args()
    c0 = time.process_time()
    sensor_noise_off()
    seen = capture()  # sea 0 of seed 777: one real fit, for its final problem (whiteners, weights)
    fresh_sea(1.0, [777, 0])
    with tempfile.TemporaryDirectory() as d:
        e = estimate_from_files(*_recordings(d), method="oe")
    prob0 = seen["prob"]
    z0 = dict(np.load(args.root / STORES[0][0] / "sea00.npz"))
    if abs(float(z0["m"]) - e.m) > 1e-6 * abs(e.m):  # the same fit to rounding (the store may be older code's)
        sys.exit(f"{args.root / STORES[0][0]}/sea00.npz is not this fit's sea 0 (m {float(z0['m'])} against {e.m})")
    x_q, J0 = z0["x_q"], z0["J"]
    a0 = np.linalg.inv(J0.T @ J0)[:, -2]

    def resid(ds):
        q = copy.copy(prob0)
        q.datasets, q.Y = ds, [oe_fit._measured(d, prob0.kn.g) for d in ds]
        return q.residual(x_q)

    fq = resid(datasets_for(0.0, [777, 10**6]))
    fixed, own = [], []
    for dname, sea_seed in STORES:
        for p in sorted((args.root / dname).glob("sea*.npz")):
            fixed.append(score_sums(J0, resid(datasets_for(1.0, [sea_seed, int(p.stem[3:])])) - fq, z0["lengths"], a0))
            own.append(score_sums(J0, np.load(p)["e_q"], z0["lengths"], a0))
    for name, X in (("fixed whitener+weights (sea 0's)", np.array(fixed)), ("each sea's own whitener+weights", np.array(own))):
        c = np.corrcoef(X.T)[np.triu_indices(3, 1)]
        print(
            f"{name}: {len(X)} seas; sd per dataset {np.round(X.std(0, ddof=1) * 1e3, 2)} g; corr (0-1, 0-2, 1-2) "
            f"{c.round(2)}; sd of sum {X.sum(1).std(ddof=1) * 1e3:.2f} g vs independent {np.sqrt(X.var(0, ddof=1).sum()) * 1e3:.2f} g"
        )
    print(f"{time.process_time() - c0:.0f} s cpu")


if __name__ == "__main__":
    main()
