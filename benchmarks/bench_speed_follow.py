"""Which recordings of the basin truth family ``mass`` follows the speed of (no fits: seconds a variant).

For every run and dataset (the seeds of bench_rollmass_truth.py) the recording is written and read as
``shiptrial mass`` reads it, and :func:`identify.rollmass.speed.speed_variation` splits its
``u / mean(u)`` at the low-pass; prints per variant the range of the low/high sd ratio, of the low-passed
sd, and how many recordings :func:`~identify.rollmass.speed.followed_speed` follows.

    python benchmarks/bench_speed_follow.py --runs 4
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identify.rollmass.recording import read_roll_csv  # noqa: E402
from identify.rollmass.speed import followed_speed, speed_variation  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--variants", default=",".join(bt.VARIANTS + ("base",)))
    ap.add_argument("--seed", type=int, default=2015)
    a = ap.parse_args()
    print(f"{'variant':10} | {'low/high sd ratio':>17} | {'low-passed sd %':>15} | followed")
    for variant in a.variants.split(","):
        seed = bt.variant_seed(a.seed, variant)
        ship, data = bt.simulate_runs(variant, a.runs, seed)
        ratio, slow, followed = [], [], 0
        with tempfile.TemporaryDirectory() as d:
            for run in range(a.runs):
                for name in bt.DATASETS:
                    cols = {k: data[name][k][run] for k in ("delta", "p", "a_s", "r", "phi", "u")}
                    rec = bt.Recording("nominal", name, bt.DEC / bt.FS, cols, {"speed_m_s": f"{data[name]['speed'][run]:.4f}"})
                    rr, _ = read_roll_csv(bt.write_csv(rec, Path(d) / "x.csv"))
                    lo, hi = speed_variation(rr)
                    ratio.append(lo / hi)
                    slow.append(100 * lo)
                    followed += followed_speed(rr) is not None
        print(
            f"{variant:10} | {min(ratio):7.2f} - {max(ratio):6.2f} | {min(slow):6.2f} - {max(slow):5.2f} | "
            f"{followed}/{len(ratio)}"
        )


if __name__ == "__main__":
    main()
