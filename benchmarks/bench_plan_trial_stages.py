"""CPU of a whole ``plan-trial`` command per process and per stage (issue 30: under 2 s warm).

    python benchmarks/bench_plan_trial_stages.py [--repeat 3] [--root CHECKOUT] [--top 25]
        [-- PLAN-TRIAL ARGS ...]   (default: --no-cache, the default ship on the bundled map)

Runs ``plan-trial --out TMP ARGS`` ``--repeat`` times after one untimed run, as a user does (a fresh interpreter
each time, the checkout's code on ``PYTHONPATH``, compiled bytecode read from a directory of the benchmark's own,
the plan, move, library, design and map caches as the user's), with a CPU-time sampler installed in it and in
every process it forks (the drawer, the drawer's PDF child, the planner's forked helper): a ``SIGPROF`` timer
every 5 ms of the process's CPU; at each tick every thread's CPU since its last tick (its own CPU clock,
``pthread_getcpuclockid``) is added to the stage of that thread's current Python stack. A tick that arrives while
C code runs (PNG encoding, a long numpy call) is handled when it returns, so its CPU still goes to the Python
frame that called it. A stack's stage is "import: PACKAGE" while a module is being imported (PACKAGE the
outermost module being imported, whatever imports it), else the first rule of :data:`STAGES` that matches any of
its frames, else "other". A process's figure is its own user + system time (``getrusage`` at its exit:
``os._exit`` and interpreter exit are both caught); what the sampler did not see (the interpreter's start before
it was installed) is "unsampled". The sampler's own cost is in the figures: compare the whole command's CPU,
printed last (``wait4``: every process it reaped), with an unsampled run's (``benchmarks/bench_plan.py --cases
cli_default``) for its size.

Printed: per process role, the CPU per stage, the least over the runs (the steadiest figure on a shared
machine) and the median; then the whole command's CPU and wall (medians), with the load average.
Then each run's critical path (:func:`handover`: when the parent's planning starts and sends the plan, when the drawer
starts drawing it, when the figures and the command end). ``--timeline``: the last run's stages per process in
wall-clock order (first and last tick); ``--top N``: the N
Python functions with the most CPU (innermost frame, summed over processes); ``--json F``: every run's rows.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
INTERVAL_S = 0.005

# (label, file-path fragment, function name or "" for any function of that file) in order of precedence: a
# stack's stage is the first rule that matches any of its frames (an import in progress is "import: PACKAGE",
# PACKAGE the outermost module being imported, whatever imports it).
STAGES: tuple[tuple[str, str, str], ...] = (
    ("design: early design (drawer)", "cli/plan_early.py", "early_design"),
    ("draw: design ratios", "expdesign/report.py", ""),
    ("draw: design ratios", "maps/librarycache.py", "kept_ratios_png"),
    ("draw: PDF card", "maps/export/cardpdf.py", ""),
    ("draw: states PNG", "maps/export/plots.py", "plot_states"),
    ("draw: track PNG", "maps/export/plots.py", "plot_track"),
    ("draw: HTML card", "maps/export/card.py", ""),
    ("draw: plan.png", "maps/output.py", "plot_plan"),
    ("plan: export chart (route, sea room)", "cli/plan_outputs.py", "export_chart"),
    ("plan: map", "maps/mapcache.py", "load_map_kept"),
    ("plan: design (parent)", "maps/trialdesign.py", "first_design"),
    ("plan: design + lattice + search + verification", "maps/planner.py", "plan_with_design"),
    ("export: text files", "cli/plan_outputs.py", ""),
    ("drawer: plumbing, pickling", "cli/drawer.py", ""),
    ("cli: summary table", "cli/plan_summary.py", ""),
    ("cli: options (typer, pydantic)", "typer/", ""),
    ("cli: options (typer, pydantic)", "click/", ""),
    ("cli: command, profile, keys", "cli/", ""),
)


# ---------------------------------------------------------------- the sampler (runs inside the command)


class _Sampler:
    """Per-thread CPU added to the current stack's stage at each SIGPROF; one per process (reset after fork)."""

    def __init__(self, out_dir: str) -> None:
        self.out_dir, self.role, self.root = out_dir, "parent", os.getcwd() + "/"
        self.t0 = float(os.environ.get("BENCH_PTS_T0", time.time()))
        self.reset()

    def reset(self) -> None:
        self.stages: dict[str, float] = {}
        self.funcs: dict[str, float] = {}
        self.own: dict[str, float] = {}  # stage | innermost frame of the checkout's own code
        self.spans: dict[str, list[float]] = {}  # stage -> [first, last] tick, wall seconds since the command began
        self.last: dict[int, float] = {}

    def start(self) -> None:
        import signal

        signal.signal(signal.SIGPROF, self.tick)
        signal.setitimer(signal.ITIMER_PROF, INTERVAL_S, INTERVAL_S)

    def tick(self, signum: int, frame: object) -> None:
        import threading

        frames = sys._current_frames()
        for th in threading.enumerate():
            f = frames.get(th.ident)  # type: ignore[arg-type]
            if f is None:
                continue
            try:
                now = time.clock_gettime(time.pthread_getcpuclockid(th.ident))  # type: ignore[arg-type]
            except (OSError, OverflowError):
                continue
            spent, self.last[th.ident] = now - self.last.get(th.ident, 0.0), now  # type: ignore[index]
            if th is threading.main_thread():  # its current frame is this handler's: the interrupted one is `frame`
                f = frame  # type: ignore[assignment]
            self.add(f, spent)

    def add(self, f: object, spent: float) -> None:
        inner = f"{f.f_code.co_filename.rsplit('/', 2)[-1]}:{f.f_code.co_name}"  # type: ignore[attr-defined]
        self.funcs[inner] = self.funcs.get(inner, 0.0) + spent
        stack, imported, own = [], None, None
        while f is not None:
            code = f.f_code  # type: ignore[attr-defined]
            stack.append((code.co_filename, code.co_name))
            if own is None and code.co_filename.startswith(self.root) and "/benchmarks/" not in code.co_filename:
                own = f"{code.co_filename[len(self.root) :]}:{code.co_name}:{f.f_lineno}"  # type: ignore[attr-defined]
            if code.co_name == "_find_and_load" and "importlib" in code.co_filename:
                imported = f.f_locals.get("name", "?")  # type: ignore[attr-defined]  # outermost wins
            f = f.f_back  # type: ignore[attr-defined]
        if imported is not None:
            label = f"import: {str(imported).split('.')[0]}"
        else:
            label = next((lab for lab, frag, fn in STAGES for name, func in stack if frag in name and fn in ("", func)), "other")
        self.stages[label] = self.stages.get(label, 0.0) + spent
        now = time.time() - self.t0
        self.spans.setdefault(label, [now, now])[1] = now
        key = f"{label} | {own}"
        self.own[key] = self.own.get(key, 0.0) + spent

    def dump(self) -> None:
        import resource
        import signal

        signal.setitimer(signal.ITIMER_PROF, 0, 0)
        ru = resource.getrusage(resource.RUSAGE_SELF)
        row = {"role": self.role, "pid": os.getpid(), "cpu_s": ru.ru_utime + ru.ru_stime}
        row |= {"stages": self.stages, "funcs": self.funcs, "own": self.own, "spans": self.spans, "end": time.time() - self.t0}
        with open(os.path.join(self.out_dir, f"{os.getpid()}.json"), "w") as fh:
            json.dump(row, fh)


