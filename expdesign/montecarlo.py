"""Monte Carlo evaluation of designs as in Ljungberg (2022) section 9.1.2.

Protocol (default ``continuous``, as the thesis): every run is ONE experiment of ``n_samples``
samples (thesis: 1000 samples, 125 s at 8 Hz) started from the nominal state of its first
primitive. A fixed design gives each primitive round(w_q * n_samples) samples (efficient rounding,
then no block shorter than ``min_block`` samples: shorter ones are dropped below min_block/2 and
raised to min_block above); the blocks are played back to back, a block longer than its primitive
repeats the primitive's input. ``order='library'`` (default) plays them in the library's order
(tau1, tau2, ... for the model ship) in every run: the thesis forms ONE optimized input sequence
("an optimized input sequence of 125 s (1000 samples) was formed", section 9.1.2) and varies the
signals and their order over the runs only for the random design. ``order='given'`` keeps the
order of the design's mapping; ``order='random'`` draws the order from the run's seed instead (the
order moves the optimized figure by several points, see benchmarks/mc_identifiability.py). The
random design picks 1 of the primitives for each of ``n_segments`` equal segments, anew in every
run. ``settle`` > 0 inserts that many samples of the forces that hold the next primitive's start
state between blocks (the shares stay those of the primitives; the experiment gets longer). The
``piecewise`` protocol (each block a separate sub-experiment started from its primitive's nominal
state) is kept as an option.

Data come from the true system with the profile's disturbances (model ship: current u_c, v_c ~
N(0, 0.025) per sample and measurement noise e ~ N(0, 0.025), variances, i.e. std 0.158). The
thesis's estimator is the IV estimator of (9.2) with instruments simulated with the nominal
parameters (Table 9.1), re-simulated with the latest estimate up to ``iv_iterations`` times, and the
design's mean subtraction (``estimator='iv'``). The default ``estimator='oe'`` refines each run's IV
estimate by output error (:func:`expdesign.estimators.output_error`, the maximum-likelihood
estimate for white measurement noise: the IV regressors hold the noisy velocities and lose
precision to them, most of all Yur) and keeps the IV result of the same runs as the result's
``reference``. Metrics: see :mod:`expdesign.mc_result`.

Reproducibility: run i draws its order/segments from ``SeedSequence(seed, spawn_key=(i, 0))`` and
its noise from ``(i, 1)``; the simulation is batched only through elementwise operations and every
reduction and solve is done per run on arrays whose shape does not depend on the batch, and the IV
iterations stop per run. So a run's result depends on (seed, run index) alone, whatever the chunk,
engine or worker count (tests compare SHA-256 digests of all per-run results).

The data step (each run's blocks, noise and simulated data) is in :mod:`expdesign.mc_data`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from expdesign.errors import DesignError
from expdesign.estimators import OEData, output_error, output_error_unsupported
from expdesign.ivsolve import Z_LIMIT, instrument_moments, iv_estimates, run_forces
from expdesign.ivsolve import solve_moments as iv_moments_solve
from expdesign.mc_data import BatchSegment, run_noise, run_rng, run_segments, run_sequence, simulate_data  # noqa: F401 - run_noise: tests
from expdesign.mc_result import MCResult, merge_results
from expdesign.mc_validation import scored, validate, validation_input
from expdesign.rounding import efficient_rounding
from primitives import jitloop, threads
from primitives.information import MEAN_SUBTRACTION
from primitives.library import Primitive, thesis_primitives
from primitives.regressors import instruments
from primitives.ship import ShipProfile
from primitives.simulate import Disturbances, simulate
from primitives.steady_forces import steady_forces
from primitives.terms import TermSet

PROTOCOLS = ("continuous", "piecewise")
ORDERS = ("library", "given", "random")
ESTIMATORS = ("oe", "iv")
MAX_CHUNK = 250  # runs per batch: bounds memory; 250 measured 8 % less CPU a run than 500 (cache), 125 no better
# Smallest value of each integer setting of MCConfig (min_block: a sub-experiment needs two samples for one increment)
_MINIMA = (("n_segments", 1), ("min_block", 2), ("settle", 0), ("iv_iterations", 0), ("oe_iterations", 1))


@dataclass(frozen=True)
class MCConfig:
    """Everything a run's numbers depend on besides (seed, run index); see the module docstring."""

    runs: int = 500
    seed: int = 0
    n_samples: int = 1000
    n_segments: int = 5
    protocol: str = "continuous"
    order: str = "library"
    min_block: int = 40
    settle: int = 0
    mean_subtraction: str = "complete"
    iv_iterations: int = 3
    estimator: str = "oe"
    oe_iterations: int = 10
    validation_seed: int = 0

    def check(self) -> None:
        """Raise a DesignError naming the setting that is out of range."""
        if self.runs < 1:
            raise DesignError(f"Monte Carlo needs at least 1 run, got {self.runs}")
        if self.protocol not in PROTOCOLS:
            raise DesignError(f"Monte Carlo protocol must be one of {list(PROTOCOLS)}, got {self.protocol!r}")
        if self.order not in ORDERS:
            raise DesignError(f"Monte Carlo primitive order must be one of {list(ORDERS)}, got {self.order!r}")
        if self.estimator not in ESTIMATORS:
            raise DesignError(f"Monte Carlo estimator must be one of {list(ESTIMATORS)}, got {self.estimator!r}")
        if self.mean_subtraction not in MEAN_SUBTRACTION:
            raise DesignError(f"mean subtraction must be one of {list(MEAN_SUBTRACTION)}, got {self.mean_subtraction!r}")
        for name, lowest in _MINIMA:
            if getattr(self, name) < lowest:
                raise DesignError(f"Monte Carlo {name} {getattr(self, name)} is below {lowest}: give {name} >= {lowest}")
        if self.n_samples // self.n_segments < self.min_block:
            raise DesignError(
                f"{self.n_samples} samples in {self.n_segments} random segments is shorter than the minimum "
                f"sub-experiment of {self.min_block} samples: raise n_samples or lower min_block"
            )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class MCShared:
    """Inputs every run of every design reads, computed once and shipped to each worker: the
    primitives' inputs and start states, the input that holds each start state (settling), the
    designs' blocks, the true parameters and the validation input with its noise-free true output."""

    profile: ShipProfile
    config: MCConfig
    names: list[str]
    inputs: dict[str, np.ndarray]
    nu0: dict[str, np.ndarray]
    hold: dict[str, np.ndarray]
    designs: dict[str, Any]
    blocks: dict[str, list[tuple[str, int]]]
    dist: Disturbances
    predictor: TermSet
    theta0: np.ndarray | None
    param_names: list[str]
    val_inputs: np.ndarray
    val_nu0: np.ndarray
    val_true: np.ndarray
    notes: dict[str, list[str]] = field(default_factory=dict)
    oe_unsupported: str | None = None


