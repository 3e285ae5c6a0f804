"""Monte Carlo evaluation of designs as in seed 001 section 9.1.2.

Each design becomes a trial of ``n_samples`` samples (thesis: 1000 samples, 125 s, at the model
ship): a fixed design runs each primitive for round(w_q * n_samples) samples (efficient rounding;
a primitive used for longer than it lasts is repeated from its start), each as a sub-experiment
started from the primitive's nominal initial state; the random design picks 1 of the primitives
for each of ``n_segments`` equal segments, anew in every run. Data come from the true system with
the profile's disturbances (model ship: current u_c, v_c ~ N(0, 0.025) per sample, measurement
noise e ~ N(0, 0.025), variances), the parameters from the IV estimator with the design's mean
subtraction. Metrics per run: the normalized parameter RMSE sqrt(mean(((theta - theta0)/|theta0|)^2))
and the cross-validation simulation RMSE (per DOF and its norm) on a seeded multisine input
unlike any primitive, simulated noise-free.

Reproducibility and distribution: run i draws everything (its random design, current, noise)
from ``SeedSequence(seed).spawn(runs)[i]``, so any split of the runs into chunks (``run_slice``,
e.g. Dask tasks) gives the same numbers; :func:`merge_results` joins chunk results.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from expdesign.errors import DesignError
from expdesign.estimators import Segment, estimate
from expdesign.rounding import efficient_rounding
from primitives.library import Primitive, thesis_primitives
from primitives.ship import ShipProfile
from primitives.simulate import Disturbances, simulate, steady_forces

PARAM_THRESHOLD = 1.5
SIM_THRESHOLD = 0.15


@dataclass
class MCResult:
    """Per-run metrics of one design: run ids, normalized parameter RMSE (runs,) (NaN when the
    predictor structure differs from the true model), simulation RMSE (runs, 3) and its norm."""

    name: str
    runs: np.ndarray
    param_rmse: np.ndarray
    sim_rmse: np.ndarray
    sim_norm: np.ndarray
    notes: list[str] = field(default_factory=list)

    def summary(self, param_threshold: float = PARAM_THRESHOLD, sim_threshold: float = SIM_THRESHOLD) -> dict[str, Any]:
        """Medians, 90th percentiles and fractions below the thresholds; a diverged run counts as
        infinite error (its percentile becomes inf, written as null in JSON)."""
        pr = self.param_rmse
        has_p = bool(np.isfinite(pr).any() or np.isinf(pr).any())
        return {
            "runs": int(len(self.runs)),
            "param_rmse_p50": _pct(pr, 50) if has_p else None,
            "param_rmse_p90": _pct(pr, 90) if has_p else None,
            f"frac_param_rmse_below_{str(param_threshold).replace('.', '_')}": float(np.mean(pr < param_threshold)) if has_p else None,
            "sim_rmse_p50": _pct(self.sim_norm, 50),
            "sim_rmse_p90": _pct(self.sim_norm, 90),
            f"frac_sim_rmse_below_{str(sim_threshold).replace('.', '_')}": float(np.mean(self.sim_norm < sim_threshold)),
            "sim_rmse_dof_p50": {k: _pct(self.sim_rmse[:, i], 50) for i, k in enumerate("uvr")},
        }


def _pct(x: np.ndarray, q: float) -> float:
    """Percentile that keeps diverged runs (inf) as inf instead of NaN."""
    v = float(np.nanpercentile(np.where(np.isinf(x), 1e300, x), q))
    return np.inf if v > 1e299 else v


def merge_results(parts: list[dict[str, MCResult]]) -> dict[str, MCResult]:
    """Join chunk results (any order) into one result per design, sorted by run id."""
    out: dict[str, MCResult] = {}
    for name in parts[0]:
        rs = [p[name] for p in parts]
        runs = np.concatenate([r.runs for r in rs])
        o = np.argsort(runs)
        out[name] = MCResult(name, runs[o], np.concatenate([r.param_rmse for r in rs])[o],
                             np.concatenate([r.sim_rmse for r in rs])[o], np.concatenate([r.sim_norm for r in rs])[o],
                             sorted({n for r in rs for n in r.notes}))
    return out


def validation_input(profile: ShipProfile, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Seeded cross-validation input unlike any primitive: multisine surge speed, a smoothed
    random binary sway and a multisine yaw rate reference, turned into feed-forward forces.
    Returns (inputs (n, m), nu0 (3,))."""
    rng = np.random.default_rng([seed, 0x5EED])
    t = np.arange(n) / n
    c, L = profile.cruise_speed_mps, profile.length_m

    def multisine(k: int) -> np.ndarray:
        f = rng.choice(np.arange(2, 12), k, replace=False)
        ph = rng.uniform(0, 2 * np.pi, k)
        s = np.sum(np.sin(2 * np.pi * f[:, None] * t + ph[:, None]), axis=0)
        return s / np.abs(s).max()

    if profile.actuator == "rudder_propeller":  # no force allocation: the same idea in helm terms
        from primitives.helm import validation_inputs

        return validation_inputs(profile, multisine)

    prbs = np.repeat(rng.choice([-1.0, 1.0], n // 50 + 1), 50)[:n]
    prbs = np.convolve(prbs, np.ones(15) / 15, mode="same")
    u = c * (0.7 + 0.3 * multisine(3))
    v = 0.1 * c * prbs
    r = 0.3 * c / L * multisine(3)
    forces = np.array([steady_forces(profile, a, b, g) for a, b, g in zip(u, v, r)])
    return profile.allocate(forces[:, 0], forces[:, 1], forces[:, 2]), np.array([u[0], v[0], r[0]])


def _layout(weights: Mapping[str, float], prims: dict[str, Primitive], n_samples: int) -> list[tuple[str, int]]:
    """(primitive, length) segments of a fixed design; long uses repeat the primitive."""
    names = list(weights)
    unknown = [k for k in names if k not in prims]
    if unknown:
        raise DesignError(f"design uses unknown primitives {unknown}; the library has {sorted(prims)}")
    lengths = efficient_rounding(np.array([weights[k] for k in names], float), n_samples)
    segs = []
    for k, total in zip(names, lengths):
        full = prims[k].n_samples
        while total >= 2:
            segs.append((k, int(min(total, full))))
            total -= min(total, full)
    return segs


class _Noise:
    """Per-run random draws from the run's own seed (chunk-independent)."""

    def __init__(self, dist: Disturbances, seeds: list[np.random.SeedSequence]):
        self.d = dist
        self.rngs = [np.random.default_rng(s) for s in seeds]

    def draw(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        d = self.d
        cur, wind, meas, head = [], [], [], []
        for g in self.rngs:
            c = np.broadcast_to(np.asarray(d.current_ne, float), (n, 2)) + g.normal(0, d.current_offset_std or 0.0, (1, 2))
            cur.append(c + g.normal(0, 1, (n, 2)) * d.current_sample_std)
            wind.append(np.broadcast_to(np.asarray(d.wind_ne, float), (n, 2)) + g.normal(0, 1, (n, 2)) * d.wind_sample_std)
            meas.append(g.normal(0, 1, (n + 1, 3)) * np.asarray(d.measurement_std, float))
            head.append(g.normal(0, 1, n + 1) * d.heading_std)
        return np.array(cur), np.array(wind), np.array(meas), np.array(head)


def _simulate_segment(profile: ShipProfile, inputs: np.ndarray, nu0: np.ndarray, noise: _Noise, b: int) -> Segment:
    n = inputs.shape[-2]
    cur, wind, meas, head = noise.draw(n)
    # per-run current/wind enter as explicit (B, N, 2) arrays so no draw depends on the batch size
    dist = Disturbances(current_ne=cur, wind_ne=wind)
    with np.errstate(all="ignore"):
        res = simulate(profile, inputs, nu0=np.broadcast_to(nu0, (b, 3)), disturbances=dist, batch=b)
    return Segment(inputs, res.y + meas, nu0, res.eta[..., 2] + head)


def _run_chunk(profile, name, spec, prims, run_ids, seeds, n_samples, n_segments, mean_subtraction, dist, theta0, val):
    b = len(run_ids)
    children = [s.spawn(2) for s in seeds]  # [noise, design choice] per run
    noise = _Noise(dist, [c[0] for c in children])
    segs: list[Segment] = []
    if isinstance(spec, str):
        names = sorted(prims, key=lambda k: list(prims).index(k))
        seg_len = n_samples // n_segments
        short = [k for k in names if prims[k].n_samples < seg_len]
        if short:
            raise DesignError(f"random design needs primitives of >= {seg_len} samples; {short} are shorter")
        choice = np.array([np.random.default_rng(c[1]).integers(0, len(names), n_segments) for c in children])
        stack_in = np.stack([prims[k].inputs[:seg_len] for k in names])
        stack_nu0 = np.stack([prims[k].nu0 for k in names])
        for s in range(n_segments):
            segs.append(_simulate_segment(profile, stack_in[choice[:, s]], stack_nu0[choice[:, s]], noise, b))
    else:
        for k, length in _layout(spec, prims, n_samples):
            segs.append(_simulate_segment(profile, prims[k].inputs[:length], prims[k].nu0, noise, b))
    est = estimate(profile, segs, method="iv", mean_subtraction=mean_subtraction)
    th = est.theta
    if theta0 is not None:
        with np.errstate(all="ignore"):
            prm = np.sqrt(np.mean(((th - theta0) / np.abs(theta0)) ** 2, axis=1))
    else:
        prm = np.full(b, np.nan)
    vin, vnu0, vtrue = val
    with np.errstate(all="ignore"):
        sim = simulate(profile, vin, th, terms=profile.predictor, nu0=vnu0, batch=b)
        err = np.sqrt(np.mean((sim.nu - vtrue) ** 2, axis=1))
    err = np.where(np.isfinite(err), err, np.inf)
    norm = np.sqrt(np.sum(err**2, axis=1))
    return MCResult(name, np.asarray(run_ids), np.where(np.isnan(prm) & (theta0 is not None), np.inf, prm), err, norm, est.notes)


def evaluate_designs(
    profile: ShipProfile,
    designs: Mapping[str, Any],
    runs: int = 500,
    seed: int = 0,
    *,
    primitives: list[Primitive] | None = None,
    n_samples: int = 1000,
    n_segments: int = 5,
    mean_subtraction: str = "complete",
    disturbances: Disturbances | None = None,
    run_slice: tuple[int, int] | None = None,
    chunk_size: int = 500,
) -> dict[str, MCResult]:
    """Monte Carlo metrics of several designs (section 9.1.2).

    ``designs`` maps a label to fractions {primitive: w}, to an object with ``.weights``, or to
    the string "random" (1 of the primitives per segment, drawn per run). ``run_slice=(a, b)``
    evaluates runs a..b-1 of the ``runs`` seeded runs only (for distributing chunks); results
    of all chunks joined with :func:`merge_results` equal one call over all runs.
    """
    if runs < 1:
        raise DesignError("Monte Carlo needs at least 1 run")
    prims = {p.name: p for p in (primitives if primitives is not None else thesis_primitives(profile)) if p.kind == "informative"}
    if not prims:
        raise DesignError(f"profile {profile.name!r} has no informative primitives to evaluate")
    dist = disturbances if disturbances is not None else Disturbances.from_profile(profile)
    model_is_predictor = profile.predictor.terms == profile.model.terms
    theta0 = profile.params(profile.simulation_set) if model_is_predictor else None
    vin, vnu0 = validation_input(profile, n_samples, seed)
    vtrue = simulate(profile, vin, nu0=vnu0).nu[0]
    val = (vin, vnu0, vtrue)
    seeds = np.random.SeedSequence(seed).spawn(runs)
    a, z = run_slice or (0, runs)
    if not 0 <= a < z <= runs:
        raise DesignError(f"run_slice {run_slice} must lie within 0..{runs}")
    out: dict[str, MCResult] = {}
    for name, spec in designs.items():
        spec = getattr(spec, "weights", spec)
        if isinstance(spec, str) and spec != "random":
            raise DesignError(f"design {name!r}: use fractions {{primitive: share}} or 'random', got {spec!r}")
        parts = []
        for c0 in range(a, z, chunk_size):
            ids = list(range(c0, min(z, c0 + chunk_size)))
            # fresh SeedSequence objects per design: spawn() is stateful, the draws must not be
            seq = [np.random.SeedSequence(seeds[i].entropy, spawn_key=seeds[i].spawn_key) for i in ids]
            parts.append({name: _run_chunk(profile, name, spec, prims, ids, seq, n_samples, n_segments,
                                           mean_subtraction, dist, theta0, val)})
        out[name] = merge_results(parts)[name]
        if theta0 is None:
            out[name].notes.append("predictor structure differs from the true model: parameter RMSE not defined")
        if any(dist.process_std):
            out[name].notes.append("process noise of the disturbances is not simulated in the Monte Carlo study")
    return out


def _chunk_task(args: tuple) -> dict[str, MCResult]:
    profile, designs, runs, seed, run_slice, kw = args
    return evaluate_designs(profile, designs, runs, seed, run_slice=run_slice, **kw)


def evaluate_designs_parallel(
    profile: ShipProfile,
    designs: Mapping[str, Any],
    runs: int = 500,
    seed: int = 0,
    *,
    scheduler: Any = None,
    chunk_runs: int | None = None,
    progress: bool = True,
    **kw: Any,
) -> dict[str, MCResult]:
    """:func:`evaluate_designs` split into chunks of runs on an engine of ``expdesign.parallel``
    (local cores by default, or a Dask cluster): the numbers equal one in-process call.

    When interrupted (Ctrl-C) the finished chunks are kept; each result then notes how many
    runs it holds.
    """
    from expdesign.parallel import get_engine

    engine = get_engine(scheduler)
    n_workers = getattr(engine, "workers", 4)
    chunk = chunk_runs or max(25, -(-runs // max(1, 2 * n_workers)))
    designs = {k: getattr(v, "weights", v) for k, v in designs.items()}
    tasks = [(profile, designs, runs, seed, (a, min(runs, a + chunk)), kw) for a in range(0, runs, chunk)]
    try:
        res = engine.map(_chunk_task, tasks, desc="Monte Carlo", progress=progress)
    finally:
        if engine is not scheduler:
            engine.close()
    parts = res.finished()
    if not parts:
        raise KeyboardInterrupt
    out = merge_results(parts)
    if res.interrupted:
        for r in out.values():
            r.notes.append(f"interrupted: {len(r.runs)} of {runs} runs finished")
    return out
