"""The Dask side of ``python benchmarks/bench_design.py --scaling --dask-local 2 4``: the Monte Carlo
on a local Dask cluster of single-thread worker processes, timed and costed as the local pool is.

- ``dask_runs``: per worker count one ``distributed.LocalCluster`` (``processes=True``, one thread per
  worker, the scheduler in this process), the Monte Carlo ``repeat`` times on it. The first run on
  new workers (imports, numba's load and its compiled passes) is printed apart from the median of the
  others (a cluster that outlives one command, or one started with ``--preload expdesign.dask_preload``,
  runs warm). CPU: this process (client and scheduler) plus every worker's ``time.process_time``
  read before and after by ``Client.run`` (the nannies' own CPU is left out).
- ``idle_rates``: the CPU a second of wall the idle cluster burns (heartbeats, event loops, the
  scheduler's periodic work), in this process and per worker, measured after the runs on each
  cluster: under load a run's wall is many times its CPU, and this part grows with the wall.
- ``dask_overhead``: what Dask adds per task and per run, with no-op tasks: the shared inputs
  scattered to every worker, W and 5 W no-op tasks, results gathered; the idle cluster's
  housekeeping over each map's wall taken out (under load a no-op map's wall is long). The parent's CPU (client and
  scheduler: serial) plus one worker's share, fitted as ``a + b W`` over the measured W so that
  16 workers can be read off, and the CPU per task on top of the task's own work.
"""

from __future__ import annotations

import os
import statistics
import time
from typing import Any

import numpy as np


def _noop(item: int, shared: Any) -> int:
    return item


def _preload_cpu() -> float | None:
    from expdesign import dask_preload

    return dask_preload.WARM_CPU


def _worker_cpu(client: Any) -> float:
    return float(sum(client.run(time.process_time).values()))


IDLE_S = 5.0  # seconds the idle cluster is watched


def idle_rates(client: Any, w: int, seconds: float = IDLE_S) -> tuple[float, float]:
    """CPU seconds per wall second of the idle cluster: (this process: client and scheduler, one worker)."""
    c, k, t = time.process_time(), _worker_cpu(client), time.perf_counter()
    time.sleep(seconds)
    wall = time.perf_counter() - t
    return (time.process_time() - c) / wall, (_worker_cpu(client) - k) / wall / w


def local_cluster(w: int, preload: bool = True) -> Any:
    """A LocalCluster of ``w`` single-thread worker processes (the scheduler in this process), each
    started with ``expdesign.dask_preload`` unless ``preload`` is False."""
    import distributed

    kw = {"preload": ["expdesign.dask_preload"]} if preload else {}
    return distributed.LocalCluster(
        n_workers=w, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40, **kw
    )


def dask_runs(run, workers: list[int], repeat: int, preload: bool = True) -> list[dict]:
    """``run(scheduler)`` -> (evaluation, digests) on a new local cluster per worker count. Rows as the
    pools': label, slots, median wall and CPU of the runs after the first, and the first's; the idle
    cluster's CPU a second (:func:`idle_rates`); ``preload_cpu``, a worker's preload (median, 0 without
    one: paid as the worker starts, before it serves, so in no run's CPU here)."""
    from distributed import Client

    rows = []
    for w in workers:
        with local_cluster(w, preload) as cluster, Client(cluster, set_as_default=False) as client:
            client.wait_for_workers(w, timeout=120)
            warm = [c for c in client.run(_preload_cpu).values() if c is not None]
            walls, cpus = [], []
            for _ in range(repeat + 1):
                c0, k0 = time.process_time(), _worker_cpu(client)
                ev, dig = run(client)
                cpus.append(time.process_time() - c0 + _worker_cpu(client) - k0)
                walls.append(ev.elapsed_s)
            idle = idle_rates(client, w)
        rows.append(
            {
                "label": f"dask x{w}{'' if preload else ' (no preload)'}",
                "slots": w,
                "wall": statistics.median(walls[1:]),
                "cpu": statistics.median(cpus[1:]),
                "first_wall": walls[0],
                "first_cpu": cpus[0],
                "preload_cpu": statistics.median(warm) if warm else 0.0,
                "idle_parent": idle[0],
                "idle_worker": idle[1],
                "engine": ev.engine,
                "digests": dig,
            }
        )
    return rows


def dask_overhead(sh: Any, workers: list[int], repeat: int = 3) -> dict[str, float]:
    """Dask's own cost with no-op tasks on warm clusters of each W in ``workers``: ``serial`` (a, b) of
    a + b W seconds (the parent's CPU, client and scheduler, plus one worker's share: the scatter of
    the shared inputs and the round trips) and ``per_task`` CPU seconds (parent and workers) per task;
    ``first_extra``, a preloaded worker's first task of MAX_CHUNK runs over its second (CPU seconds,
    median over every worker of the new clusters, clipped at 0; ``first_raw`` each), the first
    thing each cluster runs."""
    from distributed import Client

    from benchmarks.scaling_model import first_extras
    from expdesign.montecarlo import MAX_CHUNK
    from expdesign.parallel import DaskEngine

    serial, per_task, first = {}, [], []
    for w in workers:
        with local_cluster(w) as cluster, Client(cluster, set_as_default=False) as client:
            client.wait_for_workers(w, timeout=120)
            eng = DaskEngine(client)
            first += first_extras(eng, sh, MAX_CHUNK, w)  # the workers' first tasks, right after the preload
            eng.map(_noop, list(range(w)), progress=False, shared=sh)  # connections and imports, not timed
            rate_parent, rate_worker = idle_rates(client, w)
            rows = []
            for _ in range(repeat):
                for n in (w, 5 * w):
                    c0, k0, t0 = time.process_time(), _worker_cpu(client), time.perf_counter()
                    eng.map(_noop, list(range(n)), progress=False, shared=sh)
                    wall = time.perf_counter() - t0  # housekeeping over the map's wall taken out (idle_rates)
                    rows.append(
                        (n, time.process_time() - c0 - rate_parent * wall, _worker_cpu(client) - k0 - w * rate_worker * wall)
                    )
        small = [(p + k / w) for n, p, k in rows if n == w]
        big = [(p + k) for n, p, k in rows if n == 5 * w]
        whole = [(p + k) for n, p, k in rows if n == w]
        serial[w] = statistics.median(small)
        per_task.append((statistics.median(big) - statistics.median(whole)) / (4 * w))
    ws = np.array(sorted(serial), float)
    if len(ws) > 1:
        b, a = np.polyfit(ws, [serial[int(x)] for x in ws], 1)
    else:
        a, b = serial[int(ws[0])], 0.0
    return {
        "a": max(0.0, float(a)),
        "b": max(0.0, float(b)),
        "per_task": max(0.0, statistics.median(per_task)),
        "measured": serial,
        "first_extra": max(0.0, statistics.median(first)) if first else None,
        "first_raw": first,
    }


def print_overhead(ov: dict) -> None:
    print(
        "Dask's own cost (no-op tasks, warm workers): serial part "
        + ", ".join(f"{w}: {1e3 * s:.0f} ms" for w, s in sorted(ov["measured"].items()))
        + f" -> {1e3 * ov['a']:.0f} + {1e3 * ov['b']:.1f} W ms; {1e3 * ov['per_task']:.1f} ms CPU per task; "
        "a Dask worker's first task (MAX_CHUNK runs, right after the preload) over its second: "
        + ", ".join(f"{1e3 * e:.0f}" for e in ov["first_raw"])
        + f" ms (load average {os.getloadavg()[0]:.1f})"
    )
