"""The local pool's two costs that keep the 16-worker prediction of ``bench_design.py --scaling`` under 0.70
(issue 30, stop 56), measured apart:

    python benchmarks/pool_costs.py [--counters] [--reps 3] [--runs 2000] [--terms JSON [--fork-ratios Z C S]]

**Fork stages.** The parent's CPU for one bare ``os.fork`` (its thread's CPU, median of 15, the child
exiting at once) as the process grows, beside its resident and anonymous memory and its mappings (the
kernel copies a page-table entry per anonymous 4 kB page and duplicates every mapping): numpy alone;
the Monte Carlo's imports and one prepared design (what a pre-forked "zygote" holds if it is forked
before the compiled passes load); the compiled passes loaded by one run (the smallest process a worker
can be forked from without loading them itself: their CPU to load is printed); the benchmark's own
parent at pool time (the design optimised, the task-cost fit, freed memory trimmed as ``fork_map``
does); and that parent after ``MADV_COLLAPSE`` of its anonymous regions into 2 MB pages (its CPU printed:
it is paid in the same parent, before the forks).

**Counters** (``--counters``): the 2,000 x 2 Monte Carlo cut as the engines cut it for 2 slots, on a
fork pool of 1, 2 and 4 workers (alternated, ``--reps`` times); every task reports its own user and
system CPU, minor faults and voluntary / involuntary context switches (``getrusage`` in the worker), per
run and per design, a worker's first task of a design apart from its later ones: where the CPU
inflation of the scaling model's 2 and 4 processes goes. CPU depends on the load (printed); fault
counts do not.

**Which term** (``--terms``, no measurement): the scaling model's 16-worker efficiency of the local pool for
2,000 x 2 (:func:`benchmarks.scaling_model.predict`) from one ``--scaling`` run's printed terms, with each term
taken out alone, the fork cost scaled, and (``--fork-ratios``) a fork cost ratio for a zygote Z and for huge
pages C with C's collapse CPU S paid before the forks. JSON keys: ``fixed`` and ``per_run`` (per design, s),
``first`` (the first-task extra at 125 and 250 runs, s), ``fork``, ``child``, ``serial`` (s, 16 workers), ``infl``.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import resource
import statistics
import time

if __package__ in (None, ""):  # run as a script: its sibling modules, as benchmarks/run.py finds them
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

MADV_COLLAPSE = 25  # Linux 6.1+: collapse a range into transparent huge pages now, synchronously
HUGE = 2 << 20


def fork_cpu(n: int = 15) -> float:
    """Median CPU seconds of this thread for one ``os.fork`` (the child exits at once, unflushed)."""
    out = []
    for _ in range(n):
        t = time.thread_time()
        pid = os.fork()
        if pid == 0:
            os._exit(0)
        out.append(time.thread_time() - t)
        os.waitpid(pid, 0)
    return statistics.median(out)


def memory() -> str:
    """Resident and anonymous MB (of which in huge pages) and the number of mappings of this process."""
    with open("/proc/self/smaps_rollup") as f:
        roll = {ln.split()[0]: int(ln.split()[1]) for ln in f if ln.split()[0].endswith(":")}
    with open("/proc/self/maps") as f:
        maps = sum(1 for _ in f)
    return (
        f"rss {roll['Rss:'] / 1024:4.0f} MB, anonymous {roll['Anonymous:'] / 1024:4.0f} MB "
        f"({roll['AnonHugePages:'] / 1024:.0f} in huge pages), {maps:5d} mappings"
    )


def collapse() -> tuple[int, int]:
    """``MADV_COLLAPSE`` on every writable private anonymous region (and the heap) of at least 2 MB:
    (regions collapsed, regions refused)."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.madvise.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    ok = bad = 0
    with open("/proc/self/maps") as f:
        regions = [ln.split() for ln in f]
    for r in regions:
        lo, hi = (int(x, 16) for x in r[0].split("-"))
        lo, hi = (lo + HUGE - 1) & ~(HUGE - 1), hi & ~(HUGE - 1)
        if r[1].startswith("rw") and r[1][3] == "p" and (len(r) < 6 or r[5] == "[heap]") and hi > lo:
            if libc.madvise(lo, hi - lo, MADV_COLLAPSE) == 0:
                ok += 1
            else:
                bad += 1
    return ok, bad


def stage(name: str) -> None:
    print(f"{name:44s} {memory()}: fork {1e3 * fork_cpu():5.2f} ms CPU (load {os.getloadavg()[0]:.1f})", flush=True)


