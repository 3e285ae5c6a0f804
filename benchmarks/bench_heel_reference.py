"""The AHRS roll angle on the independent basin truth: its error, and what each heel reference leaves of it.

For every run and dataset of the basin truth family (tests/physics/basin_truth.py, the seeds of
bench_rollmass_truth.py) the recording is written and read as ``shiptrial mass`` reads it, and the roll
angle the oe fit would use (:func:`identify.rollmass.restoring.referenced_heel`, each of
:data:`~identify.rollmass.restoring.HEEL_REFERENCES`) is compared with the true heel through the same
filters (the recording without the AHRS error and without the IMU's misalignment). Prints per variant and
reference the median |mean error| and the median rms error [deg], and the error of the heel moment's
even part ``mean(w)`` that a bias turns into load (relative to the true ``mean(|w|)``). No fits: seconds.

    python benchmarks/bench_heel_reference.py --runs 8
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scipy.signal import remez  # noqa: E402

from identify.rollmass.model import Known, load_profile  # noqa: E402
from identify.rollmass.recording import read_roll_csv  # noqa: E402
from identify.rollmass.restoring import HEEL_REFERENCES, heel_signal, referenced_heel  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402


def _true_phi(variant: str, runs: int, seed: int) -> dict[str, np.ndarray]:
    """Every dataset's ``phi`` column without the AHRS error and the IMU's roll misalignment (the same streams)."""
    keep = bt._ahrs_error
    bt._ahrs_error = lambda R, n, s: np.zeros((R, n))
    try:
        ship, data = bt.simulate_runs(variant, runs, seed)
    finally:
        bt._ahrs_error = keep
    fir_dc = remez(21, [0, 0.5, 5.0, bt.FS / 2], [1, 0], fs=bt.FS).sum()  # the FIR's gain at 0 Hz, on the constant misalignment
    return {k: d["phi"] - fir_dc * ship.eps[:, :1] for k, d in data.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--variants", default="base,sway_roll,restoring,imu_mount,waves,speed_loss")
    ap.add_argument("--seed", type=int, default=2015)
    a = ap.parse_args()
    kn: Known = load_profile().known
    print(f"{'variant':10} {'reference':9} | {'|mean| deg':>10} {'rms deg':>8} | {'mean(w) err / mean|w|':>22}")
    for variant in a.variants.split(","):
        seed = bt.variant_seed(a.seed, variant)
        ship, data = bt.simulate_runs(variant, a.runs, seed)
        true = _true_phi(variant, a.runs, seed)
        res = {h: [] for h in HEEL_REFERENCES}
        with tempfile.TemporaryDirectory() as d:
            for run in range(a.runs):
                for name in bt.DATASETS:
                    rec = bt.Recording(
                        "nominal",
                        name,
                        bt.DEC / bt.FS,
                        {k: data[name][k][run] for k in ("delta", "p", "a_s", "r", "phi", "u")},
                        {"speed_m_s": f"{data[name]['speed'][run]:.4f}"},
                    )
                    rr, _ = read_roll_csv(bt.write_csv(rec, Path(d) / "x.csv"))
                    t = true[name][run]
                    wt = heel_signal(t, kn)
                    for h in HEEL_REFERENCES:
                        e = referenced_heel(rr, kn.g, rr.U, h) - t
                        dw = heel_signal(t + e, kn).mean() - wt.mean()
                        res[h].append((abs(e.mean()), np.sqrt(np.mean(e**2)), abs(dw) / np.abs(wt).mean()))
        for h in HEEL_REFERENCES:
            r = np.median(np.array(res[h]), axis=0)
            print(f"{variant:10} {h:9} | {np.rad2deg(r[0]):10.3f} {np.rad2deg(r[1]):8.3f} | {r[2]:22.3f}")


if __name__ == "__main__":
    main()
