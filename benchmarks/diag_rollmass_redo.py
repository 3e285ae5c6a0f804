"""Why a truth-bench ``oe`` fit leaves the exact-Jacobian path for the forward-difference redo (stop 55).

Re-runs fits of a :mod:`benchmarks.bench_rollmass_truth` family (same seeds and ships: give the family's
``--runs``) on the exact path ALONE: neither the continuation of an unconverged exact end (stop 56) nor the redo is
run (each is stopped at its first call), so a fit costs its exact path only. Per fit it prints whether the exact path
was kept or would be continued (then redone if still unconverged) or redone at once, each LM call's (evaluations,
status; 0 = at the cap ``oe_fit.LM_NFEV_EXACT``), the exact path's own answer when it has one (mass % and z mm error,
converged, decrement) and, from the given dump, the answer the full fit reported and the path it recorded. ``--cap`` overrides
``LM_NFEV_EXACT`` (a looser budget's experiment); ``--stop-at-cap`` is the fit before stop 55, whose exact path was
abandoned at the first LM at its cap ("redo (capped)"). ``--valley`` (stop 57) prints, at an unconverged exact end,
why it creeps (:func:`_valley`), and ``--profile`` the cost with the sway mass held (:func:`_profile`), ``--geodesic N`` the geodesic LM's continuation
capped at N steps (:func:`identify.rollmass.geodesic.geodesic_lm`, the fit's own continuation since stop 59).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_redo.py benchmarks/rollmass_family_s54.jsonl --runs 30 --slow 20
    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_redo.py DUMP --runs 30 --slow 20 --stop-at-cap --cap 400
    PYTHONPATH=$PWD nice -n 15 python benchmarks/diag_rollmass_redo.py benchmarks/rollmass_redo_s56.jsonl --runs 30 \
        --only base/1/case1 --valley --profile 1
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
        captured["end"] = end
        return end

    oe_fit._fit = spy
    oe_fit._continued = _no_continuation


def _valley(end: oe_fit._Ended) -> str:
    """Why an unconverged exact end creeps (stop 57): at the point the exact path ended (after the finish), the
    column-scaled Jacobian's condition number and its two weakest right singular vectors (the parameters they move,
    largest first), the Gauss-Newton step ``dx = -J^+ f`` split on those vectors, and the cost along ``x + t dx``
    against the Gauss-Newton model's ``|f + t J dx|^2`` (is the valley flat, or curved so that the step is halved?)."""
    prob, x = end.prob, end.x
    f, J = prob.residual(x), prob.jacobian(x)
    scale = np.sqrt(np.maximum(np.einsum("ij,ij->j", J, J), 1e-300))
    u, sv, vt = np.linalg.svd(J / scale, full_matrices=False)
    dx = -np.linalg.lstsq(J, f, rcond=None)[0]
    ds = dx * scale  # the step in the scaled coordinates
    out = [f"cond(J scaled) {sv[0] / sv[-1]:.3g} sv {' '.join(f'{s:.3g}' for s in sv[-3:])} X_v {x[prob.free.index('X_v')]:.4g}"]
    for k in (1, 2):
        v = vt[-k]
        top = np.argsort(-np.abs(v))[:4]
        out.append(f"weak{k} " + " ".join(f"{prob.free[i]}{v[i]:+.2f}" for i in top) + f" step along it {v @ ds:+.3g}")
    out.append(f"|step scaled| {np.linalg.norm(ds):.3g} load step {dx[-2]:+.3g} kg {1000 * dx[-1]:+.2f} mm")
    c0 = f @ f
    rows = []
    for t in (0.125, 0.25, 0.5, 1.0, 2.0, 4.0):
        fm = f + t * (J @ dx)
        ft = prob.residual(x + t * dx)
        rows.append(f"t={t:g}: {ft @ ft - c0:+.4g} (GN {fm @ fm - c0:+.4g})")
    out.append("cost change along the step " + "; ".join(rows))
    return "\n    ".join(out)


class _Fixed:
    """``prob`` with one parameter held at ``value`` (its column dropped): a point of the cost's profile along it."""

    def __init__(self, prob: object, i: int, value: float):
        self.prob, self.i, self.value = prob, i, value

    def full(self, y: np.ndarray) -> np.ndarray:
        return np.insert(y, self.i, self.value)

    def residual(self, y: np.ndarray) -> np.ndarray:
        return self.prob.residual(self.full(y))

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return np.delete(self.prob.jacobian(self.full(y)), self.i, axis=1)


def _profile(end: oe_fit._Ended, m_true: float, z_true: float, factors: tuple[float, ...]) -> str:
    """The cost's profile along the sway mass (stop 57): ``M + X_v`` held at ``factors`` times the exact end's, every
    other parameter refitted by the exact LM (cap 200) from the end's point; per factor the cost against the end's
    (half the sum of squares, the LM's), the load, evaluations and status (0: the cap, so still creeping with the sway
    mass held). Scaling the sway row's other coefficients with it (Y_v, Y_r, Y_delta, Y_pdot, K_v) was tried and is
    not this: three times the end's sway mass so scaled is an unstable model on base/1/case1."""
    prob, x = end.prob, end.x
    i = prob.free.index("X_v")
    M = prob.kn.M
    f = prob.residual(x)
    c0 = float(f @ f) / 2
    rows = []
    for fac in factors:
        xv = fac * (M + x[i]) - M
        fixed = _Fixed(prob, i, xv)
        res = oe_fit._lm_exact(fixed, np.delete(x, i), 1e-10, cap=200)
        v = fixed.full(res.x)
        rows.append(
            f"M+X_v x{fac:g} ({xv:.4g}): cost {res.cost - c0:+.5g} m {100 * (v[-2] / m_true - 1):+.2f} % "
            f"z {1000 * (v[-1] - z_true):+.1f} mm nfev {res.nfev} status {res.status}"
        )
    return "\n    ".join(rows)


