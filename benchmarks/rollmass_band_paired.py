"""Two truth-family dumps of the same fits paired run by run (stop 61: oe's band-limited objective against the full
band): per variant and case, the median |mass error| and |height error| before and after, in how many runs |error|
fell, the share of runs whose two intervals hold the truth, and the sd of the standardised errors (error / reported
sd; about 1 if the intervals are honest, benchmarks/rollmass_family_zscores.py), failures and the median CPU a fit.

    python benchmarks/rollmass_band_paired.py BEFORE AFTER [--markdown]

Only fits in both dumps are paired, and only runs whose every (variant, case) fit the AFTER dump holds (an
interrupted dump's last run is left out, as ``rollmass_family_table.py --complete-runs`` does); a failed fit (no row figures) is counted in ``fail`` and left out of the rest.
Nothing is fitted.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.compare_rollmass_dumps import _load  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402


def _z(r: list) -> tuple[float, float]:
    """The fit's standardised mass and height errors (NaN without a reported sd)."""
    m_true, _ = bt.truth_load(r[1])
    f = r[7]
    sm = (r[4][0] / 100 * m_true) / f["m_sd"] if f.get("m_sd") else float("nan")
    sz = (r[4][1] / 1000) / f["z_sd"] if f.get("z_sd") else float("nan")
    return sm, sz


def _cell(pairs: list[tuple[list, list]]) -> list[str]:
    """One cell's figures, before -> after."""
    good = [(b, a) for b, a in pairs if b[4] is not None and a[4] is not None]
    fail = (sum(b[4] is None for b, _ in pairs), sum(a[4] is None for _, a in pairs))
    if not good:
        return [str(len(pairs))] + ["-"] * 7 + [f"{fail[0]}/{fail[1]}", "-"]
    B, A = (np.array([r[4][:4] for r in side], dtype=float) for side in zip(*good))
    out = [str(len(good))]
    for k, fmt in ((0, "{:.2f}"), (1, "{:.1f}")):
        out.append(f"{fmt.format(np.median(np.abs(B[:, k])))} -> {fmt.format(np.median(np.abs(A[:, k])))}")
    out += [
        f"{int((np.abs(A[:, 0]) < np.abs(B[:, 0])).sum())}/{len(good)}",
        f"{int((np.abs(A[:, 1]) < np.abs(B[:, 1])).sum())}/{len(good)}",
    ]
    out.append(f"{100 * (B[:, 2] * B[:, 3]).mean():.0f} -> {100 * (A[:, 2] * A[:, 3]).mean():.0f}")
    zb = np.array([_z(b) for b, _ in good])
    za = np.array([_z(a) for _, a in good])
    for k in (0, 1):
        out.append(f"{np.nanstd(zb[:, k], ddof=1):.2f} -> {np.nanstd(za[:, k], ddof=1):.2f}")
    out.append(f"{fail[0]}/{fail[1]}")
    out.append(f"{np.median([b[6] for b, _ in pairs]):.1f} -> {np.median([a[6] for _, a in pairs]):.1f}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args()
    before, after = _load(a.before), _load(a.after)
    cells = {(k[0], k[1]) for k in after}
    runs = {k[3] for k in after if all((v, c, k[2], k[3]) in after for v, c in cells)}
    keys = sorted(k for k in set(before) & set(after) if k[3] in runs)
    print(f"runs paired: {sorted(runs)}")
    variants = list(dict.fromkeys(k[0] for k in keys))
    cases = sorted({k[1] for k in keys})
    head = [
        "variant",
        "case",
        "n",
        "m med %",
        "z med mm",
        "m better",
        "z better",
        "cov both %",
        "z-sd m",
        "z-sd z",
        "fail",
        "cpu s",
    ]
    print(("| " + " | ".join(head) + " |\n|" + "---|" * len(head)) if a.markdown else "  ".join(head))
    for v in variants + ["pooled"]:
        for c in cases + ["all"]:
            sel = [k for k in keys if (v == "pooled" or k[0] == v) and (c == "all" or k[1] == c)]
            row = _cell([(before[k], after[k]) for k in sel])
            cellsx = [v, c] + row
            print(("| " + " | ".join(cellsx) + " |") if a.markdown else "  ".join(cellsx))


if __name__ == "__main__":
    main()
