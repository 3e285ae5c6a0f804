"""Why the run's own-residual bootstrap loses power (issue 25, stop 49 continued; docs/detect-accuracy.md):
per variant of a stored cache, on the changed runs, the detected share with the stored records and with
``--own-misfit`` settings, the re-decided thresholds over the stored ones, the resampled residual's variance
over the stored AR term's, and the share of it that is noise the records already carry. Stop 53: the
same threshold ratio on the unchanged runs, and on the changed runs whose change is mid-record (100-300 s)
the resampled residual's variance before and after the true change time (over the stored term's): if a
change's own signal raised its thresholds, the changed runs' ratio would exceed the unchanged runs' and
the part after the change would carry more than the part before.

    python benchmarks/detect_ownboot_diag.py --cache DIR:KEY:108:2   # a stored screening of benchmarks/bench_detect_truth.py --cache DIR
"""

from __future__ import annotations

import argparse
import pickle
import warnings
from pathlib import Path

import numpy as np

from benchmarks.bench_detect_calibration import VARIANTS
from benchmarks.bench_detect_structure import _one, redecide
from benchmarks.bench_detect_truth import HULL, change_times, prior_name, screen_name, stored_recording
from benchmarks.detect_ownmisfit import post_fit_residual, stored_offsets, with_own
from identify.detect.verdict import Screening, implausible_inertia
from identify.detect.yawmodel import YawPrior


def variances(sc: Screening, prior: YawPrior) -> tuple[float, float, float]:
    """(records' own noise, the projected residual ``bootpL`` resamples, the stored AR term): variances of
    the block means; the records' noise is the stored records less the regenerated term (``stored_offsets``)."""
    nb, runs = sc.null_blocks.shape
    so = stored_offsets(prior, len(sc.eps), runs)[:nb]
    base = sc.null_blocks - so
    res = post_fit_residual(sc, prior, project=True)
    return float(np.var(base - base.mean(axis=0))), float(np.var(res)), float(np.var(so))


def split_variances(sc: Screening, prior: YawPrior, change_block: int) -> tuple[float, float]:
    """The projected residual ``bootpL`` resamples, its variance before and after the true change block,
    each over the stored AR term's variance (:func:`stored_offsets`)."""
    nb, runs = sc.null_blocks.shape
    term = np.var(stored_offsets(prior, len(sc.eps), runs)[:nb])
    res = post_fit_residual(sc, prior, project=True)
    return float(np.var(res[:change_block]) / term), float(np.var(res[change_block:]) / term)


def variant_rows(spec: str, variant: str, settings: tuple[str, ...]) -> dict:
    """Per changed run: detected (stored and each setting), median threshold ratio per setting, variances."""
    folder, key, first, ships = spec.split(":")
    out: dict = {"detected": {s: [] for s in ("stored", *settings)}, "h": {s: [] for s in settings}, "var": []}
    out |= {"h_unchanged": {s: [] for s in settings}, "split": []}
    for ship in range(int(first), int(first) + int(ships)):
        prior = pickle.loads(_one(Path(folder), prior_name(stored_recording(variant, ship, "*"), key)).read_bytes())
        if implausible_inertia(prior, **HULL):
            continue
        for i, ch in enumerate(change_times(ship, 10)):
            sc = pickle.loads(_one(Path(folder), screen_name(stored_recording(variant, ship, "*", 10, i), key)).read_bytes())
            d0 = redecide(sc, prior)
            if ch is None:
                for s in settings:
                    out["h_unchanged"][s].append(
                        float(np.median(redecide(with_own(sc, prior, s)[0], prior).threshold / d0.threshold))
                    )
                continue
            if ch > 0:
                out["split"].append(split_variances(sc, prior, int(ch / (prior.block * prior.dt))))
            out["detected"]["stored"].append(d0.alarm_s is not None)
            for s in settings:
                d = redecide(with_own(sc, prior, s)[0], prior)
                out["detected"][s].append(d.alarm_s is not None)
                out["h"][s].append(float(np.median(d.threshold / d0.threshold)))
            out["var"].append(variances(sc, prior))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True, help="folder:key:first ship:ships (read only)")
    ap.add_argument("--settings", nargs="*", default=["boot30", "bootp30", "bootp100"])
    a = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    for v in VARIANTS:
        r = variant_rows(a.cache, v, tuple(a.settings))
        det = " ".join(f"{s} {100 * np.mean(x):.0f}" for s, x in r["detected"].items())
        h = " ".join(f"{s} {np.median(x):.2f}" for s, x in r["h"].items())
        noise, res, term = np.array(r["var"]).T
        print(f"{v:20s} changed runs detected %: {det}; median h / stored h: {h}")
        print(
            f"{'':20s} resampled var / stored term var {np.median(res / term):.2f}; noise counted twice {np.median(noise / res):.3f}"
        )
        hu = " ".join(f"{s} {np.median(x):.2f}" for s, x in r["h_unchanged"].items())
        split = "n/a (no changed run starts mid-record)"
        if r["split"]:
            pre, post = np.array(r["split"]).T
            split = f"before the change {np.median(pre):.2f}, after {np.median(post):.2f}"
        print(f"{'':20s} unchanged runs: median h / stored h: {hu}; changed mid-record: resampled var / term {split}")


if __name__ == "__main__":
    main()
