"""What the yaw prior's structural spread does to `detect` on the podded truth family: the stored
screenings of benchmarks/bench_detect_truth.py (its ``--cache``) re-decided with each prior's
``structure`` as stored, scaled, or replaced, nothing else changed.

Only the thresholds (``glr.calibrate``: the structure is added there as a random apparent change along
each candidate's signature) and the verdict's estimate sd depend on the structure; the residual, the
signatures and the 400 no-change records of a screening do not. So a screening stored by the truth
bench is re-decided here in well under a second, the prior's structure set as asked:

    python benchmarks/bench_detect_structure.py --cache DIR --first-ship 102 --ships 2 --runs 10 \\
        --variants steering-lag-acting nominal-mmg --structure stored zero 0.5 \\
        --key 06129d985011   # the screening key in the cached file names (default: this code's)

``--structure``: ``stored`` (as the prior was fitted), ``zero``, a factor (``0.5``: half the stored
spread) or three percentages of I_r, damping, pod gain (``1.0,0,0``). Printed per variant and setting:
the truth bench's row (false alarms, misses, delay, named) and the priors' structure. Ship 103
steering-lag-acting, stop 47: stored 2.33 / 0 / 0.51 % -> 0 / 60 / 263 s pooled with ship 102; zero ->
5 / 15 / 198 s (main 52b12ef's screenings)."""

from __future__ import annotations

import argparse
import pickle
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.bench_detect_truth import (
    HULL,
    change_times,
    prior_name,
    row,
    screen_name,
    screening_key,
    stored_recording,
    summarise,
)
from identify.detect.glr import calibrate
from identify.detect.verdict import implausible_inertia, physical_change, verdict


def _one(folder: Path, pattern: str) -> Path:
    hits = sorted(folder.glob(pattern))
    if len(hits) != 1:
        raise SystemExit(f"{folder}: {len(hits)} files match {pattern}; give the bench's --cache and --key")
    return hits[0]


def with_structure(prior, setting: str):
    """The prior with its structure as ``setting`` says (see the module's help)."""
    if setting == "stored":
        return prior
    if setting == "zero":
        return replace(prior, structure=np.zeros_like(prior.structure))
    if "," in setting:
        return replace(prior, structure=np.array([float(s) / 100 for s in setting.split(",")]))
    return replace(prior, structure=float(setting) * prior.structure)


def theta1(min_change: float = 0.05) -> np.ndarray:
    """The LR-CUSUM's change sizes per candidate as ``api.screen`` makes them for the truth family's hull."""
    k = physical_change("yaw_inertia", 1.0, HULL["i_z"] - HULL["n_rdot"], HULL["n_rdot"])
    return np.array([min_change / k, min_change, min_change])


def redecide(sc, prior, min_change: float = 0.05, false_alarm: float = 0.02):
    """The verdict on a stored screening with thresholds recalibrated for ``prior`` (as api.screen makes them)."""
    det = calibrate(prior, sc.S, sc.null_blocks, theta1=theta1(min_change), false_alarm=false_alarm, seed=0, band=sc.roll_band)
    return verdict(replace(sc, h=np.asarray(det.h)), prior, **HULL)


def ship_study(folder: Path, variant: str, ship: int, runs: int, key: str, setting: str) -> dict:
    """bench_detect_truth.ship_study's result for one ship, from its stored prior and screenings."""
    prior = pickle.loads(_one(folder, prior_name(stored_recording(variant, ship, "*"), key)).read_bytes())
    prior = with_structure(prior, setting)
    changes = change_times(ship, runs)
    out = {"unchanged": [], "changed": [], "errors": [], "structure": prior.structure.tolist()}
    if implausible_inertia(prior, **HULL):
        out["refused"] = f"ship {ship}"
        return out
    for i, ch in enumerate(changes):
        sc = pickle.loads(_one(folder, screen_name(stored_recording(variant, ship, "*", runs, i), key)).read_bytes())
        d = redecide(sc, prior)
        res = {"alarm_s": d.alarm_s, "property": d.property, "change_s": ch, "h": float(d.threshold[0])}
        res |= {"roll_max": float("nan"), "failed": False, "evidence": d.evidence}
        out["unchanged" if ch is None else "changed"].append(res)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, required=True, help="bench_detect_truth.py's --cache folder")
    ap.add_argument("--key", default=None, help="screening key in the cached names (default: this code's)")
    ap.add_argument("--first-ship", type=int, default=102)
    ap.add_argument("--ships", type=int, default=2)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--variants", nargs="*", default=["steering-lag-acting", "nominal-mmg"])
    ap.add_argument("--structure", nargs="*", default=["stored", "zero"])
    a = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    key = a.key or screening_key()
    ships = range(a.first_ship, a.first_ship + a.ships)
    print("variant / structure setting, then bench_detect_truth's columns (roll correlation not available here)")
    for v in a.variants:
        for s in a.structure:
            studies = [ship_study(a.cache, v, k, a.runs, key, s) for k in ships]
            print(row(f"{v[:9]}/{s}", summarise(studies)))
            print(
                f"    structure % (I_r, damping, pod gain) per ship: {[np.round(100 * np.array(t['structure']), 2).tolist() for t in studies]}"
            )


if __name__ == "__main__":
    main()
