"""Benchmarks of the sea maps and the planning chain (issues 4 and 12).

    python benchmarks/bench_plan.py [--repeat 3] [--cases cli_default,default,kvlcc2_fjord,...] [--against REF]
        [--cold | --no-cache | --new-start] [--bytecode]

``cli_default`` times the command a user runs, ``plan-trial --out DIR`` for the default ship on
the bundled map with every default export (plan JSON, GeoJSON, GPX, RTZ, CSV, HTML and PDF trial
card, PNG figures), as a whole process: interpreter start, imports, design, planning, exports.
It reports the median over ``--repeat`` runs (after one untimed run) of the wall clock and of
the process's CPU time (user + system, from ``wait4``; on a shared machine the CPU time is the
steadier figure, on an idle one the wall clock is about the CPU time) and the peak resident
memory, against the 2 s target of issue 12. ``--against DIR`` runs another checkout's command
(e.g. main's) alternately with this one's, for a paired before/after on a shared machine. The
runs share one plan cache (``SHIPTRIAL_CACHE_DIR``, a temporary directory: the user's is never
touched), which the untimed run fills: the timed runs are warm, as a user's second run. With
``--cold`` every run starts as the first run after install: an empty plan cache and an empty
matplotlib configuration and font cache (``MPLCONFIGDIR``), no untimed run (issue 30: under 5 s).
``--no-cache``: every run plans afresh (``plan-trial --no-cache``: the design, the lattice, the search and every
export computed, the compiled kernels and bytecode warm, as a user who changed an option); ``--new-start``: every
timed run has a start time of its own (the plan read from the plan cache, every file exported and drawn again).
``--bytecode``: the runs read compiled bytecode as after ``pip install`` (in a directory of the benchmark's
own, filled by an untimed run; with ``PYTHONDONTWRITEBYTECODE`` set and no ``__pycache__`` in a checkout,
every run compiles that checkout's modules, which a user's installed copy never does).

Every other case runs in a fresh subprocess (its own peak resident memory, from getrusage) and is
timed as the median of ``--repeat`` runs after one warm-up in that process (wall clock, and
the process's CPU time beside it: on a shared machine the CPU time is the steadier figure).
Ratio < 1 is within target.

* ``map_load``: load and project the bundled Helsinki map (target 0.5 s).
* ``default``: the whole ``plan_trial`` for the default ship on the bundled map, design included
  (design of the library, whole manoeuvres, 16 headings, run-ins, shortcuts, verification):
  target 2 s, memory < 2 GiB (issue 12).
* ``kvlcc2_fjord``: ``plan_trial`` for kvlcc2 on the synthetic 20 km x 6 km fjord
  (tests/data/fjord.geojson), design included: target 10 s, memory < 2 GiB. Expected outcome: a
  verified plan of the whole rounded design (zz_exc_25_5_100 x11, turning circles 5 + 5,
  stopping x2), the ship shuttling up and down the fjord with round turns; the lattice spacing
  is 6 km / 8 points (~750 m) instead of four ship lengths.
* ``kvlcc2_open_sea``: kvlcc2 on 60 km x 60 km of open water (tests/data/open-sea.geojson).
* ``scenario``: the section 9.4 scenario as the thesis ran it (4 headings, no run-ins): search
  target 1 s (thesis: about 40 s for a plain A*).
* ``refusal``: how long the up-front refusal of a lattice that would not fit takes (target 1 s).
* ``stages``: the CPU time of each stage of ``cli_default`` after the imports, run one after the
  other (the least over the runs per stage; total against the 2 s target as if on one core).
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

DATA = ROOT / "tests" / "data"
TARGETS = {
    "cli_default": 2.0,
    "cli_cold": 5.0,  # issue 30: the first run after install
    "stages": 2.0,
    "map_load": 0.5,
    "default": 2.0,
    "kvlcc2_fjord": 10.0,
    "kvlcc2_open_sea": 10.0,
    "scenario": 1.0,
    "refusal": 1.0,
}


def _cpu() -> float:
    """CPU seconds of this process and of its reaped children (the planner forks a helper for
    half of some steps: maps.forked), user + system."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _plan(ship: str, sea_path: Path | None, **kw) -> dict:
    from maps.geo import load_map
    from maps.planner import plan_trial
    from maps.trialdesign import NoFitError
    from primitives.ship import load_profile

    prof = load_profile(ship)
    sea = load_map(sea_path, draught_m=prof.draught_m)
    t0, c0 = time.perf_counter(), _cpu()
    try:
        plan = plan_trial(sea, profile=prof, **kw)
    except NoFitError as exc:
        return {"total_s": time.perf_counter() - t0, "cpu_s": _cpu() - c0, "outcome": f"exit 1: {str(exc)[:160]}"}
    total, cpu = time.perf_counter() - t0, _cpu() - c0
    st = plan.stats
    return {
        "total_s": total,
        "cpu_s": cpu,
        "search_s": st["plan_time_s"],
        "setup_s": st["setup_time_s"],
        "design_s": st.get("design_time_s"),
        "expansions": st["expansions"],
        "feasible": plan.feasible,
        "counts_ok": plan.counts == plan.targets,
        "counts": plan.counts,
        "outcome": "feasible" if plan.feasible else f"infeasible: {st.get('reason')}",
        "lattice_states": st["lattice"]["states"],
        "min_clearance_m": plan.min_clearance_m,
    }


