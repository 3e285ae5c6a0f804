"""How well the kvlcc2 baseline, refitted on the calm runs of the MMG battery (``--fit-on``),
simulates other manoeuvres: the profile's own structure and the structure its ``[diagnosis]``
table declares, per run and channel, in units of the measurement noise (issue 13).

The physics is the MMG standard model (tests/physics/mmg_kvlcc2.py, not the product's model).
The baseline is fitted as ``diagnose.api`` does on the case's calm runs (the battery's CALM
set; noisy as recorded, or noise-free with ``--clean``) and scored by open-loop simulation
against the noise-free truth of every run, from the true initial state: the calm runs
themselves (in-sample), the three diagnosed runs (in a control case the same manoeuvres as
three calm ones), the two validation runs (held out; calm in a control case, with the effect
otherwise) and calm manoeuvres outside the --fit-on set
(``EXTRA``: a 15/15 zig-zag, 20 and 25 deg turning circles). A figure near 1 means the model
error is at the noise level; the summary line gives the median and the worst over the
held-out calm runs.

    python -m benchmarks.bench_baseline_structure [--cases control,model-control] [--clean] [--ship kvlcc2]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from diagnose.baseline import fit_baseline, fit_declared, fit_structure
from diagnose.model import AugmentedModel, prepare
from diagnose.recording import Recording
from primitives.ship import ShipProfile, load_profile
from tests.physics.mmg_battery import LEAD_IN_S, NOISE_FULL, _setup, case, generate
from tests.physics.mmg_kvlcc2 import kvlcc2, self_propulsion_rps
from tests.physics.mmg_sim import Manoeuvre, simulate_runs

# calm manoeuvres outside the battery's --fit-on set: held out in every case
EXTRA = [Manoeuvre("zigzag", 15, 15, 1, 650), Manoeuvre("turn", 20, 0, -1, 800), Manoeuvre("turn", 25, 0, 1, 800)]


def _recording(run, cols: dict | None, name: str, scale: float) -> Recording:
    """A full-scale Recording of a battery run (Froude-scaled from model scale like the CLI)."""
    c = cols or {
        "t": run.t,
        "x": run.x,
        "y": run.y,
        "psi": run.psi,
        "u": run.u,
        "v": run.v,
        "r": run.r,
        "delta": run.delta,
        "n": run.n,
    }
    q = np.sqrt(scale)  # Froude: times and speeds x sqrt(lambda), rates / sqrt(lambda), rps / sqrt(lambda)
    y = np.column_stack([c["u"] * q, c["v"] * q, c["r"] / q])
    return Recording(
        name, c["t"] * q, y, c["psi"], np.column_stack([c["x"], c["y"]]) * scale, {"delta": c["delta"], "n": c["n"] / q}
    )


def sim_error(profile: ShipProfile, theta: np.ndarray, rec: Recording, truth: Recording) -> np.ndarray:
    """RMS of (simulation - truth) per channel over the run, in full-scale noise units."""
    m = AugmentedModel(profile, theta, [])
    p = prepare(profile, rec)
    p.y0 = truth.y[0]
    with np.errstate(all="ignore"):
        yh = m.simulate(p, m.p0())[0]
    e = np.sqrt(np.mean((yh - truth.y) ** 2, axis=0)) / np.array([NOISE_FULL["u"], NOISE_FULL["v"], NOISE_FULL["r"]])
    return np.where(np.isfinite(e), e, np.inf)


def run_case(name: str, ship: str, clean: bool) -> list[dict]:
    c = case(name)
    prof = load_profile(ship)
    if not prof.structure_terms:
        raise SystemExit(f"ship {ship!r} declares no [diagnosis] structure: nothing to compare")
    g = generate(c)
    extra = simulate_runs(
        _setup(c)[0], EXTRA, self_propulsion_rps(kvlcc2(c.scale)), sample_time=g.sample_time, lead_in_s=LEAD_IN_S
    )
    lab = [r.manoeuvre.label for r in g.calm + g.diagnose + g.validate + extra]
    roles = ["calm"] * len(g.calm) + ["diagnose"] * len(g.diagnose) + ["validate"] * len(g.validate) + ["extra"] * len(extra)
    runs = g.calm + g.diagnose + g.validate + extra
    truth = [_recording(r, None, f"{lb}", c.scale) for r, lb in zip(runs, lab)]
    noisy = [
        _recording(r, None if clean else cols, lb, c.scale)
        for r, cols, lb in zip(runs, g.noisy["calm"] + g.noisy["diagnose"] + g.noisy["validate"] + [None] * len(extra), lab)
    ]
    calm, diag = noisy[: len(g.calm)], noisy[len(g.calm) : len(g.calm) + len(g.diagnose)]
    t0 = time.process_time()
    th_own, _ = fit_baseline(prof, prof.params(), calm)
    t1 = time.process_time()
    ext, th_ext, _src, notes, _rej = fit_structure(prof, prof.params(), calm, diag)
    t2 = time.process_time()
    if ext is prof:  # the structure was not kept: show what it would have given anyway
        ext, th_ext, _note, _added = fit_declared(prof, prof.params(), calm)
    rows = []
    for role, lb, rec, tr in zip(roles, lab, noisy, truth):
        rows.append(
            {
                "case": name,
                "role": role,
                "run": lb,
                "before": sim_error(prof, th_own, rec, tr),
                "after": sim_error(ext, th_ext, rec, tr),
                "calm": c.effect is None or role in ("calm", "extra"),
            }
        )
    rows[0]["cpu"] = (t1 - t0, t2 - t1)
    rows[0]["notes"] = notes
    return rows


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="control,control-ar1,model-control")
    ap.add_argument("--clean", action="store_true", help="fit on the noise-free calm run")
    ap.add_argument("--ship", default="kvlcc2", help="a profile with a [diagnosis] structure")
    a = ap.parse_args(argv)
    out = []
    print(
        f"simulation error / noise (u, v, r), baseline fitted on the {'noise-free' if a.clean else 'noisy'} calm runs; "
        f"ship {a.ship}"
    )
    print(f"{'case':16s} {'role':9s} {'run':14s} {'own structure':>20s} {'declared structure':>22s}")
    for name in [n.strip() for n in a.cases.split(",") if n.strip()]:
        rows = run_case(name, a.ship, a.clean)
        for r in rows:
            f = lambda e: "/".join(f"{x:6.1f}" for x in e)  # noqa: E731
            print(f"{r['case']:16s} {r['role']:9s} {r['run']:14s} {f(r['before']):>20s} {f(r['after']):>22s}")
        # calm manoeuvres outside the --fit-on set (a control's diagnosed runs repeat calm manoeuvres: not held out)
        held = [r for r in rows if r["calm"] and r["role"] in ("validate", "extra")]
        b = np.array([r["before"] for r in held])
        d = np.array([r["after"] for r in held])
        f = lambda e: "/".join(f"{x:6.1f}" for x in e)  # noqa: E731
        print(
            f"{'':16s} held-out calm, median {f(np.median(b, 0)):>25s} {f(np.median(d, 0)):>22s}   fit cpu "
            f"{rows[0]['cpu'][0]:.1f} s, {rows[0]['cpu'][1]:.1f} s" + (f"; {rows[0]['notes'][0]}" if rows[0]["notes"] else "")
        )
        print(f"{'':16s} held-out calm, worst  {f(b.max(0)):>25s} {f(d.max(0)):>22s}")
        out += rows
    return out


if __name__ == "__main__":
    main()
