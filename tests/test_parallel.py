"""Engines: the same seed gives the same numbers inline, on local cores and on a Dask cluster."""

import multiprocessing
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from expdesign.parallel import DaskEngine, Engine, LocalEngine, get_engine, task_seeds


def _noisy_sim(seed: int) -> np.ndarray:
    from primitives.ship import load_profile
    from primitives.simulate import Disturbances, simulate

    prof = load_profile("model-ship")
    res = simulate(
        prof, np.tile([3000.0, 200.0, 100.0], (80, 1)), disturbances=Disturbances.from_profile(prof), batch=4, seed=seed
    )
    return res.y[:, -1]


def _blas_threads(_item) -> int:
    from threadpoolctl import threadpool_info

    return max((lib["num_threads"] for lib in threadpool_info()), default=1)


def _own_threads(_item) -> int:
    from primitives.threads import count

    return count()


def test_workers_run_one_blas_thread(monkeypatch):
    """A pool worker limits BLAS/OpenMP to one thread (the parent may use several): W workers on W
    cores, each with the library's own threads on top, would burn CPU competing for the cores."""
    pytest.importorskip("threadpoolctl")
    from threadpoolctl import threadpool_limits

    with threadpool_limits(2):  # what an unlimited library does on a machine with >= 2 cores
        assert _blas_threads(None) == 2
        res = LocalEngine(2).map(_blas_threads, [0, 1, 2], progress=False)
    assert res.complete and res.results == [1, 1, 1]
    # nor threads of the project's own (primitives.threads: the inline Monte Carlo's chunks)
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    assert _own_threads(None) == 2
    own = LocalEngine(2).map(_own_threads, [0, 1, 2], progress=False)
    assert own.complete and own.results == [1, 1, 1]


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork", reason="workers inherit the limit only when forked")
def test_forked_workers_inherit_one_blas_thread_from_the_parent(monkeypatch):
    """Forked workers find one BLAS thread already set (the parent holds its libraries at one thread
    while it forks, then restores them) instead of each finding and limiting the libraries itself,
    about 25 ms of CPU per worker before its first task: a worker that still calls threadpool_limits
    fails here (the parent's patched function is what a forked worker sees)."""
    threadpoolctl = pytest.importorskip("threadpoolctl")

    def refuse(*_a, **_k):
        raise AssertionError("a forked worker limited its BLAS threads itself")

    with threadpoolctl.threadpool_limits(2):
        monkeypatch.setattr(threadpoolctl, "threadpool_limits", refuse)
        res = LocalEngine(2).map(_blas_threads, [0, 1, 2], progress=False)
        monkeypatch.undo()
        assert _blas_threads(None) == 2  # the parent's own setting is back
    assert res.complete and res.results == [1, 1, 1], res.errors


def test_task_seeds_are_stable_and_distinct():
    a, b = task_seeds(7, 5), task_seeds(7, 5)
    assert a == b and len(set(a)) == 5
    assert task_seeds(8, 5) != a


def test_inline_and_local_pool_agree():
    seeds = task_seeds(3, 4)
    r1 = Engine().map(_noisy_sim, seeds, progress=False)
    r2 = LocalEngine(2).map(_noisy_sim, seeds, progress=False)
    assert r1.complete and r2.complete
    for x, y in zip(r1.results, r2.results):
        np.testing.assert_array_equal(x, y)


def test_dask_local_cluster_agrees_with_local():
    distributed = pytest.importorskip("distributed")
    seeds = task_seeds(3, 4)
    local = Engine().map(_noisy_sim, seeds, progress=False)
    import dask

    # Dask's nanny sets one thread in the workers' environment by default: give them two, so that the
    # one thread per worker is the engine's doing
    two = {"OMP_NUM_THREADS": 2, "OPENBLAS_NUM_THREADS": 2, "MKL_NUM_THREADS": 2}
    with (
        dask.config.set({"distributed.nanny.pre-spawn-environ": two}),
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
    ):
        with get_engine(cluster.scheduler_address) as eng:
            assert isinstance(eng, DaskEngine)
            remote = eng.map(_noisy_sim, seeds, progress=False)
            threads = eng.map(_blas_threads, [0, 1], progress=False)
            own = eng.map(_own_threads, [0, 1], progress=False)
    assert remote.complete
    assert threads.results == [1, 1]  # Dask workers too run one BLAS thread each
    assert own.results == [1, 1]  # and start no threads of the project's own (primitives.threads)
    for x, y in zip(local.results, remote.results):
        np.testing.assert_array_equal(x, y)


def test_interrupt_keeps_finished_results():
    calls = []

    def task(i):
        if i == 2:
            raise KeyboardInterrupt
        calls.append(i)
        return i * 10

    res = Engine().map(task, [0, 1, 2, 3], progress=False)
    assert res.interrupted and res.finished() == [0, 10] and res.done == [True, True, False, False]


def test_scheduler_from_environment(monkeypatch):
    monkeypatch.setenv("SHIPTRIAL_SCHEDULER", "inline")
    assert type(get_engine()) is Engine
    monkeypatch.delenv("SHIPTRIAL_SCHEDULER")
    assert isinstance(get_engine(), LocalEngine)