def _refusal() -> dict:
    from maps.geo import MapError
    from maps.planner import plan_trial

    t0 = time.perf_counter()
    try:
        plan_trial(profile="full-scale", scenario="thesis-9.4", resolution=10.0, size=(400, 400))
        msg = "not refused"
    except MapError as exc:
        msg = str(exc)
    return {"total_s": time.perf_counter() - t0, "outcome": msg[:200]}


def _map_load() -> dict:
    from maps.geo import load_map

    t0 = time.perf_counter()
    load_map(draught_m=2.5)
    return {"total_s": time.perf_counter() - t0}


def _stages() -> dict:
    """CPU seconds (this process and its forked helpers, :func:`_cpu`) of each stage of ``plan-trial --out DIR`` run one
    after the other in this process: where the whole-process time goes. The command itself
    draws every figure (PDF and HTML card, their PNGs, plan.png, design ratios) in a drawer
    forked at its start (``cli.drawer``: it imports matplotlib and fpdf while the parent plans,
    then draws in two processes) beside the parent's plan.json, trajectory and text exports.
    The imports are timed by the ``cli_default`` case (this process has them already)."""
    import tempfile

    from maps.chain import PlanOptions
    from maps.export import _write, default_path
    from maps.export._common import iso, resolve_start
    from maps.export.card import write_card_pdf
    from maps.export.chart import embed_chart, plan_chart
    from maps.export.figures import PlanFigures
    from maps.export.geojson import sea_room_lonlat, write_geojson
    from maps.export.route import build_route
    from maps.geo import load_map
    from maps.output import plot_plan
    from maps.planner import plan_with_design
    from primitives.ship import load_profile

    cpu: dict[str, float] = {}
    last = [_cpu()]

    def mark(name: str) -> None:
        now = _cpu()
        cpu[name] = now - last[0]
        last[0] = now

    prof = load_profile("full-scale")
    sea = load_map(None, draught_m=prof.draught_m)
    mark("profile + map")
    plan, td = plan_with_design(sea, profile=prof, options=PlanOptions(size=(35, 44)))
    mark("design + planning")
    t0 = resolve_start(plan, "2026-06-01T08:00Z")
    plan.stats["start_utc"] = iso(t0)
    chart = plan_chart(plan, sea)
    build_route(plan, chart)  # as the command: one route and sea room for every export, before the figures are sent to be drawn
    sea_room_lonlat(plan)
    mark("chart + route")
    with tempfile.TemporaryDirectory(prefix="bench-stages-") as tmp:
        out = Path(tmp)
        write_card_pdf(plan, out / "card.pdf", chart, t0)
        mark("child: PDF card")
        plot_plan(plan, sea, out / "plan.png")
        mark("child: plan.png")
        embed_chart(plan, chart)
        (out / "plan.json").write_text(plan.to_json())
        write_geojson(plan, out / "trajectory.geojson", overlay=False)
        mark("plan.json + trajectory")
        from expdesign.report import plot_ratios

        plot_ratios(td.design, out / "design-ratios.png")
        mark("design-ratios.png")
        with PlanFigures(plan, chart) as figs:
            for fmt in ("geojson", "gpx", "rtz", "csv"):
                _write(plan, fmt, default_path(plan, fmt, out), sea_map=chart, start=t0, vessel=None, pdf=False, figures=figs)
                mark(fmt)
            figs.png("track")
            mark("track figure + PNG")
            figs.png("states")
            mark("states figure + PNG")
            _write(plan, "card", default_path(plan, "card", out), sea_map=chart, start=t0, vessel=None, pdf=False, figures=figs)
            mark("HTML card")
    return {"total_s": sum(cpu.values()), "stages_cpu_s": cpu}


