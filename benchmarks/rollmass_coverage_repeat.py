"""``bench_rollmass_coverage.py repeat``: one ship, case and steering of the family fitted on fresh seas (and, with
``--fresh-sensor``, fresh sensor noise), a role's dataset alone varied (``--vary``), the noise model frozen
(``--freeze-noise``), and with ``--store`` each sea's fit kept for ``sea_analyse`` and ``vary_analyse``."""

from __future__ import annotations

import argparse
import copy
import inspect
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.rollmass_coverage_fits import capture, load_fields, sensor_noise_off
from identify.rollmass import oe_fit
from identify.rollmass.api import estimate_from_files
from primitives.errors import UserError
from tests.physics import basin_truth as bt


def fresh_sea(scale: float, key: list[int], hold: tuple[list[int], set[int]] | None = None) -> None:
    """The truth's sea (JONSWAP or base disturbance) drawn from a stream of its own, ``key`` + a call
    counter, times ``scale``; the truth's own draw is made and dropped, so the run's stream goes on as
    before (the ship, the steering and the sensor noise stay the draws of the truth's seed). The sea is
    drawn once per dataset, in :data:`basin_truth.DATASETS` order, so the call counter is the dataset's index;
    ``hold = (fixed_key, varied)``: only the datasets whose index is in ``varied`` take ``key``'s sea, the others
    ``fixed_key``'s (one sea held for them over the realizations)."""
    calls = [0]

    def fresh(draw, *args):
        draw(*args)  # consumes the run's stream
        k = key if hold is None or calls[0] in hold[1] else hold[0]
        own = np.random.default_rng([*k, calls[0]])
        calls[0] += 1
        return scale * draw(*[own if isinstance(x, np.random.Generator) else x for x in args])

    for name in ("_jonswap", "_narrowband"):
        draw = _TRUTH_SEA.setdefault(name, getattr(bt, name))  # the truth's own, not an earlier call's wrapper
        setattr(bt, name, lambda *args, _draw=draw: fresh(_draw, *args))


_TRUTH_SEA: dict = {}


def fresh_sensor(key: list[int]) -> None:
    """The IMU's noise and bias (:func:`basin_truth._measure`'s draws, and its AHRS roll error's seed) drawn from a
    stream of its own, ``key`` + a call counter (the dataset's index, as in :func:`fresh_sea`), instead of the run's
    stream: each realization then has its own sensor noise, where plain ``repeat`` keeps the family's draw on every
    sea. ``_measure`` is the run stream's last consumer, so the ship, the steering and the sea are unchanged."""
    calls = [0]
    measure = _TRUTH_SEA.setdefault("_measure", bt._measure)  # the truth's own, not an earlier call's wrapper

    def fresh(*args):
        own = np.random.default_rng([*key, 0x5E45, calls[0]])
        calls[0] += 1
        return measure(args[0], own, *args[2:15], int(own.integers(2**31)))  # args[15]: the AHRS error's seed

    bt._measure = fresh


def _quiet_reference(a: argparse.Namespace, seed: int, seen: dict) -> dict:
    """The same ship, case and steering without the sea (and, with ``--no-sensor-noise``, without the sensor's noise):
    its fit's final point ``x_q`` (the ship's pseudo-true parameters in the oe model) and its datasets as the
    fit read them (for :func:`_disturbance`)."""
    fresh_sea(0.0, [a.sea_seed, 10**6])
    ship, data = bt.simulate_runs(a.variant, a.runs, seed)
    seen.clear()
    with tempfile.TemporaryDirectory() as d:
        recs = bt.case_recordings(ship, data, a.case, a.run)
        e = estimate_from_files(*[bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs], method="oe")
    print(f"quiet: m {e.m:.4f}, z {e.zbar_m:.4f}, converged {e.converged}", flush=True)
    return {"x": seen["x"], "datasets": seen["prob"].datasets}


def _disturbance(prob, quiet: dict) -> dict:
    """The residual of one sea's fit at the quiet fit's point ``x_q``, on its own data and on the quiet data with the
    same whiteners, weights and turn inputs: ``e = f(x_q; sea) - f(x_q; quiet)`` is the sea's response in the
    residual at fixed parameters (the true disturbance the fit sees, not projected)."""
    q = copy.copy(prob)
    q.datasets = quiet["datasets"]
    q.Y = [oe_fit._measured(d, prob.kn.g) for d in q.datasets]
    f_sea, f_quiet = prob.residual(quiet["x"]), q.residual(quiet["x"])
    return {"x_q": quiet["x"], "f_sea_q": f_sea, "e_q": f_sea - f_quiet}


def _store_sea(out: Path, seen: dict, quiet: dict, fields: dict[str, float]) -> None:
    """One sea's whole Jacobian, residual and final point with the sea's own response (see `sea_analyse`)."""
    keep = {k: seen[k] for k in ("J", "f", "x", "lengths", "lags")}
    np.savez_compressed(out, **keep, free=np.array(seen["free"]), **fields, **_disturbance(seen["prob"], quiet))


ROLES = ("nominal", "calibration", "loaded")


# a fit's _reweighted calls per LM path: fit_output_error's n_reweight default (read, so it cannot go stale)
FROZEN_STAGES = inspect.signature(oe_fit.fit_output_error).parameters["n_reweight"].default