def test_sweep_table_same_inline_and_on_local_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    from expdesign.sweep import load_sweep, run_sweep, write_table

    cfg = tmp_path / "sweep.toml"
    cfg.write_text(
        '[sweep]\nships = ["model-ship"]\ncriteria = ["D", "A"]\nmean_subtraction = ["batchwise", "complete"]\nseed = 3\n'
    )
    cells = load_sweep(cfg)
    assert len(cells) == 4
    local = run_sweep(cells, "inline", progress=False)
    import dask

    # Dask's nanny sets one thread in the workers' environment by default: give them two, so that the
    # one thread per worker is the engine's doing
    two = {"OMP_NUM_THREADS": 2, "OPENBLAS_NUM_THREADS": 2, "MKL_NUM_THREADS": 2}
    with (
        dask.config.set({"distributed.nanny.pre-spawn-environ": two}),
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
    ):
        remote = run_sweep(cells, cluster.scheduler_address, progress=False)
    key = ["ship", "criterion", "mean_subtraction", "weights", "top_primitive"]
    assert [{k: r[k] for k in key} for r in local.results] == [{k: r[k] for k in key} for r in remote.results]
    # SLSQP on a flat optimum: last digits differ with the BLAS thread count (Dask workers use one)
    assert [r["logdet"] for r in local.results] == pytest.approx([r["logdet"] for r in remote.results], rel=1e-6)
    assert all(r["error"] is None for r in local.results)
    # D-optimal with complete mean subtraction is at least as good as the uniform mix
    d_complete = next(r for r in local.results if r["criterion"] == "D" and r["mean_subtraction"] == "complete")
    assert d_complete["efficiency_vs_uniform"] >= 1.0
    path = write_table(local.results, tmp_path / "out.csv")
    lines = path.read_text().splitlines()
    assert lines[0].startswith("ship,library,speed_mps,criterion") and len(lines) == 5


def test_write_table_refuses_a_path_that_names_no_table_format(tmp_path):
    from expdesign.sweep import SweepError, write_table

    rows = [{"ship": "model-ship", "criterion": "D"}]
    with pytest.raises(SweepError, match=r"table .*out\.txt: the extension must name the table format: \.csv or \.parquet"):
        write_table(rows, tmp_path / "out.txt")
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(SweepError, match="dir.csv: is a directory"):
        write_table(rows, tmp_path / "dir.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.csv"]
    assert write_table(rows, tmp_path / "out.CSV").read_text().startswith("ship,")


def test_sweep_config_errors_name_the_field(tmp_path):
    from expdesign.sweep import SweepError, load_sweep

    cfg = tmp_path / "s.toml"
    cfg.write_text('[sweep]\ncriteria = ["Q"]\n')
    with pytest.raises(SweepError, match=r"sweep\.criteria"):
        load_sweep(cfg)
    cfg.write_text('[sweep]\nlibrary = "standard"\nspeeds = [-1]\n')
    with pytest.raises(SweepError, match=r"sweep\.speeds"):
        load_sweep(cfg)


def test_profiles_and_primitives_cross_process_boundaries():
    import pickle

    from primitives.library import model_ship_thesis
    from primitives.ship import load_profile

    prof = load_profile("model-ship")
    prim = model_ship_thesis(prof)[5]
    prof.model.increments(
        {"u": 1.0, "v": 0.0, "r": 0.0, "u_r": 1.0, "v_r": 0.0, "tau_x": 0.0, "tau_y": 0.0, "tau_n": 0.0}, prof.params()
    )
    _ = prim.footprint
    again = pickle.loads(pickle.dumps(prim))
    np.testing.assert_array_equal(again.nu, prim.nu)
    assert again.profile.model.terms == prof.model.terms
    sig = {"u": 0.5, "v": 0.1, "r": 0.2, "u_r": 0.5, "v_r": 0.1, "tau_x": 1.0, "tau_y": 2.0, "tau_n": 3.0}
    assert again.profile.model.increments(sig, prof.params()) == prof.model.increments(sig, prof.params())


def _die_on_two(i: int) -> int:
    if i == 2:
        import os

        os._exit(3)  # a worker lost (killed, out of memory)
    return i


def test_lost_local_worker_is_an_error_not_a_result():
    res = LocalEngine(2).map(_die_on_two, [0, 1, 2, 3, 4, 5], progress=False)
    assert not res.complete and res.errors and 2 in res.errors and not res.done[2]
    assert all(res.results[i] == i for i, d in enumerate(res.done) if d)


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork", reason="the fork pool")
def test_a_lost_worker_costs_only_its_own_task():
    """The other tasks still finish on the workers left (Python's process pool failed every task
    not yet finished once one worker died)."""
    res = LocalEngine(2).map(_die_on_two, [0, 1, 2, 3, 4, 5], progress=False)
    assert res.done == [True, True, False, True, True, True] and list(res.errors) == [2]
    assert res.errors[2].startswith("worker lost")


