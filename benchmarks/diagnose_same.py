"""Whether two trees give the same diagnosis on issue 26's size of case, and at what CPU.

Diagnoses each case of :mod:`benchmarks.bench_diagnose_size`'s recordings (``--data``, as that
benchmark wrote them; nothing is generated here) as that benchmark does, and writes per case the
whole answer a user gets (``diagnose.report.to_json`` without its elapsed time, plus the final
parameter vector ``P`` and the baseline ``theta``) and the case's CPU time (``time.process_time``,
one warm process, an untimed warm-up case first). ``--against OTHER.json`` compares with another
tree's file (run this script with that tree first on ``PYTHONPATH``): every string and flag equal,
every number within ``--rtol`` (relative, with ``--atol`` for numbers near zero; 0: bit for bit), every
line of the printed report (``shiptrial diagnose``'s text) equal as a string.
Prints the largest difference per case and exits 1 when any case differs beyond the tolerance.

    PYTHONPATH=REF python -m benchmarks.diagnose_same --data DIR --out main.json   # REF: a checkout of main
    PYTHONPATH=$PWD python -m benchmarks.diagnose_same --data DIR --out new.json --against main.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from benchmarks.bench_diagnose_size import DEFAULT, build, diagnose


def answer(d) -> dict:
    """The diagnosis as the command's JSON report gives it, with P and theta, without timings, and
    its printed report line by line (``text``: compared as strings, so a tolerance on the numbers
    still says whether any printed digit moved)."""
    from diagnose.report import to_json, to_text
    from primitives.io import to_jsonable

    out = to_json(d, None)
    out.pop("elapsed_s", None)
    return out | to_jsonable({"P": d.P, "theta": d.theta}) | {"text": to_text(d).splitlines()}


def differences(a, b, rtol: float, atol: float, where: str = "") -> tuple[list[str], float]:
    """(paths where ``a`` and ``b`` differ beyond the tolerance, largest relative difference of any number)."""
    if isinstance(a, dict) and isinstance(b, dict):
        bad, worst = ([f"{where}: keys {sorted(set(a) ^ set(b))}"] if set(a) != set(b) else []), 0.0
        for k in sorted(set(a) & set(b)):
            x, w = differences(a[k], b[k], rtol, atol, f"{where}.{k}")
            bad, worst = bad + x, max(worst, w)
        return bad, worst
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} against {len(b)} items"], 0.0
        bad, worst = [], 0.0
        for i, (x, y) in enumerate(zip(a, b)):
            p, w = differences(x, y, rtol, atol, f"{where}[{i}]")
            bad, worst = bad + p, max(worst, w)
        return bad, worst
    num = (int, float)
    if isinstance(a, num) and isinstance(b, num) and not isinstance(a, bool) and not isinstance(b, bool):
        if a == b or (math.isnan(a) and math.isnan(b)):
            return [], 0.0
        rel = abs(a - b) / max(abs(a), abs(b))
        ok = abs(a - b) <= rtol * max(abs(a), abs(b)) + atol
        return ([] if ok else [f"{where}: {a!r} against {b!r}"]), rel
    return ([] if a == b else [f"{where}: {a!r} against {b!r}"]), 0.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="bench_diagnose_size's recordings (read only)")
    ap.add_argument("--cases", default=DEFAULT, help="comma-separated cases (default: the issue's ten)")
    ap.add_argument("--out", required=True, help="write the answers and CPU times here (JSON)")
    ap.add_argument("--against", default="", help="another tree's --out file to compare with")
    ap.add_argument("--rtol", type=float, default=0.0, help="relative tolerance of a number (0: bit for bit)")
    ap.add_argument("--atol", type=float, default=0.0, help="absolute tolerance of a number")
    a = ap.parse_args(argv)
    names = [n for n in a.cases.split(",") if n]
    built = {n: build(n, None, 3500, Path(a.data)) for n in names}
    diagnose(built[names[0]], 1)  # warm-up: loads the compiled kernels
    rows = {}
    for n in names:
        c0 = time.process_time()
        d, _sizes = diagnose(built[n], 1)
        cpu = time.process_time() - c0
        rows[n] = {"cpu_s": cpu, "answer": answer(d)}
        print(f"{n:24s} CPU {cpu:6.2f} s, named {', '.join(sorted(f['effect'] for f in d.findings)) or 'nothing'}", flush=True)
    Path(a.out).write_text(json.dumps(rows, indent=1), encoding="utf-8")
    if not a.against:
        return 0
    other = json.loads(Path(a.against).read_text(encoding="utf-8"))
    failed = False
    for n in names:
        if n not in other:
            print(f"{n:24s} not in {a.against}")
            failed = True
            continue
        bad, worst = differences(rows[n]["answer"], other[n]["answer"], a.rtol, a.atol)
        same = "bit for bit" if worst == 0.0 and not bad else f"largest relative difference {worst:.3g}"
        print(f"{n:24s} CPU {other[n]['cpu_s']:6.2f} -> {rows[n]['cpu_s']:6.2f} s; {same}; {len(bad)} beyond tolerance")
        for line in bad[:10]:
            print("   ", line)
        failed |= bool(bad)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
