"""Page faults and CPU of consecutive Monte Carlo batches in forked processes, glibc's default
malloc trimming against freed memory kept (:func:`primitives.heap.keep_freed_memory`):

    python benchmarks/heap_faults.py [--runs 125] [--batches 3] [--repeat 3]

The parent prepares the model ship's random design, runs one batch (warm, as the benchmark's
parent is after its inline runs) and then forks, alternately, a child with glibc's defaults and a
child that keeps freed memory; each runs ``--batches`` batches of ``--runs`` runs and reports the
minor page faults and CPU milliseconds of each. Fault counts do not depend on the machine's load;
CPU does (the load average is printed).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import time

if __package__ in (None, ""):  # run as a script: its sibling modules, as benchmarks/run.py finds them
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def batch(sh: object, i: int, n: int) -> tuple[float, int]:
    """CPU milliseconds and minor page faults of batch ``i`` of ``n`` runs."""
    from expdesign.montecarlo import run_chunk

    r, t = resource.getrusage(resource.RUSAGE_SELF).ru_minflt, time.process_time()
    run_chunk(sh, "random", range(i * n, (i + 1) * n))
    return 1e3 * (time.process_time() - t), resource.getrusage(resource.RUSAGE_SELF).ru_minflt - r


def child(sh: object, keep: bool, first: int, n: int, batches: int) -> list[tuple[float, int]]:
    """In a forked child: batches one after the other, with freed memory kept or glibc's defaults."""
    from primitives.heap import keep_freed_memory

    if keep:
        keep_freed_memory(always=True)
    return [batch(sh, first + k, n) for k in range(batches)]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=125)
    ap.add_argument("--batches", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    import platform

    if platform.libc_ver()[0] != "glibc" or "MALLOC_TRIM_THRESHOLD_" in os.environ:  # before any fork: a child cannot say it
        raise SystemExit("heap_faults: needs glibc and no MALLOC_TRIM_THRESHOLD_ (freed memory could not be kept)")
    from expdesign.montecarlo import MCConfig, prepare, warm_compiled
    from primitives.library import model_ship_thesis
    from primitives.ship import load_profile

    p = load_profile("model-ship")
    n_total = (1 + 2 * a.repeat * a.batches) * a.runs
    sh = prepare(p, {"random": "random"}, MCConfig(runs=n_total), model_ship_thesis(p))
    warm_compiled(sh)
    batch(sh, 0, a.runs)
    out: dict[bool, list[list[tuple[float, int]]]] = {False: [], True: []}
    for r in range(a.repeat):
        for keep in (False, True):
            rfd, wfd = os.pipe()
            pid = os.fork()
            if pid == 0:
                os.close(rfd)
                first = 1 + (2 * r + keep) * a.batches
                os.write(wfd, json.dumps(child(sh, keep, first, a.runs, a.batches)).encode())
                os._exit(0)
            os.close(wfd)
            with os.fdopen(rfd) as f:
                out[keep].append(json.load(f))
            os.waitpid(pid, 0)
    print(f"batches of {a.runs} runs (random design, model ship) in forked children, load average {os.getloadavg()[0]:.1f}")
    for keep in (False, True):
        rows = out[keep]
        print(f"  {'freed memory kept' if keep else 'glibc defaults':18s}", end="")
        for k in range(a.batches):
            cpu = statistics.median(r[k][0] for r in rows)
            faults = statistics.median(r[k][1] for r in rows)
            print(f"  batch {k + 1}: {faults:6.0f} faults {cpu:6.1f} ms CPU", end="")
        print(f"   (medians of {a.repeat}; each: {rows})")


if __name__ == "__main__":
    main()