def fork_stages(runs: int) -> None:
    """The fork's CPU at each stage of the module docstring, in one process that grows."""
    import numpy  # noqa: F401 - the stage's content

    stage("numpy imported")
    from expdesign.montecarlo import MCConfig, prepare, run_chunk
    from primitives.heap import release_freed_memory
    from primitives.library import model_ship_thesis
    from primitives.ship import load_profile

    p = load_profile("model-ship")
    sh = prepare(p, {"random": "random"}, MCConfig(runs=100), model_ship_thesis(p))
    stage("imports + one design prepared")
    t = time.process_time()
    run_chunk(sh, "random", [0])
    kernels = time.process_time() - t
    release_freed_memory()
    stage(f"compiled passes loaded ({kernels:.2f} s CPU)")
    from benchmarks.scaling_model import fit_task_cost, setup

    p, lib, designs = setup()
    fit_task_cost(prepare(p, designs, MCConfig(runs=runs), lib), repeat=1)
    release_freed_memory()  # as fork_map does before its forks
    stage("the benchmark's parent at pool time")
    t = time.thread_time()
    ok, bad = collapse()
    stage(f"after MADV_COLLAPSE ({ok} + {bad} refused, {1e3 * (time.thread_time() - t):.0f} ms CPU)")


_TASKS = 0  # tasks this worker has run


def _counted(item: tuple[str, int, int], shared: object) -> dict:
    """One task with its own CPU, faults and context switches (this process's getrusage deltas)."""
    from expdesign.montecarlo import run_chunk

    global _TASKS
    first, _TASKS = _TASKS == 0, _TASKS + 1
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    run_chunk(shared, item[0], range(item[1], item[2]))
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    keys = ("ru_utime", "ru_stime", "ru_minflt", "ru_nvcsw", "ru_nivcsw")
    return {"design": item[0], "first": first, "n": item[2] - item[1]} | {k: getattr(r1, k) - getattr(r0, k) for k in keys}


def counters(runs: int, reps: int) -> None:
    """Per worker count 1 / 2 / 4, per design, first against later tasks of a worker: per-run figures."""
    from benchmarks.scaling_model import setup
    from expdesign.forkpool import fork_map
    from expdesign.mc_parallel import cut_tasks, plan_tasks
    from expdesign.montecarlo import MCConfig, prepare, run_chunk

    p, lib, designs = setup()
    sh = prepare(p, designs, MCConfig(runs=runs), lib)
    run_chunk(sh, "random", range(8))  # the compiled passes loaded before the forks, as warm_compiled does
    tasks = cut_tasks(list(sh.designs), runs, plan_tasks(runs, len(sh.designs), 2))  # one task list for every W
    rows: dict[int, list[dict]] = {1: [], 2: [], 4: []}
    failed: dict[int, list[str]] = {w: [] for w in rows}  # a failed task is said, not averaged away

    def keep(w: int, ok: bool, out) -> None:
        (rows[w].append(out) if ok else failed[w].append(str(out)))

    for _ in range(reps):
        for w in rows:
            fork_map(_counted, tasks, w, sh, lambda i, ok, out, w=w: keep(w, ok, out))
        print(f"  rep done, load {os.getloadavg()[0]:.1f}", flush=True)
    for w, errs in failed.items():
        if errs:
            print(f"W={w}: {len(errs)} of {reps * len(tasks)} tasks FAILED, left out of its figures: {errs[0]}")
    for w, rs in rows.items():
        for d in sh.designs:
            for first in (True, False):
                sel = [r for r in rs if r["design"] == d and r["first"] == first]
                n = sum(r["n"] for r in sel)
                if n:
                    per = {k: sum(r[k] for r in sel) / n for k in sel[0] if k.startswith("ru_")}
                    print(
                        f"W={w} {d:9s} {'first' if first else 'later'} tasks {len(sel):3d}: per run user "
                        f"{1e3 * per['ru_utime']:.3f} ms, system {1e3 * per['ru_stime']:.3f} ms, minor faults "
                        f"{per['ru_minflt']:5.2f}, context switches voluntary {per['ru_nvcsw']:.3f} involuntary {per['ru_nivcsw']:.3f}"
                    )


TERM_KEYS = {"fixed": dict, "per_run": dict, "first": list, "fork": float, "child": float, "serial": float, "infl": float}


