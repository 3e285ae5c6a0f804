"""The truth family's 95 % intervals at several sandwich windows (stop 62): from the ``lag_windows`` each oe row of a
:mod:`benchmarks.bench_rollmass_truth` dump records (the same converged fit's load sds and Satterthwaite degrees of
freedom at 5, 10, 20, 40 s and Andrews' automatic windows, ``identify.rollmass.sandwich.andrews_lags``), per window and
per variant and case, and pooled: the coverage of the mass's, the height's and both intervals, the z-scores' sd and the
intervals' median full width (mass in % of the true load, height in mm).

    python benchmarks/rollmass_lag_windows.py DUMP [DUMP ...] [--by-case] [--same-as DUMP [DUMP ...]]

An interval is ``estimate +- t_{0.975, nu} sd`` (``MassEstimate.critical``), as the product prints it. A failed fit
counts as a miss in the coverage of all runs; a row without ``lag_windows`` (a dump of before stop 62) is refused in
one line. ``--same-as``: the largest difference of the estimates, row by row, against other dumps of the same fits
(stop 61's "fixed" ones): the window must not move a fit. Nothing is fitted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.rollmass_family_table import load as load_dumps  # noqa: E402
from benchmarks.rollmass_family_zscores import critical  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402


def _fit_windows(row: list) -> dict[str, tuple[float, ...]] | None:
    """``{window: (s_m, s_z, t_m, t_z, width_m %, width_z mm, window s)}`` of one row; None for a failed fit."""
    if row[4] is None:
        return None
    m_true, _ = bt.truth_load(row[1])
    err_m, err_z = row[4][0] / 100 * m_true, row[4][1] / 1000  # kg, m (the row holds % and mm)
    T = 5.0 / row[7]["lag_windows"]["5"][4]  # the sample time (the 5 s window's lags)
    out = {}
    for key, (m_sd, z_sd, m_dof, z_dof, lags) in row[7]["lag_windows"].items():
        t_m, t_z = critical(m_dof), critical(z_dof)
        out[key] = (err_m / m_sd, err_z / z_sd, t_m, t_z, 200 * t_m * m_sd / m_true, 2000 * t_z * z_sd, lags * T)
    return out


def _line(label: str, rows: list[list], key: str) -> str:
    fits = [_fit_windows(r) for r in rows]
    good = np.array([f[key] for f in fits if f is not None])
    n = len(rows)
    if not len(good):
        return f"{label:22} {key:>6} {n:4d}  all failed"
    hm, hz = np.abs(good[:, 0]) <= good[:, 2], np.abs(good[:, 1]) <= good[:, 3]
    ref = np.array([f["5"] for f in fits if f is not None])  # paired with main's window, fit by fit
    both5 = (np.abs(ref[:, 0]) <= ref[:, 2]) & (np.abs(ref[:, 1]) <= ref[:, 3])
    return (
        f"{label:22} {key:>6} {n:4d} {n - len(good):3d} | {100 * hm.sum() / n:5.0f} {100 * hz.sum() / n:5.0f} "
        f"{100 * (hm & hz).sum() / n:5.0f} | {good[:, 0].std():5.2f} {good[:, 1].std():5.2f} | "
        f"{np.median(good[:, 2]):5.2f} {np.median(good[:, 3]):5.2f} | {np.median(good[:, 4]):6.2f} "
        f"{np.median(good[:, 5]):6.1f} | {np.median(good[:, 6]):5.2f} | {int((hm & hz & ~both5).sum()):2d} "
        f"{int((~(hm & hz) & both5).sum()):2d}"
    )


def _same_as(rows: list[list], others: list[list]) -> str:
    """The largest |difference| of the mass (pp) and height (mm) errors between the fits two sets of dumps share."""
    theirs = {tuple(r[:4]): r[4] for r in others}
    d = [
        (abs(r[4][0] - theirs[k][0]), abs(r[4][1] - theirs[k][1]))
        for r in rows
        if (k := tuple(r[:4])) in theirs and r[4] is not None and theirs[k] is not None
    ]
    fails = sum((r[4] is None) != (theirs.get(tuple(r[:4]), 0) is None) for r in rows if tuple(r[:4]) in theirs)
    if not d:
        return "no fit in common"
    a = np.array(d)
    return f"{len(d)} fits in common: max |d mass| {a[:, 0].max():.2g} pp, max |d height| {a[:, 1].max():.2g} mm; {fails} differ in failing"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump", nargs="+")
    ap.add_argument("--by-case", action="store_true", help="also each variant and case (else per variant, and pooled)")
    ap.add_argument("--same-as", nargs="+", help="dumps of the same fits whose estimates these must equal")
    a = ap.parse_args()
    rows = [r for r in load_dumps(a.dump) if r[2] == "oe"]
    for p in a.dump:  # file by file, so that the refusal names the file
        for r in load_dumps([p]):
            if r[2] == "oe" and r[4] is not None and not (isinstance(r[7], dict) and r[7].get("lag_windows")):
                sys.exit(f"{p}: fit {'/'.join(map(str, r[:4]))} has no lag_windows; fix: give a dump of stop 62's bench or later")
    if not any(r[4] is not None for r in rows):
        sys.exit(f"{a.dump[0]}: no converged oe fit; fix: give a dump of stop 62's bench with oe fits")
    keys = list(next(r[7]["lag_windows"] for r in rows if r[4] is not None))
    keys.remove("own")
    print(
        f"{'group':22} {'window':>6} {'n':>4} {'nf':>3} | {'cov m':>5} {'cov z':>5} {'both':>5} | {'sd sm':>5} {'sd sz':>5} | "
        f"{'t m':>5} {'t z':>5} | {'w m %':>6} {'w z mm':>6} | {'lag s':>5} | {'+':>2} {'-':>2}"
    )
    groups = [(v, [r for r in rows if r[0] == v]) for v in dict.fromkeys(r[0] for r in rows)]
    if a.by_case:
        groups = [(f"{v} {c}", [r for r in g if r[1] == c]) for v, g in groups for c in ("case1", "case2", "case3")]
    groups += [(f"pooled {c}", [r for r in rows if r[1] == c]) for c in ("case1", "case2", "case3")]
    groups.append(("pooled", rows))
    for label, sel in groups:
        for key in keys:
            print(_line(label, sel, key))
        print()
    print(
        "cov: % of all fits (a failure a miss) whose interval estimate +- t sd holds the truth (basin_truth); sd sm/sz: "
        "sd of the z-scores error/sd; t: median critical value; w: median full width (mass % of the true load, height "
        "mm); lag s: median window in s; +/-: fits whose two intervals hold the truth at this window and not at 5 s / at "
        "5 s and not at this one"
    )
    if a.same_as:
        print("\nestimates against " + " ".join(a.same_as) + ": " + _same_as(rows, load_dumps(a.same_as)))


if __name__ == "__main__":
    main()
