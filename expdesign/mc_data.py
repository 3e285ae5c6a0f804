"""The data step of the Monte Carlo of :mod:`expdesign.montecarlo`: each run's sequence of
primitive blocks, its inputs, its noise drawn from its own generators, and the batch's simulated
noisy data (Ljungberg 2022, section 9.1.2: the true system with the profile's disturbances and
measurement noise, and the instrument model simulated calm with the nominal parameters).

Run i draws its order/segments from ``SeedSequence(seed, spawn_key=(i, 0))`` and its noise from
``(i, 1)``; every operation across the batch is elementwise, so a run's data depend on (seed, run
index) alone.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from primitives.regressors import predictor_regressors
from primitives.simulate import Disturbances, signals_read, simulate

if TYPE_CHECKING:
    from expdesign.montecarlo import MCShared


def run_rng(seed: int, run: int, stream: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run, stream)))


def run_sequence(sh: MCShared, design: str, run: int) -> list[tuple[str, int]]:
    """Run ``run``'s (primitive, samples) blocks in the order they are played; its generator of
    stream 0 made only where it is read (a fixed design in a fixed order reads none)."""
    cfg, spec = sh.config, sh.designs[design]
    if isinstance(spec, str):
        seg = cfg.n_samples // cfg.n_segments
        return [(sh.names[i], seg) for i in run_rng(cfg.seed, run, 0).integers(0, len(sh.names), cfg.n_segments)]
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
    return [blocks[i] for i in run_rng(cfg.seed, run, 0).permutation(len(blocks))]


def run_segments(
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
class BatchSegment:
    """One segment position of a batch of runs: inputs (B, L, m), or (1, L, m) when every run plays
    the same array (:func:`_batch_inputs`: read by run only through a broadcast), nu0 (B, 3), regressors and
    target from the noisy data (B, L, p) / (B, L, 3), instruments (B, L, p), measured velocities
    (B, L+1, 3). With the fused pass (:func:`_fused`) the pass builds phi, target and instruments
    itself: None here."""

    inputs: np.ndarray
    nu0: np.ndarray
    phi: np.ndarray | None
    tgt: np.ndarray | None
    z: np.ndarray | None
    y: np.ndarray


def run_noise(
    d: Disturbances, gens: list[np.random.Generator], n: int, offsets: list[np.ndarray], heading: bool = True
) -> tuple[np.ndarray, ...]:
    """Each run's current (B, n, 2), wind (B, n, 2), measurement noise (B, n+1, 3) and heading noise
    (B, n+1): per run its standard normals from its own generator, in the order current, wind,
    measurement, heading (consecutive calls give the numbers of one call of their total size), each
    drawn straight into its own contiguous array, then scaled for all runs at once (elementwise:
    each number as a run alone gives it). Without ``heading`` (a caller that reads no heading noise
    and draws nothing after it) the heading's normals, the last, are not drawn and its noise is
    None. A wind without a random part is its mean, read-only, for every run and sample (mean + 0 *
    draw is the mean: no (B, n, 2) array); its normals are still drawn, into one scratch row that
    the next run overwrites, since the measurement's follow them in the run's stream."""
    b = len(gens)
    cur = np.empty((b, n, 2))
    wind_ne = np.asarray(d.wind_ne, float)
    calm_wind = d.wind_sample_std == 0 and not np.signbit(wind_ne).any()  # (-0.0 + 0.0 would be +0.0)
    wind_z = np.empty((1 if calm_wind else b, n, 2))
    meas = np.empty((b, n + 1, 3))
    head = np.empty((b, n + 1)) if heading else None
    for j, g in enumerate(gens):  # standard_normal is normal(0, 1)'s numbers: 0 + 1 * these
        g.standard_normal(out=cur[j])
        g.standard_normal(out=wind_z[0 if calm_wind else j])
        g.standard_normal(out=meas[j])
        if head is not None:
            g.standard_normal(out=head[j])
    # scaled in place (a * s + m is m + a * s: addition commutes, the same bits)
    cur *= d.current_sample_std
    cur += (np.asarray(d.current_ne, float) + np.stack(offsets))[:, None, :]
    if calm_wind:
        wind = np.broadcast_to(wind_ne, (b, n, 2))
    else:
        wind = wind_ne + wind_z * d.wind_sample_std
    meas *= np.asarray(d.measurement_std, float)
    if head is not None:
        head *= d.heading_std
    return cur, wind, meas, head


def _batch_inputs(runs: list[np.ndarray], shared: bool) -> np.ndarray:
    """The inputs (B, L, m) of a batch's runs at one segment position, or (1, L, m) when ``shared``
    and every run plays the same array (a fixed design in a fixed order: :func:`run_segments`
    builds its experiment once). The compiled passes read input column 0 for every run of a
    one-column batch (the same numbers, so the same bits) and step no (B, L, m) copy, nor its
    time-major forces (stop 53); the numpy path's regressors take the full stack."""
    if shared and all(r is runs[0] for r in runs):
        return runs[0][None]
    return np.stack(runs)


def simulate_data(sh: MCShared, exps: list, gens: list[np.random.Generator], fused: bool = False) -> list[BatchSegment]:
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
        inp = _batch_inputs([e[j][0] for e in exps], fused)
        nu0 = np.stack([e[j][1] for e in exps])
        # the heading noise is read by the unfused path's regressors only; it is drawn all the same
        # before another experiment of the run, whose draws follow it
        last = j == len(exps[0]) - 1
        cur, wind, meas, head = run_noise(d, gens, inp.shape[1], offsets, heading=not (fused and last))
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
        y = np.add(meas, res.nu[:b], out=meas)  # nu + e, written over the noise (no third array)
        if fused:  # the pass builds the regressors from y
            out.append(BatchSegment(inp, nu0, None, None, None, y))
            continue
        phi, tgt = predictor_regressors(prof, y, inp, res.eta[:b, :, 2] + head, terms=sh.predictor)
        z, _ = predictor_regressors(prof, res.nu[b:], inp, res.eta[b:, :, 2], terms=sh.predictor)
        out.append(BatchSegment(inp, nu0, phi, tgt, z, y))
    return out