def parse_terms(text: str) -> dict:
    """The ``--terms`` JSON (module docstring), checked: ValueError naming the bad key and what it needs."""
    try:
        t = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"not JSON ({e.msg} at character {e.pos}); give the keys {', '.join(TERM_KEYS)}") from None
    if not isinstance(t, dict):
        raise ValueError(f"a JSON object with the keys {', '.join(TERM_KEYS)} is needed")
    for key, kind in TERM_KEYS.items():
        v = t.get(key)
        if kind is float and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ValueError(f"key {key!r} must be a number (seconds; infl a ratio), got {v!r}")
        if kind is dict and not (isinstance(v, dict) and set(v) == {"optimized", "random"}):
            raise ValueError(f"key {key!r} must map 'optimized' and 'random' to seconds, got {v!r}")
        if kind is list and not (isinstance(v, list) and len(v) == 2):
            raise ValueError(f"key {key!r} must be [extra at 125 runs, extra at 250 runs] in seconds, got {v!r}")
    return t


def which_term(t: dict, ratios: list[float] | None = None) -> None:
    """The 16-worker prediction with each term of ``t`` (module docstring) taken out alone, and the designs' ratios."""
    import numpy as np

    from benchmarks.scaling_model import TaskCost, predict

    names = ["optimized", "random"]

    def eff(
        fork: float = 1.0,
        child: float = 1.0,
        serial: float | None = 0.0,
        infl: bool = True,
        first: float = 1.0,
        fixed: float = 1.0,
        tpw: int | None = None,
    ) -> float:
        cost = TaskCost({d: v * fixed for d, v in t["fixed"].items()}, t["per_run"])
        extra = lambda n: float(np.interp(n, (125, 250), t["first"]))  # noqa: E731 - as first_extra_curve
        inline = predict(cost, names, 2000, 1, 0.0, first_extra=extra)["wall"]
        starts = [(k + 1) * t["fork"] * fork + t["child"] * child for k in range(16)]
        s = 0.0 if serial is None else t["serial"] + serial  # None: without the serial rest
        pr = predict(
            cost,
            names,
            2000,
            16,
            s,
            tasks_per_worker=tpw,
            first_extra=lambda n: extra(n) * first,
            inflation=t["infl"] if infl else 1.0,
            starts=starts,
        )
        return inline / pr["wall"] / 16

    print(f"terms: {json.dumps(t, sort_keys=True)}")
    print(f"16 workers, all terms: {eff():.3f}")
    for name, kw in (
        ("the forks' delay", {"fork": 0.0}),
        ("a worker's start and exit", {"child": 0.0}),
        ("the serial rest", {"serial": None}),
        ("the CPU inflation", {"infl": False}),
        ("the first-task extra", {"first": 0.0}),
        ("the tasks' fixed cost", {"fixed": 0.0}),
    ):
        print(f"  without {name:26s}: {eff(**kw):.3f}")
    print("  fork cost x0.5 / x0.25 / x0.1: " + " / ".join(f"{eff(fork=f):.3f}" for f in (0.5, 0.25, 0.1)))
    print("  1 / 2 / 4 tasks per worker: " + " / ".join(f"{eff(tpw=k):.3f}" for k in (1, 2, 4)))
    if ratios:
        z, c, cs = ratios
        print(
            f"  zygote (fork x{z:.2f}): {eff(fork=z):.3f}; huge pages (fork x{c:.2f}, +{1e3 * cs:.0f} ms serial): {eff(fork=c, serial=cs):.3f}; both, the collapse paid elsewhere: {eff(fork=z * c):.3f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counters", action="store_true", help="per-task CPU, faults, context switches at 1/2/4 workers")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--runs", type=int, default=2000)
    ap.add_argument("--terms", help="which term: a JSON of one --scaling run's terms (module docstring)")
    ap.add_argument("--fork-ratios", type=float, nargs=3, metavar=("ZYGOTE", "COLLAPSE", "COLLAPSE_CPU_S"))
    a = ap.parse_args()
    if a.fork_ratios and not a.terms:
        ap.error("--fork-ratios scales the terms of --terms JSON: give --terms too")
    if a.terms:
        try:
            which_term(parse_terms(a.terms), a.fork_ratios)
        except ValueError as e:
            ap.error(f"--terms: {e}")
        return
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    if a.counters:
        counters(a.runs, a.reps)
    else:
        fork_stages(a.runs)


if __name__ == "__main__":
    main()
