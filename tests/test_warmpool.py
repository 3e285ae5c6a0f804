"""The warm pool (expdesign/warmpool.py): started before its work, reused by later maps, with the fork
pool's behaviour on failures (tests/test_forkpool.py): the same results as a fresh pool, a pool never
used ends cleanly (and close() kills a stuck warm-up after its time limit), a worker dying is reported
and never hangs the map, Ctrl-C stops every worker, a failed warm-up is warned about."""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from expdesign.forkpool import fork_map
from expdesign.parallel import LocalEngine
from expdesign.warmpool import NO_WORKER, WarmPool
from tests.procs import deadline

pytestmark = pytest.mark.skipif(
    multiprocessing.get_start_method() != "fork" or not os.path.isdir("/proc/self/fd"), reason="the fork pool, Linux"
)


def _gone(pid: int, within: float = 5.0) -> bool:
    """The process ``pid`` has exited and been reaped (or is a zombie of another parent, state Z)."""
    end = time.monotonic() + within
    while time.monotonic() < end:
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.02)
    return False


def _scaled(i: int, shared: dict) -> tuple[int, int, int]:
    return i, i * shared["k"], os.getpid()


def _map(pool: WarmPool, fn, items, shared=None) -> dict:
    out = {}
    pool.map(fn, items, shared, lambda i, ok, r: out.__setitem__(i, (ok, r)))
    return out


def test_reuse_gives_the_results_of_a_fresh_pool_and_runs_on_the_same_workers():
    fresh = {}
    fork_map(_scaled, list(range(9)), 3, {"k": 7}, lambda i, ok, r: fresh.__setitem__(i, (ok, r[:2])))
    with deadline(30), WarmPool(3) as pool:
        pids = {p.pid for p in pool.procs.values()}
        first = _map(pool, _scaled, list(range(9)), {"k": 7})
        second = _map(pool, _scaled, list(range(9)), {"k": 7})
        other = _map(pool, _scaled, list(range(4)), {"k": -1})  # a new map's shared inputs replace the last's
    for out in (first, second):
        assert {i: (ok, r[:2]) for i, (ok, r) in out.items()} == fresh
        assert {r[2] for _, r in out.values()} <= pids  # no new process: the pool's own workers ran them
    assert other == {i: (True, (i, -i, other[i][1][2])) for i in range(4)}


def test_the_monte_carlo_on_a_warm_pool_gives_the_digests_of_inline():
    from benchmarks.scaling_model import setup
    from expdesign.mc_parallel import evaluate_designs_parallel, start_warm_pool

    p, lib, designs = setup()

    def digests(engine):
        ev = evaluate_designs_parallel(p, designs, runs=24, seed=3, scheduler=engine, primitives=lib, progress=False)
        assert ev.complete and ev.engine["tasks"] > 1
        return {k: r.digest() for k, r in ev.results.items()}

    inline = digests("inline")
    pool = start_warm_pool(p, lib, workers=2)
    with deadline(300), pool:
        assert digests(LocalEngine(pool=pool)) == inline
        assert digests(LocalEngine(pool=pool)) == inline  # reused


def test_a_pool_started_early_and_never_used_exits_cleanly():
    pool = WarmPool(3, warm=lambda: time.sleep(0.3))
    pids = [p.pid for p in pool.procs.values()]
    procs = list(pool.procs.values())
    with deadline(20):
        pool.close()  # during the warm-up: each worker finishes it, reads the stop and exits
    assert [p.exitcode for p in procs] == [0, 0, 0]
    assert all(_gone(pid, 0.1) for pid in pids)
    assert pool.size == 0
    with pytest.raises(RuntimeError, match="no worker left"):
        _map(pool, _scaled, [1, 2], {"k": 1})