def block_lengths(weights: Mapping[str, float], n_samples: int, min_block: int) -> tuple[list[tuple[str, int]], list[str]]:
    """(primitive, samples) blocks of a fixed design and notes on what the minimum changed.

    Efficient rounding of the shares to ``n_samples``; a block shorter than ``min_block`` is
    dropped when below min_block/2 (its samples re-rounded over the others) and otherwise raised
    to ``min_block``, the samples taken from the longest block."""
    names = [k for k, w in weights.items() if w > 0]
    w = np.array([float(weights[k]) for k in names])
    notes = []
    lengths = efficient_rounding(w, n_samples)
    while ((lengths > 0) & (lengths < min_block / 2)).any():
        j = int(np.where((lengths > 0) & (lengths < min_block / 2), lengths, np.inf).argmin())
        notes.append(f"{names[j]} dropped: {lengths[j]} samples is below half the minimum block of {min_block}")
        w[j] = 0.0
        lengths = efficient_rounding(w, n_samples)
    for j in np.flatnonzero((lengths > 0) & (lengths < min_block)):
        notes.append(f"{names[j]} raised from {lengths[j]} to the minimum block of {min_block} samples")
        lengths[int(lengths.argmax())] -= min_block - lengths[j]
        lengths[j] = min_block
    return [(n, int(c)) for n, c in zip(names, lengths) if c > 0], notes