def _role_of_fork() -> str:
    """Which of the command's forks this is, from the calling frames."""
    f = sys._getframe(2)
    names = []
    while f is not None:
        names.append(f.f_code.co_name)
        f = f.f_back
    if "beside" in names:
        return "drawer's PDF child"
    if "__init__" in names and any("drawer" in n or n in ("start_early", "plan_and_write") for n in names):
        return "drawer"
    return "planner's forked helper"


def install(out_dir: str) -> None:
    """Sample this process and every process it forks; each writes ``out_dir/PID.json`` when it ends."""
    import atexit

    s = _Sampler(out_dir)
    real_exit = os._exit

    def child() -> None:
        parent_role = s.role
        s.reset()
        s.role = _role_of_fork() if parent_role == "parent" else f"{parent_role} > {_role_of_fork()}"
        s.start()

    def exit_dumping(code: int) -> None:
        try:
            s.dump()
        finally:
            real_exit(code)

    os.register_at_fork(after_in_child=child)
    os._exit = exit_dumping  # type: ignore[assignment]
    atexit.register(s.dump)
    s.start()


# ---------------------------------------------------------------- the benchmark (runs the command)

_BOOT = (
    "import sys; sys.path.insert(0, {bench!r}); import bench_plan_trial_stages as b; b.install({out!r}); "
    "sys.argv = ['plan-trial'] + {args!r}; from cli.app import plan_main; plan_main()"
)


