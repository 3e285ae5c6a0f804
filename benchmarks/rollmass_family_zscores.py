"""Why a truth family's 95 % intervals miss (stop 60): each oe fit's standardised errors (error / reported sd, of the
mass and of the height ``zbar_m``), and per variant their bias (median) and spread (sd), split into the misses each
alone would make.

    python benchmarks/rollmass_family_zscores.py DUMP [DUMP ...] [--inflate K | --inflate-from DUMP [DUMP ...]]

``DUMP``: ``--dump`` files of :mod:`benchmarks.bench_rollmass_truth` whose rows record the reported sds (``m_sd``,
``z_sd``, since stop 55) and the intervals' Satterthwaite degrees of freedom (``m_dof``, ``z_dof``, since stop 60); a
row without them is counted as "no sd" (an older dump, stop 54's, records neither). Nothing is fitted.

A fit's interval is ``estimate +- t sd`` with ``t = t_{0.975, nu}`` (``MassEstimate.critical``), so it misses exactly
when ``|s| > t`` for ``s = (estimate - truth) / sd``. If the reported sds were right, ``s`` would be about standard
normal: a median far from 0 is a bias the sd does not know, an sd above 1 a spread it underrates. With the
``s`` of a group read as ``N(b, k^2)`` (``b`` its median, ``k`` its sd), the share missed is
``1 - [Phi((t - b) / k) - Phi((-t - b) / k)]`` (the group's median ``t``): ``k = 1`` gives the bias alone,
``b = 0`` the spread alone, both the two together, beside the misses counted.

``--inflate K`` reads every interval ``K`` times as wide (``|s| <= K t``) and prints the coverage it would have;
``--inflate-from DUMP ...`` takes ``K`` per quantity as ``sqrt(mean(s^2))`` over those dumps' fits (1 if the sds were
right), so the factor is measured on fits other than the ones it is judged on. An analysis option only: the
product's intervals are not changed by it.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.special import stdtrit
from scipy.stats import kurtosis, norm, shapiro

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.rollmass_family_table import load as load_dumps  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402


def critical(dof: float) -> float:
    """``MassEstimate.critical``'s value for one variance: Student's ``t_{0.975, nu}``, 1.96 when ``nu`` is not finite."""
    return float(stdtrit(dof, 0.975)) if math.isfinite(dof) else 1.96


def standardised(row: list) -> tuple[float, float, float, float] | None:
    """``(s_m, s_z, t_m, t_z)`` of one dump row: the mass and height errors in units of the reported sd and the
    intervals' critical values; None for a failed fit or a row without the sds and degrees of freedom."""
    extra = row[7] if isinstance(row[7], dict) else {}
    if row[4] is None or not {"m_sd", "z_sd", "m_dof", "z_dof"} <= extra.keys():
        return None
    m_true, _ = bt.truth_load(row[1])
    err_m = row[4][0] / 100 * m_true  # kg (the row holds 100 (m / m_true - 1))
    err_z = row[4][1] / 1000  # m (the row holds mm)
    return err_m / extra["m_sd"], err_z / extra["z_sd"], critical(extra["m_dof"]), critical(extra["z_dof"])


def miss_share(b: float, k: float, t: float) -> float:
    """The share of ``N(b, k^2)`` outside ``[-t, t]``, in per cent."""
    return 100 * (1 - (norm.cdf((t - b) / k) - norm.cdf((-t - b) / k)))


def _one(s: np.ndarray, t: np.ndarray) -> dict[str, float]:
    """One quantity's figures over a group: median, sd, rms of ``s``, misses counted, and the modelled misses."""
    b, k, tm = float(np.median(s)), float(np.std(s, ddof=1)) if len(s) > 1 else float("nan"), float(np.median(t))
    return {
        "med": b,
        "sd": k,
        "rms": float(np.sqrt(np.mean(s**2))),
        # the sd a normal with this median absolute deviation has: near "sd" when the whole spread is wider, well
        # under it when a few large misses make it
        "rsd": 1.4826 * float(np.median(np.abs(s - b))),
        "miss": 100 * float(np.mean(np.abs(s) > t)),
        "bias_only": miss_share(b, 1.0, tm),
        "spread_only": miss_share(0.0, k, tm),
        "both": miss_share(b, k, tm),
        "pos": int(np.sum(s > t)),
        "neg": int(np.sum(s < -t)),
    }