def held_sea(a: argparse.Namespace) -> tuple[list[int], set[int]] | None:
    """``--vary ROLE``: the fresh sea for that role's dataset only, the case's other datasets on one held sea
    (``--held-sea K``: realization K's of ``--sea-seed``), for :func:`fresh_sea`; ``None`` for ``--vary all``."""
    if not 0 <= a.held_sea < a.realizations:
        raise SystemExit(f"--held-sea {a.held_sea}: must be one of the {a.realizations} realizations (it is fitted first)")
    if a.vary == "all":
        return None
    name = bt.CASES[a.case][ROLES.index(a.vary)]
    return [a.sea_seed, a.held_sea], {list(bt.DATASETS).index(name)}


def frozen_noise() -> list:
    """``--freeze-noise``: the first fit after this call records its stages' whiteners and weights
    (``oe_fit._reweighted``'s returns), every later fit replays them in the same order instead of estimating its own
    from its residuals (the noise model held, as the sandwich takes it: given, not estimated from the same data)."""
    kept: list = []
    calls = [0]
    orig = oe_fit._reweighted

    def frozen(errs, ar, ar_order):
        if len(kept) < FROZEN_STAGES:
            kept.append(orig(errs, ar, ar_order))
            return kept[-1]
        calls[0] += 1
        return kept[(calls[0] - 1) % FROZEN_STAGES]

    oe_fit._reweighted = frozen
    return kept


def _sensor_label(a: argparse.Namespace) -> str:
    """Which sensor noise the realizations had, for the summary line."""
    return "off" if a.no_sensor_noise else "fresh" if a.fresh_sensor else "the run's"


def repeat(a: argparse.Namespace) -> None:
    """One ship, case and steering of the family (``--variant``, ``--run``, ``--case``: the truth bench's
    draws), fitted on ``--realizations`` fresh seas (:func:`fresh_sea`): the load's spread over the seas
    against the mean sd the fits report, and the z-scores ``(estimate - truth) / reported sd``. Unlike the
    pooled fits of ``fit`` (ships and cases differ, and a run's cases share datasets) this measures the
    interval of one ship: its sandwich's error, not the spread of the family's biases."""
    if a.fresh_sensor and a.no_sensor_noise:
        raise SystemExit("--fresh-sensor with --no-sensor-noise: there is no sensor noise to draw afresh; fix: drop one")
    if a.no_sensor_noise:
        sensor_noise_off()
    seed = bt.variant_seed(a.seed, a.variant)  # as bench_rollmass_truth.py
    m_true, z_true = bt.truth_load(a.case)
    seen = capture()
    if a.store:
        Path(a.store).mkdir(parents=True, exist_ok=True)
    quiet = _quiet_reference(a, seed, seen) if a.store else None
    rows = []
    hold = held_sea(a)
    if a.freeze_noise:  # recorded on the held sea's fit (realization --held-sea is fitted first)
        frozen_noise()
    order = sorted(range(a.realizations), key=lambda k: k != a.held_sea)
    for k in order:
        seen.clear()
        fresh_sea(a.sea_scale, [a.sea_seed, k], hold)
        if a.fresh_sensor:
            fresh_sensor([a.sea_seed, k])
        ship, data = bt.simulate_runs(a.variant, a.runs, seed)
        with tempfile.TemporaryDirectory() as d:
            recs = bt.case_recordings(ship, data, a.case, a.run)
            paths = [bt.write_csv(r, Path(d) / f"{r.role}.csv") for r in recs]
            c0 = time.process_time()
            try:
                e = estimate_from_files(*paths, method="oe")
            except UserError as exc:
                print(f"sea {k:2d}: refused: {exc}", flush=True)
                continue
        if e.converged and np.isfinite(e.m_sd) and np.isfinite(e.zbar_m_sd):  # a failed fit is said, not averaged
            rows.append((e.m, e.m_sd, e.zbar_m, e.zbar_m_sd))
            if a.store and "J" in seen:
                _store_sea(Path(a.store) / f"sea{k:02d}.npz", seen, quiet, load_fields(e, m_true, z_true))
        print(
            f"sea {k:2d}: m {e.m:.4f} sd {e.m_sd:.4f}, z {e.zbar_m:.4f} sd {e.zbar_m_sd:.4f}, converged {e.converged}, "
            f"{time.process_time() - c0:.1f} s cpu",
            flush=True,
        )
    if len(rows) < 2:
        print(f"{len(rows)} of {a.realizations} fits converged: no spread to compare")
        return
    x = np.array(rows)
    zs = np.column_stack([(x[:, 0] - m_true) / x[:, 1], (x[:, 2] - z_true) / x[:, 3]])
    inside = int(np.all(np.abs(zs) <= 1.96, axis=1).sum())
    print(
        f"{a.variant} run {a.run} {a.case}, sea x{a.sea_scale:g}, vary {a.vary}, sensor {_sensor_label(a)}, {len(x)} of {a.realizations} seas converged: spread / mean reported sd "
        f"{x[:, 0].std(ddof=1) / x[:, 1].mean():.2f} (mass) {x[:, 2].std(ddof=1) / x[:, 3].mean():.2f} (height); "
        f"z sd {zs[:, 0].std(ddof=1):.2f} / {zs[:, 1].std(ddof=1):.2f}, mean {zs[:, 0].mean():+.2f} / {zs[:, 1].mean():+.2f}; "
        f"both inside {inside} of {len(x)}"
    )