@pytest.mark.skipif(multiprocessing.get_start_method() != "fork", reason="the fork pool")
def test_each_worker_gets_its_first_task_as_soon_as_it_is_forked(monkeypatch):
    """Worker k has its first task before worker k + 1 is forked, so it computes while the parent
    forks the others (Python's process pool forked every worker before feeding any: ~50 ms of forks
    of a large parent before the last of 16 workers starts, none overlapped)."""
    from multiprocessing import connection, context

    events = []
    start, send = context.ForkProcess.start, connection.Connection.send
    monkeypatch.setattr(context.ForkProcess, "start", lambda self: (events.append("fork"), start(self))[1])
    monkeypatch.setattr(connection.Connection, "send", lambda self, obj: (events.append(f"task {obj}"), send(self, obj))[1])
    res = LocalEngine(3).map(_add_shared, [1, 2, 3, 4], progress=False, shared={"offset": 10})
    monkeypatch.undo()
    assert res.results == [11, 12, 13, 14]
    assert events[:6] == ["fork", "task 0", "fork", "task 1", "fork", "task 2"]


def _add_shared(item: int, shared: dict) -> int:
    return item + shared["offset"]


def test_shared_inputs_reach_every_task():
    for eng in (Engine(), LocalEngine(2)):
        assert eng.map(_add_shared, [1, 2, 3], progress=False, shared={"offset": 10}).results == [11, 12, 13]
    assert LocalEngine(3).capacity() == (3, 1) and Engine().capacity() == (1, 1)


def test_design_says_when_dask_workers_run_several_threads(capsys):
    """Threads of one Dask worker share the interpreter lock the Monte Carlo's time loops hold:
    the design command says so (and how to start the workers) instead of silently scaling badly."""
    from types import SimpleNamespace

    from cli.design_cmd import _echo_speed

    def ev(name, threads):
        eng = {"name": name, "workers": 4, "threads_per_worker": threads, "tasks": 64, "tasks_per_worker": 64 / (4 * threads)}
        return SimpleNamespace(engine=eng, runs_finished={"optimized": 500}, elapsed_s=2.0)

    _echo_speed(ev("dask", 4))
    err = capsys.readouterr().err
    assert "4 workers x 4 threads" in err and "--nthreads 1" in err
    for quiet in (ev("dask", 1), ev("local", 1)):
        _echo_speed(quiet)
        assert "--nthreads" not in capsys.readouterr().err


def _worker_state(dask_worker) -> tuple[bool, bool, int, bool, bool]:
    from primitives import heap, jitloop

    profiling = any(k in dask_worker.periodic_callbacks for k in ("profile", "profile-cycle"))
    return "expdesign.montecarlo" in sys.modules, jitloop.loaded(), _blas_threads(None), heap._MALLOC_SET, profiling


def test_dask_preload_warms_a_worker_before_any_task():
    """A worker started with ``--preload expdesign.dask_preload`` has the Monte Carlo imported, the
    compiled passes loaded, one BLAS thread and the nanny's MALLOC_TRIM_THRESHOLD_ undone (freed
    memory kept for the next batch) before the first command sends it a task (without it, each new
    worker pays that in its first task: the first run's wall on a fresh cluster), and no
    statistical profiler sampling its stacks while the tasks run."""
    distributed = pytest.importorskip("distributed")
    from primitives import jitloop

    kw = dict(threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40)
    with (
        distributed.LocalCluster(n_workers=1, preload=["expdesign.dask_preload"], **kw) as warm,
        distributed.Client(warm, set_as_default=False) as client,
    ):
        (state,) = client.run(_worker_state).values()
        faults = client.submit(_first_task_faults, pure=False).result()
    # a plain worker: (False, False, the library's default, False, True); mallopt only on glibc
    assert state == (True, jitloop.AVAILABLE, 1, platform.libc_ver()[0] == "glibc", False)
    if state[3]:  # its heap grown in its task thread: the first task's working set is faulted in already
        assert faults < 1000, faults  # 7,670 with the heap grown in the preload's own thread, 20 here


def _first_task_faults() -> int:
    """Page faults of a 125-run Monte Carlo batch, the first task on a worker."""
    import resource

    from expdesign.montecarlo import MCConfig, prepare, run_chunk
    from primitives.ship import load_profile

    sh = prepare(load_profile("model-ship"), {"random": "random"}, MCConfig(runs=126))
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    run_chunk(sh, "random", range(1, 126))
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def test_the_inline_engine_leaves_the_callers_malloc_alone():
    """The inline engine runs in the caller's process (a notebook, a script): it must not set glibc's
    trim threshold there (process-wide and permanent: the caller would keep up to 256 MB of every
    later job's freed memory; primitives.heap). In a fresh process without MALLOC_TRIM_THRESHOLD_."""
    env = {k: v for k, v in os.environ.items() if k != "MALLOC_TRIM_THRESHOLD_"}
    code = "from primitives import heap; from expdesign import parallel; parallel.Engine().map(abs, [-1, 2], progress=False); print(heap._MALLOC_SET)"
    root = Path(__file__).resolve().parent.parent
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=root, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"]
