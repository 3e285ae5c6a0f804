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