def group(rows: list[list], inflate: tuple[float, float] = (1.0, 1.0)) -> dict:
    """The figures of a group of rows: fits with sds, failures, each quantity's :func:`_one`, the share where both
    intervals hold as recorded and as recomputed from ``s`` and ``t`` (they must agree), and with ``inflate``."""
    got = [standardised(r) for r in rows]
    a = np.array([g for g in got if g is not None], dtype=float).reshape(-1, 4)
    out = {
        "n": len(rows),
        "fail": sum(r[4] is None for r in rows),
        "no_sd": sum(g is None and r[4] is not None for g, r in zip(got, rows)),
    }
    if not len(a):
        return out
    hold_rec = np.array([r[4][2] and r[4][3] for g, r in zip(got, rows) if g is not None], dtype=bool)
    hold = (np.abs(a[:, 0]) <= a[:, 2]) & (np.abs(a[:, 1]) <= a[:, 3])
    hold_k = (np.abs(a[:, 0]) <= inflate[0] * a[:, 2]) & (np.abs(a[:, 1]) <= inflate[1] * a[:, 3])
    out.update(
        ng=len(a),
        m=_one(a[:, 0], a[:, 2]),
        z=_one(a[:, 1], a[:, 3]),
        both=100 * float(hold.mean()),
        both_recorded=100 * float(hold_rec.mean()),
        both_inflated=100 * float(hold_k.mean()),
        t_m=(float(a[:, 2].min()), float(a[:, 2].max())),
        t_z=(float(a[:, 3].min()), float(a[:, 3].max())),
    )
    return out


def rms_factor(rows: list[list]) -> tuple[float, float]:
    """``K`` per quantity for ``--inflate-from``: ``sqrt(mean(s^2))`` over the rows with sds (1: the sds are right)."""
    a = np.array([g for g in map(standardised, rows) if g is not None], dtype=float).reshape(-1, 4)
    if not len(a):
        raise SystemExit("--inflate-from: no row records the sds and degrees of freedom; fix: give a dump of stop 60 or later")
    return float(np.sqrt(np.mean(a[:, 0] ** 2))), float(np.sqrt(np.mean(a[:, 1] ** 2)))


def checks(rows: list[list]) -> dict[str, float] | None:
    """The pooled checks the stop-60 reading rests on, over the rows with sds (None if none): ``corr`` of the mass and
    height ``s`` (the two intervals miss together), both intervals holding as read with ``t`` (``hold_t``) and with the
    normal 1.96 (``hold_196``: the critical value's share of the misses), the mass ``s``'s excess ``kurtosis`` (its
    standard error about sqrt(24 / n): a t on few degrees of freedom shows in it) and Shapiro-Wilk ``shapiro_p``, and
    the (variant, run) pairs with a miss in some case (``runs_missed``) and in every case given (``runs_all_missed``)
    of ``runs`` pairs."""
    got = [(r, g) for r, g in zip(rows, map(standardised, rows)) if g is not None]
    if len(got) < 3:
        return None
    a = np.array([g for _, g in got], dtype=float)
    hold = (np.abs(a[:, 0]) <= a[:, 2]) & (np.abs(a[:, 1]) <= a[:, 3])
    by_run: dict[tuple, list[bool]] = {}
    for (r, _), h in zip(got, hold):
        by_run.setdefault((r[0], r[3]), []).append(bool(h))
    return {
        "n": len(a),
        "corr": float(np.corrcoef(a[:, 0], a[:, 1])[0, 1]),
        "hold_t": int(hold.sum()),
        "hold_196": int(((np.abs(a[:, 0]) <= 1.96) & (np.abs(a[:, 1]) <= 1.96)).sum()),
        "kurtosis": float(kurtosis(a[:, 0])),
        "kurtosis_se": math.sqrt(24 / len(a)),
        "shapiro_p": float(shapiro(a[:, 0]).pvalue),
        "runs": len(by_run),
        "runs_missed": sum(not all(v) for v in by_run.values()),
        "runs_all_missed": sum(not any(v) for v in by_run.values()),
    }


