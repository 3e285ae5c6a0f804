"""The compiled simulation kernel in isolation on a diagnosis's own calls (issue 30: "a kernel an
order of magnitude faster"): CPU per member-step of ``primitives.jitloop.time_loop`` (and of the
forward-sensitivity loop ``primitives.jitsens._sens_loop``) replayed on every call one diagnosis of
an MMG KVLCC2 battery case made, and whether the outputs are byte for byte those recorded.

``record`` diagnoses one case of ``benchmarks.bench_diagnose_size`` (its CSVs read from ``--data``)
and pickles every compiled kernel call's inputs and outputs (1-2 GB for a 3,500-sample case);
``replay`` calls the kernel of the checkout on ``PYTHONPATH`` on those inputs ``--repeat`` times
(after one untimed call of each kernel: loading or compiling), prints the median CPU
(``time.process_time`` around each call only) and compares every output with the recorded bytes.
Record with one checkout and replay with two, alternately, for paired figures.

    python -m benchmarks.bench_kernel record --case thrust-loss-20 --data DIR --out calls.pkl
    python -m benchmarks.bench_kernel replay calls.pkl [--repeat 3]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import pickle
import statistics
import sys
import time
from pathlib import Path

import numpy as np

# the output arrays of each recorded kernel (argument positions, filled in place)
OUTPUTS = {"time_loop": (1, 2), "sens": (16,)}


def _kernels() -> dict:
    from primitives import jitloop, jitsens

    return {"time_loop": jitloop.time_loop, "sens": jitsens._sens_loop}


def record(case: str, data: str, out: str) -> None:
    """Diagnose ``case`` with every compiled kernel call's inputs and outputs kept, then pickle them."""
    import importlib.util

    from benchmarks.bench_diagnose_size import build, diagnose
    from primitives import jitloop, jitsens

    calls: list = []

    def keeping(name, fn):
        def call(*args):
            before = [np.array(a, copy=True) if isinstance(a, np.ndarray) else a for a in args]
            fn(*args)
            calls.append((name, before, [np.array(args[i], copy=True) for i in OUTPUTS[name]]))

        return call

    loop = keeping("time_loop", jitloop.time_loop)
    jitloop.time_loop = loop
    if importlib.util.find_spec("primitives.jittime") is not None:  # where the loop lives since stop 41
        importlib.import_module("primitives.jittime").time_loop = loop
    jitsens._sens_loop = keeping("sens", jitsens._sens_loop)
    d, _ = diagnose(build(case, None, 3500, Path(data)), 1, 4)
    tmp = f"{out}.part"  # a recording cut short (disk full, interrupted) never stands as a whole one
    with open(tmp, "wb") as f:
        pickle.dump(calls, f, protocol=5)
    os.replace(tmp, out)
    print(f"{case}: named {sorted(x['effect'] for x in d.findings)}; {len(calls)} kernel calls written to {out}")


def _member_steps(name: str, args: list) -> int:
    return (args[1].shape[0] - 1) * args[1].shape[2] if name == "time_loop" else args[0].shape[0] - 1


def replay(path: str, repeat: int) -> dict:
    """Median CPU of each kernel over ``repeat`` passes over the recorded calls; outputs compared."""
    from primitives import jitloop

    with open(path, "rb") as f:
        calls = pickle.load(f)
    jitloop.use(jitloop.MIN_WORK)
    kernels = _kernels()
    c0 = time.process_time()
    for kind in kernels:  # load (or compile) each kernel once, untimed
        first = next((a for n, a, _o in calls if n == kind), None)
        if first is not None:
            kernels[kind](*[x.copy() if isinstance(x, np.ndarray) else x for x in first])
    load_s = time.process_time() - c0
    cpu = {k: [] for k in kernels}
    steps = dict.fromkeys(kernels, 0)
    digest, same = hashlib.sha256(), True
    for rep in range(repeat):
        tot = dict.fromkeys(kernels, 0.0)
        for name, args, outs in calls:
            a = [x.copy() if isinstance(x, np.ndarray) else x for x in args]
            t0 = time.process_time()
            kernels[name](*a)
            tot[name] += time.process_time() - t0
            if rep == 0:
                steps[name] += _member_steps(name, args)
                for i, want in zip(OUTPUTS[name], outs):
                    digest.update(a[i].tobytes())
                    same = same and a[i].tobytes() == want.tobytes()
        for k in kernels:
            cpu[k].append(tot[k])
    for k in kernels:
        m = statistics.median(cpu[k])
        print(
            f"{k}: CPU median {m:.3f} s over {repeat} passes ({', '.join(f'{x:.3f}' for x in cpu[k])}), "
            f"{steps[k] / 1e6:.2f} M {'member-steps' if k == 'time_loop' else 'steps'}, "
            f"{1e9 * m / max(steps[k], 1):.1f} ns each"
        )
    print(
        f"outputs byte-identical to the recording: {same}; sha256 {digest.hexdigest()[:16]}; first calls (load/compile) "
        f"{load_s:.2f} s CPU; load average {os.getloadavg()[0]:.1f}"
    )
    return {"cpu": cpu, "steps": steps, "same": same}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record", help="diagnose one case and keep its kernel calls")
    r.add_argument("--case", default="thrust-loss-20")
    r.add_argument("--data", required=True, help="the recordings of benchmarks.bench_diagnose_size --data")
    r.add_argument("--out", required=True)
    p = sub.add_parser("replay", help="time the kernels on recorded calls and compare their outputs")
    p.add_argument("calls")
    p.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    if a.cmd == "record":
        record(a.case, a.data, a.out)
    else:
        res = replay(a.calls, a.repeat)
        sys.exit(0 if res["same"] else 1)


if __name__ == "__main__":
    main()
