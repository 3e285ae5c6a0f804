"""Judge ``shiptrial diagnose`` on the MMG KVLCC2 battery (tests/physics/mmg_battery.py): physics
the tool did not generate, one concealed effect per case, full and model scale, white and
coloured noise (issue 13).

The "visible" column is how far the effect moves the diagnosed runs (RMS of the difference to
the same manoeuvres without it, in noise units, per channel). Each case is diagnosed as a user would: the recordings are written as CSV, read back with
``diagnose.recording.load_recording`` and passed to ``diagnose.api.run`` with ``--fit-on`` the
calm run and ``--validate`` the two held-out runs (or, with ``--cli``, through
``shiptrial diagnose REC... --ship kvlcc2 --fit-on CALM --validate ... --json``). A case is a
hit when the named effects are exactly the concealed ones (a control and the effect outside
the candidate list claim nothing), every magnitude is within the issue's tolerance, no
held-out run fits worse after the diagnosis on any channel (per run, 1 point slack), and no
number is NaN.

    python -m benchmarks.bench_diagnose_mmg [--cases a,b] [--seeds 1-14] [--cli] [--jobs 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.physics.mmg_battery import CASES, case, generate, write_case

WORSE_SLACK = 1.0  # fit points a held-out run may lose on a channel ...
# ... or more where a point is less than a fifth of the noise: a fit is 100 (1 - |e| / |y - mean y|),
# so on a channel spread over s noise stds (the realised noise of the recording, against the
# noise-free run) a residual rising by a fifth of the noise (RMS) costs 20 / s points
NOISE_FRACTION = 0.2


# The kvlcc2 profile (the nonlinear MARIN fit), whose declared [diagnosis] structure --fit-on
# refits on the calm runs: the baseline a user diagnoses this ship with, and the one the figures
# in tests/test_diagnose_mmg_battery.py were measured with (`--ship kvlcc2`). The gap to the MMG
# ship is part of the test. `--ship kvlcc2-linear` judges the deliberately linear baseline.
BASELINE = "kvlcc2"


def _num(x) -> float | None:
    try:
        return float(x)
    except (TypeError, ValueError):
        return None


def _has_nan(obj) -> bool:
    if isinstance(obj, float):
        return math.isnan(obj) or math.isinf(obj)
    if isinstance(obj, dict):
        return any(_has_nan(v) for v in obj.values())
    if isinstance(obj, list | tuple):
        return any(_has_nan(v) for v in obj)
    return False


def thrust_loss_percent(params: dict, extra: dict) -> float | None:
    """A thrust loss in percent from whatever the finding reports (read defensively)."""
    for k in ("thrust_loss_pct", "loss_percent", "thrust_loss_percent", "loss_pct"):
        if _num(params.get(k)) is not None:
            return float(params[k])
    for k in ("loss_fraction", "fraction"):
        if _num(params.get(k)) is not None:
            return 100.0 * float(params[k])
    # a u_r*n coefficient against the baseline n^2 thrust, at the approach speed and rps
    coef, xnn = _num(params.get("coefficient")), extra.get("Xnn")
    if coef is not None and xnn and params.get("term") in ("u_r*n", "u*n"):
        return -100.0 * coef * extra["u0"] / (xnn * extra["n0"])
    return None


def _value_error(kind: str, est, true, tol) -> str | None:
    if kind == "equal":
        return None if est == true else f"{est!r} instead of {true!r}"
    e = _num(est)
    if e is None:
        return "not reported"
    if kind == "angle":
        err = abs((e - true + 180.0) % 360.0 - 180.0)
        return None if err <= tol else f"{e:.1f} deg, true {true:.1f} (tolerance {tol:g} deg)"
    if kind == "rel":
        err = abs(e - true) / abs(true)
        return None if err <= tol else f"{e:.4g}, true {true:.4g} ({100 * err:.0f} % off, tolerance {100 * tol:.0f} %)"
    err = abs(e - true)
    return None if err <= tol else f"{e:.4g}, true {true:.4g} (tolerance {tol:.3g})"


def _wind_error(params: dict, chk: dict) -> str | None:
    """Weighted relative error of the wind coefficients (weights: each DOF's share of the true
    wind effect in noise units)."""
    true, tol = chk["wind"][0], chk["wind"][1]
    wts = chk["weights"][0]
    num = den = 0.0
    for k, t in true.items():
        e = _num(params.get(k))
        if e is None:
            return f"no parameter {k}"
        if t == 0.0:  # no share of the effect (still air): nothing to weigh
            continue
        num += wts[k] * ((e - t) / t) ** 2
        den += wts[k]
    err = math.sqrt(num / den)
    return None if err <= tol else f"wind coefficients {100 * err:.0f} % off (weighted), tolerance {100 * tol:.0f} %"


# Froude power (of sqrt(lambda)) of each checked quantity, model -> full scale. Per-sample
# coefficients: the sample count is the same at both scales (the sample time scales as a time),
# so a coefficient c of dy = c * f(y) scales as [dy] / [f]: r|r| in yaw (rate / rate^2) as
# sqrt(lambda); the wind's mean accelerations: linear ones are the same at both scales (lengths
# over times squared, both lambda), the angular one scales as 1 / lambda.
FROUDE_POWER = {"speed_mps": 1, "delay_s": 1, "value": 1, "wind_accel_surge": 0, "wind_accel_sway": 0, "wind_accel_yaw": -2}
BIAS_POWER = {"u": 1, "v": 1, "r": -1}


def full_scale_truth(truth: dict) -> dict:
    """The truth at the scale of the findings. A model-scale case is generated (and its truth
    stated) at model scale, but the recordings are Froude-scaled to the full-scale ship before
    the diagnosis (``conform``), so every finding is a full-scale value: this converts the truth
    (value and tolerance) to full scale; angles, percentages and names stay as they are. A
    full-scale truth is returned unchanged."""
    lam = float(truth.get("scale_factor") or 1.0)
    if truth.get("scale") != "model" or lam == 1.0:
        return truth
    s = math.sqrt(lam)
    checks = {}
    for eff, chk in truth["checks"].items():
        new = {}
        for key, spec in chk.items():
            spec = list(spec)
            if key == "wind":
                spec[0] = {k: v * s ** FROUDE_POWER[k] for k, v in spec[0].items()}
            elif key == "bias":
                spec[0] *= s ** BIAS_POWER[chk["signal"][0]]
            elif key in FROUDE_POWER:
                f = s ** FROUDE_POWER[key]
                spec[0] *= f
                if spec[2] == "abs":  # an absolute tolerance carries the unit too
                    spec[1] *= f
            new[key] = spec
        checks[eff] = new
    return {**truth, "checks": checks, "scale_of_checks": f"full (Froude-scaled from model, lambda = {lam:g})"}


def held_out_spread(g, paths: dict[str, list[Path]]) -> dict[str, dict[str, float]]:
    """Each validation recording's spread per channel (std) in stds of its realised noise (the
    recorded column minus the noise-free run), by file name."""
    out = {}
    for p, cols, run in zip(paths["validate"], g.noisy["validate"], g.validate):
        dofs = {"surge": ("u", run.u), "sway": ("v", run.v), "yaw": ("r", run.r)}
        out[Path(p).name] = {ch: float(np.std(cols[c]) / np.std(cols[c] - x)) for ch, (c, x) in dofs.items()}
    return out


def worse_slack(spread: float | None) -> float:
    """Fit points a held-out channel spread over ``spread`` noise stds may lose (WORSE_SLACK, NOISE_FRACTION)."""
    return max(WORSE_SLACK, 100.0 * NOISE_FRACTION / spread) if spread else WORSE_SLACK


def score(truth: dict, out: dict, spread: dict[str, dict[str, float]] | None = None) -> tuple[bool, list[str]]:
    """(hit, reasons for a miss) of one diagnosis output (``out``: findings, per_run, fits),
    judged at full scale (:func:`full_scale_truth`), the scale of the findings. ``spread``: the
    held-out runs' spread in noise stds (:func:`held_out_spread`; without it every channel may
    lose WORSE_SLACK points)."""
    truth = full_scale_truth(truth)
    why = []
    if out.get("error"):
        return False, [f"error: {out['error']}"]
    findings = out.get("findings") or []
    named = sorted(f.get("effect") for f in findings)
    want = sorted(truth["effects"])
    if named != want:
        why.append(f"claimed {named or 'nothing'}, concealed {want or 'nothing'}")
    for eff, checks in truth["checks"].items():
        f = next((f for f in findings if f.get("effect") == eff), None)
        if f is None:
            continue
        p = f.get("parameters") or {}
        if eff == "wind":
            e = _wind_error(p, checks)
            if e:
                why.append(e)
            continue
        for key, (true, tol, kind) in checks.items():
            est = thrust_loss_percent(p, out.get("extra", {})) if key == "loss_percent" else p.get(key, f.get(key))
            e = _value_error(kind, est, true, tol)
            if e:
                why.append(f"{eff} {key}: {e}")
    for row in out.get("per_run") or []:
        b, a = row.get("before", {}), row.get("after", {})
        for ch in b:
            if _num(a.get(ch)) is None or _num(b.get(ch)) is None:
                continue
            if a[ch] < b[ch] - worse_slack((spread or {}).get(Path(str(row.get("run"))).name, {}).get(ch)):
                why.append(f"held-out {Path(str(row.get('run'))).name} {ch} fit {b[ch]:.1f} -> {a[ch]:.1f} %")
    if _has_nan(findings) or _has_nan(out.get("per_run")) or _has_nan(out.get("fit_after")):
        why.append("NaN in the output")
    return not why, why


BEFORE = "_before"  # suffix of a std or 95 % half-width without the held-out runs' part (diagnose.heldout_interval.with_heldout)


def _recording_before(with_interval, add_wind_means):
    """diagnose.api's ``with_interval`` and ``add_wind_means`` that also record each std and 95 %
    half-width of a finding without the held-out runs' part of its interval, as ``<name>_before``:
    the coverage before and after that part from one diagnosis (it changes no decision: the part
    is added after the rules that read a std)."""
    from dataclasses import replace as dc_replace

    def without(cov):
        return dc_replace(cov, heldout=None, heldout_runs=0)

    def keep(out: dict, before: dict, prefix: str = "") -> None:
        for k, v in before.items():
            if k.startswith(prefix) and ("_std" in k) and not k.endswith(("_noise", "_runs")):
                out[k + BEFORE] = v

    def interval(c, model, P, cov, free):
        out = with_interval(c, model, P, cov, free)
        if getattr(cov, "heldout", None) is not None:
            keep(out, with_interval(c, model, P, without(cov), free))
        return out

    def wind_means(findings, model, preps, P, cov, free):
        if getattr(cov, "heldout", None) is not None:
            before = [{**f, "parameters": dict(f["parameters"])} for f in findings]
            add_wind_means(before, model, preps, P, without(cov), free)
            for f, b in zip(findings, before):
                keep(f["parameters"], b["parameters"], "wind_accel_")
        add_wind_means(findings, model, preps, P, cov, free)

    return interval, wind_means


PARTS = "_parts"  # suffix of a std's record of its interval's parts (_recording_parts)


def _recording_parts(add_95):
    """diagnose.describe's ``_add_95`` that also records, beside each std ``<name>``, the std of
    each part of its interval and the runs they were measured over as ``<name>_parts`` (noise,
    model, within, reference, heldout, n_runs, n_heldout): the arguments of
    ``diagnose.uncertainty.half_width_95``, so ``benchmarks.mmg_battery_table --rescore``
    recomputes a 95 % half-width exactly from a stored diagnosis under another quantile rule."""
    from diagnose.describe import STD_SUFFIXES, args_95

    def add(out: dict, by_part: dict[str, dict], cov) -> None:
        add_95(out, by_part, cov)
        for k in [k for k in out if k.endswith(STD_SUFFIXES) and isinstance(out[k], float)]:
            if (a := args_95(by_part, k, cov)) is not None:
                out[k + PARTS] = a

    return add


def _api(paths: dict[str, list[Path]], joint: bool = False, ship: str = BASELINE) -> dict:
    from unittest import mock

    import diagnose.api as api
    import diagnose.describe as describe
    from diagnose.api import run
    from diagnose.recording import load_recording
    from diagnose.recording_checks import conform
    from primitives.ship import load_profile

    prof = load_profile(ship)

    def load(ps):  # as the CLI does: Froude-scaled to the ship when the header says model scale
        return conform([r for p in ps for r in load_recording(p)], prof)

    interval, wind_means = _recording_before(api.with_interval, api.add_wind_means)
    with (
        mock.patch.object(api, "with_interval", interval),
        mock.patch.object(api, "add_wind_means", wind_means),
        mock.patch.object(describe, "_add_95", _recording_parts(describe._add_95)),
    ):
        d = run(
            load(paths["diagnose"]), prof, fit_on=load(paths["calm"]), validate=load(paths["validate"]), joint_reference=joint
        )
    names = [n for dof in prof.parameter_names for n in dof]
    extra = {"u0": prof.cruise_speed_mps}
    if "Xnn" in names:
        extra["Xnn"] = float(d.theta[names.index("Xnn")])
        extra["n0"] = float(np.mean(load(paths["calm"])[0].channels["n"]))
    return {
        "findings": d.findings,
        "per_run": getattr(d, "per_run", None),
        "fit_before": d.fit_before,
        "fit_after": d.fit_after,
        "extra": extra,
        "notes": getattr(d, "notes", []),
        "cannot_tell": d.cannot_tell,
        "unpinned": d.unpinned,
        "rejected": getattr(d, "rejected", []),
        "structure": getattr(d, "structure", []),
        "baseline_rms_over_noise": d.location.get("rms_over_noise"),
        "screened": [
            {
                "round": sc["round"],
                "top": [
                    {k: c[k] for k in ("key", "heldout_delta_aic", "runs_improved", "p_value")} for c in sc["candidates"][:5]
                ],
            }
            for sc in d.screened
        ],
    }


def _cli(paths: dict[str, list[Path]], ship: str = BASELINE) -> dict:
    cmd = [
        str(Path(sys.executable).with_name("shiptrial")),
        "diagnose",
        *map(str, paths["diagnose"]),
        "--ship",
        ship,
        "--fit-on",
        ",".join(map(str, paths["calm"])),
        "--validate",
        ",".join(map(str, paths["validate"])),
        "--json",
    ]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or [f"exit status {p.returncode}"])[-1]}
    j = json.loads(p.stdout)
    return {
        "findings": j.get("findings"),
        "per_run": j.get("per_run") or j.get("heldout_per_run"),
        "fit_before": j.get("fit_before"),
        "fit_after": j.get("fit_after"),
        "notes": j.get("notes"),
        "rejected": j.get("rejected"),
    }


STD_KEY = {
    "delay_s": "delay_std",
    "speed_mps": "speed_std",
    "loss_percent": "loss_percent_std",
    "bias": "bias_std",
    "value": "value_std",
    "offset_deg": "offset_std",  # in rad: converted below
}


def z_scores(truth: dict, findings: list[dict] | None, part: str = "") -> dict[str, float]:
    """(estimate - truth) / reported std of each checked magnitude that carries a std, at the
    scale of the findings (how honest the reported uncertainty is, over noise seeds). ``part``
    "_noise": against the std's noise part alone (the interval before the model-misfit term)."""
    truth = full_scale_truth(truth)
    out = {}
    for eff, checks in truth["checks"].items():
        f = next((f for f in findings or [] if f.get("effect") == eff), None)
        for key, spec in checks.items():
            p = (f or {}).get("parameters") or {}
            if key == "wind":  # one estimate per DOF (the wind candidate's scales)
                for k, true in spec[0].items():
                    est, sd = _num(p.get(k)), _num(p.get(f"{k}_std{part}"))
                    if est is not None and sd:
                        out[k] = (est - true) / sd
                continue
            est, sd = _num(p.get(key)), _num(p.get(STD_KEY.get(key, "") + part))
            if key == "offset_deg" and sd:
                sd = math.degrees(sd)
            if est is not None and sd and isinstance(spec[0], int | float):
                out[key] = (est - spec[0]) / sd
    return out