def _positive(text: str) -> float:
    """``--inflate``'s K: a finite number above 0 (0 would read no interval, a negative one none either)."""
    try:
        k = float(text)
    except ValueError:
        k = float("nan")
    if not (math.isfinite(k) and k > 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a factor above 0; fix: give e.g. --inflate 1.45")
    return k


def _line(label: str, g: dict) -> str:
    if "ng" not in g:
        return f"{label:18} {g['n']:4d} fits, none with sds ({g['fail']} failed)"
    m, z = g["m"], g["z"]
    q = [
        f"{d['med']:+6.2f} {d['sd']:5.2f} {d['rsd']:5.2f} {d['rms']:5.2f} {d['miss']:5.0f} {d['bias_only']:5.0f} {d['spread_only']:5.0f} {d['both']:5.0f} {d['pos']:3d}+{d['neg']:<3d}"
        for d in (m, z)
    ]
    return f"{label:18} {g['ng']:4d} {g['fail']:3d} | {q[0]} | {q[1]} | {g['both']:5.0f} {g['both_recorded']:5.0f} {g['both_inflated']:6.0f}"


def load(paths: list[str]) -> list[list]:
    """The oe rows of the dumps (``rollmass_family_table.load``: a fit in two of them refused)."""
    return [r for r in load_dumps(paths) if r[2] == "oe"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump", nargs="+")
    how = ap.add_mutually_exclusive_group()
    how.add_argument("--inflate", type=_positive, help="read every interval K times as wide (both quantities)")
    how.add_argument("--inflate-from", nargs="+", help="K per quantity: sqrt(mean(s^2)) over these dumps' fits")
    a = ap.parse_args()
    rows = load(a.dump)
    if not rows:
        raise SystemExit(f"{', '.join(a.dump)}: no oe fit; fix: give a dump of bench_rollmass_truth --methods oe")
    k = (a.inflate, a.inflate) if a.inflate else rms_factor(load(a.inflate_from)) if a.inflate_from else (1.0, 1.0)
    runs = sorted({r[3] for r in rows})
    print(f"{len(rows)} oe fits, runs {runs[0]}-{runs[-1]}; inflation K mass {k[0]:.3f}, height {k[1]:.3f}")
    cols = "med    sd   rsd   rms  miss% bias% sprd% b+s%  +/- "
    print(f"{'group':18} {'fits':>4} {'fail':>3} | mass s: {cols}| height s: {cols}| both holding %: recomputed, recorded, x K")
    variants, cases = list(dict.fromkeys(r[0] for r in rows)), sorted({r[1] for r in rows})
    for v in variants + ["pooled"]:
        sub = [r for r in rows if v in ("pooled", r[0])]
        for c in cases + ["all"]:
            print(_line(f"{v} {c}", group([r for r in sub if c in ("all", r[1])], k)))
    g = group(rows, k)
    if "ng" in g:
        print(f"critical values t: mass {g['t_m'][0]:.2f}-{g['t_m'][1]:.2f}, height {g['t_z'][0]:.2f}-{g['t_z'][1]:.2f}")
    c = checks(rows)
    if c is not None:
        print(
            f"pooled checks: corr(mass s, height s) {c['corr']:.3f}; both holding {c['hold_t']} of {c['n']} with t, "
            f"{c['hold_196']} with 1.96; mass s excess kurtosis {c['kurtosis']:+.2f} (se ~{c['kurtosis_se']:.2f}), "
            f"Shapiro-Wilk p {c['shapiro_p']:.2f}; variant-runs with a miss {c['runs_missed']} of {c['runs']}, "
            f"in every case {c['runs_all_missed']}"
        )
    print(
        "s: error / reported sd; rsd: 1.4826 x its median absolute deviation; miss%: |s| > t counted; bias% / sprd% / b+s%: the misses of N(median, 1), N(0, sd^2),"
        "\nN(median, sd^2) at the group's median t (1.96-2.2: 5-3 % if the sds were right); +/-: misses above / below;"
        "\nboth holding: recomputed from s and t, as the bench recorded it, and with the intervals K times as wide."
    )


if __name__ == "__main__":
    main()
