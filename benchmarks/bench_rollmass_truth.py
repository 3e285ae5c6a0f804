"""`shiptrial mass` on an independent truth: the basin truth family of tests/physics/basin_truth.py.

Each run draws its own model ship around nominal and records the four datasets of Table 2 of
Linder et al. (2015) (nominal, 0.2 kg twice, 0.4 kg) with an Xsens MTi-G; each Table 2 case is
then estimated as a user would: the three CSVs written with their headers (role, speed, IMU z,
known load) and read by ``estimate_from_files`` (library of ``shiptrial mass``), no profile edited.
Per variant, case and method it prints the median absolute mass error [%] and z error [mm], the
share of runs whose 95 % interval holds the truth (mass, z, both), the runs with a warning and the
failures (a refused, diverged or NaN fit, counted, never averaged), then the pooled rows, beside
the paper's Table 3 (one real dataset per case).

    python benchmarks/bench_rollmass_truth.py --runs 100 --methods oe                # Done-when size (the default method)
    python benchmarks/bench_rollmass_truth.py --runs 8 --methods all                # every method
    python benchmarks/bench_rollmass_truth.py --runs 4 --no-u                       # logs without the speed u(t)
    python benchmarks/bench_rollmass_truth.py --runs 100 --dump fam.jsonl --resume  # continue a stopped family
    python benchmarks/bench_rollmass_truth.py --runs 30 --only base/1/case1          # one fit of the 30-run family

Each dumped row's last element also holds the fit's path (``path``: exact, geodesic, continued or forward-difference redo, why, each
LM call's evaluations; identify.rollmass.fit_path) and the family's settings (``family``), which ``--resume`` checks;
an oe row also the same fit's interval at other sandwich windows (``lag_windows``, stop 62: :func:`_windowed`;
tabled by benchmarks/rollmass_lag_windows.py).
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import json
import os
import sys
import tempfile
import time
from multiprocessing import Pool
from pathlib import Path

# One BLAS thread in this process and the workers it forks, set before numpy is imported (OpenBLAS
# reads it once): the fits' products are tall and thin, and on the shared 2-core machine under load
# a multi-threaded 9000 x 15 QR was about 30 times slower than a single-threaded one. Two workers
# already keep both cores busy.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identify.rollmass import oe_fit  # noqa: E402
from identify.rollmass import restoring as rm_restoring  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from identify.rollmass.estimate import METHODS  # noqa: E402
from identify.rollmass.sandwich import andrews_lags  # noqa: E402
from primitives.errors import UserError  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

# Table 3 of the paper (IV): mass error %, z error mm (|estimate - truth| of the printed -zbar_m).
PAPER = {"case1": (0.1338, 3.1), "case2": (7.7532, 25.4), "case3": (16.631, 0.9)}


# the sandwich's Bartlett windows (s) each oe fit's interval is also given at, from the same converged fit (stop 62):
# the window enters only the meat, so no refit; "auto" is Andrews' (1991) AR(1) plug-in on the load's scores
# (sandwich.andrews_lags), "auto1s" the same on their 1 s sums
LAG_WINDOWS_S = (5.0, 10.0, 20.0, 40.0)
_LOAD_INTERVAL = oe_fit.load_interval


def _windowed(T: float, seen: list[dict]):
    """``oe_fit.load_interval`` that also records, per call, the load's sds and Satterthwaite dofs at every window of
    :data:`LAG_WINDOWS_S` and at Andrews' automatic ones (samples, 1 s sums), from the same basis and residual: ``{window: [m_sd, z_sd,
    m_dof, z_dof, lags]}`` (``"auto"`` too), the first entry the call's own window (to find the reported call)."""

    def wrapped(basis, f, lengths, lags):
        out = _LOAD_INTERVAL(basis, f, lengths, lags)
        rec = {"own": [*np.sqrt(np.diag(out.cov)), *out.dof, lags]}
        auto = [("auto", andrews_lags(basis, f, lengths)), ("auto1s", andrews_lags(basis, f, lengths, max(1, round(1.0 / T))))]
        for key, L in [(f"{w:g}", max(1, round(w / T))) for w in LAG_WINDOWS_S] + auto:
            iv = _LOAD_INTERVAL(basis, f, lengths, L)
            rec[key] = [*np.sqrt(np.diag(iv.cov)), *iv.dof, L]
        seen.append({k: [float(v) for v in r] for k, r in rec.items()})
        return out

    return wrapped


