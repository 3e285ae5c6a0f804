"""The warm pool's terms in the model of ``python benchmarks/bench_design.py --scaling`` (issue 30,
:mod:`benchmarks.scaling_model`): a :class:`expdesign.warmpool.WarmPool` started and warmed before the
Monte Carlo, so its forks and its workers' warm-up are not on the Monte Carlo's path. What is:

- ``send``: the parent's CPU per worker in a map of no-op tasks (the map's function, items and shared
  inputs pickled once, then written to each worker; collecting): worker k gets its first task after
  k + 1 of them;
- ``child``: a worker's CPU in that map (reading and unpickling the shared inputs), in parallel;
- the first-task extra of a worker warmed as a command warms it (:func:`expdesign.mc_parallel.warm_worker`), measured as
  :func:`benchmarks.scaling_model.first_extras` on warm workers;
- off the path, said apart: the pool's start (the parent's CPU per fork, the workers' warm-up CPU)
  and its close.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable, Iterable

import numpy as np

from benchmarks.scaling_model import EXTRA_SIZES, _noop, first_extras
from expdesign.montecarlo import MCShared

_TICK = os.sysconf("SC_CLK_TCK")


def procs_cpu_s(pids: Iterable[int]) -> float:
    """User + system CPU seconds of the running processes ``pids`` (/proc, 1 / CLK_TCK resolution)."""
    total = 0
    for pid in pids:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of proc(5))
    return total / _TICK


def _warm(sh: MCShared) -> Callable[[], None]:
    from expdesign.mc_parallel import warm_worker

    return lambda: warm_worker(sh)  # as a command's pool (expdesign.mc_parallel.start_warm_pool)


def warm_pool_overhead(sh: MCShared, w: int, repeat: int = 3) -> dict[str, float]:
    """Medians of ``repeat`` pools of ``w`` workers, each started, ready (without the Monte Carlo's
    warm-up, which does not change these terms and is measured by :func:`warm_first_extra_curve`)
    and then given one no-op map of ``w`` tasks: seconds of ``send`` and ``child`` (module
    docstring), the map's ``wall``, and off the map's path ``fork`` (the parent's CPU per fork),
    ``warm`` (a worker's CPU to ready) and ``close`` (the parent's wall to stop and join them)."""
    from expdesign.warmpool import WarmPool

    runs = []
    for _ in range(repeat):
        c = time.process_time()
        pool = WarmPool(w)
        fork = (time.process_time() - c) / w
        pool.wait_ready()
        pids = [p.pid for p in pool.procs.values()]
        k0 = procs_cpu_s(pids)
        t, c = time.perf_counter(), time.process_time()
        pool.map(_noop, list(range(w)), sh, lambda *_: None)
        parent, wall = time.process_time() - c, time.perf_counter() - t
        kids = procs_cpu_s(pids) - k0
        t = time.perf_counter()
        pool.close()
        runs.append(
            {
                "send": parent / w,
                "child": kids / w,
                "wall": wall,
                "fork": fork,
                "warm": k0 / w,
                "close": time.perf_counter() - t,
            }
        )
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def warm_starts(ov: dict[str, float], w: int) -> list[float]:
    """When each of ``w`` warm workers can start its first task (:func:`warm_pool_overhead`)."""
    return [(k + 1) * ov["send"] + ov["child"] for k in range(w)]


def warm_first_extra_curve(sh: MCShared, sizes: tuple[int, ...] = EXTRA_SIZES, repeat: int = 2) -> Callable[[int], float]:
    """A warm worker's first-task extra CPU seconds by the task's runs, as
    :func:`benchmarks.scaling_model.first_extra_curve` for fresh workers: measured at ``sizes`` on warm
    pools of 2 workers (each warmed as a command's), linear between them and held beyond."""
    from expdesign.parallel import LocalEngine
    from expdesign.warmpool import WarmPool

    extra, warm = [], []
    for n in sizes:
        got = []
        for _ in range(repeat):
            with WarmPool(2, _warm(sh)) as pool:
                pool.wait_ready()
                warm.append(procs_cpu_s(q.pid for q in pool.procs.values()) / 2)
                got += first_extras(LocalEngine(pool=pool), sh, n, 2)
        extra.append(max(0.0, statistics.median(got)))
    print(
        "a warm worker's first task (passes loaded, heap grown) over its second: "
        + ", ".join(f"{1e3 * e:.0f} ms at {n} runs" for n, e in zip(sizes, extra))
        + f"; the warm-up (off the path) {statistics.median(warm):.2f} s CPU a worker"
    )
    return lambda n: float(np.interp(n, sizes, extra))


def print_warm_terms(pools: dict[int, dict[str, float]]) -> None:
    """The warm pool's terms per worker count, on the Monte Carlo's path and off it."""
    print(
        "warm pool (started and warmed before the Monte Carlo; no-op tasks): on the path, the parent's CPU per worker "
        "(pickle once, send, collect) + a worker's CPU (unpickle) [map wall]: "
        + ", ".join(f"{w}: {1e3 * v['send']:.1f} + {1e3 * v['child']:.1f} ms [{1e3 * v['wall']:.0f}]" for w, v in pools.items())
        + "; the last worker starts its first task "
        + ", ".join(f"{w}: {1e3 * warm_starts(v, w)[-1]:.0f} ms" for w, v in pools.items())
        + " after the map does; off the path (earlier, while the command does other work): the parent's CPU per fork, "
        "a worker's CPU to ready (without the warm-up), the close's wall: "
        + ", ".join(f"{w}: {1e3 * v['fork']:.1f} ms, {v['warm']:.2f} s, {1e3 * v['close']:.0f} ms" for w, v in pools.items())
    )