CASES = {
    "map_load": _map_load,
    "default": lambda: _plan("full-scale", None),
    "kvlcc2_fjord": lambda: _plan("kvlcc2", DATA / "fjord.geojson"),
    "kvlcc2_open_sea": lambda: _plan("kvlcc2", DATA / "open-sea.geojson"),
    "scenario": lambda: _plan("full-scale", None, scenario="thesis-9.4", headings=4, run_in_s=0.0),
    "refusal": _refusal,
    "stages": _stages,
}


def child(case: str, repeat: int) -> dict:
    CASES[case]()  # warm-up: imports, caches of the numerical libraries
    rows = [CASES[case]() for _ in range(repeat)]
    key = "search_s" if case == "scenario" else "total_s"  # the thesis compares the search alone
    med = statistics.median(r[key] for r in rows)
    out = {k: v for k, v in rows[-1].items() if k != "total_s"}
    if "stages_cpu_s" in rows[-1]:  # the least CPU of each stage over the runs: the steadiest figure on a shared machine
        out["stages_cpu_s"] = {k: round(min(r["stages_cpu_s"][k] for r in rows), 3) for k in rows[-1]["stages_cpu_s"]}
    if "cpu_s" in rows[-1]:  # CPU time of the process: what the wall clock would be on an idle machine (no threads here)
        out["median_cpu_s"] = statistics.median(r["cpu_s"] for r in rows)
    out.update(
        median_s=med,
        timed=key,
        median_total_s=statistics.median(r["total_s"] for r in rows),
        runs_s=[round(r["total_s"], 3) for r in rows],
        target_s=TARGETS[case],
        ratio_to_target=med / TARGETS[case],
        peak_rss_gib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2,
        memory_target_gib=2.0,
    )
    return out


def _cli_run(root: Path, out: Path, env_extra: dict[str, str] | None = None, args: tuple[str, ...] = (), start: str = "") -> dict:
    """One ``plan-trial --out OUT`` process run from the checkout ``root``: wall, CPU (user + system
    of it and every child it reaped: the drawer, the lattice's forked helper), peak memory.
    ``env_extra``: environment variables set for it (the plan cache, matplotlib's cache); ``args``: more options
    (``--no-cache``); ``start``: its ``--start-time``."""
    import os

    code = "from cli.app import plan_main; plan_main()"
    env = dict(os.environ, PYTHONPATH=str(root), **(env_extra or {}))  # the checkout's code, not an installed copy
    start = start or _start_time(0)
    cmd = [sys.executable, "-c", code, "--out", str(out), "--start-time", start, *args]
    r = timed_process(cmd, root, env, subprocess.DEVNULL)
    if r["exit"] != 0:
        raise RuntimeError(f"plan-trial failed: {r['stderr'].strip().splitlines()[-1] if r['stderr'].strip() else r['exit']}")
    return {k: r[k] for k in ("wall_s", "cpu_s", "rss_gib")} | {"files": len(list(out.iterdir()))}


