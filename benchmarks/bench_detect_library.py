"""CPU of the library's ``detect`` on recordings in a warm process (stop 51): ``detect_all`` as ``shiptrial detect``
calls it (the noise cache on, freed memory kept, the hull given), one warm-up call that also writes the cache's
entry, then the median of ``--repeat`` ``time.process_time`` figures (and of the wall clock's). No interpreter start-up,
imports, option parsing or printing: what is left of the command's CPU once those are paid (``bench_detect_stages.py`` for them).

    cd RECORDINGS && PYTHONPATH=REPO SHIPTRIAL_DETECT_CACHE_DIR=DIR nice -n 10 python REPO/benchmarks/bench_detect_library.py \\
        prior.json run.csv [more.csv ...] [--repeat 7] [--threads]

PYTHONPATH names the tree timed; alternate two trees' runs (each its own cache directory) to compare them. With
``--threads`` each call alternates ``OMP_NUM_THREADS`` 1 and 2 (stop 52: the noise's share beside the ships'
simulation, :func:`identify.detect.nullsim.null_records`): its wall saving needs a free second core.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from identify.detect import noisecache
from identify.detect.api import hull_inertia, load_prior, load_runs
from identify.detect.batch import detect_all
from primitives.heap import DETECT_KEEP_BYTES, keep_freed_memory
from primitives.threads import SETTING as THREADS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("prior", type=Path)
    ap.add_argument("recordings", type=Path, nargs="+")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--profile", default="naval-vessel", help="the hull's I_z and N_rdot, as detect's --profile")
    ap.add_argument(
        "--threads",
        action="store_true",
        help="alternate OMP_NUM_THREADS=1 and 2: the no-change records' two jobs one after the other or at once",
    )
    a = ap.parse_args()
    keep_freed_memory(always=True, keep_bytes=DETECT_KEEP_BYTES)  # as the command's own process does
    prior = load_prior(a.prior)
    recs = load_runs(a.recordings, prior.kind, [])
    i_z, n_rdot = hull_inertia(a.profile, None, None)

    def once(threads: str | None = None) -> tuple[float, float]:
        if threads is not None:  # primitives.threads.count reads it per call: the no-change records' two jobs at once or not
            os.environ[THREADS] = threads
        t, w = time.process_time(), time.perf_counter()
        with noisecache.used():
            detect_all(recs, prior, n_rdot=n_rdot, i_z=i_z)
        return time.process_time() - t, time.perf_counter() - w

    once()  # warm: the cache's entry written or read once, the heap grown
    counts = ["1", "2"] if a.threads else [None]
    runs = {k: [] for k in counts}
    for _ in range(a.repeat):
        for k in counts:  # alternated: the machine's load drifts alike over both
            runs[k].append(once(k))
    for k, rs in runs.items():
        spent, wall = [c for c, _ in rs], [w for _, w in rs]
        print(
            f"library detect on {len(recs)} recording(s){'' if k is None else f', {THREADS}={k}'}, CPU s: median "
            f"{statistics.median(spent):.3f} (min {min(spent):.3f}, max {max(spent):.3f}, {a.repeat} runs); wall s: median "
            f"{statistics.median(wall):.3f} (min {min(wall):.3f})"
        )


if __name__ == "__main__":
    main()
