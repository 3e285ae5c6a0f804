"""Which of a basin-truth variant's terms costs ``oe`` (or the stop-55 oracle) accuracy (stop 56).

The variant's ships are drawn as the truth bench draws them (``--runs 30`` family, seed 2015 and the variant's
offset), then a COPY of the draw has the named terms zeroed before the recordings are simulated: basin_truth's code
and its random streams are untouched, so a run differs from the family's run by those terms only (same rudder,
sea and sensor noise). ``oe`` is fitted as the bench fits it (``bench_rollmass_truth._one``: the three CSVs read
by ``estimate_from_files``); ``--oracle`` runs ``benchmarks/rollmass_oracle.py`` on the same changed ships instead.

Terms: ``Yp Yphi Kv Np`` (sway_roll's couplings), ``Ypd`` (Y_pdot set equal to K_vdot: symmetric added mass),
``x_imu`` (the IMU at midship), ``eps0 eps1 eps2`` (its misalignment about x, y, z).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_truth_terms.py --variant sway_roll --zero Yp,Yphi --dump D
    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_truth_terms.py --variant imu_mount --quiet --cases case2,case3 --dump D
    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_truth_terms.py --variant sway_roll --zero Yp,Yphi,Kv,Np,Ypd --oracle --dump D

Rows are the bench's (``--dump`` format of bench_rollmass_truth, its family field naming the zeroed terms), so
``benchmarks/compare_rollmass_dumps.py`` pairs them with ``benchmarks/rollmass_family_s54.jsonl``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, as the bench

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_rollmass_truth as bench  # noqa: E402
import numpy as np  # noqa: E402

from tests.physics import basin_truth as bt  # noqa: E402

TERMS = ("Yp", "Yphi", "Kv", "Np", "Ypd", "x_imu", "eps0", "eps1", "eps2")
FAMILY_RUNS, FAMILY_SEED = 30, 2015  # the stop-54 family's draw (bench_rollmass_truth --runs 30)


def zeroed(ship: bt.Ship, terms: list[str]) -> bt.Ship:
    """``ship`` with ``terms`` switched off in place (``Ypd``: Y_pdot = K_vdot, the paper's symmetric coupling)."""
    for t in terms:
        if t.startswith("eps"):
            ship.eps[:, int(t[3])] = 0.0
        elif t == "Ypd":
            ship.Ypd = ship.Kvd.copy()
        else:
            setattr(ship, t, np.zeros_like(getattr(ship, t)))
    return ship


def _oe(a: argparse.Namespace, terms: list[str], runs: range) -> None:
    """The bench's oe fits of ``runs`` on the changed ships, each row appended to ``a.dump`` as it finishes."""
    seed = FAMILY_SEED + 1000 * (bt.VARIANTS + ("base",)).index(a.variant)
    ship = zeroed(bt.draw_ships(FAMILY_RUNS, a.variant, seed), terms)
    data = {
        name: bt.simulate(ship, a.variant, (m, zm), samples, seed * 7919 + 101 * i + 1, a.quiet)
        for i, (name, (samples, m, zm)) in enumerate(bt.DATASETS.items())
    }
    family = {"diag": "s56 truth terms", "zero": ",".join(terms), "quiet": a.quiet}
    heel = bench.rm_restoring.DEFAULT_HEEL_REFERENCE
    with open(a.dump, "w") as fh:
        for run in runs:
            for case in a.cases.split(","):
                recs = bt.case_recordings(ship, data, case, run)
                for r in bench._one((a.variant, run, case, recs, ["oe"], True, heel, family)):
                    fh.write(json.dumps(r, default=bool) + "\n")
                    fh.flush()
                    print(r[:7], flush=True)


def _oracle(a: argparse.Namespace, terms: list[str]) -> None:
    """benchmarks/rollmass_oracle.py on the changed ships: its draw goes through :func:`zeroed`."""
    import rollmass_oracle

    draw = bt.draw_ships
    Path(a.dump).write_text("")  # the oracle appends; a dump holds one diagnostic's rows
    bt.draw_ships = lambda n, variant, seed: zeroed(draw(n, variant, seed), terms)
    sys.argv = ["rollmass_oracle.py", "--variants", a.variant, "--runs", str(a.last + 1), "--dump", a.dump]
    rollmass_oracle.main()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", required=True, choices=bt.VARIANTS + ("base",))
    ap.add_argument("--zero", default="", help=f"comma-separated terms to switch off: {', '.join(TERMS)}")
    ap.add_argument("--quiet", action="store_true", help="no sea, no sensor noise (oe only)")
    ap.add_argument("--last", type=int, default=6, help="runs 0..LAST of the 30-run family")
    ap.add_argument("--cases", default="case1,case2,case3", help="oe only; the oracle fits its own")
    ap.add_argument("--oracle", action="store_true", help="run the stop-55 oracle instead of oe")
    ap.add_argument("--dump", required=True, help="rows written here (emptied first)")
    a = ap.parse_args()
    terms = [t for t in a.zero.split(",") if t]
    bad = [t for t in terms if t not in TERMS] + [c for c in a.cases.split(",") if c not in bt.CASES]
    if bad or not 0 <= a.last < FAMILY_RUNS:
        ap.exit(
            2,
            f"{ap.prog}: error: --zero/--cases/--last: {bad or a.last} unknown; fix: terms of {TERMS}, cases of {tuple(bt.CASES)}, 0 <= last < 30\n",
        )
    if a.oracle:
        _oracle(a, terms)
    else:
        _oe(a, terms, range(a.last + 1))


if __name__ == "__main__":
    main()
