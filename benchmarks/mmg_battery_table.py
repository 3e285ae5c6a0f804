"""The MMG battery over noise seeds as one table (issue 26): per case x seed right/wrong, the
coverage of the findings' 95 % intervals (estimate +- 1.96 reported std holding the battery's
true value) and the diagnosis wall and CPU time per case, from the ``--json`` files of
``benchmarks.bench_diagnose_mmg --seeds ...`` runs (one or several, e.g. chunks of cases).

    python -m benchmarks.mmg_battery_table run1.json [run2.json ...]
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict

import numpy as np

from benchmarks.bench_diagnose_mmg import z_scores

Z95 = 1.96


def table(rows: list[dict]) -> str:
    """The per-case x seed table, the 95 % coverage and the times, as text."""
    by_case: dict[str, dict[int, dict]] = defaultdict(dict)
    for r in rows:
        m = re.fullmatch(r"(.+)-seed(\d+)", r["case"])
        name, seed = (m.group(1), int(m.group(2))) if m else (r["case"], 0)
        by_case[name][seed] = r
    seeds = sorted({s for c in by_case.values() for s in c})
    head = (
        f"{'case':24s} "
        + " ".join(f"{'s' + str(s):>5s}" for s in seeds)
        + "   right  in 95 %  held-out fit change surge/sway/yaw (points)  wall s (median)  CPU s (median)"
    )
    lines = [head]
    zs_all, zs_wind, zs_rest, walls, cpus = [], [], [], [], []
    for name, runs in by_case.items():
        cells = " ".join(f"{('hit' if runs[s]['hit'] else 'MISS') if s in runs else '-':>5s}" for s in seeds)
        # recomputed from each row's truth and findings: every estimate with a reported std
        zs = [abs(v) for r in runs.values() for v in z_scores(r["truth"], r["findings"]).values()]
        zs_all += zs
        (zs_wind if name.startswith(("wind", "model-wind")) else zs_rest).extend(zs)
        cov = f"{sum(z < Z95 for z in zs)}/{len(zs)}" if zs else "-"
        w = [r["diagnose_s"] for r in runs.values()]
        c = [r["cpu_s"] for r in runs.values()]
        walls += w
        cpus += c
        hits = sum(r["hit"] for r in runs.values())
        ho = _heldout_change(list(runs.values()))
        lines.append(f"{name:24s} {cells}   {hits}/{len(runs):<4d} {cov:>7s}  {ho:>43s}  {np.median(w):14.1f}  {np.median(c):14.1f}")
    hits = sum(r["hit"] for r in rows)
    lines.append(f"right {hits}/{len(rows)} ({100 * hits / max(len(rows), 1):.0f} %)")
    for label, zs in (("all", zs_all), ("wind scales (truth: Isherwood, estimator: Blendermann)", zs_wind), ("the others", zs_rest)):
        if zs:
            n_in = sum(z < Z95 for z in zs)
            lines.append(f"95 % intervals holding the true value, {label}: {n_in}/{len(zs)} ({100 * n_in / len(zs):.0f} %)")
    lines.append(
        "(estimates with a reported std: delay, current speed, offset, thrust loss, bias, damping value, wind scale per DOF)"
    )
    lines.append(
        f"diagnosis wall per case: median {np.median(walls):.1f} s, max {np.max(walls):.1f} s; "
        f"CPU per case (generation + diagnosis): median {np.median(cpus):.1f} s, max {np.max(cpus):.1f} s"
    )
    return "\n".join(lines)


def _heldout_change(rows: list[dict]) -> str:
    """Mean change of the validation runs' fit per channel after the diagnosis, over runs and seeds."""
    d = [
        [pr["after"][ch] - pr["before"][ch] for ch in ("surge", "sway", "yaw")]
        for r in rows
        for pr in r.get("per_run") or []
        if pr.get("role") == "validation" and pr.get("after") and pr.get("before")
    ]
    return "/".join(f"{x:+.1f}" for x in np.mean(d, axis=0)) if d else "-"


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json", nargs="+", help="--json outputs of benchmarks.bench_diagnose_mmg")
    a = ap.parse_args(argv)
    rows = [r for p in a.json for r in json.load(open(p, encoding="utf-8"))["rows"]]
    text = table(rows)
    print(text)
    return text


if __name__ == "__main__":
    main()
