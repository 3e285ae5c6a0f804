"""Monte Carlo of Linder et al. (2015) Table 3: mass and CoG height from roll, ours beside the paper's.

Simulated basin experiment of the 1:24 Our Lass II model (identify/rollmass/our_lass_ii.toml) with
the Xsens MTi-G noise and biases as the realistic IMU case, for each Table 2 case and each
estimator (the paper's LS and IV, our refined IV 'improved' and our output-error 'oe'). Prints
median and 90th-percentile absolute errors of the mass [%] and the CoG height [mm] over the noise
seeds, and how many fits failed.

    python benchmarks/bench_rollmass.py --seeds 50 --methods ls,paper-iv,oe   # realistic: Xsens MTi-G, basin reflections
    python benchmarks/bench_rollmass.py --seeds 10 --methods oe --length 3 --cases case1   # 3x longer runs
    python benchmarks/bench_rollmass.py --seeds 50 --waves 10   # rough-water stress case
    python benchmarks/bench_rollmass.py --seeds 50 --noise 0.3  # a 3x better IMU
    python benchmarks/bench_rollmass.py --cpu 3   # CPU of one fit and of the `mass` command, the bundled example

``--cpu N`` times the default fit (oe) on the bundled example (``shiptrial mass-sim DIR --case case1
--seed 3``): N fits in this process (CPU each, ``time.process_time``) and N runs of the whole
``mass`` command in a fresh interpreter (its CPU, user + system, imports included), medians printed.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # run as a script from a checkout: its own code, not an installed one
    sys.path.insert(0, str(ROOT))

from identify.rollmass.estimate import METHODS, estimate  # noqa: E402
from identify.rollmass.model import load_profile  # noqa: E402
from identify.rollmass.output_error import start_values  # noqa: E402
from identify.rollmass.simulate import Noise, simulate_case  # noqa: E402

# Table 3 (IV) and Table 4 (LS) of the paper: relative errors of m and zbar_m, in %.
PAPER = {
    "case1": {"paper-iv": (0.1338, 1.2120), "ls": (71.282, 152.88)},
    "case2": {"paper-iv": (7.7532, 9.4842), "ls": (115.05, 54.455)},
    "case3": {"paper-iv": (16.631, 0.3286), "ls": (39.501, 31.866)},
}


def _start(prof, seed: int, pert: float) -> dict[str, float]:
    """The oe start values: the profile's, each scaled by (1 + pert N(0,1)) drawn from the seed,
    so the benchmark does not start our estimator at the simulation's truth."""
    rng = np.random.default_rng(10_000 + seed)
    return {k: v * (1 + pert * rng.standard_normal()) for k, v in start_values(prof).items()}


def _one(job: tuple) -> list[tuple]:
    case, seed, waves, noise_scale, length, methods, pert = job
    prof = load_profile()
    for k in ("wave_roll_sd", "wave_sway_sd", "wave_yaw_sd"):
        prof.raw["experiment"][k] *= waves
    ds = simulate_case(prof, case, Noise.from_profile(prof, noise_scale), seed, length_factor=length)
    truth = next((d["load_kg"], d["load_height"]) for d in prof.raw["dataset"] if d["name"] == ds[2].name)
    out = []
    for method in methods:
        c0 = time.process_time()
        try:
            e = estimate(ds, prof.known, ds[1].load, method, start=_start(prof, seed, pert))
            ok = e.converged and np.isfinite(e.m) and np.isfinite(e.zbar_m)
            mz_true = truth[0] * (truth[1] + prof.truth.z_f)
            mz = e.m * (e.zbar_m + e.params["z_f"])
            out.append(
                (
                    case,
                    method,
                    seed,
                    100 * abs(e.m / truth[0] - 1) if ok else np.nan,
                    1000 * abs(e.zbar_m - truth[1]) if ok else np.nan,
                    100 * abs(mz / mz_true - 1) if ok else np.nan,
                    time.process_time() - c0,
                )
            )
        except Exception:  # a diverged fit is counted as a failure, never as a number
            out.append((case, method, seed, np.nan, np.nan, np.nan, time.process_time() - c0))
    return out


