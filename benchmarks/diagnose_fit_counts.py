"""Where a diagnosis at issue 26's size spends its refits: per call site of ``diagnose.fitting.fit``,
its calls, Jacobians, CPU and simulated member-samples, and each fit's objective at every Jacobian.

Reads :mod:`benchmarks.bench_diagnose_size`'s recordings (``--data``, as that benchmark wrote them;
nothing is generated here), diagnoses one case once untimed (loads the compiled kernels), then
once counted. Member-samples (members simulated times samples) do not depend on the machine's
load, unlike CPU: issue 30's stop 50 found a refit crawling by them (docs/kernel-speed.md).

    PYTHONPATH=$PWD python -m benchmarks.diagnose_fit_counts --data DIR [--case thrust-loss-20]
"""

from __future__ import annotations

import argparse
import collections
import time
import traceback
from pathlib import Path

import numpy as np

import diagnose.fitting as fitting
import diagnose.model as dmodel
from benchmarks.bench_diagnose_size import build, diagnose

# the modules that call fit by the name they imported (wrapped there)
CALLERS = (
    "diagnose.baseline",
    "diagnose.search",
    "diagnose.magnitude",
    "diagnose.api",
    "diagnose.perrun",
    "diagnose.uncertainty",
)


def counted(case_paths: dict) -> tuple[dict, list, float, list[str]]:
    """Diagnose once with ``fit``, ``jacobian`` and ``simulate_many`` wrapped: (per call site
    [calls, Jacobians, CPU s, member-samples], per fit (site, objective at each Jacobian), CPU, named)."""
    import importlib

    stats: dict[str, list] = collections.defaultdict(lambda: [0, 0, 0.0, 0])
    fits: list[tuple[str, list[float]]] = []
    site: list[str] = []
    real_fit, real_jac, real_sim = fitting.fit, fitting.jacobian, dmodel.AugmentedModel.simulate_many

    def jac(*a, **k):
        out = real_jac(*a, **k)
        if site:
            stats[site[-1]][1] += 1
            fits[-1][1].append(float(out[0] @ out[0]))
        return out

    def sim(self, preps, P):
        if isinstance(P, list):
            n = sum(np.atleast_2d(q).shape[0] * len(p.y) for q, p in zip(P, preps))
        else:
            n = np.atleast_2d(P).shape[0] * sum(len(p.y) for p in preps)
        stats[site[-1] if site else "outside the refits"][3] += n
        return real_sim(self, preps, P)

    def fit(*a, **k):
        f = traceback.extract_stack(limit=2)[0]
        site.append(f"{Path(f.filename).name}:{f.lineno}")
        fits.append((site[-1], []))
        c = time.process_time()
        try:
            return real_fit(*a, **k)
        finally:
            stats[site[-1]][0] += 1
            stats[site[-1]][2] += time.process_time() - c
            site.pop()

    mods = [importlib.import_module(m) for m in CALLERS]
    fitting.jacobian, dmodel.AugmentedModel.simulate_many = jac, sim
    for m in mods:
        m.fit = fit
    try:
        c0 = time.process_time()
        d, _sizes = diagnose(case_paths, 1)
        cpu = time.process_time() - c0
    finally:
        fitting.jacobian, dmodel.AugmentedModel.simulate_many = real_jac, real_sim
        for m in mods:
            m.fit = real_fit
    return stats, fits, cpu, sorted(f["effect"] for f in d.findings)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="bench_diagnose_size's recordings (read only)")
    ap.add_argument("--case", default="thrust-loss-20", help="one battery case (default thrust-loss-20)")
    a = ap.parse_args(argv)
    paths = build(a.case, None, 3500, Path(a.data))
    diagnose(paths, 1)  # warm-up: loads the compiled kernels
    stats, fits, cpu, named = counted(paths)
    print(f"{a.case}: CPU {cpu:.2f} s (with the counters), named {', '.join(named) or 'nothing'}")
    for k, (n, j, c, ms) in sorted(stats.items(), key=lambda x: -x[1][3]):
        print(f"  {k:22s} fits {n:3d}  Jacobians {j:4d}  CPU {c:6.2f} s  member-samples {ms / 1e6:7.2f} M")
    total = [sum(v[i] for v in stats.values()) for i in (1, 3)]
    print(f"  {'all':22s}           Jacobians {total[0]:4d}                 member-samples {total[1] / 1e6:7.2f} M")
    for k, objective in fits:
        print(f"  {k}: {len(objective)} Jacobians, objective {' '.join(f'{v:.6g}' for v in objective)}")


if __name__ == "__main__":
    main()
