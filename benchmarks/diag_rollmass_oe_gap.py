"""Which of ``oe``'s differences from the stop-55 oracle costs its accuracy (stop 57)?

The oracle is given the ship and the true rudder and fits only the loaded recording; ``oe`` learns the ship from
the nominal and calibration recordings and reads the recorded rudder. Here oe is fitted as the truth bench fits it
(``bench_rollmass_truth._one``: the three CSVs through ``estimate_from_files``) on the family's recordings (the
``--runs 30`` draw, seed 2015 and the variant's offset, runs 0..LAST) with ONE difference removed at a time, the
rest of each recording the same draw:

- ``--parts ROLE=PART,...``: the recording of that role (nominal, calibration, loaded) simulated with only some of
  its noise: ``quiet`` (no sea disturbance, no sensor noise: basin_truth.simulate's ``quiet``), ``sea`` (the
  disturbance, no sensor noise, biases or AHRS error) or ``sensor`` (those, no disturbance):
  basin_truth.simulate_parts, the same random streams; a role not named keeps its recording (``all``).
- ``--true-rudder``: every recording's rudder column replaced by the true rudder angle through the same FIR and
  decimation (the quiet simulation's column: no encoder offset or quantisation), the other columns as recorded.

    PYTHONPATH=$PWD nice -n 15 python benchmarks/diag_rollmass_oe_gap.py --variant sway_roll --parts nominal=quiet,calibration=quiet --dump D
    PYTHONPATH=$PWD nice -n 15 python benchmarks/diag_rollmass_oe_gap.py --variant base --true-rudder --dump D
    python benchmarks/diag_rollmass_oe_gap.py --table D1,D2 --base benchmarks/rollmass_family_s54.jsonl

Rows are the bench's (``--dump`` format of bench_rollmass_truth, the family field naming the split); a dump that
already holds rows is refused unless ``--append`` (add to it) or ``--force`` (empty it) is given. ``--table``
pairs each split's fits with the baseline dump's fits of the same variant, case and run: median |mass| % and |z| mm
per case, and the per-fit change of |error| (mean and median) against the baseline.
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
import rollmass_oracle  # noqa: E402

from tests.physics import basin_truth as bt  # noqa: E402

ROLES = ("nominal", "calibration", "loaded")
PARTS = ("all", "quiet", "sea", "sensor")


class Family:
    """The variant's family of runs, each dataset simulated on demand with the noise a part keeps (cached)."""

    def __init__(self, variant: str, runs: int = rollmass_oracle.FAMILY_RUNS, seed: int | None = None) -> None:
        self.variant, self.seed = variant, bt.variant_seed(rollmass_oracle.FAMILY_SEED, variant) if seed is None else seed
        self.ship = bt.draw_ships(runs, variant, self.seed)
        self._data: dict[tuple[str, str], dict] = {}

    def data(self, dataset: str, part: str) -> dict[str, np.ndarray]:
        """``dataset``'s channels (runs, n) with ``part`` of its noise (see the module's doc)."""
        if (dataset, part) not in self._data:
            i = list(bt.DATASETS).index(dataset)
            samples, m, zm = bt.DATASETS[dataset]
            dseed = bt.dataset_seed(self.seed, i)
            sea, sensor = part in ("all", "sea"), part in ("all", "sensor")
            d = bt.simulate_parts(self.ship, self.variant, (m, zm), samples, dseed, sea=sea, sensor=sensor)
            self._data[dataset, part] = d
        return self._data[dataset, part]

    def recordings(self, case: str, run: int, parts: dict[str, str], true_rudder: bool) -> list[bt.Recording]:
        """The case's three recordings of ``run`` (basin_truth.case_recordings), each role's with its part's
        noise, and with the true rudder column if asked."""
        names = dict(zip(ROLES, bt.CASES[case]))  # a case's three roles are three distinct datasets
        data = {names[r]: self.data(names[r], parts.get(r, "all")) for r in ROLES}
        recs = bt.case_recordings(self.ship, data, case, run)
        if true_rudder:
            for rec in recs:
                rec.cols["delta"] = self.data(rec.name, "quiet")["delta"][run]
        return recs


def parse_parts(text: str) -> dict[str, str]:
    """``ROLE=PART,...`` as a dict; ValueError naming the bad item."""
    out: dict[str, str] = {}
    for item in [t for t in text.split(",") if t]:
        role, _, part = item.partition("=")
        if role not in ROLES or part not in PARTS or role in out:
            raise ValueError(item)
        out[role] = part
    return out


def split_name(parts: dict[str, str], true_rudder: bool) -> str:
    """The split's label in the dump's family field and the table."""
    name = ",".join(f"{r}={parts[r]}" for r in ROLES if parts.get(r, "all") != "all") or "recorded"
    return name + ("+true_rudder" if true_rudder else "")


