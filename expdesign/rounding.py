"""From time fractions to whole repetitions of (split) primitives.

Step 1, efficient rounding (Pukelsheim & Rieder 1992, "Efficient rounding of approximate
designs"): n_q = ceil((n - l/2) w_q) on the support (l points), then add one to the q with the
smallest n_q / w_q or remove one from the q with the largest (n_q - 1) / w_q until sum n_q = n.
For units of different length (pieces of different primitives) the counts are apportioned in
time: floor(w_q T / d_q), then units are added greedily while they fit the trial length.
Step 2, a local exchange: move one unit from one primitive to another (and, for unequal units,
add or drop one) whenever that raises the design criterion of the realised mix and keeps the
total within the trial length. The efficiency lost against the continuous design is reported.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from expdesign.errors import DesignError


def efficient_rounding(weights: np.ndarray, n: int, tol: float = 1e-9) -> np.ndarray:
    """Pukelsheim-Rieder efficient apportionment of n units to fractions ``weights``: sum = n."""
    w = np.asarray(weights, float)
    if n < 0 or w.ndim != 1 or np.any(w < -tol) or w.sum() <= 0:
        raise DesignError("rounding needs non-negative fractions with a positive sum and n >= 0")
    w = np.clip(w, 0, None) / w.sum()
    support = w > tol
    c = np.zeros(len(w), int)
    c[support] = np.ceil((n - support.sum() / 2.0) * w[support]).astype(int)
    c = np.maximum(c, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        while c.sum() < n:
            j = np.where(support, c / np.where(support, w, 1), np.inf).argmin()
            c[j] += 1
        while c.sum() > n:
            k = np.where(support & (c > 0), (c - 1) / np.where(support, w, 1), -np.inf).argmax()
            c[k] -= 1
    return c


def criterion_efficiency(value: float, reference: float, n_params: int, criterion: str) -> float:
    """Efficiency of a design value against a reference value of the same criterion:
    D (log det): exp((v - ref) / p); A (-tr M^-1): ref / v; E (lambda_min): v / ref."""
    if criterion not in ("D", "A", "E"):
        raise DesignError(f"efficiency of criterion {criterion!r}: only D, A and E values compare")
    if not (np.isfinite(value) and np.isfinite(reference)):
        return 0.0
    if criterion == "D":
        return float(np.exp((value - reference) / n_params))
    if criterion == "A":
        return float(reference / value) if value < 0 else 0.0
    return float(value / reference) if reference > 0 else 0.0


@dataclass
class Rounded:
    """counts: units of each primitive; unit_samples: samples per unit; samples = counts * unit;
    fractions: the realised time fractions; objective: criterion of the realised design in
    absolute samples; continuous_objective: the same for the fractions at the same total length;
    efficiency: criterion efficiency against the continuous design (1 = nothing lost)."""

    counts: np.ndarray
    unit_samples: np.ndarray
    samples: np.ndarray
    fractions: np.ndarray
    objective: float
    continuous_objective: float
    efficiency: float
    exchanges: int

    @property
    def efficiency_loss(self) -> float:
        return float(max(0.0, 1.0 - self.efficiency))


def round_design(
    weights: np.ndarray,
    unit_samples: np.ndarray,
    total_samples: int,
    objective: Callable[[np.ndarray], float],
    n_params: int,
    *,
    criterion: str = "D",
    max_rounds: int = 200,
) -> Rounded:
    """Whole units per primitive for a trial of ``total_samples``.

    ``objective(samples_per_primitive)`` is the design criterion in absolute samples (for D:
    log|det(sum N_q Gamma_q)|, which is what a real trial of that many samples gets). With equal
    unit lengths the count is exactly total_samples // unit (efficient rounding + exchanges keep
    the sum); otherwise the total never exceeds the trial length.
    """
    w = np.asarray(weights, float)
    d = np.asarray(unit_samples, int)
    if np.any(d <= 0):
        raise DesignError("every primitive unit needs at least one sample")
    if total_samples < d.min():
        raise DesignError(
            f"trial length of {total_samples} samples is shorter than the shortest primitive unit ({d.min()} samples)"
        )
    equal = bool(np.all(d == d[0]))
    c = efficient_rounding(w, total_samples // d[0]) if equal else _apportion_time(w, d, total_samples)
    c, best, moves = _exchange(c, d, total_samples, objective, equal, max_rounds)
    samples = c * d
    cont = objective(w * total_samples)
    eff = criterion_efficiency(best, cont, n_params, criterion)
    frac = samples / samples.sum() if samples.sum() else samples.astype(float)
    return Rounded(c, d, samples, frac, float(best), float(cont), eff, moves)


def _apportion_time(w: np.ndarray, d: np.ndarray, total_samples: int) -> np.ndarray:
    """Step 1 for units of different length: floor(w_q T / d_q) units, a unit for every support
    point that fits, then units added greedily while they fit the trial length."""
    c = np.floor(w * total_samples / d).astype(int)
    # every support point gets a unit first (largest weight first) if it fits, as the
    # efficient rounding does for equal units: a primitive left out can make Gamma singular
    for q in np.argsort(-w):
        if w[q] > 1e-3 and c[q] == 0:
            while c @ d + d[q] > total_samples and np.any((c > 1) & (np.arange(len(c)) != q)):
                surplus = np.where(c > 1, c * d - w * total_samples, -np.inf)
                c[surplus.argmax()] -= 1
            if c @ d + d[q] <= total_samples:
                c[q] += 1
    while True:  # greedy fill by largest remaining time deficit that still fits
        room = total_samples - c @ d
        deficit = w * total_samples - c * d
        ok = (d <= room) & (w > 1e-9)
        if not ok.any():
            break
        c[np.where(ok, deficit, -np.inf).argmax()] += 1
    return c


def _moves(c: np.ndarray, equal: bool) -> list[tuple[int, int]]:
    """Step 2's single moves (from, to) of one unit, -1 for none: between two primitives, and
    for unequal units also adding or dropping one."""
    q = len(c)
    cands = [(i, j) for i in range(q) if c[i] != 0 for j in range(q) if i != j]
    if not equal:
        cands += [(-1, j) for j in range(q)] + [(i, -1) for i in range(q) if c[i] > 0]
    return cands


def _exchange(
    c: np.ndarray, d: np.ndarray, total_samples: int, objective: Callable[[np.ndarray], float], equal: bool, max_rounds: int
) -> tuple[np.ndarray, float, int]:
    """Step 2, the local exchange: the steepest single move (:func:`_moves`) that raises the
    criterion and keeps the total within the trial length, until none does. Returns the counts,
    their criterion and the number of moves made."""

    def obj(cnt: np.ndarray) -> float:
        return objective(cnt * d) if cnt.sum() else -np.inf

    best = obj(c)
    moves = 0
    for _ in range(max_rounds):
        best_new, best_v = None, best
        for i, j in _moves(c, equal):  # best improvement: the steepest single move
            new = c.copy()
            if i >= 0:
                new[i] -= 1
            if j >= 0:
                new[j] += 1
            if new @ d > total_samples or not new.any():
                continue
            v = obj(new)
            if v > best_v + 1e-10 * (1 + abs(best_v)):
                best_new, best_v = new, v
        if best_new is None:
            break
        c, best = best_new, best_v
        moves += 1
    return c, best, moves
