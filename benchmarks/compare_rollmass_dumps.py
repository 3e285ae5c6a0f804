"""Pair the fits of two truth-bench dumps (benchmarks/bench_rollmass_truth.py --dump) of the same family, fit by fit
(stop 55): CPU, mass % and z mm error, whether both intervals hold the truth, before and after, and the path the
"after" fit took (identify.rollmass.fit_path, when its dump records it); a fit whose row is bit-identical says so
(or that its shared fields are, naming the fields only one row records).

    python benchmarks/compare_rollmass_dumps.py benchmarks/rollmass_family_s54.jsonl benchmarks/rollmass_redo_s55.jsonl
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def _load(path: str) -> dict[tuple, list]:
    """The dump's rows by (variant, case, method, run); a fit there twice is refused (which copy to pair is unknown)."""
    out: dict[tuple, list] = {}
    for i, r in enumerate(map(json.loads, Path(path).read_text().splitlines()), 1):
        if tuple(r[:4]) in out:
            raise SystemExit(f"{path}: line {i} repeats the fit {'/'.join(map(str, r[:4]))}; fix: delete one of its lines")
        out[tuple(r[:4])] = r
    return out


def _same(b: list, r: list) -> str:
    """How far two rows hold the same fit (answer, warning text and fitted parameters; CPU, path and family aside):
    ``" (row bit-identical)"``; ``" (shared fields bit-identical; only after: m_sd, z_sd)"`` when the fields both record
    agree but one row records a field the other does not (a difference, said: a later bench records more, e.g.
    ``m_sd`` and ``z_sd`` since stop 55's oracle, and a row that drops a field is not the same row); else ``""``."""
    skip = {"path", "family"}
    kb, kr = b[7].keys() - skip, r[7].keys() - skip
    if b[4:6] != r[4:6] or any(b[7][k] != r[7][k] for k in kb & kr):
        return ""
    if kb == kr:
        return " (row bit-identical)"
    one = [f"only {which}: {', '.join(sorted(k))}" for which, k in (("before", kb - kr), ("after", kr - kb)) if k]
    return f" (shared fields bit-identical; {'; '.join(one)})"


def _answer(r: list) -> str:
    if r[4] is None:
        return f"{'failed':>16} {'-':>4}"
    m, z, hm, hz, _ = r[4]
    return f"{m:+7.2f} {z:+7.1f} {'yes' if hm and hz else 'no':>4}"


def _path(r: list) -> str:
    p = r[7].get("path")
    if p is None:
        return "-"
    out = f"{p['path']:9} exact LMs [{_calls(p['exact'])}] res {p['exact']['residuals']} jac {p['exact']['jacobians']}"
    c = p.get("continued")  # the exact path's continuation (stop 56's exact LM, stop 59's geodesic LM), when it was tried
    if c is not None:
        out += f"; continued [{_calls(c)}] res {c['residuals']} jac {c['jacobians']}"
    return out


def _calls(tally: dict) -> str:
    """A path's LM calls' evaluations, ``*`` marking a call at its cap."""
    return " ".join(f"{n}{'*' if s == 0 else ''}" for n, s in tally["lm"])


def _paths(before: dict, after: dict) -> str:
    """The paired fits per recorded path (exact, continued, geodesic, redo; ``-``: a row without one), before ->
    after, with their CPU, e.g. ``redo 5 (550 s) -> 0; geodesic 0 -> 5 (120 s)``."""
    keys = [k for k in after if k in before]
    out = []
    for name in ("exact", "continued", "geodesic", "redo", "-"):
        sides = [
            [r for r in (rows[k] for k in keys) if (r[7].get("path") or {}).get("path", "-") == name] for rows in (before, after)
        ]
        if any(sides):
            out.append(f"{name} " + " -> ".join(f"{len(s)}" + (f" ({sum(r[6] for r in s):.0f} s)" if s else "") for s in sides))
    return "; ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    a = ap.parse_args()
    before, after = _load(a.before), _load(a.after)
    print(f"{'fit':24} {'cpu s':>13} | {'before m% z mm both':>20} | {'after':>20} | path of the after fit (* = LM at its cap)")
    tot = [0.0, 0.0]
    for key, r in after.items():
        b = before.get(key)
        if b is None:
            continue
        tot[0], tot[1] = tot[0] + b[6], tot[1] + r[6]
        fit = f"{key[0]}/{key[3]}/{key[1]}"
        print(f"{fit:24} {b[6]:6.1f} {r[6]:6.1f} | {_answer(b)} | {_answer(r)} | {_path(r)}{_same(b, r)}")
    print(f"total of the paired fits: {tot[0]:.0f} s cpu before, {tot[1]:.0f} s after")
    print(f"paths, before -> after: {_paths(before, after)}")


if __name__ == "__main__":
    main()