def fit(a: argparse.Namespace, parts: dict[str, str], cases: list[str]) -> None:
    """The bench's oe fits of runs 0..``a.last`` (case by case within a run), each row appended to ``a.dump``."""
    fam = Family(a.variant)
    family = {"diag": "s57 oe gap", "split": split_name(parts, a.true_rudder)}
    heel = bench.rm_restoring.DEFAULT_HEEL_REFERENCE
    for run in range(a.first, a.last + 1):
        for case in cases:
            recs = fam.recordings(case, run, parts, a.true_rudder)
            for r in bench._one((a.variant, run, case, recs, ["oe"], True, heel, family)):
                with open(a.dump, "a") as fh:
                    fh.write(json.dumps(r, default=bool) + "\n")
                print(r[:7], flush=True)


def _rows(path: str | Path) -> list:
    return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]


def _err(r: list) -> tuple[float, float] | None:
    """|mass| % and |z| mm of a converged row, else None."""
    return None if r[4] is None else (abs(r[4][0]), abs(r[4][1]))


def _oracle(path: str) -> dict[tuple, tuple[float, float]]:
    """|mass| % and |z| mm of the oracle's converged fits (rollmass_oracle's dump rows) by (variant, case, run): a
    case's loaded recording's fit (cases 2 and 3 share one); the last row of a fit wins (re-runs are appended)."""
    by = {(o["variant"], o["dataset"], o["run"]): o for o in _rows(path)}
    return {
        (v, case, run): (abs(o["m_err_pct"]), abs(o["z_err_mm"]))
        for (v, dataset, run), o in by.items()
        if o["converged"]
        for case, names in bt.CASES.items()
        if names[2] == dataset
    }


def table(dumps: list[str], base: str, oracle: str | None = None) -> str:
    """Per split, variant and case: n, median |m| %, |z| mm, and the per-fit change of |m| and |z| against the
    baseline's fit of the same variant, case and run (mean / median over the pairs both converged, and how many
    are lower), each case and the cases pooled ("pool"); with ``oracle``
    (rollmass_oracle's dump), its median |m| and |z| over the same runs. A fit (split, variant, case, method, run)
    given twice (the same split re-run, in one dump or two) counts once, the last row read; a warning on stderr."""
    ref = {tuple(r[:4]): r for r in _rows(base) if r[2] == "oe"}
    orc = _oracle(oracle) if oracle else {}
    fits: dict[tuple, list] = {}
    n_rows = 0
    for path in dumps:
        rows = _rows(path)
        n_rows += len(rows)
        for r in rows:
            fits[(r[7].get("family", {}).get("split", "?"), *r[:4])] = r
    if n_rows > len(fits):
        print(
            f"warning: {n_rows - len(fits)} repeated fit(s) in {','.join(map(str, dumps))}: the last row of each kept",
            file=sys.stderr,
        )
    cells: dict[tuple, list] = {}
    for (split, *_), r in fits.items():
        for case in (r[1], "pool"):  # each case, and the variant's cases pooled
            cells.setdefault((split, r[0], case), []).append(r)
    head = f"{'split':44s} {'variant':9s} {'case':5s}  n nc |   m%    zmm | base m%  zmm | dm mean  med | dz mean  med | orc m%  zmm | lower"
    out = [head]
    for (split, variant, case), rows in sorted(cells.items()):
        ok = [e for e in map(_err, rows) if e]
        pairs = [(e, b) for r in rows if (e := _err(r)) and (b := _err(ref.get(tuple(r[:4]), [None] * 5)))]
        bsel = [b for _, b in pairs]
        dm = [e[0] - b[0] for e, b in pairs]
        dz = [e[1] - b[1] for e, b in pairs]
        osel = [orc[variant, r[1], r[3]] for r in rows if (variant, r[1], r[3]) in orc]

        def med(x: list, i: int | None = None) -> float:
            return float(np.median([v if i is None else v[i] for v in x])) if x else float("nan")

        def mean(x: list) -> float:
            return float(np.mean(x)) if x else float("nan")

        out.append(
            f"{split:44s} {variant:9s} {case:5s} {len(rows):2d} {len(rows) - len(ok):2d} | {med(ok, 0):6.2f} "
            f"{med(ok, 1):6.1f} | {med(bsel, 0):6.2f} {med(bsel, 1):5.1f} | {mean(dm):+6.2f} {med(dm):+5.2f} "
            f"| {mean(dz):+6.1f} {med(dz):+5.1f} | {med(osel, 0):6.2f} {med(osel, 1):4.1f} | {sum(d < 0 for d in dm)}/{len(dm)}"
        )
    return "\n".join(out)