def run_once(root: Path, args: list[str], pycache: str) -> dict:
    """One sampled run of ``plan-trial ARGS`` in ``root``: per process rows, the whole CPU and wall. ``pycache``:
    where compiled bytecode is read and written (``PYTHONPYCACHEPREFIX``), whatever ``PYTHONDONTWRITEBYTECODE``
    says: every module read compiled, as after ``pip install``, and neither checkout favoured by what its own
    ``__pycache__`` happens to hold."""
    with tempfile.TemporaryDirectory(prefix="bench-pts-") as tmp:
        samples = Path(tmp, "samples")
        samples.mkdir()
        argv = ["--out", str(Path(tmp, "out")), *args]
        code = _BOOT.format(bench=str(Path(__file__).resolve().parent), out=str(samples), args=argv)
        env = dict(os.environ, PYTHONPATH=str(root), BENCH_PTS_T0=repr(time.time()))
        env |= {"PYTHONPYCACHEPREFIX": pycache, "PYTHONDONTWRITEBYTECODE": ""}
        t = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-c", code], cwd=root, env=env, stdout=subprocess.DEVNULL)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        if os.waitstatus_to_exitcode(status) != 0:
            raise SystemExit(f"plan-trial {' '.join(args)}: exit {os.waitstatus_to_exitcode(status)} in {root}")
        rows = [json.loads(p.read_text()) for p in samples.glob("*.json")]
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "processes": rows}


_SENT = "plan: export chart (route, sea room)"  # the parent's last stage before it hands the plan to the drawer


def handover(run: dict) -> dict[str, float] | None:
    """The critical path's points in one run (wall s since the command began): the parent's planning
    starts (its first "plan: map" tick) and ends (its last export-chart tick: the plan is sent), the drawer
    starts drawing the plan (its first "draw: plan.png" tick; a drawer still importing or drawing the design
    ratios when the plan came starts late: ``late``), its figures end, the command ends. None for a run
    without those stages (a plan read from the plan cache, ``--no-export``)."""
    rows = {r["role"]: r for r in run["processes"]}
    par, drw = rows.get("parent"), rows.get("drawer")
    if par is None or drw is None or _SENT not in par["spans"] or "draw: plan.png" not in drw["spans"]:
        return None
    plan_start = par["spans"].get("plan: map", par["spans"][_SENT])[0]
    sent, drawn_from = par["spans"][_SENT][1], drw["spans"]["draw: plan.png"][0]
    return {
        "plan_start": plan_start,
        "sent": sent,
        "drawer_starts": drawn_from,
        "late": drawn_from - sent,
        "drawer_ends": drw["end"],
        "end": par["end"],
    }


def print_handover(runs: list[dict]) -> None:
    """Each run's :func:`handover` points, one line a run."""
    print("\ncritical path (wall s since the command began; late = drawer's first plan.png tick - plan sent):")
    for i, run in enumerate(runs):
        h = handover(run)
        if h is None:
            print(f"  run {i + 1}: no plan handed to a drawer")
            continue
        print(
            f"  run {i + 1}: planning {h['plan_start']:.2f} .. {h['sent']:.2f}, drawer draws from {h['drawer_starts']:.2f} "
            f"(late {h['late']:+.2f}), figures end {h['drawer_ends']:.2f}, command ends {h['end']:.2f}; "
            f"wall {run['wall_s']:.2f}, CPU {run['cpu_s']:.2f}"
        )


