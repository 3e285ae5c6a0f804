"""The time of ``Plan.to_json`` on a saved plan (stop 61): the median of 20 calls in one process, wall and CPU.

python benchmarks/time_plan_json.py DIR/plan.json
cp benchmarks/time_plan_json.py /tmp/ && PYTHONPATH=REF python /tmp/time_plan_json.py DIR/plan.json   # another
    checkout REF (main): the script puts its own tree first on sys.path, so run a copy from outside any tree
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from maps.plan import Plan  # noqa: E402


def main() -> None:
    plan = Plan.load(sys.argv[1])
    plan.to_json()  # the first call's imports are not the serialisation's
    wall, cpu = [], []
    for _ in range(20):
        t0, c0 = time.perf_counter(), time.process_time()
        plan.to_json()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    print(
        f"{sys.argv[1]}: to_json median {1000 * statistics.median(wall):.1f} ms wall, "
        f"{1000 * statistics.median(cpu):.1f} ms CPU (20 calls)"
    )


if __name__ == "__main__":
    main()