def prepare(
    profile: ShipProfile,
    designs: Mapping[str, Any],
    config: MCConfig,
    primitives: list[Primitive] | None = None,
    disturbances: Disturbances | None = None,
) -> MCShared:
    """Check the designs and compute the shared inputs once (see :class:`MCShared`)."""
    config.check()
    lib = primitives if primitives is not None else thesis_primitives(profile)
    prims = {p.name: p for p in lib if p.kind == "informative"}
    if not prims:
        raise DesignError(f"profile {profile.name!r} has no informative primitives to evaluate")
    specs, blocks, notes = {}, {}, {}
    for name, spec in designs.items():
        spec = getattr(spec, "weights", spec)
        if isinstance(spec, str):
            if spec != "random":
                raise DesignError(f"design {name!r}: use fractions {{primitive: share}} or 'random', got {spec!r}")
        else:
            unknown = sorted(set(spec) - set(prims))
            if unknown:
                raise DesignError(f"design {name!r} uses unknown primitives {unknown}; the library has {sorted(prims)}")
            if not any(float(v) > 0 for v in spec.values()):
                raise DesignError(f"design {name!r} has no positive share")
            keys = [k for k in prims if k in spec] if config.order == "library" else list(spec)
            spec = {k: float(spec[k]) for k in keys}
            blocks[name], notes[name] = block_lengths(spec, config.n_samples, config.min_block)
        specs[name] = spec
    predictor = profile.predictor
    theta0 = profile.params(profile.simulation_set) if predictor.terms == profile.model.terms else None
    vin, vnu0 = validation_input(profile, config.n_samples, config.validation_seed)
    hold = (
        {k: profile.allocate(*np.array(steady_forces(profile, *p.nu0))[:, None])[0] for k, p in prims.items()}
        if config.settle
        else {}
    )
    return MCShared(
        profile=profile,
        config=config,
        names=list(prims),
        inputs={k: p.inputs for k, p in prims.items()},
        nu0={k: np.asarray(p.nu0, float) for k, p in prims.items()},
        hold=hold,
        designs=specs,
        blocks=blocks,
        dist=disturbances if disturbances is not None else Disturbances.from_profile(profile),
        predictor=predictor,
        theta0=theta0,
        param_names=profile.predictor_param_names,
        val_inputs=vin,
        val_nu0=vnu0,
        val_true=simulate(profile, vin, nu0=vnu0).nu[0],
        notes=notes,
        oe_unsupported=output_error_unsupported(profile, predictor) if config.estimator == "oe" else None,
    )


# -- one run's experiment -------------------------------------------------------------------------


# -- per-run estimation -----------------------------------------------------------------------------


def _solve_runs(sh: MCShared, segs: list[BatchSegment], runs: np.ndarray, starts: list[list[int]]) -> np.ndarray:
    """IV estimates (len(runs), p) of the runs at batch positions ``runs``
    (:func:`expdesign.ivsolve.iv_estimates`), the instrument mean removed per block (7.19) or over
    the experiment (7.20); NaN (a failed run) where a DOF's system is singular or
    ill-conditioned. The runs are solved as one stack (per-run reductions over the sample axis
    and LAPACK calls per system: a run's numbers are those of a solve of it alone), grouped by
    their block starts when the mean is removed per block."""
    theta = np.empty((len(runs), sh.predictor.n_params))
    if sh.config.mean_subtraction == "batchwise":
        groups: dict[tuple, list[int]] = {}
        for j, i in enumerate(runs):
            groups.setdefault(tuple(starts[i]), []).append(j)
    else:
        groups = {(0,): list(range(len(runs)))}
    for key, js in groups.items():
        sel = runs[js]
        if len(segs) == 1:  # the continuous protocol: the runs' rows as they are
            phi, tgt, z = segs[0].phi[sel], segs[0].tgt[sel], segs[0].z[sel]
        else:
            phi = np.concatenate([s.phi[sel] for s in segs], axis=1)
            tgt = np.concatenate([s.tgt[sel] for s in segs], axis=1)
            z = np.concatenate([s.z[sel] for s in segs], axis=1)
        theta[js] = iv_estimates(sh.predictor, phi, z, tgt, sh.config.mean_subtraction, list(key))
    return theta


