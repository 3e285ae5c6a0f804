"""Where independent work runs: in this process and its cores, or on a Dask cluster.

Monte Carlo chunks, sweep cells and primitive simulations are independent tasks whose
randomness comes only from seeds derived from (root seed, task index) with
``numpy.random.SeedSequence``. So a task computes the same numbers wherever it runs, and the
results are reassembled in task order: local and cluster runs agree exactly.

Select the engine with ``scheduler``: None or "local" (default; a process pool over all cores,
no server), "inline" (this process, one task at a time), or a Dask scheduler address such as
"tcp://10.0.0.5:8786" (also read from the environment variable SHIPTRIAL_SCHEDULER).
Ctrl-C stops cleanly: tasks not finished are cancelled and the finished results are kept.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any

import numpy as np

ENV_SCHEDULER = "SHIPTRIAL_SCHEDULER"


@dataclass
class MapResult:
    """Results in task order; ``None`` where a task did not finish (interrupted or failed)."""

    results: list[Any]
    done: list[bool]
    interrupted: bool = False
    errors: dict[int, str] = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return all(self.done)

    def finished(self) -> list[Any]:
        return [r for r, d in zip(self.results, self.done) if d]


def task_seeds(seed: int, n: int) -> list[int]:
    """One independent 63-bit seed per task from the root seed (same on every engine)."""
    return [int(s.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1)) for s in np.random.SeedSequence(seed).spawn(n)]


class _Progress:
    """A rich progress bar on stderr when it is a terminal; silent otherwise."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        if enabled and total > 1:
            import sys

            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            if sys.stderr.isatty():
                from rich.console import Console

                self.bar = Progress(
                    TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                    console=Console(stderr=True), transient=True,
                )
                self.bar.start()
                self.task = self.bar.add_task(desc, total=total)

    def advance(self) -> None:
        if self.bar is not None:
            self.bar.advance(self.task)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


class Engine:
    """Runs ``fn(item)`` for every item and returns a :class:`MapResult` in item order."""

    name = "inline"

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any], desc: str = "working", progress: bool = True) -> MapResult:
        res, done = [None] * len(items), [False] * len(items)
        bar = _Progress(len(items), desc, progress)
        try:
            for i, it in enumerate(items):
                res[i] = fn(it)
                done[i] = True
                bar.advance()
        except KeyboardInterrupt:
            return MapResult(res, done, interrupted=True)
        finally:
            bar.close()
        return MapResult(res, done)

    def close(self) -> None:
        pass

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class LocalEngine(Engine):
    """A process pool over the machine's cores (no server to start)."""

    name = "local"

    def __init__(self, workers: int | None = None):
        self.workers = workers or os.cpu_count() or 1

    def map(self, fn, items, desc="working", progress=True) -> MapResult:
        if self.workers <= 1 or len(items) <= 1:
            return super().map(fn, items, desc, progress)
        res, done = [None] * len(items), [False] * len(items)
        bar = _Progress(len(items), desc, progress)
        pool = ProcessPoolExecutor(max_workers=min(self.workers, len(items)))
        futures = {pool.submit(fn, it): i for i, it in enumerate(items)}
        pending = set(futures)
        try:
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    i = futures[f]
                    res[i] = f.result()
                    done[i] = True
                    bar.advance()
        except KeyboardInterrupt:
            for f in pending:
                f.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            bar.close()
            return MapResult(res, done, interrupted=True)
        bar.close()
        pool.shutdown()
        return MapResult(res, done)


class DaskEngine(Engine):
    """Tasks on a Dask distributed cluster (an address, or a Client / LocalCluster object)."""

    name = "dask"

    def __init__(self, address_or_cluster: Any):
        try:
            from distributed import Client
        except ImportError:  # pragma: no cover - depends on the environment
            raise RuntimeError("a Dask scheduler was given but the 'distributed' package is not installed: pip install 'shiptrial[dask]'") from None
        if isinstance(address_or_cluster, Client):
            self.client, self._own = address_or_cluster, False
        else:
            self.client, self._own = Client(address_or_cluster, set_as_default=False), True

    def map(self, fn, items, desc="working", progress=True) -> MapResult:
        from distributed import as_completed

        res, done = [None] * len(items), [False] * len(items)
        futures = self.client.map(fn, list(items), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        bar = _Progress(len(items), f"{desc} (dask)", progress)
        try:
            for f in as_completed(futures, loop=self.client.loop):
                i = index[f.key]
                res[i] = f.result()
                done[i] = True
                bar.advance()
        except KeyboardInterrupt:
            self.client.cancel([f for f in futures if not f.done()])
            bar.close()
            return MapResult(res, done, interrupted=True)
        bar.close()
        return MapResult(res, done)

    def close(self) -> None:
        if self._own:
            self.client.close()


def get_engine(scheduler: Any = None, workers: int | None = None) -> Engine:
    """The engine for ``scheduler`` (see the module docstring); SHIPTRIAL_SCHEDULER is the default."""
    if scheduler is None:
        scheduler = os.environ.get(ENV_SCHEDULER) or "local"
    if isinstance(scheduler, Engine):
        return scheduler
    if scheduler == "inline":
        return Engine()
    if scheduler == "local":
        return LocalEngine(workers)
    return DaskEngine(scheduler)