def test_a_pool_never_closed_ends_with_its_parent():
    code = (
        "import time\nfrom expdesign.warmpool import WarmPool\n"
        "pool = WarmPool(3, warm=lambda: time.sleep(0.2))\n"
        "print(*[p.pid for p in pool.procs.values()], flush=True)\n"
    )
    env = os.environ | {"PYTHONPATH": os.pathsep.join(sys.path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env, check=True)
    pids = [int(x) for x in out.stdout.split()]
    assert len(pids) == 3 and all(_gone(pid) for pid in pids)
    assert out.stderr == ""


def _slow(i: int) -> int:
    time.sleep(0.4 if i == 0 else 0.05)
    return i


def test_a_worker_dying_mid_task_is_reported_and_the_map_ends():
    with deadline(30), WarmPool(2) as pool:
        pool.wait_ready()
        victim = next(iter(pool.procs.values()))  # the first worker gets task 0, the slow one
        out = {}

        def on_result(i, ok, r):
            out[i] = (ok, r)
            if len(out) == 1:
                os.kill(victim.pid, signal.SIGKILL)

        pool.map(_slow, list(range(6)), None, on_result)
        assert out[0] == (False, "worker lost: exit code -9")
        assert all(out[i] == (True, i) for i in range(1, 6))
        assert pool.size == 1 and _gone(victim.pid, 0.1)
        assert _map(pool, _slow, [1, 2, 3]) == {0: (True, 1), 1: (True, 2), 2: (True, 3)}  # the survivor is reused


def test_a_worker_dead_between_maps_loses_no_task():
    with deadline(30), WarmPool(3) as pool:
        pool.wait_ready()
        victim = next(iter(pool.procs.values()))
        os.kill(victim.pid, signal.SIGKILL)
        victim.join(5)
        assert _map(pool, _slow, list(range(1, 5))) == {i: (True, i + 1) for i in range(4)}
        assert pool.size == 2


def test_every_worker_lost_is_reported_not_hung():
    with deadline(30), WarmPool(2) as pool:
        out = _map(pool, os._exit, [5, 6, 7, 8])
    assert sorted(r for ok, r in out.values() if r.startswith("worker lost")) == [
        "worker lost: exit code 5",
        "worker lost: exit code 6",
    ]
    assert [out[i] for i in (2, 3)] == [(False, "not run: every worker of the pool was lost")] * 2


def test_ctrl_c_during_a_map_stops_every_worker_and_closes_the_pool():
    pool = WarmPool(3)
    pids = [p.pid for p in pool.procs.values()]

    def interrupt(i, ok, r):
        raise KeyboardInterrupt

    with deadline(30), pytest.raises(KeyboardInterrupt):
        pool.map(_slow, list(range(1, 10)), None, interrupt)
    assert pool.size == 0 and all(_gone(pid, 0.1) for pid in pids)


def test_the_engine_reports_ctrl_c_as_an_interrupted_partial_result(monkeypatch):
    with deadline(30), WarmPool(2) as pool:
        eng = LocalEngine(pool=pool)
        assert eng.capacity() == (2, 1)
        calls = []

        def advance(self, i):
            calls.append(i)
            if len(calls) == 2:
                raise KeyboardInterrupt

        monkeypatch.setattr("expdesign.parallel._Progress.advance", advance)
        res = eng.map(_slow, list(range(1, 8)), progress=False)
    assert res.interrupted and 1 <= sum(res.done) <= 2 and pool.size == 0


def _fail_warm() -> None:
    raise ValueError("no cache")


def test_a_failed_warm_up_is_said_and_the_tasks_still_run():
    from expdesign.warmpool import WarmUpFailed

    with deadline(30), WarmPool(2, warm=_fail_warm) as pool:
        with pytest.warns(WarmUpFailed, match="no cache") as said:
            assert set(pool.wait_ready().values()) == {"ValueError: no cache"}
        assert len(said) == 1  # once for the distinct error, not once per worker
        assert pool.warm_up_errors() == ["ValueError: no cache"]
        assert _map(pool, _slow, [1, 2, 3]) == {0: (True, 1), 1: (True, 2), 2: (True, 3)}


def test_close_kills_workers_still_warming_up_after_its_time_limit():
    pool = WarmPool(2, warm=lambda: time.sleep(60))  # a warm-up stuck (or a cold cache's compile)
    procs = list(pool.procs.values())
    t0 = time.monotonic()
    with deadline(30):
        pool.close(timeout=0.5)
    assert time.monotonic() - t0 < 10
    assert all(p.exitcode == -signal.SIGTERM for p in procs) and pool.size == 0


def test_start_warm_pool_loads_the_compiled_passes_in_the_parent_before_forking_on_the_usable_cores(monkeypatch):
    import expdesign.mc_parallel as mcp
    import expdesign.warmpool as wp

    events = []
    monkeypatch.setattr(mcp, "prepare", lambda *a, **k: "sh")
    monkeypatch.setattr(mcp, "warm_compiled", lambda sh: events.append(("parent warm_compiled", os.getpid())))

    class Pool:
        def __init__(self, workers, warm):
            events.append(("fork", workers))

    monkeypatch.setattr(wp, "WarmPool", Pool)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)  # the host's count, in a container limited to 3 CPUs
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2}, raising=False)
    assert isinstance(mcp.start_warm_pool(None, [], "local"), Pool)
    assert events == [("parent warm_compiled", os.getpid()), ("fork", 3)]