def claimed(out: dict) -> str:
    if out.get("error"):
        return "ERROR"
    parts = []
    for f in out.get("findings") or []:
        p = f.get("parameters") or {}
        e = f.get("effect")
        if e == "current":
            parts.append(f"current {p.get('speed_mps', float('nan')):.2f} m/s to {p.get('toward_deg', float('nan')):.0f}")
        elif e == "actuator_delay":
            parts.append(f"delay {p.get('delay_s', float('nan')):.2f} s")
        elif e == "input_offset":
            parts.append(f"offset {p.get('offset_deg', float('nan')):.2f} deg")
        elif e == "thrust_loss":
            pct = thrust_loss_percent(p, out.get("extra", {}))
            parts.append(f"thrust loss {pct:.0f} %" if pct is not None else "thrust loss")
        elif e == "sensor_bias":
            parts.append(f"bias {p.get('signal')} {p.get('bias', float('nan')):.2g}")
        else:
            parts.append(f"{e}:{f.get('dof')}" + (f" {p['term']}" if "term" in p else ""))
    return "; ".join(parts) or ("cannot tell" if out.get("cannot_tell") else "nothing")


def truth_text(t: dict) -> str:
    if not t["effects"]:
        return "control" + (" (shallow water, outside the list)" if t["concealed"] == "shallow_water" else "")
    return f"{t['concealed']} {json.dumps(t['magnitude'])}"


