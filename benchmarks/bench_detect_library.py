"""CPU of the library's ``detect`` on recordings in a warm process (stop 51): ``detect_all`` as ``shiptrial detect``
calls it (the noise cache on, freed memory kept, the hull given), one warm-up call that also writes the cache's
entry, then the median of ``--repeat`` ``time.process_time`` figures (and of the wall clock's). No interpreter start-up,
imports, option parsing or printing: what is left of the command's CPU once those are paid (``bench_detect_stages.py`` for them).

    cd RECORDINGS && PYTHONPATH=REPO SHIPTRIAL_DETECT_CACHE_DIR=DIR nice -n 10 python REPO/benchmarks/bench_detect_library.py \\
        prior.json run.csv [more.csv ...] [--repeat 7]

PYTHONPATH names the tree timed; alternate two trees' runs (each its own cache directory) to compare them.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from identify.detect import noisecache
from identify.detect.api import hull_inertia, load_prior, load_runs
from identify.detect.batch import detect_all
from primitives.heap import DETECT_KEEP_BYTES, keep_freed_memory


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("prior", type=Path)
    ap.add_argument("recordings", type=Path, nargs="+")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--profile", default="naval-vessel", help="the hull's I_z and N_rdot, as detect's --profile")
    a = ap.parse_args()
    keep_freed_memory(always=True, keep_bytes=DETECT_KEEP_BYTES)  # as the command's own process does
    prior = load_prior(a.prior)
    recs = load_runs(a.recordings, prior.kind, [])
    i_z, n_rdot = hull_inertia(a.profile, None, None)

    def once() -> tuple[float, float]:
        t, w = time.process_time(), time.perf_counter()
        with noisecache.used():
            detect_all(recs, prior, n_rdot=n_rdot, i_z=i_z)
        return time.process_time() - t, time.perf_counter() - w

    once()  # warm: the cache's entry written or read once, the heap grown
    runs = [once() for _ in range(a.repeat)]
    spent, wall = [c for c, _ in runs], [w for _, w in runs]
    print(
        f"library detect on {len(recs)} recording(s), CPU s: median {statistics.median(spent):.3f} "
        f"(min {min(spent):.3f}, max {max(spent):.3f}, {a.repeat} runs); wall s: median {statistics.median(wall):.3f} "
        f"(min {min(wall):.3f})"
    )


if __name__ == "__main__":
    main()
