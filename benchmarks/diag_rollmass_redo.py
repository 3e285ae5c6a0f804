"""Why a truth-bench ``oe`` fit leaves the exact-Jacobian path for the forward-difference redo (stop 55).

Re-runs fits of a :mod:`benchmarks.bench_rollmass_truth` family (same seeds and ships: give the family's
``--runs``) on the exact path ALONE: neither the continuation of an unconverged exact end (stop 56) nor the redo is
run (each is stopped at its first call), so a fit costs its exact path only. Per fit it prints whether the exact path
was kept or would be continued (then redone if still unconverged) or redone at once, each LM call's (evaluations,
status; 0 = at the cap ``oe_fit.LM_NFEV_EXACT``), the exact path's own answer when it has one (mass % and z mm error,
converged, decrement) and, from the given dump, the answer the full fit reported and the path it recorded. ``--cap`` overrides
``LM_NFEV_EXACT`` (a looser budget's experiment); ``--stop-at-cap`` is the fit before stop 55, whose exact path was
abandoned at the first LM at its cap ("redo (capped)").

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_redo.py benchmarks/rollmass_family_s54.jsonl --runs 30 --slow 20
    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_redo.py DUMP --runs 30 --slow 20 --stop-at-cap --cap 400
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, as the bench

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from identify.rollmass import oe_fit  # noqa: E402
from identify.rollmass.api import estimate_from_files  # noqa: E402
from identify.rollmass.fit_path import PathTally  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402


class _NoRedo(Exception):
    """Raised at the redo's first LM call: this diagnostic measures the exact path only."""


class _NoContinuation(Exception):
    """Raised where the exact path's unconverged end would be continued (stop 56): the exact path only, too."""


def _no_continuation(*args: object) -> object:
    raise _NoContinuation


class _Capped(Exception):
    """An exact LM reached its cap under ``--stop-at-cap`` (the fit before stop 55 left the exact path there)."""


def _stopping_at_cap(lm: object, tally_of: dict) -> object:
    """``oe_fit._lm_exact`` as it was before stop 55: at the cap the exact path ends (here: the fit ends)."""

    def run(prob: object, x0: np.ndarray, tol: float) -> object:
        res = lm(prob, x0, tol)
        if res.status == 0:
            tally_of["capped"] = int(res.nfev)
            # _tallied (which wraps this) would record the call after it returns: the capped call, the one the
            # diagnosis is about, is appended here so that the printed LM calls end with it
            tally_of["tally"].lm.append((int(res.nfev), 0))
            raise _Capped
        return res

    return run


def _exact_only(captured: dict) -> None:
    """Patch oe_fit so the exact path's fit is kept in ``captured`` and the continuation and the redo stop at once."""
    orig = oe_fit._fit

    def spy(*args: object, lm: object, tally: PathTally) -> object:
        if lm is oe_fit._lm:
            raise _NoRedo
        captured["tally"] = tally
        end = orig(*args, lm=lm, tally=tally)
        captured["fit"] = end.fit  # the exact path's own end (the continuation, stop 56, is stopped below)
        return end

    oe_fit._fit = spy
    oe_fit._continued = _no_continuation


def _select(rows: list, a: argparse.Namespace) -> list[tuple[str, int, str]]:
    if a.only:
        return [(v, int(r), c) for v, r, c in (s.split("/") for s in a.only.split(","))]
    return [(r[0], r[3], r[1]) for r in sorted(rows, key=lambda r: r[6]) if (r[6] > a.slow) == (not a.fast)][: a.limit]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump", help="the family's bench dump (its answers are printed beside)")
    ap.add_argument("--runs", type=int, required=True, help="the family's --runs (its ships depend on it)")
    ap.add_argument("--seed", type=int, default=2015)
    ap.add_argument("--slow", type=float, default=30.0, help="select the dump's fits over this CPU [s]")
    ap.add_argument("--fast", action="store_true", help="select the fits under --slow instead")
    ap.add_argument("--limit", type=int, default=1000)
    ap.add_argument("--only", help="comma-separated variant/run/case")
    ap.add_argument("--cap", type=int, default=oe_fit.LM_NFEV_EXACT, help="the exact LM's evaluation cap")
    ap.add_argument("--stop-at-cap", action="store_true", help="leave the exact path at an LM's cap (before stop 55)")
    a = ap.parse_args()
    oe_fit.LM_NFEV_EXACT = a.cap
    rows = [json.loads(x) for x in Path(a.dump).read_text().splitlines()]
    by_key = {(r[0], r[3], r[1]): r for r in rows}
    sims: dict[str, tuple] = {}
    captured: dict = {}
    _exact_only(captured)
    if a.stop_at_cap:
        oe_fit._lm_exact = _stopping_at_cap(oe_fit._lm_exact, captured)
    for variant, run, case in _select(rows, a):
        if variant not in sims:
            seed = bt.variant_seed(a.seed, variant)
            sims[variant] = bt.simulate_runs(variant, a.runs, seed)
        ship, data = sims[variant]
        m_true, z_true = bt.truth_load(case)
        captured.clear()
        with tempfile.TemporaryDirectory() as d:
            paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv", True) for r in bt.case_recordings(ship, data, case, run)]
            c0 = time.process_time()
            try:
                estimate_from_files(*paths, method="oe")
                why = "exact path kept"
            except _NoContinuation:
                why = "continued (then redone if still unconverged)"
            except _NoRedo:
                why = "redo"
            except _Capped:
                why = f"redo (capped at {captured['capped']})"
            cpu = time.process_time() - c0
        t, f = captured.get("tally"), captured.get("fit")
        ans = "-"
        if f is not None:
            ans = f"m {100 * (f.m / m_true - 1):+7.2f} % z {1000 * (f.zbar_m - z_true):+7.1f} mm conv {f.converged} dec {f.decrement:.3g}"
            ans += "" if f.converged else f" ({f.message[-70:]})"
        old = by_key.get((variant, run, case))
        was = "failed" if old is None or old[4] is None else f"m {old[4][0]:+7.2f} % z {old[4][1]:+7.1f} mm"
        if old is not None and len(old) > 7 and isinstance(old[7], dict) and "path" in old[7]:
            was += f" path {old[7]['path']['path']}"  # the full fit's recorded path (stop 55 on)
        print(
            f"{variant}/{run}/{case}: {why}; exact LM calls {t.lm if t else '-'} res {t.residuals if t else '-'} "
            f"jac {t.jacobians if t else '-'}; exact {ans}; dump {was} "
            f"({old[6] if old else float('nan'):.1f} s); exact path {cpu:.1f} s cpu, load {os.getloadavg()[0]:.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
