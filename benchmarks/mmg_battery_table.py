"""The MMG battery over noise seeds as one table (issue 26): per case x seed right/wrong, the
coverage of the findings' 95 % intervals (estimate +- the reported half-width ``<std>_95``, a
Student-t quantile at the interval parts' degrees of freedom, or +- 1.96 reported std in files
without it, holding the battery's true value; their median half-width in per cent of the true value
is shown per case; a concealed magnitude that is not estimated, has no std or sits in an ERROR row counts
as not covered, and every magnitude of a finding that was not concealed is scored against a true
value of 0) and the diagnosis wall and CPU time per case, from the ``--json`` files of
``benchmarks.bench_diagnose_mmg --seeds ...`` runs (one or several, e.g. chunks of cases).

    python -m benchmarks.mmg_battery_table run1.json [run2.json ...]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections import Counter, defaultdict

import numpy as np

from benchmarks.bench_diagnose_mmg import PARTS as PARTS_KEY
from benchmarks.bench_diagnose_mmg import STD_KEY, _num, full_scale_truth
from diagnose.describe import includes_no_effect

Z95 = 1.96
# the parts of the reported std scored: the total, noise with run-to-run misfit (the interval
# before the --fit-on misfit term was added), the noise alone
PARTS = {
    "": "whole interval",
    "_before": "whole interval without the held-out runs' part",
    "_runs": "noise and run-to-run part",
    "_noise": "noise part",
}
OUTCOMES = ("in", "out", "no estimate", "no std", "error", "spurious in", "spurious out")
NOT_COVERED = ("out", "no estimate", "no std", "error", "spurious out")
# magnitudes shown apart, never counted in a coverage figure: the wind's mean yaw acceleration is
# near zero by cancellation (the yaw moment changes sign with the relative wind's side over a
# run's headings: 5e-7 to 1e-6 rad/s^2 at full scale, 0.13 and 0.35 of its rms over the diagnosed
# runs on seed 1 of wind-18-gusty and wind-18, where surge's and sway's means are 0.64 to 0.83 of
# theirs), so an error relative to it, or a 95 % interval's hold on it, says little about how
# well the yaw moment was measured
APART = {"wind_accel_yaw": "a mean near zero by cancellation over the headings, not counted in the figures above"}


def _score(est: float | None, sd: float | None, true: float, deg: bool = False, half: float | None = None) -> str:
    """In or out of the 95 % interval: the reported half-width ``half`` (``<std>_95``, Student-t at
    the interval parts' degrees of freedom) when given, else ``Z95`` stds."""
    if est is None:
        return "no estimate"
    if not sd or not math.isfinite(sd):
        return "no std"
    # the tool's half-width is never below Z95 printed stds (files written before it said so: the same rule here)
    width = max(half, Z95 * sd) if half is not None and math.isfinite(half) else Z95 * sd
    return "in" if abs(est - true) < (math.degrees(width) if deg else width) else "out"


def _half_of(p: dict, key: str, part: str = "") -> float | None:
    """The reported 95 % half-width of ``key`` (the whole interval, or without the held-out runs'
    part for ``part`` "_before", then the whole one when that part was not measured; None for the
    other parts or when absent)."""
    name = f"{key}_std" if key.startswith("wind_") else STD_KEY.get(key, f"{key}_std")
    if part == "_before":
        return _num(p.get(name + "_95" + part, p.get(name + "_95")))
    return _num(p.get(name + "_95")) if part == "" else None


def _matches(f: dict, checks: dict) -> bool:
    """The finding is the concealed effect's: its name-like checks (dof, term, signal) agree."""
    p = {**(f.get("parameters") or {}), "dof": f.get("dof")}
    return all(p.get(k) == spec[0] for k, spec in checks.items() if len(spec) > 2 and spec[2] == "equal")


def _magnitudes(checks: dict) -> list[tuple[str, float]]:
    """(key, true value) of every checked magnitude that has a std key (the wind: one per DOF but
    those shown :data:`APART`)."""
    out = []
    for key, spec in checks.items():
        if key == "wind":
            out += [(k, v) for k, v in spec[0].items() if k not in APART]
        elif key in STD_KEY and isinstance(spec[0], int | float):
            out.append((key, float(spec[0])))
    return out


def _std_of(p: dict, key: str, part: str = "") -> float | None:
    """The reported std of ``key``; ``part`` "_runs": its noise and run-to-run part alone (the
    interval before the --fit-on misfit term; the total when that term was not measured),
    "_noise": its noise part."""
    name = f"{key}_std" if key.startswith("wind_") else STD_KEY[key]
    return _num(p.get(name + part, p.get(name) if part in ("_runs", "_before") else None))


def coverage(row: dict, part: str = "") -> Counter:
    """Outcome counts (OUTCOMES) of one battery row's 95 % intervals: each concealed magnitude
    is in, out, not estimated (a miss or a wrong effect), without a std, or in an ERROR row; each
    magnitude of a finding that is not the concealed effect's is scored against 0 (spurious)."""
    checks = {e: c for e, c in full_scale_truth(row["truth"])["checks"].items() if e != "weights"}
    if row.get("error") or row.get("findings") is None:
        return Counter({"error": sum(len(_magnitudes(c)) for c in checks.values()) or 1})
    out: Counter = Counter()
    used: set[int] = set()
    for eff, chk in checks.items():
        i = next((i for i, f in enumerate(row["findings"]) if f.get("effect") == eff and _matches(f, chk)), None)
        p = row["findings"][i].get("parameters") or {} if i is not None else {}
        if i is not None:
            used.add(i)
        for key, true in _magnitudes(chk):
            out[_score(_num(p.get(key)), _std_of(p, key, part), true, key == "offset_deg", _half_of(p, key, part))] += 1
    for i, f in enumerate(row["findings"]):
        if i in used:
            continue
        p = f.get("parameters") or {}
        keys = [
            k
            for k in p
            if (k in STD_KEY or k.startswith("wind_accel_") and "_std" not in k) and k not in APART and _num(p[k]) is not None
        ]
        for key in keys or ["-"]:
            s = (
                "no std"
                if key == "-"
                else _score(_num(p.get(key)), _std_of(p, key, part), 0.0, key == "offset_deg", _half_of(p, key, part))
            )
            out[s if s == "no std" else f"spurious {s}"] += 1
    return out


def half_widths(row: dict, part: str = "") -> list[float]:
    """The 95 % half-width of each concealed magnitude the row estimated, in per cent of its true
    value (``part`` "_before": without the held-out runs' part)."""
    checks = {e: c for e, c in full_scale_truth(row["truth"])["checks"].items() if e != "weights"}
    out = []
    for eff, chk in checks.items():
        f = next((f for f in row.get("findings") or [] if f.get("effect") == eff and _matches(f, chk)), None)
        p = (f or {}).get("parameters") or {}
        for key, true in _magnitudes(chk):
            sd, half = _std_of(p, key, part), _half_of(p, key, part)
            width = max(half, Z95 * sd) if half is not None and sd else (Z95 * sd if sd else None)
            if width is not None and true:
                out.append(100.0 * (math.degrees(width) if key == "offset_deg" else width) / abs(true))
    return out


def wind_by_dof(rows: list[dict]) -> str:
    """Coverage of the concealed wind's mean acceleration per DOF (whole interval), over the rows;
    a DOF shown :data:`APART` says why it is not counted elsewhere."""
    hit: Counter = Counter()
    n: Counter = Counter()
    for row in rows:
        chk = full_scale_truth(row["truth"])["checks"].get("wind", {}).get("wind")
        if not chk or row.get("error"):
            continue
        f = next((f for f in row.get("findings") or [] if f.get("effect") == "wind"), None)
        p = (f or {}).get("parameters") or {}
        for key, true in chk[0].items():
            n[key] += 1
            hit[key] += _score(_num(p.get(key)), _std_of(p, key), true, half=_half_of(p, key)) == "in"
    return ", ".join(f"{k.removeprefix('wind_accel_')} {hit[k]}/{n[k]}" + (f" ({APART[k]})" if k in APART else "") for k in n)


def _coverage_text(c: Counter) -> str:
    n = sum(c.values())
    parts = ", ".join(f"{k} {c[k]}" for k in OUTCOMES if c[k])
    return f"{c['in'] + c['spurious in']}/{n} ({100 * (c['in'] + c['spurious in']) / max(n, 1):.0f} %; {parts})"


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
        + "   right  in 95 % (before)  width % (before)  held-out fit change surge/sway/yaw (points)  wall s (median)  CPU s (median)"
    )
    lines = [head]
    groups = {g: {part: Counter() for part in PARTS} for g in ("all", "wind", "rest")}
    walls, cpus, flips = [], [], []
    for name, runs in by_case.items():
        cells = " ".join(f"{('hit' if runs[s]['hit'] else 'MISS') if s in runs else '-':>5s}" for s in seeds)
        # recomputed from each row's truth and findings; misses, errors and spurious findings count
        per = {part: sum((coverage(r, part) for r in runs.values()), Counter()) for part in PARTS}
        for part in PARTS:
            groups["all"][part] += per[part]
            groups["wind" if name.startswith(("wind", "model-wind")) else "rest"][part] += per[part]
        c, c0 = per[""], per["_before"]
        flips += [f"{r['case']} {f['effect']}" for r in runs.values() for f in r.get("findings") or [] if includes_no_effect(f)]
        n = sum(c.values())
        cov = f"{c['in'] + c['spurious in']}/{n}" if n else "-"
        hw, hb = ([h for r in runs.values() for h in half_widths(r, part)] for part in ("", "_before"))
        width = f"{np.median(hw):.1f} ({np.median(hb):.1f})" if hw else "-"
        cov += f" ({c0['in'] + c0['spurious in']})" if n else ""
        w = [r["diagnose_s"] for r in runs.values()]
        cpu = [r["cpu_s"] for r in runs.values()]
        walls += w
        cpus += cpu
        hits = sum(r["hit"] for r in runs.values())
        ho = _heldout_change(list(runs.values()))
        lines.append(
            f"{name:24s} {cells}   {hits}/{len(runs):<4d} {cov:>15s}  {width:>16s}  {ho:>43s}  {np.median(w):14.1f}  {np.median(cpu):14.1f}"
        )
    hits = sum(r["hit"] for r in rows)
    lines.append(f"right {hits}/{len(rows)} ({100 * hits / max(len(rows), 1):.0f} %)")
    for g, label in (
        ("all", "all"),
        ("wind", "wind's mean acceleration in surge and sway (truth: Isherwood, estimator: Blendermann)"),
        ("rest", "the others"),
    ):
        for part, what in PARTS.items():
            if groups[g][part]:
                lines.append(f"95 % intervals holding the true value, {label}, {what}: {_coverage_text(groups[g][part])}")
    if any(r["truth"].get("concealed") == "wind" for r in rows):
        lines.append(f"the wind's mean acceleration inside its 95 % interval, per DOF: {wind_by_dof(rows)}")
    lines.append(
        "named findings whose reported 95 % interval includes no effect (named because a held-out run confirms "
        f"them; their size not resolved): {len(flips)}" + (f" ({', '.join(flips)})" if flips else "")
    )
    lines.append(
        "(magnitudes scored: delay, current speed, offset, thrust loss, bias, damping value, wind's mean acceleration in "
        "surge and sway (yaw's shown apart above); "
        "not covered: out, no estimate (missed or wrong effect), no std, error (ERROR row), spurious out "
        "(a finding not concealed whose interval excludes 0); spurious in counts as covered)"
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


def rescore(rows: list[dict]) -> int:
    """Each 95 % half-width (``<std>_95``, and ``<std>_95_before`` without the held-out runs' part)
    recomputed in place by this code's :func:`diagnose.uncertainty.half_width_95` from the parts
    ``bench_diagnose_mmg`` recorded beside it (``<std>_parts``): exact, the diagnosis reads no
    half-width. Returns the number of findings with no recorded parts (left as they ran)."""
    from diagnose.uncertainty import half_width_95

    missing = 0
    for row in rows:
        for f in row.get("findings") or []:
            p = f.get("parameters") or {}
            keys = [k for k in p if k.endswith((PARTS_KEY, PARTS_KEY + "_before")) and isinstance(p[k], dict)]
            missing += not keys and any(k.endswith("_95") for k in p)
            for k in keys:
                name, _s, after = k.partition(PARTS_KEY)
                p[f"{name}_95{after}"] = half_width_95(**p[k])
    return missing


def main(argv: list[str] | None = None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json", nargs="+", help="--json outputs of benchmarks.bench_diagnose_mmg")
    ap.add_argument(
        "--rescore",
        action="store_true",
        help="recompute every 95 %% half-width with this code's quantile rule from the parts the run recorded "
        "(<std>_parts): the same diagnoses scored under the current rule",
    )
    a = ap.parse_args(argv)
    rows = []
    for p in a.json:
        try:
            with open(p, encoding="utf-8") as fh:
                rows += json.load(fh)["rows"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(
                f"error: {p}: not a benchmarks.bench_diagnose_mmg --json output ({e}); pass the file --json wrote",
                file=sys.stderr,
            )
            raise SystemExit(2) from None
    if a.rescore and (n := rescore(rows)):
        print(f"note: {n} findings carry no recorded parts (a run before they were recorded): their half-widths are as run")
    text = table(rows)
    print(text)
    return text


if __name__ == "__main__":
    main()
