"""One runner for every speed figure named in the issues.

    python benchmarks/run.py [--repeat 5] [--only NAME ...] [--json benchmarks/results.json]

Each case runs in a fresh subprocess (so its peak memory is its own): one warm-up call, then
``repeat`` timed calls; the runner prints the median, min and max wall time, the peak resident
memory, and the ratio of the median to the target (< 1: within target) and to the reference
figure it is compared with (the thesis's, where it gives one). The same is written as JSON so
that later changes can be compared with ``--compare OLD.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


# -- cases: (function, target seconds, reference seconds or None, what the reference is) --------------


def _library_build():
    from benchmarks.bench_primitives import case_library_build

    return case_library_build


def _mc_sim():
    from benchmarks.bench_primitives import case_monte_carlo_sim

    return case_monte_carlo_sim


def _design_setup():
    from expdesign.dopt import InfoSet
    from primitives.information import library_information
    from primitives.library import model_ship_thesis
    from primitives.ship import load_profile

    prof = load_profile("model-ship")
    prims = model_ship_thesis(prof)
    return prof, prims, InfoSet.from_infos(library_information(prof, prims))


def _convex():
    from expdesign.dopt import solve_convex

    _, _, info = _design_setup()
    return lambda: solve_convex(info, "D", "complete")


def _nonconvex():
    from expdesign.dopt import solve_convex
    from expdesign.nonconvex import solve_nonconvex

    _, _, info = _design_setup()
    start = solve_convex(info, "D", "complete").weights
    return lambda: solve_nonconvex(info, convex_start=start, n_random=4)


def _mc_design():
    from expdesign.api import run_design
    from expdesign.montecarlo import evaluate_designs

    prof, prims, _ = _design_setup()
    w = run_design(prof, prims).weights

    def go():
        r = evaluate_designs(prof, {"optimized": w}, runs=500, seed=0, primitives=prims)["optimized"].summary()
        return {"param_rmse_p50": r["param_rmse_p50"], "sim_rmse_p50": r["sim_rmse_p50"]}

    return go


def _mc_scaling(workers):
    """2,000 runs x 2 designs (issue 14) on ``workers`` local processes (1: inline)."""
    from expdesign.api import run_design
    from expdesign.mc_parallel import evaluate_designs_parallel
    from expdesign.parallel import Engine, LocalEngine

    prof, prims, _ = _design_setup()
    designs = {"optimized": run_design(prof, prims).weights, "random": "random"}

    def go():
        with Engine() if workers == 1 else LocalEngine(workers) as eng:
            ev = evaluate_designs_parallel(prof, designs, runs=2000, seed=0, scheduler=eng, primitives=prims, progress=False)
        return {
            "runs_per_s": 4000 / ev.elapsed_s,
            "tasks_per_worker": ev.engine["tasks_per_worker"],
            "digest": "".join(r.digest()[:8] for r in ev.results.values()),
        }

    return go


def _planner(counts, **kw):
    from maps.geo import load_map
    from maps.planner import plan_trial
    from primitives.ship import load_profile

    prof = load_profile("full-scale")
    sea = load_map(draught_m=prof.draught_m)

    def run():
        plan = plan_trial(sea, profile=prof, counts=counts, **kw)
        st = plan.stats
        if not (plan.feasible and plan.counts == plan.targets):
            raise RuntimeError(f"planning case failed: {st.get('reason')}")
        return {
            "search_s": st["plan_time_s"],
            "expansions": st["expansions"],
            "expansions_per_s": st["expansions_per_s"],
            "lattice_states": st["lattice"]["states"],
            "optimal": plan.optimal,
        }

    return run


THESIS_LATTICE = {"headings": 4, "run_in_s": 0.0}  # section 9.4: four headings, no run-ins


def _plan_thesis():
    return _planner(None, scenario="thesis-9.4", **THESIS_LATTICE)  # three primitives used three times each


def _plan_5x5():
    return _planner(
        dict.fromkeys(["steep_zigzag_surge", "wide_zigzag_surge", "wide_zigzag_sway", "tau17", "tau19"], 5), **THESIS_LATTICE
    )


def _plan_design():
    return _planner(None)  # plan-trial's default: design of the library, 16 headings, run-ins, shortcuts


def _plan_cli_no_cache():
    """``plan-trial --out DIR --no-cache`` for the default ship as a whole process (interpreter, imports, design,
    planning, every export and figure), warm: bytecode read as after ``pip install`` (a directory of the case's own,
    filled by the warm-up run), no plan read from or written to a cache. The case's time is the process's wall
    clock; ``process_cpu_s`` is its CPU with its drawer's and helpers' (this runner's own CPU is near 0)."""
    import atexit
    import shutil
    import tempfile

    from benchmarks.bench_plan import _cli_run

    tmp = Path(tempfile.mkdtemp(prefix="bench-plan-cli-"))
    atexit.register(shutil.rmtree, tmp, True)  # this case's child process ends after its runs
    env = {"SHIPTRIAL_CACHE_DIR": str(tmp / "cache"), "PYTHONPYCACHEPREFIX": str(tmp / "pyc"), "PYTHONDONTWRITEBYTECODE": ""}

    def go():
        shutil.rmtree(tmp / "out", ignore_errors=True)
        r = _cli_run(ROOT, tmp / "out", env, ("--no-cache",))
        return {"process_cpu_s": r["cpu_s"], "files": r["files"]}

    return go


def _diagnose_2000():
    from diagnose.api import run
    from diagnose.battery import scenario
    from primitives.ship import load_profile

    ship = load_profile("model-ship")
    rec = scenario(("current", "actuator_delay"), 7, n_prims=9).diagnose[0].window(0, 2001)

    def go():
        d = run([rec], ship)
        return {"findings": [f["effect"] for f in d.findings]}

    return go


def _diagnose_13x3500():
    from benchmarks.bench_diagnose import model_test
    from diagnose.api import run
    from primitives.ship import load_profile

    ship = load_profile("model-ship")
    recs = model_test()

    def go():
        d = run(recs, ship)
        return {"findings": [f["effect"] for f in d.findings]}

    return go


def _diagnose_mmg_case():
    """Issue 26/30's case shape on the MMG battery (tests/physics/mmg_battery.py, an independent
    truth): three diagnosed runs (2,090 samples), ``--fit-on`` the four calm runs (2,920), one
    validation run (581), the kvlcc2 profile with its declared [diagnosis] structure; the
    recordings written as CSV and read back as the CLI reads them (generation not timed)."""
    import tempfile

    from benchmarks.bench_diagnose_mmg import BASELINE
    from diagnose.api import run
    from diagnose.recording import load_recording
    from diagnose.recording_checks import conform
    from primitives.ship import load_profile
    from tests.physics.mmg_battery import case, generate, write_case

    prof = load_profile(BASELINE)
    with tempfile.TemporaryDirectory() as tmp:
        paths = write_case(generate(case("wind-18-gusty")), tmp)
        recs = {role: conform([r for p in ps for r in load_recording(p)], prof) for role, ps in paths.items()}

    def go():
        d = run(recs["diagnose"], prof, fit_on=recs["calm"], validate=recs["validate"][:1])
        return {"findings": [f["effect"] for f in d.findings]}

    return go


def _mass_example():
    """Issue 25's ``mass`` figure: the default method (oe) on the three datasets (nominal, calibration,
    loaded) of the bundled example (``shiptrial mass-sim DIR --case case1 --seed 3``), read from
    their CSVs by the ``mass`` command's library call (writing them is not timed)."""
    import contextlib
    import io
    import tempfile

    from cli.app import _run
    from identify.rollmass.api import estimate_from_files

    tmp = tempfile.TemporaryDirectory(prefix="bench_mass_")  # removed when the child exits
    out = Path(tmp.name) / "example"
    with contextlib.redirect_stdout(io.StringIO()):  # the child's stdout carries its JSON
        if _run(["mass-sim", str(out), "--case", "case1", "--seed", "3"]) != 0:
            raise RuntimeError("mass-sim failed")
    paths = [out / f"{role}.csv" for role in ("nominal", "calibration", "loaded")]

    def go(_keep=tmp):
        e = estimate_from_files(*paths)
        if not e.converged:
            raise RuntimeError(f"mass case did not converge: {e.warnings}")
        return {"m_kg": e.m, "zbar_m": e.zbar_m}

    return go


_DETECT_FILES = """
import sys
from pathlib import Path
from cli.app import _run
from diagnose.recording import write_csv
from identify.detect.api import simulated_recording
from identify.detect.vessel import Vessel
d = Path(sys.argv[1])
write_csv(simulated_recording(Vessel(), 500, seed=1, measured_moment=True), d / "nominal.csv")
run = simulated_recording(Vessel(), 500, seed=2, change_at_s=150, changed=Vessel(inertia=1.1), measured_moment=True)
write_csv(run, d / "run.csv")
sys.exit(_run(["detect-prior", str(d / "nominal.csv"), "--out", str(d / "prior.json")]))
"""


def _whole_process(prefix: str, prepare: str, argv: list[str], check: Callable[[str], bool], what: str):
    """A case timing one ``shiptrial`` command as a whole process (interpreter, imports, option parsing, the
    work, printing), warm: bytecode from a directory of the case's own and detect's noise cache in the case's
    own directory, both filled by the warm-up run. ``prepare`` (Python run once in a separate process, the
    case's directory as ``sys.argv[1]``) writes the command's input files; ``check`` reads its output.
    The case's time is the process's wall clock, ``process_cpu_s`` its user + system CPU."""
    import atexit
    import os
    import shutil
    import tempfile

    from benchmarks.bench_plan import timed_process

    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    atexit.register(shutil.rmtree, tmp, True)  # this case's child process ends after its runs
    env = dict(os.environ, PYTHONPATH=str(ROOT), SHIPTRIAL_DETECT_CACHE_DIR=str(tmp / "cache"))
    env |= {"PYTHONPYCACHEPREFIX": str(tmp / "pyc"), "PYTHONDONTWRITEBYTECODE": ""}
    subprocess.run([sys.executable, "-c", prepare, str(tmp)], cwd=ROOT, env=env, check=True, capture_output=True)
    cmd = [sys.executable, "-c", "from cli.app import main; main()", *argv]

    def go():
        with open(tmp / "out.txt", "wb") as out:
            r = timed_process(cmd, tmp, env, out)
        text = (tmp / "out.txt").read_text(errors="replace")
        if r["exit"] != 0 or not check(text):
            raise RuntimeError(f"{what}: {(text + r['stderr'])[-200:]}")
        return {"process_cpu_s": r["cpu_s"]}

    return go


def _detect_one():
    """Issue 25's ``detect`` figure: ``shiptrial detect run.csv --prior prior.json --profile naval-vessel`` as a
    whole process (:func:`_whole_process`; the stages inside it: ``benchmarks/bench_detect_stages.py``). The
    recording is README's example (500 s, a 10 % yaw-inertia change at 150 s, seed 2) against the prior of a
    nominal run (seed 1), both with the measured pod moment, written by another process (detect-prior's
    bootstrap loads numba, which a `detect` process does not load)."""
    argv = ["detect", "run.csv", "--prior", "prior.json", "--profile", "naval-vessel"]
    return _whole_process("bench-detect-", _DETECT_FILES, argv, lambda t: "CHANGED" in t, "detect failed or missed the change")


_MASS_FILES = """
import sys
from cli.app import _run
sys.exit(_run(["mass-sim", sys.argv[1] + "/ex", "--case", "case1", "--seed", "3"]))
"""


def _mass_command():
    """Issue 25's ``mass`` figure as a user meets it: ``shiptrial mass nominal.csv calibration.csv loaded.csv``
    (the default method, oe) on the bundled example's three datasets (``mass-sim DIR --case case1 --seed 3``,
    written by another process) as a whole process (:func:`_whole_process`)."""
    argv = ["mass", "ex/nominal.csv", "ex/calibration.csv", "ex/loaded.csv"]
    return _whole_process("bench-mass-", _MASS_FILES, argv, lambda t: "mass change" in t, "mass failed")


CASES = {
    "library_build": (_library_build, 2.0, None, ""),
    "monte_carlo_sim_500x1000": (_mc_sim, 2.0, None, ""),
    "design_convex_11": (_convex, 0.5, None, ""),
    "design_nonconvex_11": (_nonconvex, 1.0, None, ""),
    "monte_carlo_design_500": (_mc_design, 20.0, None, ""),
    "monte_carlo_2000x2_inline": (lambda: _mc_scaling(1), 20.0, None, "issue 14: reference for the speed-up"),
    "monte_carlo_2000x2_local2": (
        lambda: _mc_scaling(2),
        6.0,
        None,
        "issue 14: >= 1.8x faster than inline on 2 workers, same digest (compare the two cases)",
    ),
    "plan_thesis_scenario": (
        _plan_thesis,
        1.0,
        40.0,
        "thesis: plain A* about 40 s on a laptop (section 9.4); whole plan_trial call timed, search alone in search_s",
    ),
    "plan_5x5": (_plan_5x5, 30.0, None, "thesis: 19.25 M-state lattice, 'quite time-consuming'"),
    "plan_default_design": (
        _plan_design,
        2.0,
        None,
        "issue 12: whole plan_trial, design included (more in benchmarks/bench_plan.py)",
    ),
    "plan_trial_cli_no_cache": (
        _plan_cli_no_cache,
        2.0,
        None,
        "issue 30: the whole plan-trial --out DIR --no-cache process under 2 s warm (more in benchmarks/bench_plan.py)",
    ),
    "diagnose_2000": (_diagnose_2000, 2.0, None, "issue 13: under 2 s"),
    "diagnose_13x3500": (_diagnose_13x3500, 10.0, None, "issue 13: 13-run model test, 3,500 samples per run, under 10 s"),
    "diagnose_mmg_case": (
        _diagnose_mmg_case,
        10.0,
        None,
        "issues 26/30: one MMG battery case (wind-18-gusty), 3 runs + --fit-on (4 calm runs) + 1 validation run, under 10 s",
    ),
    "detect_one_recording": (
        _detect_one,
        1.0,
        None,
        "issue 25: the whole `shiptrial detect` process on one 500 s recording once the prior exists, under 1 s warm",
    ),
    "mass_3_datasets": (
        _mass_example,
        5.0,
        None,
        "issue 25: `mass` (oe) on the bundled example's three datasets (mass-sim case1 seed 3), under 5 s; "
        "its library call estimate_from_files, warm: the command's start-up, imports and printing not timed",
    ),
    "mass_one_command": (
        _mass_command,
        5.0,
        None,
        "issue 25: the whole `shiptrial mass` process on the bundled example's three datasets, under 5 s warm",
    ),
}


def run_case_here(name: str, repeat: int) -> dict:
    """Run one case in this process (the child side)."""
    factory = CASES[name][0]
    fn = factory()
    fn()  # warm-up
    times, cpu, extras = [], [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        r = fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)  # this process's CPU: on a loaded machine the steadier figure
        if isinstance(r, dict):
            extras.append(r)
    peak_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    extra = dict(extras[-1]) if extras else {}
    for k in extra:  # timings reported by the case itself: their median
        if k.endswith("_s") or k.endswith("_per_s"):
            extra[k] = statistics.median(e[k] for e in extras)
    return {"times_s": times, "cpu_s": cpu, "peak_mib": peak_kib / 1024.0, "extra": extra}


def run_case(name: str, repeat: int, timeout: float) -> dict:
    _, target, ref, ref_what = CASES[name]
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", name, "--repeat", str(repeat)]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    except subprocess.TimeoutExpired:
        return {"name": name, "error": f"timed out after {timeout:.0f} s", "target_s": target}
    if out.returncode != 0:
        err = (out.stderr.strip().splitlines() or ["failed"])[-1]
        return {"name": name, "error": err, "target_s": target}
    r = json.loads(out.stdout.strip().splitlines()[-1])
    med = statistics.median(r["times_s"])
    return {
        "name": name,
        "median_s": med,
        "min_s": min(r["times_s"]),
        "max_s": max(r["times_s"]),
        "cpu_median_s": statistics.median(r["cpu_s"]),
        "runs": len(r["times_s"]),
        "peak_mib": r["peak_mib"],
        "target_s": target,
        "ratio_to_target": med / target,
        "reference_s": ref,
        "ratio_to_reference": None if ref is None else med / ref,
        "reference": ref_what,
        **({"figures": r["extra"]} if r.get("extra") else {}),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--only", nargs="*", default=None, choices=list(CASES))
    ap.add_argument("--json", type=Path, default=None, help="write the figures to this JSON file")
    ap.add_argument("--compare", type=Path, default=None, help="an earlier results JSON to compare with")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per case")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        print(json.dumps(run_case_here(a.child, a.repeat)))
        return
    old = {}
    if a.compare and a.compare.exists():
        old = {c["name"]: c for c in json.loads(a.compare.read_text())["cases"]}
    results = []
    for name in a.only or list(CASES):
        r = run_case(name, a.repeat, a.timeout)
        if name in old and "median_s" in old[name] and "median_s" in r:
            r["ratio_to_previous"] = r["median_s"] / old[name]["median_s"]
        results.append(r)
        if "error" in r:
            print(f"{name:28s} ERROR {r['error']}")
            continue
        line = (
            f"{name:28s} median {r['median_s']:8.3f} s  [{r['min_s']:.3f} .. {r['max_s']:.3f}]  peak {r['peak_mib']:7.0f} MiB  "
            f"cpu {r['cpu_median_s']:.3f} s  target {r['target_s']:g} s (ratio {r['ratio_to_target']:.2f})"
        )
        if r["ratio_to_reference"] is not None:
            line += f"  vs reference {r['reference_s']:g} s: {r['ratio_to_reference']:.3f}"
        if "figures" in r:
            line += "  " + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in r["figures"].items())
        if "ratio_to_previous" in r:
            line += f"  vs previous {r['ratio_to_previous']:.2f}"
        print(line, flush=True)
    doc = {
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "processor": platform.processor(),
            "cpus": __import__("os").cpu_count(),
        },
        "date": time.strftime("%Y-%m-%d"),
        "repeat": a.repeat,
        "cases": results,
    }
    if a.json:
        _say_dropped(a.json, results)
        a.json.write_text(json.dumps(doc, indent=2) + "\n")
        print(f"wrote {a.json}")


def _say_dropped(path: Path, results: list[dict]) -> None:
    """Name the keys of ``path``'s cases the new file will not hold (added by hand, or a case not
    run): this script rewrites the file from its own runs; hand-made figures belong in a sibling
    file (benchmarks/results_issue30.json)."""
    if not path.exists():
        return
    new = {r["name"]: r for r in results}
    for c in json.loads(path.read_text()).get("cases", []):
        lost = ["(whole case)"] if c.get("name") not in new else sorted(set(c) - set(new[c["name"]]))
        if lost:
            print(f"note: {path} loses {c.get('name')}: {', '.join(lost)}")


if __name__ == "__main__":
    main()
