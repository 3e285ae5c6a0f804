"""Stop 51's check (docs/mass-accuracy.md): does the correlation over the seas of the datasets' load score sums
(``sea_analyse``'s per-dataset line) survive one fixed whitener and weights (sea 0's fit) for every sea? If it
vanished, the whiteners and weights each sea's stages estimate from all three datasets would couple them; it stays.
Needs the ``repeat --store`` directories of imu_mount run 1 case 2 (sea seeds 777, 778, 779) in /tmp/s51:

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_dataset_coupling.py
"""

import copy
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks import bench_rollmass_coverage as bc  # noqa: E402
from identify.rollmass import oe_fit
from identify.rollmass.api import estimate_from_files
from tests.physics import basin_truth as bt

c0 = time.process_time()
bc._sensor_noise_off()
V, RUN, CASE = "imu_mount", 1, "case2"
seed = 2015 + 1000 * (bt.VARIANTS + ("base",)).index(V)


class Got(Exception):
    pass


orig_best = oe_fit._best_start


def grab(datasets, *a, **k):
    raise Got(datasets)


def datasets_for(scale, key):
    bc._fresh_sea(scale, key)
    ship, data = bt.simulate_runs(V, 4, seed)
    oe_fit._best_start = grab
    try:
        with tempfile.TemporaryDirectory() as d:
            paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in bt.case_recordings(ship, data, CASE, RUN)]
            try:
                estimate_from_files(*paths, method="oe")
            except Got as g:
                return g.args[0]
    finally:
        oe_fit._best_start = orig_best
    raise RuntimeError("no datasets")


# sea 0 of seed 777: one real fit, to get its final problem (whiteners, weights)
seen = bc._capture()
bc._fresh_sea(1.0, [777, 0])
ship, data = bt.simulate_runs(V, 4, seed)
with tempfile.TemporaryDirectory() as d:
    paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in bt.case_recordings(ship, data, CASE, RUN)]
    e = estimate_from_files(*paths, method="oe")
prob0 = seen["prob"]
z0 = dict(np.load("/tmp/s51/imu1c2b/sea00.npz"))
assert float(z0["m"]) == e.m
x_q = z0["x_q"]
J0 = z0["J"]
a0 = np.linalg.inv(J0.T @ J0)[:, -2]
quiet = datasets_for(0.0, [777, 10**6])


def resid(ds):
    q = copy.copy(prob0)
    q.datasets = ds
    q.Y = [oe_fit._measured(d, prob0.kn.g) for d in ds]
    return q.residual(x_q)


fq = resid(quiet)
S, Sown = [], []
for dname, sseed in (("imu1c2b", 777), ("imu1c2_s778", 778), ("imu1c2_s779", 779)):
    for p in sorted(Path("/tmp/s51", dname).glob("sea*.npz")):
        k = int(p.stem[3:])
        ek = resid(datasets_for(1.0, [sseed, k])) - fq
        s, i = [], 0
        for n in z0["lengths"]:
            s.append((J0[i : i + 3 * n].T @ ek[i : i + 3 * n]) @ a0)
            i += 3 * n
        S.append(s)
        z = np.load(p)
        so, i = [], 0
        for n in z0["lengths"]:
            so.append((J0[i : i + 3 * n].T @ z["e_q"][i : i + 3 * n]) @ a0)
            i += 3 * n
        Sown.append(so)
for name, X in (("fixed whitener+weights (sea 0's)", np.array(S)), ("each sea's own whitener+weights", np.array(Sown))):
    c = np.corrcoef(X.T)[np.triu_indices(3, 1)]
    print(
        f"{name}: {len(X)} seas; sd per dataset {np.round(X.std(0, ddof=1) * 1e3, 2)} g; corr (0-1, 0-2, 1-2) {c.round(2)}; "
        f"sd of sum {X.sum(1).std(ddof=1) * 1e3:.2f} g vs independent {np.sqrt(X.var(0, ddof=1).sum()) * 1e3:.2f} g"
    )
print(f"{time.process_time() - c0:.0f} s cpu")