def cpu_example(repeats: int) -> None:
    """Median CPU of the default fit and of the whole ``mass`` command on the bundled example."""
    cli = [sys.executable, "-c", "from cli.app import main; main()"]
    with tempfile.TemporaryDirectory() as d:
        subprocess.run([*cli, "mass-sim", d, "--case", "case1", "--seed", "3"], check=True, capture_output=True, cwd=ROOT)
        files = [f"{d}/{r}.csv" for r in ("nominal", "calibration", "loaded")]
        fits = []
        from identify.rollmass.api import estimate_from_files

        for _ in range(repeats):
            c0 = time.process_time()
            e = estimate_from_files(*files, known_load="0.2@-0.256")
            fits.append(time.process_time() - c0)
        cmd = [*cli, "mass", *files, "--known-load", "0.2@-0.256"]
        runs = []
        for _ in range(repeats):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            runs.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    print(f"bundled example (mass-sim case1 seed 3), oe: m {e.m:.4f} kg, z {e.zbar_m:+.4f} m")
    print(f"fit (estimate_from_files): median {statistics.median(fits):.2f} s cpu of {', '.join(f'{t:.2f}' for t in fits)}")
    print(f"`mass` command, whole process: median {statistics.median(runs):.2f} s cpu of {', '.join(f'{t:.2f}' for t in runs)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--waves", type=float, default=1.0, help="scale of the profile's wave disturbance")
    ap.add_argument("--noise", type=float, default=1.0, help="scale of the Xsens MTi-G noise and biases")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--length", type=float, default=1.0, help="run length as a multiple of the paper's (Table 2 sample counts)")
    ap.add_argument("--methods", default=",".join(METHODS), help=f"comma-separated subset of {','.join(METHODS)}")
    ap.add_argument("--cases", default="case1,case2,case3", help="comma-separated Table 2 cases")
    ap.add_argument("--start-pert", type=float, default=0.2, help="relative random error of the oe start values")
    ap.add_argument("--progress", action="store_true", help="print a line per finished case-seed")
    ap.add_argument(
        "--cpu", type=int, default=0, metavar="N", help="time N fits and N mass commands on the bundled example, nothing else"
    )
    a = ap.parse_args()
    if a.cpu:
        cpu_example(a.cpu)
        return
    prof = load_profile()
    imu = prof.raw["imu"]
    print(
        f"IMU: Xsens MTi-G x{a.noise:g}: gyro {imu['gyro_density_deg'] * a.noise:g} deg/s/rtHz, bias sd {imu['gyro_bias_deg'] * a.noise:g} deg/s; "
        f"accelerometer {imu['acc_density'] * a.noise:g} m/s^2/rtHz, bias sd {imu['acc_bias'] * a.noise:g} m/s^2"
    )
    ex = prof.raw["experiment"]
    print(
        f"waves x{a.waves:g}: roll moment sd {ex['wave_roll_sd'] * a.waves:g} N m, sway {ex['wave_sway_sd'] * a.waves:g} N, "
        f"yaw {ex['wave_yaw_sd'] * a.waves:g} N m at {ex['wave_freq_hz']:g} Hz; {a.seeds} seeds"
    )
    methods, cases = tuple(a.methods.split(",")), tuple(a.cases.split(","))
    if not set(cases) <= set(prof.raw["cases"]):
        ap.error(f"--cases: choose from {','.join(prof.raw['cases'])}")
    if not set(methods) <= set(METHODS):
        ap.error(f"--methods: choose from {','.join(METHODS)}")
    n = {d["name"]: int(d["samples"] * a.length) for d in prof.raw["dataset"]}
    print(
        f"run length x{a.length:g} of the paper's: "
        + ", ".join(f"{k} {v} samples ({v * 0.02:.0f} s)" for k, v in n.items())
        + f"; oe start values: profile x (1 + {a.start_pert:g} N(0,1))"
    )
    # seed-major order, so an interrupted run still covers the three cases evenly (--progress rows)
    jobs = [(c, s, a.waves, a.noise, a.length, methods, a.start_pert) for s in range(a.seeds) for c in cases]
    t0 = time.perf_counter()
    rows, cpu = [], 0.0
    with Pool(a.workers) as pool:
        for i, part in enumerate(pool.imap_unordered(_one, jobs), 1):
            rows += [r[:6] for r in part]
            cpu += sum(r[6] for r in part)
            if a.progress:
                print(
                    f"  {i}/{len(jobs)} case-seeds, {time.perf_counter() - t0:.0f} s: "
                    + "; ".join(f"{r[0]} {r[1]} seed {r[2]} m {r[3]:.2f} % z {r[4]:.1f} mm" for r in part),
                    flush=True,
                )
    print(f"{len(jobs)} case-seeds in {time.perf_counter() - t0:.0f} s wall, {cpu:.0f} s cpu in the workers\n")
    print(
        f"{'case':6} {'method':9} | {'paper m %':>9} {'paper z %':>9} | {'m med %':>8} {'m p90 %':>8} {'z med mm':>8} {'z p90 mm':>8} "
        f"{'mz med %':>8} {'mz p90 %':>8} {'failed':>6}"
    )
    for case in cases:
        for method in methods:
            e = np.array([r[3:] for r in rows if r[0] == case and r[1] == method])
            good = e[np.all(np.isfinite(e), axis=1)]
            pm, pz = PAPER[case].get(method, (np.nan, np.nan))
            med = np.median(good, axis=0) if len(good) else np.full(3, np.nan)
            p90 = np.percentile(good, 90, axis=0) if len(good) else np.full(3, np.nan)
            print(
                f"{case:6} {method:9} | {pm:9.3g} {pz:9.3g} | {med[0]:8.2f} {p90[0]:8.2f} {med[1]:8.1f} {p90[1]:8.1f} "
                f"{med[2]:8.2f} {p90[2]:8.2f} {len(e) - len(good):6d}"
            )
    print(
        "\npaper: one real dataset per case (no spread); its z error is relative (%), ours absolute (mm);"
        "\nmz = m (zbar_m + z_f), the load's moment about the CR, which the roll data determine best."
    )


if __name__ == "__main__":
    main()