def _resimulated_instruments(sh: MCShared, seg: BatchSegment, theta: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Instruments of the runs ``idx`` from the predictor simulated with their estimates."""
    with np.errstate(all="ignore"):
        return instruments(sh.profile, seg.inputs[idx], theta[idx], seg.nu0[idx], sim_terms=sh.predictor, terms=sh.predictor)


def _estimate(sh: MCShared, segs: list[BatchSegment], starts: list[list[int]]) -> np.ndarray:
    """Per-run IV estimates; each run re-simulates its instruments until its own estimate
    changes by less than 1e-3 (relative) or ``iv_iterations`` re-simulations were made."""

    def resolve(idx: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        znew = [_resimulated_instruments(sh, s, theta, idx) for s in segs]
        with np.errstate(invalid="ignore"):
            sane = np.logical_and.reduce([np.isfinite(z).all(axis=(1, 2)) & (np.abs(z).max(axis=(1, 2)) < Z_LIMIT) for z in znew])
        for s, z in zip(segs, znew):
            s.z[idx[sane]] = z[sane]
        th = np.full((len(idx), theta.shape[1]), np.nan)
        if sane.any():
            th[sane] = _solve_runs(sh, segs, idx[sane], starts)
        return th, sane

    return _iterate(_solve_runs(sh, segs, np.arange(segs[0].phi.shape[0]), starts), sh.config.iv_iterations, resolve)


def _iterate(theta: np.ndarray, iterations: int, resolve) -> np.ndarray:
    """The IV iterations from the first estimates ``theta`` (B, p): ``resolve(idx, theta)`` gives
    the runs ``idx``'s estimates from instruments re-simulated with their latest ones and whether
    that simulation stayed sane; a run stops when it did not (it keeps its estimate), when its
    estimate changes by less than 1e-3 (relative) or fails, or after ``iterations``."""
    active = np.isfinite(theta).all(axis=1)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        th, sane = resolve(idx, theta)
        active[idx[~sane]] = False  # its simulation diverged: keep the previous instruments and estimate
        idx, th = idx[sane], th[sane]
        if not idx.size:
            break
        with np.errstate(all="ignore"):
            change = np.max(np.abs(th - theta[idx]) / np.maximum(np.abs(th), 1e-12), axis=1)
        theta[idx] = th
        active[idx] = np.isfinite(th).all(axis=1) & (change >= 1e-3)
    return theta


def _fused(sh: MCShared) -> bool:
    """Whether the runs' instruments are simulated inside the IV moments' compiled pass
    (:func:`expdesign.ivsolve.instrument_moments`: no instrument array stored, the same numbers):
    the continuous protocol (one experiment per run), the mean removed over it or not at all, and
    a model the pass covers (checked on a one-sample problem; numba loaded)."""
    cfg, prof = sh.config, sh.profile
    if cfg.protocol != "continuous" or cfg.mean_subtraction == "batchwise" or not jitloop.loaded():
        return False
    inputs, nu0, y = np.zeros((1, 1, len(prof.inputs))), np.zeros((1, 3)), np.zeros((1, 2, 3))
    one = np.zeros(1, np.int64)
    return all(
        instrument_moments(prof, t, sh.predictor, inputs, nu0, np.zeros((t.n_params, 1)), one, y, "none") is not None
        for t in (prof.model, sh.predictor)
    )


def _estimate_fused(sh: MCShared, seg: BatchSegment) -> np.ndarray:
    """:func:`_estimate` with the instruments simulated in the moments' pass: the same iterations,
    stopping rules and numbers (the instrument model first, then each run's latest estimate)."""
    prof, cfg, b = sh.profile, sh.config, seg.y.shape[0]
    forces = run_forces(prof, seg.inputs)  # once for the four passes

    def solve(sim_terms: TermSet, coef: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        moments, sane = instrument_moments(prof, sim_terms, sh.predictor, forces, seg.nu0, coef, idx, seg.y, cfg.mean_subtraction)
        return iv_moments_solve(sh.predictor, *moments, cfg.mean_subtraction), sane

    first, _ = solve(prof.model, prof.params(prof.instrument_set)[:, None], np.arange(b))
    return _iterate(first, cfg.iv_iterations, lambda idx, theta: solve(sh.predictor, theta[idx].T, idx))


def run_chunk(sh: MCShared, design: str, run_ids: Sequence[int]) -> MCResult:
    """Runs ``run_ids`` of one design; each run's numbers depend only on (seed, run index). With
    the output-error estimator the IV estimate it starts from (the thesis's estimator) is scored
    too, as the result's ``reference``."""
    cfg = sh.config
    ids = [int(i) for i in run_ids]
    # The compiled passes sum in another order than numpy (estimates within the tolerance of
    # tests/test_oekernel.py): load them whatever the chunk's size, so that a run's numbers do not
    # depend on how the runs are cut into tasks (numba's load, about 0.6 s, once per process).
    jitloop.use(jitloop.MIN_WORK)
    played, layout = {}, {}  # the blocks and whole experiments built so far (a fixed design plays one)
    seqs = [tuple(run_sequence(sh, design, i)) for i in ids]
    for seq in seqs:
        if seq not in layout:
            layout[seq] = run_segments(sh, list(seq), played)
    layouts = [layout[seq] for seq in seqs]
    fused = _fused(sh)
    segs = simulate_data(sh, [lay[0] for lay in layouts], [run_rng(cfg.seed, i, 1) for i in ids], fused)
    theta = _estimate_fused(sh, segs[0]) if fused else _estimate(sh, segs, [lay[1] for lay in layouts])
    notes = list(sh.notes.get(design, []))
    if sh.theta0 is None:
        notes.append("predictor structure differs from the true model: parameter error not defined")
    if any(sh.dist.process_std):
        notes.append("process noise of the disturbances is not simulated in the Monte Carlo study")
    if cfg.estimator == "iv":
        return scored(sh, design, ids, theta, "iv", notes)
    if sh.oe_unsupported:
        return scored(sh, design, ids, theta, "iv", notes + [f"{sh.oe_unsupported}: the IV estimate is reported unrefined"])
    oe = output_error(
        sh.profile, [OEData(s.inputs, s.nu0, s.y) for s in segs], theta, terms=sh.predictor, max_iter=cfg.oe_iterations
    )
    b = len(ids)
    val = validate(sh, np.concatenate([oe.theta, theta]))  # one simulation loop for both; elementwise, so no change
    result = scored(sh, design, ids, oe.theta, "oe", notes, (val[0][:b], val[1][:b]))
    result.reference = scored(sh, design, ids, theta, "iv", list(notes), (val[0][b:], val[1][b:]))
    return result


def warm_compiled(sh: MCShared) -> None:
    """Load numba and compile (or load from its disk cache) every compiled pass a run of ``sh``
    calls, in this process, by running run 0 of the first design and dropping its result. A
    process pool forked after this inherits the machine code (no worker imports numba or loads
    a cache); workers started otherwise load the cache this wrote instead of each compiling the
    same code at once (a cold cache costs about 15 s of CPU per process)."""
    if jitloop.AVAILABLE:
        run_chunk(sh, next(iter(sh.designs)), [0])


# -- entry points ---------------------------------------------------------------------------------


def evaluate_designs(
    profile: ShipProfile,
    designs: Mapping[str, Any],
    runs: int = 500,
    seed: int = 0,
    *,
    primitives: list[Primitive] | None = None,
    disturbances: Disturbances | None = None,
    run_slice: tuple[int, int] | None = None,
    chunk_size: int = MAX_CHUNK,
    **protocol: Any,
) -> dict[str, MCResult]:
    """Monte Carlo results of several designs in this process (section 9.1.2): chunks of at most
    ``chunk_size`` runs (MAX_CHUNK at most), run on :func:`primitives.threads.count` threads
    (``OMP_NUM_THREADS``, else the cores, at most four; one in a pool or Dask worker).

    ``designs`` maps a label to fractions {primitive: w}, to an object with ``.weights``, or to
    "random". ``protocol`` takes the other :class:`MCConfig` fields (n_samples, n_segments,
    protocol, order, min_block, settle, mean_subtraction, iv_iterations, estimator, oe_iterations, validation_seed).
    ``run_slice=(a, b)`` evaluates runs a..b-1 only; chunks joined with :func:`merge_results`
    are bit-identical to one call over all runs.
    """
    cfg = MCConfig(runs=runs, seed=seed, **protocol)
    sh = prepare(profile, designs, cfg, primitives, disturbances)
    a, z = run_slice or (0, runs)
    if not 0 <= a < z <= runs:
        raise DesignError(f"run_slice {run_slice} must lie within 0..{runs}")
    step = max(1, min(chunk_size, MAX_CHUNK))
    chunks = [(d, c, min(z, c + step)) for d in sh.designs for c in range(a, z, step)]
    # the chunks on this process's threads (primitives.threads): a run's numbers depend on (seed,
    # run index) alone, so on neither the thread that runs its chunk nor what runs beside it
    parts = threads.map_in_threads(lambda ch: {ch[0]: run_chunk(sh, ch[0], range(ch[1], ch[2]))}, chunks)
    return merge_results(parts)