def _geodesic_end(end: oe_fit._Ended, m_true: float, z_true: float, steps: int) -> str:
    """The fit's geodesic continuation (``oe_fit._lm_geodesic``, :func:`identify.rollmass.geodesic.geodesic_lm`, stop 59)
    from the exact end on its last stage's problem (same weights and whiteners) capped at ``steps`` steps, then the fit's
    finish (``oe_fit._conclude``). Prints its status (converged or at its cap), the load, its decrement, standard
    errors, evaluations and CPU."""
    c0 = time.process_time()
    res = oe_fit._lm_geodesic(end.prob, end.x, 1e-10, cap=steps)
    sd = np.array([e.std(axis=0) for e in end.prob.errors(res.x)])
    fit = oe_fit._conclude(end.prob, res, sd, end.fit.noise, True, end.fit.z_f).fit
    se = np.sqrt(np.diag(fit.cov_load))
    return (
        f"{res.message} ({res.nfev} res, {res.njev} jac): fit conv {fit.converged} dec {fit.decrement:.3g} "
        f"m {100 * (fit.m / m_true - 1):+.3f} % z {1000 * (fit.zbar_m - z_true):+.2f} mm (SE {se[0]:.4g} kg, "
        f"{1000 * se[1]:.3g} mm) X_v {fit.values['X_v']:.4g}, {time.process_time() - c0:.1f} s cpu"
    )


def _factors(text: str) -> tuple[float, ...]:
    """``--profile``'s factors, checked at parse time (before the exact path's ~13 s)."""
    try:
        facs = tuple(float(q) for q in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"not comma-separated numbers: {text!r}") from None
    if not facs or any(not np.isfinite(q) or q <= 0 for q in facs):
        raise argparse.ArgumentTypeError(f"factors must be positive numbers: {text!r}")
    return facs


def _select(rows: list, a: argparse.Namespace) -> list[tuple[str, int, str]]:
    if a.only:
        return [(v, int(r), c) for v, r, c in (s.split("/") for s in a.only.split(","))]
    return [(r[0], r[3], r[1]) for r in sorted(rows, key=lambda r: r[6]) if (r[6] > a.slow) == (not a.fast)][: a.limit]


def main() -> None:
    a = _args()
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
        captured.clear()
        why, cpu = _redo(ship, data, case, run, captured)
        _print_fit(a, (variant, run, case), why, cpu, captured, by_key.get((variant, run, case)))


def _args() -> argparse.Namespace:
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
    ap.add_argument("--valley", action="store_true", help="at an unconverged exact end, print why it creeps (stop 57)")
    ap.add_argument(
        "--geodesic", type=int, help="with --valley: run the geodesic LM this many steps from the exact end (stop 57)"
    )
    ap.add_argument(
        "--profile",
        type=_factors,
        help="with --valley: comma-separated factors of the sway mass M + X_v to profile the cost at, e.g. 1,10,100",
    )
    a = ap.parse_args()
    if (a.geodesic or a.profile) and not a.valley:
        ap.error("--geodesic and --profile need --valley")
    if a.geodesic is not None and a.geodesic < 1:
        ap.error("--geodesic: give a number of steps >= 1")
    return a


def _redo(ship: bt.Ship, data: dict, case: str, run: int, captured: dict) -> tuple[str, float]:
    """Fit one case's recordings (written to a temporary directory) on the exact path; why it ended there and
    its CPU seconds (what the fit did is in ``captured``)."""
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
        return why, time.process_time() - c0


def _print_fit(a: argparse.Namespace, key: tuple, why: str, cpu: float, captured: dict, old: list | None) -> None:
    """One fit's line beside the dump's answer ``old``, and with --valley why an unconverged exact end creeps."""
    variant, run, case = key
    m_true, z_true = bt.truth_load(case)
    t, f = captured.get("tally"), captured.get("fit")
    ans = "-"
    if f is not None:
        ans = f"m {100 * (f.m / m_true - 1):+7.2f} % z {1000 * (f.zbar_m - z_true):+7.1f} mm conv {f.converged} dec {f.decrement:.3g}"
        ans += "" if f.converged else f" ({f.message[-70:]})"
    was = "failed" if old is None or old[4] is None else f"m {old[4][0]:+7.2f} % z {old[4][1]:+7.1f} mm"
    if old is not None and len(old) > 7 and isinstance(old[7], dict) and "path" in old[7]:
        was += f" path {old[7]['path']['path']}"  # the full fit's recorded path (stop 55 on)
    print(
        f"{variant}/{run}/{case}: {why}; exact LM calls {t.lm if t else '-'} res {t.residuals if t else '-'} "
        f"jac {t.jacobians if t else '-'}; exact {ans}; dump {was} "
        f"({old[6] if old else float('nan'):.1f} s); exact path {cpu:.1f} s cpu, load {os.getloadavg()[0]:.1f}",
        flush=True,
    )
    if a.valley and f is not None and not f.converged and "end" in captured:
        print("    " + _valley(captured["end"]), flush=True)
        if a.profile:
            print("    " + _profile(captured["end"], m_true, z_true, a.profile), flush=True)
        if a.geodesic:
            print("    " + _geodesic_end(captured["end"], m_true, z_true, a.geodesic), flush=True)
    elif a.valley:
        print(f"    exact path {'failed' if f is None else 'converged'}: no valley", flush=True)


if __name__ == "__main__":
    main()
