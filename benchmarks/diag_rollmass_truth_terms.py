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

oe's rows are the bench's (``--dump`` format of bench_rollmass_truth, its family field naming the zeroed terms), so
``benchmarks/compare_rollmass_dumps.py`` pairs them with ``benchmarks/rollmass_family_s54.jsonl``; the oracle's rows
are rollmass_oracle's with ``/zero=TERMS`` appended to their variant (``rollmass_oracle.py --from-dump`` tells them
from the unmodified variant's). ``--quiet`` and ``--cases`` are oe's only and refused with ``--oracle``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from unittest import mock

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, as the bench

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_rollmass_truth as bench  # noqa: E402
import numpy as np  # noqa: E402
import rollmass_oracle  # noqa: E402

from tests.physics import basin_truth as bt  # noqa: E402

TERMS = ("Yp", "Yphi", "Kv", "Np", "Ypd", "x_imu", "eps0", "eps1", "eps2")
# the stop-54 family's draw (bench_rollmass_truth --runs 30), as the oracle reads it: one source for both paths
FAMILY_RUNS, FAMILY_SEED = rollmass_oracle.FAMILY_RUNS, rollmass_oracle.FAMILY_SEED


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


@contextmanager
def zeroed_draws(terms: list[str]) -> Iterator[None]:
    """Every ``basin_truth.draw_ships`` inside the block returns the draw with ``terms`` zeroed (restored after),
    so the bench's and the oracle's own seeding (``simulate_runs``, ``loaded_recording``) is what pairs the runs."""
    draw = bt.draw_ships
    with mock.patch.object(bt, "draw_ships", lambda n, variant, seed: zeroed(draw(n, variant, seed), terms)):
        yield


def _oe(a: argparse.Namespace, terms: list[str], cases: list[str]) -> None:
    """The bench's oe fits of runs 0..``a.last`` on the changed ships, each row appended to ``a.dump`` as it ends."""
    seed = bt.variant_seed(FAMILY_SEED, a.variant)  # bench_rollmass_truth._jobs' offset
    with zeroed_draws(terms):
        ship, data = bt.simulate_runs(a.variant, FAMILY_RUNS, seed, quiet=a.quiet)
    family = {"diag": "s56 truth terms", "zero": ",".join(terms), "quiet": a.quiet}
    heel = bench.rm_restoring.DEFAULT_HEEL_REFERENCE
    for run in range(a.last + 1):
        for case in cases:
            recs = bt.case_recordings(ship, data, case, run)
            for r in bench._one((a.variant, run, case, recs, ["oe"], True, heel, family)):
                with open(a.dump, "a") as fh:
                    fh.write(json.dumps(r, default=bool) + "\n")
                print(r[:7], flush=True)


def _oracle(a: argparse.Namespace, terms: list[str]) -> None:
    """rollmass_oracle.run_variant on the changed ships; each row's variant names the zeroed terms."""
    with zeroed_draws(terms):
        rows = rollmass_oracle.run_variant(a.variant, a.last + 1, None)
    with open(a.dump, "a") as fh:
        for row in rows:
            row["variant"] += "/zero=" + ",".join(terms)
            fh.write(json.dumps(row) + "\n")
    print(rollmass_oracle.table(rows, None))


def _bad(a: argparse.Namespace, ap: argparse.ArgumentParser, terms: list[str], cases: list[str]) -> str | None:
    """The first bad option as ``OPTION VALUE: what; fix: how``, or None."""
    unknown = [t for t in terms if t not in TERMS]
    if unknown or len(set(terms)) < len(terms):
        what = f"unknown {', '.join(unknown)}" if unknown else "a term twice"
        return f"--zero {a.zero}: {what}; fix: distinct terms of {', '.join(TERMS)}"
    for option, given in (("--quiet", a.quiet), ("--cases", a.cases != ap.get_default("cases"))):
        if a.oracle and given:
            return f"{option}: oe only; fix: drop it with --oracle (the oracle fits its own datasets, noisy)"
    if not cases or [c for c in cases if c not in bt.CASES] or len(set(cases)) < len(cases):
        return f"--cases {a.cases!r}: unknown, empty or repeated; fix: distinct cases of {', '.join(bt.CASES)}"
    if not 0 <= a.last < FAMILY_RUNS:
        return f"--last {a.last}: out of range; fix: 0 <= LAST <= {FAMILY_RUNS - 1}"
    seed = bt.variant_seed(FAMILY_SEED, a.variant)
    same = [t for t in terms if _unchanged(bt.draw_ships(FAMILY_RUNS, a.variant, seed), t)]
    if same:
        return f"--zero {a.zero}: {', '.join(same)} already zero in {a.variant}; fix: drop them (the dump would name them)"
    return None


def _unchanged(ship: bt.Ship, term: str) -> bool:
    """Whether zeroing ``term`` leaves ``ship`` (a fresh draw) as it is."""
    before = {k: np.copy(v) for k, v in vars(ship).items()}
    after = vars(zeroed(ship, [term]))
    return all(np.array_equal(before[k], after[k]) for k in before)


def main() -> None:
    """Parse and check every option, open ``--dump`` (emptied), then fit oe or the oracle; a bad option or an
    unwritable dump is one stderr line and exit 2, before any simulation."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", required=True, choices=bt.VARIANTS + ("base",))
    ap.add_argument("--zero", default="", help=f"comma-separated terms to switch off: {', '.join(TERMS)}")
    ap.add_argument("--quiet", action="store_true", help="no sea, no sensor noise (oe only)")
    ap.add_argument("--last", type=int, default=6, help="runs 0..LAST of the 30-run family")
    ap.add_argument("--cases", default="case1,case2,case3", help="oe only; the oracle fits its own")
    ap.add_argument("--oracle", action="store_true", help="run the stop-55 oracle instead of oe")
    ap.add_argument("--dump", required=True, help="rows written here (emptied first)")
    a = ap.parse_args()
    terms, cases = [t for t in a.zero.split(",") if t], [c for c in a.cases.split(",") if c]
    bad = _bad(a, ap, terms, cases)
    if bad:
        ap.exit(2, f"{ap.prog}: error: {bad}\n")
    try:  # before the simulation: an unwritable dump must not cost the run
        Path(a.dump).write_text("")
    except OSError as e:
        ap.exit(2, f"{ap.prog}: error: --dump {a.dump}: {e.strerror}; fix: give a writable file in an existing folder\n")
    if a.oracle:
        _oracle(a, terms)
    else:
        _oe(a, terms, cases)


if __name__ == "__main__":
    main()