def summarise(runs: list[dict], top: int, timeline: bool = False) -> None:
    """Print the CPU per process role and stage (least and median over the runs)."""
    by_role: dict[str, list[dict]] = {}
    for run in runs:
        merged: dict[str, dict] = {}
        for row in run["processes"]:  # one role can fork twice (the planner's helper): summed
            m = merged.setdefault(row["role"], {"cpu_s": 0.0, "stages": {}})
            m["cpu_s"] += row["cpu_s"]
            for k, v in row["stages"].items():
                m["stages"][k] = m["stages"].get(k, 0.0) + v
        for role, m in merged.items():
            m["stages"]["unsampled (start-up, sampler)"] = m["cpu_s"] - sum(m["stages"].values())
            by_role.setdefault(role, []).append(m)
    order = sorted(by_role, key=lambda r: (r != "parent", r))
    for role in order:
        ms = by_role[role]
        tot = [m["cpu_s"] for m in ms]
        print(f"\n{role}: CPU {min(tot):.3f} s least, {statistics.median(tot):.3f} s median ({len(ms)} of {len(runs)} runs)")
        labels = sorted(
            {k for m in ms for k in m["stages"]}, key=lambda k: -statistics.median(m["stages"].get(k, 0.0) for m in ms)
        )
        for k in labels:
            vals = [m["stages"].get(k, 0.0) for m in ms]
            print(f"  {k:<52s} {min(vals):7.3f} {statistics.median(vals):7.3f}")
    per_run = [sum(r["cpu_s"] for r in run["processes"]) for run in runs]
    whole = [run["cpu_s"] for run in runs]
    walls = [run["wall_s"] for run in runs]
    print(
        f"\nsum of the processes: {statistics.median(per_run):.3f} s median; whole command (wait4) CPU "
        f"{statistics.median(whole):.3f} s median ({min(whole):.3f}-{max(whole):.3f}), wall {statistics.median(walls):.3f} s "
        f"median ({min(walls):.3f}-{max(walls):.3f})"
    )
    print_handover(runs)
    if timeline:  # the last run's stages in wall-clock order, per process
        print("\ntimeline of the last run (wall s since the command began: first .. last tick, CPU):")
        for row in sorted(runs[-1]["processes"], key=lambda r: r["role"] != "parent"):
            print(f"  {row['role']} (pid {row['pid']}, ends {row['end']:.2f})")
            for k, (a, b) in sorted(row["spans"].items(), key=lambda kv: kv[1][0]):
                print(f"    {a:6.2f} .. {b:6.2f}  {row['stages'][k]:6.3f}  {k}")
    if top:
        funcs: dict[str, float] = {}
        for run in runs:
            for row in run["processes"]:
                for k, v in row["funcs"].items():
                    funcs[k] = funcs.get(k, 0.0) + v / len(runs)
        print(f"\ntop {top} innermost Python frames (CPU s a run, all processes):")
        for k, v in sorted(funcs.items(), key=lambda kv: -kv[1])[:top]:
            print(f"  {v:7.3f} {k}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--root", type=Path, default=ROOT, help="checkout whose plan-trial runs (default: this one)")
    ap.add_argument("--top", type=int, default=0)
    ap.add_argument("--timeline", action="store_true", help="print the last run's stages in wall-clock order")
    ap.add_argument("--json", type=Path, default=None, help="also write every run's rows here")
    ap.add_argument(
        "--new-start",
        action="store_true",
        help="each run at a start time no run of this benchmark used (--start-time from the clock): a cached plan "
        "whose files for that start time are not kept, as the next hour's run of the default start time",
    )
    ap.add_argument("args", nargs="*", default=None, help="plan-trial arguments after -- (default: --no-cache)")
    ns = ap.parse_args()
    args = ns.args or ["--no-cache"]

    def argv() -> list[str]:
        if not ns.new_start:
            return args
        # a start minute from the clock (decisecond resolution, 2030-2049, period 11.6 days): two runs share it
        # only if they start within 0.1 s of each other
        t = time.gmtime(1_900_000_000 + int(time.time() * 10) % 10_000_000 * 60)
        return [*args, "--start-time", time.strftime("%Y-%m-%dT%H:%MZ", t)]

    with tempfile.TemporaryDirectory(prefix="bench-pts-pyc-") as pycache:
        run_once(ns.root, argv(), pycache)  # untimed: bytecode, caches and page cache warm
        load0 = os.getloadavg()[0]
        runs = [run_once(ns.root, argv(), pycache) for _ in range(ns.repeat)]
    print(f"plan-trial --out TMP {' '.join(args)} in {ns.root}, {ns.repeat} runs, load {load0:.2f} -> {os.getloadavg()[0]:.2f}")
    summarise(runs, ns.top, ns.timeline)
    if ns.json is not None:
        ns.json.write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
