"""CPU by stage without a profiler, for the benchmarks: library functions wrapped in place so that each
adds the CPU seconds spent in it to a label (``bench_mc_inline.py --stages``, ``bench_detect_stages.py``)."""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Iterable, MutableMapping

_LOCK = threading.Lock()


def time_stages(
    stages: Iterable[tuple[object, str, str]],
    cpu: MutableMapping[str, float],
    clock: Callable[[], float] = time.thread_time,
) -> None:
    """Replace each ``module.name`` of ``stages`` (module, function name, label) by a wrapper adding the CPU
    seconds ``clock`` counts while it runs to ``cpu[label]``. ``thread_time`` (the default) counts the calling
    thread's alone, so threads running one stage at once each add their own; ``process_time`` counts the
    process's BLAS threads too. Nested stages count in both."""
    for module, name, label in stages:
        fn = getattr(module, name)

        @functools.wraps(fn)
        def timed(*a, _fn=fn, _label=label, **k):
            t = clock()
            try:
                return _fn(*a, **k)
            finally:
                with _LOCK:  # two threads' += on one label would lose one of them
                    cpu[_label] = cpu.get(_label, 0.0) + clock() - t

        setattr(module, name, timed)


def run_command_quietly(main: Callable[[], object], argv: list[str]) -> float:
    """Run a CLI entry point ``main`` on ``argv`` (``sys.argv[1:]``'s form) with its stdout discarded (the
    command's report is not the figure); the process CPU seconds when it ends."""
    import os
    import sys

    sys.argv = ["shiptrial", *argv]
    saved = sys.stdout
    sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - closed below
    try:
        main()
    except SystemExit:
        pass
    finally:
        sys.stdout.close()
        sys.stdout = saved
    return time.process_time()


def print_stages(imports: str, cpu: MutableMapping[str, float]) -> None:
    """The import line, then each stage's CPU seconds."""
    print(f"CPU s: {imports}")
    for k, v in cpu.items():
        print(f"  {k}: {v:.3f}")
