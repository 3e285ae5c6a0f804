"""Stops 55-56: each recorded channel's noise as ``detect``'s prior reads it, against the podded truth's own
sensor settings (tests/physics/podded_truth.py: Table 4.1 levels behind first-order low-passes).

For every nominal recording in the given truth-bench caches (``bench_detect_truth.py --cache DIR``), the
white-noise reading (:func:`identify.detect.priorfit.white_noise_sd`, main's) and the low-passed white noise
read from the spectrum above the ship's motion (:func:`identify.detect.noisespec.spectral_noise`, stop 56: sd
and time constant) of each channel (stop 55's fourth-difference reader's columns left with it at stop 57: its
figures are in docs/detect-accuracy.md),
as ratios to the truth's sd and time constant; mean and range per variant. The truth's settings are
read here only to be compared with; the readings see the recording alone.

    PYTHONPATH=$PWD python benchmarks/detect_noise_read.py DIR [DIR ...]   # folders of benchmarks/bench_detect_truth.py --cache
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from identify.detect.noisespec import spectral_noise
from identify.detect.priorfit import white_noise_sd
from tests.physics.podded_truth import TABLE_4_1, Ship

CHANNELS = ("r", "u", "v", "v_dot", "phi", "p", "tau_n")
TRUE_SD = TABLE_4_1 | {"p": 0.01}
TRUE_TAU = dict(Ship().lp)


def read_csv(path: Path) -> tuple[dict[str, np.ndarray], float]:
    """The recording's channels and its sample time (the truth bench's CSV: a '# sample_time' line, a header)."""
    first = path.open().readline()
    dt = float(first.split(":")[1]) if first.startswith("#") else 0.1
    a = np.genfromtxt(path, delimiter=",", names=True, skip_header=1 if first.startswith("#") else 0)
    return {k: np.asarray(a[k], float) for k in a.dtype.names}, dt


def nominal_recordings(folder: Path) -> list[tuple[str, Path]]:
    """(variant, path) of every ship's stored nominal recording in a ``bench_detect_truth.py --cache`` folder, in
    file-name order: the files whose names :func:`benchmarks.bench_detect_truth.stored_recording` gives for a
    variant of the truth family, a ship and a truth-code fingerprint (any: a folder filled by earlier truth code is
    read too, as the readings compare with the settings of the truth code here)."""
    from benchmarks.bench_detect_truth import ALL_VARIANTS, batch_name, stored_recording

    found = []
    for p in folder.glob("*.csv"):
        for v in ALL_VARIANTS:
            ship = p.name.removeprefix(f"{v}-").split("-", 1)[0]
            if not p.name.startswith(f"{v}-") or not ship.isdigit():
                continue
            # the fingerprint is what lies between the batch's name and the run's number: the name given back whole
            fp = p.name[len(batch_name(v, int(ship))) + 1 :].rsplit("-", 1)[0]
            if p.name == stored_recording(v, int(ship), fp):
                found.append((p.name, v, p))
    return [(v, p) for _, v, p in sorted(found)]


def readings(folders: list[Path]) -> dict[str, list[dict[str, tuple[float, float, float]]]]:
    """Per variant, per nominal recording: channel -> (white sd / true, spectral sd / true, spectral tau / true)."""
    out: dict[str, list] = {}
    for folder in folders:
        for variant, p in nominal_recordings(folder):
            ch, dt = read_csv(p)
            row = {}
            for k in CHANNELS:
                ss, ts = spectral_noise(ch[k], dt)
                row[k] = (
                    white_noise_sd(ch[k]) / TRUE_SD[k],
                    ss / TRUE_SD[k],
                    ts / TRUE_TAU[k],
                )
            out.setdefault(variant, []).append(row)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    a = ap.parse_args(argv)
    missing = [str(f) for f in a.folders if not f.is_dir()]
    if missing:
        print(f"error: {', '.join(missing)}: no such folder; give bench_detect_truth.py --cache folders", file=sys.stderr)
        return 2
    res = readings(a.folders)
    print(
        "| variant (recordings) | channel | true sd | true tau s | white read / true sd | spectral read / true sd |"
        " spectral tau / true tau |"
    )
    print("|---|---|---|---|---|---|---|")
    for v, rows in res.items():
        for k in CHANNELS:
            w, ss, ts = (np.array([r[k][i] for r in rows]) for i in range(3))
            cell = lambda x: f"{x.mean():.2f} ({x.min():.2f}-{x.max():.2f})"  # noqa: E731
            print(f"| {v} ({len(rows)}) | {k} | {TRUE_SD[k]:g} | {TRUE_TAU[k]:g} | {cell(w)} | {cell(ss)} | {cell(ts)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