def _reported_windows(seen: list[dict], m_sd: float, z_sd: float) -> dict | None:
    """The record of :func:`_windowed` whose own window gave the reported sds (the fit's last finish may not be its
    last call: a redo is judged against the exact path's end); None when none did (no interval)."""
    hits = [r for r in seen if np.allclose(r["own"][:2], [m_sd, z_sd], rtol=1e-12, atol=0.0)]
    return hits[-1] if hits else None


def _one(job: tuple) -> list[tuple]:
    variant, run, case, recs, methods, with_u, heel_ref, family = job
    seen: list[dict] = []
    oe_fit.load_interval = _windowed(recs[0].T, seen)  # in the worker itself: a spawned one would not inherit it
    m_true, z_true = bt.truth_load(case)
    out = []
    with tempfile.TemporaryDirectory() as d:
        paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv", with_u) for r in recs]
        for method in methods:
            c0, fitted = time.process_time(), {}
            seen.clear()
            try:
                e = estimate_from_files(*paths, method=method, heel_reference=heel_ref)
                (mlo, mhi), (zlo, zhi) = e.ci()
                ok = e.converged and np.all(np.isfinite([e.m, e.zbar_m, mlo, mhi, zlo, zhi]))
                row = (
                    (
                        100 * (e.m / m_true - 1),  # signed: scatter and bias told apart (older dumps hold |.|)
                        1000 * (e.zbar_m - z_true),
                        mlo <= m_true <= mhi,
                        zlo <= z_true <= zhi,
                        len(e.warnings) > 0,
                    )
                    if ok
                    else None
                )
                why = "" if ok else "; ".join(e.warnings)[:80]
                # what absorbs a structural mismatch shows in these (stop 41: speed_loss had kappa < 0,
                # X_v -1,070 to -29,000 and a mass-height correlation near 1)
                fitted = {k: e.params[k] for k in ("kappa", "X_v", "K_ur", "Y_pdot") if k in e.params}
                fitted["corr"] = e.corr
                if e.fit_path is not None:
                    fitted["path"] = e.fit_path.record()
                fitted["m_sd"], fitted["z_sd"] = e.m_sd, e.zbar_m_sd  # the reported sds (kg, m), for the stop-55 oracle
                # the intervals' Satterthwaite degrees of freedom (MassEstimate.critical's t): a miss's z-score is read
                # against its own critical value (stop 60), which the sd alone does not give
                fitted["m_dof"], fitted["z_dof"] = e.m_dof, e.zbar_m_dof
                # stop 62: the same fit's interval at other sandwich windows ([m_sd, z_sd, m_dof, z_dof, lags] each)
                if method == "oe":
                    fitted["lag_windows"] = _reported_windows(seen, e.m_sd, e.zbar_m_sd)
            except UserError as exc:
                row, why = None, str(exc)[:80]
            out.append((variant, case, method, run, row, why, time.process_time() - c0, {**fitted, "family": family}))
    return out


def _summary(rows: list[tuple], label: str, case: str, method: str) -> str:
    sel = [r for r in rows if r[1] == case and r[2] == method]
    good = [r[4] for r in sel if r[4] is not None]
    n, nf = len(sel), len(sel) - len(good)
    if good:
        a = np.array(good, dtype=float)
        med_m, med_z, bias_m = np.median(np.abs(a[:, 0])), np.median(np.abs(a[:, 1])), np.median(a[:, 0])
        cm, cz, cb, nw = 100 * a[:, 2].mean(), 100 * a[:, 3].mean(), 100 * (a[:, 2] * a[:, 3]).mean(), int(a[:, 4].sum())
    else:
        med_m = med_z = bias_m = cm = cz = cb = float("nan")
        nw = 0
    pm, pz = PAPER[case]
    return (
        f"{label:10} {case:6} {method:9} {n:5d} | {pm:7.2f} {pz:6.1f} | {med_m:7.2f} {med_z:7.1f} {bias_m:+7.2f} | "
        f"{cm:6.0f} {cz:6.0f} {cb:6.0f} | {nw:5d} {nf:5d}"
    )