def _bad(a: argparse.Namespace, cases: list[str]) -> str | None:
    """The first bad option as ``OPTION VALUE: what; fix: how``, or None."""
    try:
        parse_parts(a.parts)
    except ValueError as e:
        return f"--parts {a.parts}: bad item {e}; fix: ROLE=PART, ROLE of {', '.join(ROLES)}, PART of {', '.join(PARTS)}"
    if not cases or [c for c in cases if c not in bt.CASES] or len(set(cases)) < len(cases):
        return f"--cases {a.cases!r}: unknown, empty or repeated; fix: distinct cases of {', '.join(bt.CASES)}"
    if not 0 <= a.first <= a.last < rollmass_oracle.FAMILY_RUNS:
        return f"--first {a.first} --last {a.last}: out of range; fix: 0 <= FIRST <= LAST <= {rollmass_oracle.FAMILY_RUNS - 1}"
    if a.variant is None or a.dump is None:
        return "--variant/--dump: missing; fix: give both (or --table to read dumps)"
    return None


def _open_dump(a: argparse.Namespace) -> str | None:
    """Make ``--dump`` ready (emptied with ``--force``, kept with ``--append``; an existing non-empty dump without
    either is refused: it may hold hours of fits); the error line, or None."""
    p = Path(a.dump)
    if not (a.append or a.force) and p.is_file() and p.stat().st_size > 0:
        return f"--dump {a.dump}: exists and is not empty; fix: --append to add rows, --force to empty it, or another file"
    try:  # before the simulation: an unwritable dump must not cost the run
        with open(p, "a" if a.append else "w"):
            pass
    except OSError as e:
        return f"--dump {a.dump}: {e.strerror}; fix: give a writable file in an existing folder"
    return None


def _print_table(ap: argparse.ArgumentParser, a: argparse.Namespace) -> None:
    """``--table``, a missing or unreadable file one stderr line and exit 2; fit options given with it are named."""
    ignored = [o for o, v in (("--variant", a.variant), ("--parts", a.parts), ("--true-rudder", a.true_rudder)) if v]
    if ignored or a.dump:
        print(f"{ap.prog}: note: {', '.join(ignored + ['--dump'] * bool(a.dump))} ignored with --table", file=sys.stderr)
    try:
        out = table(a.table.split(","), a.base, a.oracle)
    except OSError as e:
        ap.exit(2, f"{ap.prog}: error: --table: {e.filename}: {e.strerror}; fix: give existing dumps (--base, --oracle too)\n")
    except (json.JSONDecodeError, IndexError, KeyError, TypeError, AttributeError) as e:
        ap.exit(
            2,
            f"{ap.prog}: error: --table: a row not in the dump format ({type(e).__name__}: {e}); fix: give bench/oracle dumps\n",
        )
    print(out)


def main() -> None:
    """Parse and check every option, open ``--dump`` (refused if it holds rows, unless ``--append`` or
    ``--force``), then fit; or print ``--table``. A bad option, an unwritable or non-empty dump or a missing table
    file is one stderr line and exit 2, before any simulation."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", choices=bt.VARIANTS + ("base",))
    ap.add_argument("--parts", default="", help="ROLE=PART,...: the noise a role's recording keeps (default all)")
    ap.add_argument("--true-rudder", action="store_true", help="the true rudder column in every recording")
    ap.add_argument("--first", type=int, default=0, help="runs FIRST..LAST of the 30-run family")
    ap.add_argument("--last", type=int, default=6)
    ap.add_argument("--cases", default="case1,case2,case3")
    ap.add_argument("--dump", help="rows written here (a non-empty file only with --append or --force)")
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--append", action="store_true", help="add rows to an existing --dump")
    mode.add_argument("--force", action="store_true", help="empty an existing --dump first")
    ap.add_argument("--table", help="comma-separated dumps to tabulate against --base (no fitting)")
    here = Path(__file__).resolve().parent
    ap.add_argument("--base", default=str(here / "rollmass_family_s54.jsonl"), help="the baseline dump for --table")
    ap.add_argument("--oracle", default=str(here / "rollmass_oracle_s55.jsonl"), help="the oracle's dump for --table")
    a = ap.parse_args()
    if a.table:
        _print_table(ap, a)
        return
    cases = [c for c in a.cases.split(",") if c]
    bad = _bad(a, cases)
    if bad:
        ap.exit(2, f"{ap.prog}: error: {bad}\n")
    bad = _open_dump(a)
    if bad:
        ap.exit(2, f"{ap.prog}: error: {bad}\n")
    fit(a, parse_parts(a.parts), cases)


if __name__ == "__main__":
    main()
