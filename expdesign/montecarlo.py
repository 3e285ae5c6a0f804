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
from expdesign.mc_result import MCResult, merge_results
from expdesign.mc_validation import scored, validate, validation_input
from expdesign.rounding import efficient_rounding
from primitives import jitloop
from primitives.information import MEAN_SUBTRACTION
from primitives.library import Primitive, thesis_primitives
from primitives.regressors import instruments, predictor_regressors
from primitives.ship import ShipProfile
from primitives.simulate import Disturbances, signals_read, simulate
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


def _run_rng(seed: int, run: int, stream: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, stream)))


def _sequence(sh: MCShared, design: str, run: int) -> list[tuple[str, int]]:
    """Run ``run``'s (primitive, samples) blocks in the order they are played; its generator of
    stream 0 made only where it is read (a fixed design in a fixed order reads none)."""
    cfg, spec = sh.config, sh.designs[design]
    if isinstance(spec, str):
        seg = cfg.n_samples // cfg.n_segments
        return [(sh.names[i], seg) for i in _run_rng(cfg.seed, run, 0).integers(0, len(sh.names), cfg.n_segments)]
    blocks = sh.blocks[design]
    if cfg.protocol == "piecewise":
        # each block restarts from the nominal state: the order does not matter, long blocks are
        # cut into equal pieces no longer than the primitive
        out = []
        for k, n in blocks:
            m = -(-n // len(sh.inputs[k]))
            out += [(k, n // m + (i < n % m)) for i in range(m)]
        return out
    if cfg.order != "random":
        return list(blocks)
    return [blocks[i] for i in _run_rng(cfg.seed, run, 0).permutation(len(blocks))]


def _experiment(
    sh: MCShared, seq: list[tuple[str, int]], played: dict | None = None
) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[int]]:
    """Segments [(inputs (L, m), nu0 (3,))] of one run and the block start indices in the
    concatenated data (for batchwise mean subtraction). ``played`` keeps each (primitive,
    samples) block's inputs for the next run that plays it (read only)."""
    played = {} if played is None else played

    def block(k: str, n: int) -> np.ndarray:
        if (k, n) not in played:
            played[k, n] = np.resize(sh.inputs[k], (n, sh.inputs[k].shape[1]))
        return played[k, n]

    if sh.config.protocol == "piecewise":
        segs = [(block(k, n), sh.nu0[k]) for k, n in seq]
        return segs, list(np.cumsum([0] + [n for _, n in seq[:-1]]))
    parts, starts, pos = [], [], 0
    for j, (k, n) in enumerate(seq):
        starts.append(pos)
        if j and sh.config.settle:
            parts.append(np.tile(sh.hold[k], (sh.config.settle, 1)))
        parts.append(block(k, n))
        pos += n + (sh.config.settle if j else 0)
    return [(np.concatenate(parts), sh.nu0[seq[0][0]])], starts


@dataclass
class _Seg:
    """One segment position of a batch of runs: inputs (B, L, m), nu0 (B, 3), regressors and
    target from the noisy data (B, L, p) / (B, L, 3), instruments (B, L, p), measured velocities
    (B, L+1, 3). With the fused pass (:func:`_fused`) the pass builds phi, target and instruments
    itself: None here."""

    inputs: np.ndarray
    nu0: np.ndarray
    phi: np.ndarray | None
    tgt: np.ndarray | None
    z: np.ndarray | None
    y: np.ndarray


def _noise(
    d: Disturbances, gens: list[np.random.Generator], n: int, offsets: list[np.ndarray], heading: bool = True
) -> tuple[np.ndarray, ...]:
    """Each run's current (B, n, 2), wind (B, n, 2), measurement noise (B, n+1, 3) and heading noise
    (B, n+1): per run one draw of all its standard normals from its own generator, in the order
    current, wind, measurement, heading (the draws of four calls of that order, the same numbers),
    then scaled for all runs at once (elementwise: each number as a run alone gives it). Without
    ``heading`` (a caller that reads no heading noise and draws nothing after it) the heading's
    normals, the last, are not drawn and its noise is None. A wind without a random part is its
    mean, read-only, for every run and sample (mean + 0 * draw is the mean: no (B, n, 2) array)."""
    sizes = np.cumsum([0, 2 * n, 2 * n, 3 * (n + 1), n + 1])
    z = np.empty((len(gens), sizes[4 if heading else 3]))
    for g, row in zip(gens, z):
        g.standard_normal(out=row)  # normal(0, 1) is 0 + 1 * these: the same numbers
    b = len(gens)
    part = [z[:, sizes[i] : sizes[i + 1]] for i in range(4)]
    # scaled in place, in the draws' own array (a * s + m is m + a * s: addition commutes, the same bits)
    cur = part[0].reshape(b, n, 2)
    cur *= d.current_sample_std
    cur += (np.asarray(d.current_ne, float) + np.stack(offsets))[:, None, :]
    wind_ne = np.asarray(d.wind_ne, float)
    if d.wind_sample_std == 0 and not np.signbit(wind_ne).any():  # (-0.0 + 0.0 would be +0.0)
        wind = np.broadcast_to(wind_ne, (b, n, 2))
    else:
        wind = wind_ne + part[1].reshape(b, n, 2) * d.wind_sample_std
    meas = part[2].reshape(b, n + 1, 3)
    meas *= np.asarray(d.measurement_std, float)
    return cur, wind, meas, part[3] * d.heading_std if heading else None


def _simulate_data(sh: MCShared, exps: list, gens: list[np.random.Generator], fused: bool = False) -> list[_Seg]:
    """Noisy data of every segment position for a batch of runs (noise drawn per run); without
    the instruments (``z`` None) when ``fused``."""
    prof, d, b = sh.profile, sh.dist, len(exps)
    offsets = [g.normal(0.0, d.current_offset_std, 2) for g in gens]
    # the true system (disturbed) and the instrument model (calm) in one batch of 2B: the time
    # loop's cost is per step, not per realisation, and every operation in it is elementwise
    # (with the fused pass, :func:`_fused`, the instruments are simulated with the IV moments: the true system alone)
    sets = [prof.simulation_set] if fused else [prof.simulation_set, prof.instrument_set]
    theta = np.repeat(np.stack([prof.params(s) for s in sets]), b, axis=0)
    out = []
    for j in range(len(exps[0])):
        inp = np.stack([e[j][0] for e in exps])
        nu0 = np.stack([e[j][1] for e in exps])
        # the heading noise is read by the unfused path's regressors only; it is drawn all the same
        # before another experiment of the run, whose draws follow it
        last = j == len(exps[0]) - 1
        cur, wind, meas, head = _noise(d, gens, inp.shape[1], offsets, heading=not (fused and last))
        if not fused:  # the calm instrument model after the true system
            cur, wind = (np.concatenate([a, np.zeros_like(cur)]) for a in (cur, wind))
        env = Disturbances(current_ne=cur, wind_ne=wind, current_turning=d.current_turning)
        with np.errstate(all="ignore"):
            res = simulate(
                prof,
                np.concatenate([inp] * len(sets)),
                theta,
                nu0=np.concatenate([nu0] * len(sets)),
                disturbances=env,
                batch=len(sets) * b,
                positions="psi" in signals_read(sh.predictor),
            )  # the data's heading: integrated when the dynamics need it
        y = res.nu[:b] + meas
        if fused:  # the pass builds the regressors from y
            out.append(_Seg(inp, nu0, None, None, None, y))
            continue
        phi, tgt = predictor_regressors(prof, y, inp, res.eta[:b, :, 2] + head, terms=sh.predictor)
        z, _ = predictor_regressors(prof, res.nu[b:], inp, res.eta[b:, :, 2], terms=sh.predictor)
        out.append(_Seg(inp, nu0, phi, tgt, z, y))
    return out


# -- per-run estimation -----------------------------------------------------------------------------


def _solve_runs(sh: MCShared, segs: list[_Seg], runs: np.ndarray, starts: list[list[int]]) -> np.ndarray:
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


def _resimulated_instruments(sh: MCShared, seg: _Seg, theta: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Instruments of the runs ``idx`` from the predictor simulated with their estimates."""
    with np.errstate(all="ignore"):
        return instruments(sh.profile, seg.inputs[idx], theta[idx], seg.nu0[idx], sim_terms=sh.predictor, terms=sh.predictor)


def _estimate(sh: MCShared, segs: list[_Seg], starts: list[list[int]]) -> np.ndarray:
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


def _estimate_fused(sh: MCShared, seg: _Seg) -> np.ndarray:
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
    seqs = [tuple(_sequence(sh, design, i)) for i in ids]
    for seq in seqs:
        if seq not in layout:
            layout[seq] = _experiment(sh, list(seq), played)
    layouts = [layout[seq] for seq in seqs]
    fused = _fused(sh)
    segs = _simulate_data(sh, [lay[0] for lay in layouts], [_run_rng(cfg.seed, i, 1) for i in ids], fused)
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
    """Monte Carlo results of several designs in this process (section 9.1.2).

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
    return merge_results([{d: run_chunk(sh, d, range(c, min(z, c + step)))} for d in sh.designs for c in range(a, z, step)])