# the project modules outside identify/rollmass/ that the estimator imports (all of them, indirect ones too:
# tests/test_bench_rollmass_truth.py checks this list against a fresh interpreter's imports of identify.rollmass.api),
# hashed into a dump's code key: an edit there (the IIR filters, the CSV reader) can change a fit as well
ESTIMATOR_IMPORTS = (
    "diagnose/__init__.py",
    "diagnose/recording.py",
    "diagnose/recording_checks.py",
    "diagnose/recording_kinematics.py",
    "diagnose/recording_meta.py",
    "diagnose/recording_table.py",
    "identify/__init__.py",
    "primitives/__init__.py",
    "primitives/diagnosed_sections.py",
    "primitives/errors.py",
    "primitives/goodness.py",
    "primitives/iir.py",
    "primitives/iirmodal.py",
    "primitives/io.py",
    "primitives/jitloop.py",
    "primitives/jitprogram.py",
    "primitives/orderstats.py",
    "primitives/physical_tables.py",
    "primitives/pods.py",
    "primitives/powers.py",
    "primitives/profile_fields.py",
    "primitives/profile_tables.py",
    "primitives/rigidbody.py",
    "primitives/ship.py",
    "primitives/terms.py",
    "primitives/threads.py",
    "primitives/unit_ranges.py",
    "primitives/validate.py",
    "primitives/zerophase.py",
)


def _code_hash() -> str:
    """A sha1 of the estimator's and the bench's sources (identify/rollmass/*.py, the modules it imports from elsewhere
    in the project, :data:`ESTIMATOR_IMPORTS`, the truth simulator, this file): rows of two estimators must not be
    mixed in one family; a commit id would also refuse a resume across a docs commit."""
    root = Path(__file__).resolve().parents[1]
    files = sorted(root.glob("identify/rollmass/*.py")) + [root / f for f in ESTIMATOR_IMPORTS]
    files += [root / "tests/physics/basin_truth.py", Path(__file__).resolve()]
    h = hashlib.sha1()
    for f in files:
        h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:12]


def _family(a: argparse.Namespace) -> dict[str, object]:
    """The settings that decide a family's ships and recordings (its runs' seeds depend on ``--runs``), and the
    code that fitted them (:func:`_code_hash`)."""
    out = {"runs": a.runs, "seed": a.seed, "quiet": a.quiet, "with_u": not a.no_u, "heel_ref": a.heel_ref, "code": _code_hash()}
    # the oe weights' innovation sd, the only one since stop 62 (oe_fit._reweighted): recorded so that these rows pool
    # with stop 61's "fixed" dumps, and rows of a dump without the field (main's "legacy" sd, stop 60 and before) or
    # with "legacy" do not (rollmass_family_table.load refuses two family settings)
    out["innovation_sd"] = "fixed"
    return out


def _misfit(i: int, theirs: object, family: dict[str, object]) -> str | None:
    """Why line ``i``'s family ``theirs`` cannot be resumed as ``family`` (None: it can)."""
    if theirs is None:
        return f"line {i} was written before --resume existed (no family recorded); fix: start a new --dump"
    if not isinstance(theirs, dict):
        return f"line {i} is not a bench row; fix: start a new --dump"
    if "code" not in theirs:
        return f"line {i} records no code hash (written before the bench recorded one); fix: start a new --dump"
    if theirs["code"] != family["code"]:
        return f"line {i} was written by other code (hash {theirs['code']}, this code {family['code']}); fix: start a new --dump"
    if theirs != family:
        return f"line {i} is of family {theirs}, not {family}; fix: resume with that row's settings, or start a new --dump"
    return None