def timed_process(cmd: list[str], cwd: Path, env: dict[str, str], stdout: Any) -> dict:
    """Run ``cmd`` as one process and reap it: its wall clock, CPU (user + system of it and every child it
    reaped), peak memory, exit code and standard error (``stdout`` where its output goes)."""
    import os

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=stdout, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)  # the rusage of it and its reaped children, which Popen.wait does not give
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    return {
        "wall_s": wall,
        "cpu_s": ru.ru_utime + ru.ru_stime,
        "rss_gib": ru.ru_maxrss / 1024**2,
        "exit": os.waitstatus_to_exitcode(status),
        "stderr": err,
    }


def cli_default(
    repeat: int,
    against: Path | None = None,
    cold: bool = False,
    bytecode: bool = False,
    no_cache: bool = False,
    new_start: bool = False,
) -> dict:
    """The whole ``plan-trial --out DIR`` process, ``repeat`` times after one untimed run (``cold``:
    without it, each run with an empty plan cache and matplotlib cache); with ``against`` (another
    checkout, e.g. main's) that checkout's command run alternately with this one's, paired on the
    same machine state, under ``against_*`` keys. ``bytecode``: every run reads compiled bytecode as
    after ``pip install`` (which compiles it), kept in a directory of the benchmark's own
    (``PYTHONPYCACHEPREFIX``: nothing written into the checkouts) and filled by an untimed run,
    whatever ``PYTHONDONTWRITEBYTECODE`` says; without it, the environment decides. ``no_cache``: every run
    with ``--no-cache``; ``new_start``: every run with a start time of its own (the pair of a round the same one)."""
    import tempfile

    rows: list[dict] = []
    other: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="bench-plan-") as tmp:
        for k in range(-1 if cold and bytecode else 0, repeat + (0 if cold else 1)):
            for root, into in ((ROOT, rows), (against, other)):
                if root is None:
                    continue
                name = f"{'this' if root is ROOT else 'other'}{k}"
                caches = Path(tmp) / (f"caches-{name}" if cold else "caches")
                env = {"SHIPTRIAL_CACHE_DIR": str(caches / "plans"), "MPLCONFIGDIR": str(caches / f"mpl-{name}")}
                if not cold:  # warm: the plan cache shared by the runs, matplotlib's the user's
                    env.pop("MPLCONFIGDIR")
                if bytecode:
                    env |= {"PYTHONPYCACHEPREFIX": str(Path(tmp) / "pycache"), "PYTHONDONTWRITEBYTECODE": ""}
                start = _start_time(k if new_start else 0)
                r = _cli_run(root, Path(tmp) / name, env, ("--no-cache",) if no_cache else (), start)
                if k > 0 or (cold and k == 0):  # k == -1 (cold) or 0 (warm): untimed, fills the caches
                    into.append(r)
    target = TARGETS["cli_cold" if cold else "cli_default"]
    out = _cli_summary(rows, target) | {"cold": cold, "bytecode": bytecode, "no_cache": no_cache, "new_start": new_start}
    if against is not None:
        base = _cli_summary(other, target)
        out.update({f"against_{k}": v for k, v in base.items() if k in ("median_s", "median_cpu_s", "runs_s", "cpu_runs_s")})
        out["against"] = str(against)
    return out


def _start_time(k: int) -> str:
    """The ``k``-th full hour after 2026-06-01 08:00 UTC, as ``--start-time`` takes it."""
    from datetime import UTC, datetime, timedelta

    return (datetime(2026, 6, 1, 8, tzinfo=UTC) + timedelta(hours=k)).strftime("%Y-%m-%dT%H:%MZ")