def test_a_closed_or_emptied_pool_is_refused_with_one_message_not_replaced_by_a_fresh_one():
    """A LocalEngine on a closed pool once forked a fresh pool without a word; every use now raises."""
    pool = WarmPool(2)
    eng = LocalEngine(pool=pool)
    pool.close()
    uses = [lambda: eng.map(_scaled, [1, 2, 3], progress=False, shared={"k": 1}), eng.capacity, lambda: LocalEngine(pool=pool)]
    with deadline(30), WarmPool(2) as emptied:  # every worker lost while idle: the map's own check
        for p in emptied.procs.values():
            os.kill(p.pid, signal.SIGKILL)
            p.join(5)
        uses.append(lambda: _map(emptied, _scaled, [1, 2], {"k": 1}))
        for use in uses:
            with pytest.raises(RuntimeError) as caught:
                use()
            assert str(caught.value) == NO_WORKER


class _RebuildFails:
    """Pickles in the parent, raises when a worker rebuilds it (as a function the parent defined after the fork)."""

    def __reduce__(self):
        return (_refuse, ())


def _refuse():
    raise ValueError("no such object in the worker")


def test_a_payload_that_does_not_pickle_or_unpickle_raises_one_error_naming_it_and_the_pool_goes_on(capfd):
    """Stop 59: shared inputs that pickled in the parent but not in the workers killed every worker, each
    printing a traceback, and the map reported its tasks as 'worker lost'. Now the map raises one RuntimeError
    naming the part (parent or worker side), no worker dies or prints, and the next map runs on the same workers."""
    import threading

    cases = [
        (lambda i: i, [1, 2], None, "the map's function cannot be pickled"),
        (_scaled, [1, 2], threading.Lock(), "the map's shared inputs cannot be pickled (TypeError"),
        (_scaled, [1, 2, 3, 4, 5], _RebuildFails(), "a worker could not unpickle the map's shared inputs (ValueError: no such"),
        (_scaled, [_RebuildFails()], {"k": 1}, "a worker could not unpickle the map's items (ValueError"),
    ]
    reported: list = []
    with deadline(60), WarmPool(2) as pool:
        pids = {p.pid for p in pool.procs.values()}
        for fn, items, shared, said in cases:
            with pytest.raises(RuntimeError, match=re.escape(said)):
                pool.map(fn, items, shared, lambda *answer: reported.append(answer))
            assert reported == []  # no task ran, none was reported lost
            assert {p.pid for p in pool.procs.values()} == pids and all(p.is_alive() for p in pool.procs.values())
        after = _map(pool, _scaled, list(range(6)), {"k": 3})
    assert {i: (ok, r[:2]) for i, (ok, r) in after.items()} == {i: (True, (i, 3 * i)) for i in range(6)}
    assert "Traceback" not in capfd.readouterr().err