def _locked(dump: Path) -> int:
    """``dump`` opened (created when missing, never emptied here) and locked for this process (an exclusive
    ``fcntl.flock``, held until the descriptor is closed): two processes resuming, or one starting, the same dump would both
    append, or one empty the other's rows. A dump another process holds is refused in one line, the file untouched."""
    try:
        fd = os.open(dump, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        sys.exit(f"{dump}: cannot be opened for writing ({exc.strerror}); fix: give a --dump in a writable directory")
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        sys.exit(
            f"{dump}: another process is writing this dump (a running process holds its lock: see `ps`); fix: wait for it to end, or give another --dump"
        )
    return fd


def _unlocked(fd: int) -> None:
    """A pool worker's start: close the locked dump's descriptor it inherited from the fork. A worker holding it holds
    the lock (the same open file description), so an orphaned worker of a killed bench kept "kill it, resume at once"
    refused until its fit ended (62 s measured, stop 56 review); the parent's own descriptor keeps its lock."""
    if fd >= 0:
        os.close(fd)


def _done(dump: Path, family: dict[str, object], fd: int) -> tuple[list[tuple], set[tuple]]:
    """The rows of an existing ``--dump`` to resume from and their (variant, case, method, run) keys. A last line cut
    by an interrupted write (no final newline) is dropped from the file with a note, so its fit is redone; otherwise
    exits with a one-line error, the file untouched, when a row is of another family or code, a fit is there twice
    (two processes resumed one dump) or the file is not a dump."""
    text = dump.read_text() if dump.exists() else ""
    lines, rows, seen = text.splitlines(), [], {}
    for i, line in enumerate(lines, 1):
        try:
            r = tuple(json.loads(line))
            theirs = r[7].get("family")
        except (ValueError, TypeError, IndexError, AttributeError):
            if i == len(lines) and not text.endswith("\n"):
                os.ftruncate(fd, len(text.encode()) - len(lines[-1].encode()))  # in place: a new file would drop the lock
                print(f"{dump}: line {i} truncated (interrupted write): dropped, its fit is redone", file=sys.stderr)
                break
            sys.exit(f"{dump}: line {i} is not a bench row; fix: give --resume a --dump file this bench wrote")
        why = _misfit(i, theirs, family)
        if why is not None:
            sys.exit(f"{dump}: {why}")
        if tuple(r[:4]) in seen:
            sys.exit(
                f"{dump}: lines {seen[tuple(r[:4])]} and {i} hold the same fit {'/'.join(map(str, r[:4]))} (two processes "
                "resumed this dump?); fix: delete one of the two lines, and resume a dump from one process at a time"
            )
        seen[tuple(r[:4])] = i
        rows.append(r)
    return rows, set(seen)


def _only(a: argparse.Namespace, variants: list[str], cases: list[str]) -> set[tuple] | None:
    """The (variant, run, case) fits ``--only`` names (None: all); ValueError for a spec that names no fit of this
    family (the caller's usage error, exit 2, before the dump is touched), so a typo never makes an empty run."""
    if not a.only:
        return None
    out = set()
    for s in a.only.split(","):
        f = s.split("/")
        if len(f) != 3 or f[0] not in variants or f[2] not in cases or not f[1].isdigit() or int(f[1]) >= a.runs:
            raise ValueError(
                f"--only {s}: no such fit of this family; fix: give variant/run/case with the variant in --variants, "
                f"0 <= run < --runs ({a.runs}) and the case in --cases"
            )
        out.add((f[0], int(f[1]), f[2]))
    return out


def _jobs(
    a: argparse.Namespace,
    variants: list[str],
    cases: list[str],
    methods: list[str],
    done: set,
    only: set | None,
    family: dict[str, object],
) -> tuple[list, float]:
    """The fits to make, run-major: (variant, run, case, recordings, methods not in ``done``, ...), and the
    simulations' CPU. Every variant's whole family is simulated (its ships depend on ``--runs``), so a fit
    selected by ``--only`` or left by ``--resume`` is the one a fresh run of the same ``--runs`` makes."""
    jobs, c_sim = [], 0.0
    for variant in variants:
        c0 = time.process_time()
        # a variant's seed does not depend on which others are run, so runs pair across invocations
        seed = bt.variant_seed(a.seed, variant)
        ship, data = bt.simulate_runs(variant, a.runs, seed, quiet=a.quiet)
        c_sim += time.process_time() - c0
        for run in range(a.runs):
            for case in cases:
                todo = [m for m in methods if (variant, case, m, run) not in done]
                if todo and (only is None or (variant, run, case) in only):
                    recs = bt.case_recordings(ship, data, case, run)
                    jobs.append((variant, run, case, recs, todo, not a.no_u, a.heel_ref, family))
    # run-major (a stable sort): an interrupted run (its --dump) has about as many runs of every variant
    jobs.sort(key=lambda j: j[1])
    return jobs, c_sim


def _rows(
    a: argparse.Namespace, variants: list[str], cases: list[str], methods: list[str], only: set | None
) -> tuple[list[tuple], list[str], float]:
    """The rows to summarise (a ``--from-dump`` file's, or the fits made now, each appended to ``--dump`` as it
    finishes), the variants they are of, and the simulations' CPU."""
    if a.from_dump:  # a (possibly interrupted) run's rows, summarised
        rows = [tuple(r) for r in map(json.loads, Path(a.from_dump).read_text().splitlines())]
        return rows, list(dict.fromkeys(r[0] for r in rows)), 0.0
    fd = _locked(Path(a.dump)) if a.dump else -1  # held while this process writes the dump (its rows appended below)
    try:
        rows, done, family = [], set(), _family(a)  # the family key hashes the sources: once
        if a.resume:  # the dump's rows are one family's (checked): keep them, fit the rest
            rows, done = _done(Path(a.dump), family, fd)
        elif a.dump:  # a dump holds one family's rows: appending to an old one would mix runs of two families
            os.ftruncate(fd, 0)
        jobs, c_sim = _jobs(a, variants, cases, methods, done, only, family)
        with Pool(a.workers, initializer=_unlocked, initargs=(fd,)) as pool:  # also a worker the pool replaces
            for part in pool.imap(_one, jobs):
                for r in part:
                    rows.append(r)
                    if a.dump:
                        with open(a.dump, "a") as fh:
                            fh.write(json.dumps(r, default=bool) + "\n")
    finally:
        if fd >= 0:
            os.close(fd)  # the lock goes with it
    return rows, variants, c_sim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="runs (model ships) per variant")
    ap.add_argument(
        "--variants", default=",".join(bt.VARIANTS), help="comma-separated; base = the estimator's structure (reference)"
    )
    ap.add_argument("--methods", default="oe", help=f"comma-separated subset of {','.join(METHODS)}, or 'all'")
    ap.add_argument("--cases", default="case1,case2,case3")
    ap.add_argument("--seed", type=int, default=2015)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument(
        "--no-u", action="store_true", help="write the recordings without the surge-speed column u (one speed per run)"
    )
    ap.add_argument(
        "--quiet",
        action="store_true",
        help="no waves and no sensor noise: a variant still biased is a structural mismatch, not noise",
    )
    ap.add_argument(
        "--heel-ref",
        choices=rm_restoring.HEEL_REFERENCES,
        default=rm_restoring.DEFAULT_HEEL_REFERENCE,
        help="how oe references the AHRS roll angle (identify.rollmass.restoring.referenced_heel); for comparisons",
    )
    ap.add_argument(
        "--dump",
        help="write every fit's row to this file (JSON lines, emptied first unless --resume) as it finishes; its last element holds "
        "the fitted kappa, X_v, K_ur, Y_pdot and the mass-height correlation",
    )
    ap.add_argument("--from-dump", help="print the tables from a --dump file (also an interrupted run's) and fit nothing")
    ap.add_argument(
        "--resume",
        action="store_true",
        help="keep the --dump's rows and fit only the missing ones (same --runs, seed, settings and code as the "
        "dump's); one process per dump at a time (a dump another process holds is refused)",
    )
    ap.add_argument("--only", help="comma-separated variant/run/case fits of the family to make, e.g. base/1/case1")
    a = ap.parse_args()
    variants, cases = a.variants.split(","), a.cases.split(",")
    methods = list(METHODS) if a.methods == "all" else a.methods.split(",")
    if not set(methods) <= set(METHODS) or not set(variants) <= set(bt.VARIANTS + ("base",)) or not set(cases) <= set(bt.CASES):
        ap.error("unknown method, variant or case")
    if a.resume and not a.dump:
        ap.error("--resume needs --dump")
    try:
        only = _only(a, variants, cases)
    except ValueError as exc:  # one line (ap.error would print the usage too), exit 2 as a usage error, no dump touched
        ap.exit(2, f"{ap.prog}: error: {exc}\n")
    t0 = time.perf_counter()
    rows, variants, c_sim = _rows(a, variants, cases, methods, only)
    c_fit = sum(r[6] for r in rows)
    fails = [f"{r[0]} {r[1]} {r[2]} run {r[3]}: {r[5]}" for r in rows if r[4] is None]
    print(
        f"truth family: {len(variants)} variants x {'the dump' if a.from_dump else a.runs} runs x {len(cases)} cases, seed {a.seed}, "
        f"{'without' if a.no_u else 'with'} the u column{', quiet (no waves, no noise)' if a.quiet else ''}, heel reference {a.heel_ref}; "
        f"{time.perf_counter() - t0:.0f} s wall, simulation {c_sim:.0f} s cpu, fits {c_fit:.0f} s cpu "
        f"({c_fit / max(len(rows), 1):.2f} s per fit)\n"
    )
    print(
        f"{'variant':10} {'case':6} {'method':9} {'runs':>5} | {'paper m%':>7} {'z mm':>6} | {'m med%':>7} {'z medmm':>7} {'m bias%':>7} | "
        f"{'cov m':>6} {'cov z':>6} {'both':>6} | {'warn':>5} {'fail':>5}"
    )
    for variant in variants + ["pooled"]:
        sub = rows if variant == "pooled" else [r for r in rows if r[0] == variant]
        for method in methods:
            for case in cases:
                print(_summary(sub, variant, case, method))
    print(
        "\nm med% / z medmm: median |error|; m bias%: median signed mass error (a dump before signed rows: |.|);"
        "\ncov: % of the non-failed runs whose 95 % interval holds the true mass / z / both; warn: runs with a warning;"
        "\npaper: Table 3 (IV), one real dataset per case, z error |0.2529-0.256| etc. in mm."
    )
    if fails:
        print(f"\nfailures ({len(fails)}):")
        for f in fails[:40]:
            print("  " + f)


if __name__ == "__main__":
    main()