def run_case(
    name: str,
    out_dir: Path,
    use_cli: bool,
    joint: bool = False,
    ship: str = BASELINE,
    oracle: bool = False,
    seed: int | None = None,
    no_anemometer: bool = False,
    calm_runs: int | None = None,
) -> dict:
    """Generate, diagnose and score one case (with ``seed``: its noise drawn from that seed instead;
    with ``no_anemometer``: the wind columns left out of the recordings, the wind still blowing;
    with ``calm_runs``: only the first that many calm runs as --fit-on)."""
    t0 = time.perf_counter()
    c0 = time.process_time()
    c = case(name)
    if seed is not None:
        c = replace(c, seed=seed, name=f"{c.name}-seed{seed}")
    g = generate(c, visibility=True, oracle_calm=oracle)
    if no_anemometer:
        for runs in g.noisy.values():
            for cols in runs:
                cols.pop("wind_speed", None), cols.pop("wind_dir", None)
    paths = write_case(g, out_dir / name)
    paths["calm"] = paths["calm"][:calm_runs]
    t_gen = time.perf_counter() - t0
    t1 = time.perf_counter()
    try:
        out = _cli(paths, ship) if use_cli else _api(paths, joint, ship)
    except Exception as exc:  # a user error or a crash: both are misses, said as such
        out = {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"}
    secs = time.perf_counter() - t1
    cpu = time.process_time() - c0  # this process's CPU (the CLI's child process is not counted)
    hit, why = score(g.truth, out, held_out_spread(g, paths))
    return {
        "case": c.name,
        "truth": g.truth,
        "truth_text": truth_text(g.truth),
        "claimed": claimed(out),
        "hit": hit,
        "why": why,
        "hit_at_one_point": score(g.truth, out)[0],  # every held-out channel held to WORSE_SLACK alone
        "diagnose_s": secs,
        "generate_s": t_gen,
        "cpu_s": cpu,
        "per_run": out.get("per_run"),
        "findings": out.get("findings"),
        "error": out.get("error"),
        "notes": out.get("notes"),
        "cannot_tell": out.get("cannot_tell"),
        "unpinned": out.get("unpinned"),
        "rejected": out.get("rejected"),
        "structure": out.get("structure"),
        "screened": out.get("screened"),
        "baseline_rms_over_noise": out.get("baseline_rms_over_noise"),
    }


def finding_z(r: dict) -> list[tuple[str, float, str]]:
    """Each finding's |estimate / std| (diagnose.describe.z_score), labelled true (its effect is
    the case's truth), spurious, or dropped (rejected as including no effect, |z| from the reason)."""
    from diagnose.describe import z_score

    truth = set(r["truth"].get("effects", []))
    out = [
        (f["effect"], z_score(f), "true" if f["effect"] in truth else "spurious")
        for f in (r.get("findings") or []) + (r.get("structure") or [])
    ]
    for j in r.get("rejected") or []:
        m = re.search(r"\|estimate/std\| = ([0-9.]+)", j.get("reason", ""))
        if m:
            out.append((j["effect"], float(m.group(1)), "dropped, " + ("true" if j["effect"] in truth else "spurious")))
    return out


def _print_z_spread(rows: list[dict]) -> None:
    """The spread of |estimate/std| for true and spurious findings over all rows (kept or dropped)."""
    for kind in ("true", "spurious"):
        zs = sorted(z for r in rows for _e, z, k in r.get("finding_z", []) if k.endswith(kind))
        if zs:
            print(f"|estimate/std| of {kind} findings (kept and dropped) over {len(zs)}: " + ", ".join(f"{z:.2f}" for z in zs))


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--cli", action="store_true", help="run the shiptrial CLI instead of the library API")
    ap.add_argument("--jobs", type=int, default=1, help="cases in parallel (processes)")
    ap.add_argument("--out", default="", help="directory for the generated recordings (default: a temporary one)")
    ap.add_argument("--json", default="", help="write the per-case results here")
    ap.add_argument("--ship", default=BASELINE, help=f"baseline profile (default {BASELINE})")
    ap.add_argument(
        "--joint",
        action="store_true",
        help="experimental: extended baseline structure refitted jointly on "
        "the calm run and the diagnosed runs, candidates on the diagnosed runs only (diagnose.reference)",
    )
    ap.add_argument(
        "--seeds",
        default="",
        help="noise seeds to run each case with instead of its own, e.g. 1-14 or "
        "3,5 (the spread of the estimates and how often the reported std covers the truth)",
    )
    ap.add_argument(
        "--oracle-calm",
        action="store_true",
        help="study: the --fit-on runs are the diagnosed and "
        "validation manoeuvres without the effect (isolates the search from the baseline's misfit)",
    )
    ap.add_argument(
        "--no-anemometer",
        action="store_true",
        help="the wind columns left out of every recording (the wind still blows): the steady-wind candidate's test",
    )
    ap.add_argument(
        "--calm-runs",
        type=int,
        choices=range(1, 5),
        default=None,
        help="--fit-on only the first N of the four calm runs (35 deg turns to starboard and port, 10/10, 20/20 zig-zags)",
    )
    a = ap.parse_args(argv)
    names = [n.strip() for n in a.cases.split(",") if n.strip()] or [c.name for c in CASES]
    for n in names:
        case(n)  # unknown names fail before any work
    seeds: list[int | None] = [None]
    if a.seeds:
        seeds = [
            k for part in a.seeds.split(",") for lo, _s, hi in [part.partition("-")] for k in range(int(lo), int(hi or lo) + 1)
        ]
    jobs = [(n, s) for n in names for s in seeds]
    out_dir = Path(a.out) if a.out else Path(tempfile.mkdtemp(prefix="mmg-battery-"))
    t0 = time.perf_counter()
    if a.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(a.jobs) as ex:
            futs = [
                ex.submit(run_case, n, out_dir, a.cli, a.joint, a.ship, a.oracle_calm, sd, a.no_anemometer, a.calm_runs)
                for n, sd in jobs
            ]
            for f in as_completed(futs):  # progress as cases finish (a long run can be followed)
                r = f.result()
                print(
                    f"  {r['case']}: {'hit' if r['hit'] else 'MISS'} {r['claimed']} ({r['cpu_s']:.0f} s CPU)",
                    file=sys.stderr,
                    flush=True,
                )
            rows = [f.result() for f in futs]
    else:
        rows = []
        for n, sd in jobs:
            rows.append(run_case(n, out_dir, a.cli, a.joint, a.ship, a.oracle_calm, sd, a.no_anemometer, a.calm_runs))
            r = rows[-1]
            print(f"  {r['case']}: {'hit' if r['hit'] else 'MISS'} ({r['diagnose_s']:.1f} s)", file=sys.stderr, flush=True)
    print(f"{'case':22s} {'truth':44s} {'visible u/v/r':>15s}  {'claimed':48s} {'result':6s} {'time s':>7s} {'cpu s':>7s}")
    for r in rows:
        vis = r["truth"].get("visibility_rms_over_noise", {})
        vt = "/".join(f"{vis[k]:.1f}" for k in "uvr") if vis else "-"
        print(
            f"{r['case']:22s} {r['truth_text'][:44]:44s} {vt:>15s}  {r['claimed'][:48]:48s} "
            f"{'hit' if r['hit'] else 'MISS':6s} {r['diagnose_s']:7.1f} {r['cpu_s']:7.1f}"
        )
        for w in r["why"]:
            print(f"{'':24s}- {w}")
        z, zn = z_scores(r["truth"], r["findings"]), z_scores(r["truth"], r["findings"], "_noise")
        r["z"], r["z_noise"] = z, zn
        if z:
            print(
                f"{'':24s}  error / reported std: "
                + ", ".join(f"{k} {v:+.2f}" for k, v in z.items())
                + " (noise part alone: "
                + ", ".join(f"{k} {v:+.2f}" for k, v in zn.items())
                + ")"
            )
        sig = finding_z(r)
        r["finding_z"] = sig
        if sig:
            print(f"{'':24s}  |estimate/std| of each finding: " + ", ".join(f"{e} {z:.2f} ({k})" for e, z, k in sig))
    _print_z_spread(rows)
    for label, key in (("reported std (noise + run-to-run misfit)", "z"), ("its noise part alone", "z_noise")):
        zs = np.array([v for r in rows for v in r[key].values()])
        if len(zs) >= 3:
            print(
                f"{label} over {len(zs)} estimates: RMS of error/std {np.sqrt(np.mean(zs**2)):.2f}, within 1 std "
                f"{np.mean(np.abs(zs) < 1):.0%} (68 % if honest), within 2 std {np.mean(np.abs(zs) < 2):.0%} (95 %)"
            )
    hits = sum(r["hit"] for r in rows)
    times = sorted(r["diagnose_s"] for r in rows)
    cpus = sorted(r["cpu_s"] for r in rows)
    print(
        f"hit rate {hits}/{len(rows)} = {100 * hits / max(len(rows), 1):.0f} %; diagnosis time median "
        f"{times[len(times) // 2]:.1f} s, max {times[-1]:.1f} s; case CPU (generation + diagnosis) median "
        f"{cpus[len(cpus) // 2]:.1f} s, total {sum(cpus):.0f} s; wall {time.perf_counter() - t0:.0f} s "
        f"({'CLI' if a.cli else 'API'}{', oracle calm runs' if a.oracle_calm else ''}); recordings in {out_dir}"
    )
    res = {"hits": hits, "cases": len(rows), "rows": rows}
    if a.json:
        from primitives.io import atomic_write_text, to_jsonable

        atomic_write_text(a.json, json.dumps(to_jsonable(res), indent=1))
    return res


if __name__ == "__main__":
    main()