def _cli_summary(rows: list[dict], target: float) -> dict:
    import os

    med = statistics.median(r["wall_s"] for r in rows)
    return {
        "median_s": med,
        "median_cpu_s": statistics.median(r["cpu_s"] for r in rows),
        "target_s": target,
        "ratio_to_target": med / target,
        "cpu_ratio_to_target": statistics.median(r["cpu_s"] for r in rows) / target,
        "runs_s": [round(r["wall_s"], 3) for r in rows],
        "cpu_runs_s": [round(r["cpu_s"], 3) for r in rows],
        "peak_rss_gib": max(r["rss_gib"] for r in rows),
        "files_written": rows[-1]["files"],
        "memory_target_gib": 2.0,
        "load_average_1min": os.getloadavg()[0],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cases", default=",".join(["cli_default", *CASES]))
    ap.add_argument(
        "--against",
        type=Path,
        help="cli_default only: also time this other checkout's plan-trial (e.g. a checkout of main), alternating runs",
    )
    mode = ap.add_mutually_exclusive_group()  # one kind of run a call: the printed label names one
    mode.add_argument(
        "--cold",
        action="store_true",
        help="cli_default only: every run as the first after install (empty plan and matplotlib caches)",
    )
    ap.add_argument(
        "--bytecode",
        action="store_true",
        help="cli_default only: runs read compiled bytecode (as after pip install), kept in a directory of the benchmark's own",
    )
    mode.add_argument(
        "--no-cache", action="store_true", help="cli_default only: every run plans afresh (plan-trial --no-cache), caches warm"
    )
    mode.add_argument(
        "--new-start",
        action="store_true",
        help="cli_default only: every timed run with a start time of its own (the plan read from the plan cache, every file exported)",
    )
    ap.add_argument("--case", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        print(json.dumps(child(args.case, args.repeat), default=str))
        return
    for name in args.cases.split(","):
        if name == "cli_default":
            r = cli_default(args.repeat, args.against, args.cold, args.bytecode, args.no_cache, args.new_start)
            mode = " cold" if args.cold else " no-cache" if args.no_cache else " new-start" if args.new_start else ""
            print(
                f"{name + mode + (' pyc' if args.bytecode else ''):18s} median {r['median_s']:8.3f} s  target {r['target_s']:5.1f} s  ratio {r['ratio_to_target']:.3f}  "
                f"peak {r['peak_rss_gib']:.2f} GiB  (cpu median {r['median_cpu_s']:.3f} s, cpu ratio {r['cpu_ratio_to_target']:.3f}, "
                f"wall runs {r['runs_s']}, cpu runs {r['cpu_runs_s']}, {r['files_written']} files, "
                f"load average {r['load_average_1min']:.1f} when done)"
            )
            if args.against:
                print(
                    f"{'  against':18s} median {r['against_median_s']:8.3f} s  cpu median {r['against_median_cpu_s']:.3f} s  "
                    f"(wall runs {r['against_runs_s']}, cpu runs {r['against_cpu_runs_s']}; {r['against']}, run alternately)"
                )
            continue
        proc = subprocess.run(
            [sys.executable, __file__, "--case", name, "--repeat", str(args.repeat)], capture_output=True, text=True
        )
        if proc.returncode:
            print(f"{name:18s} FAILED: {proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else proc.returncode}")
            continue
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        extra = ", ".join(
            f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
            for k, v in r.items()
            if k not in ("median_s", "target_s", "ratio_to_target", "memory_target_gib")
        )
        print(
            f"{name:18s} median {r['median_s']:8.3f} s  target {r['target_s']:5.1f} s  ratio {r['ratio_to_target']:.3f}  "
            f"peak {r['peak_rss_gib']:.2f} GiB  ({extra})"
        )


if __name__ == "__main__":
    main()
