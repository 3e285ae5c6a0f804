"""Option validators and size estimates: refuse a bad or runaway request before any work.

Every check raises :class:`primitives.errors.UserError` (or the subclass the caller passes) with
one line that names the option, the value, the unit and what to give instead. Size checks print
their estimate, so a user sees why a request is refused and which option to change.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping

from primitives.errors import UserError

# Measured by timing expdesign.montecarlo.evaluate_designs (one design, 40 runs x 1000 and 4000
# samples, model-ship and full-scale): 16-26 us per run-sample on one core of this machine.
# 30 us keeps the estimate on the safe side.
MC_SECONDS_PER_RUN_SAMPLE = 30e-6
# Stated limits (not machine limits): beyond them a request is almost surely a typo.
MAX_MC_RUN_SAMPLES = 1e8  # runs x samples per design: ~50 CPU-minutes per design at the rate above
MAX_MC_SAMPLES = 1_000_000  # samples per Monte Carlo experiment (thesis: 1000)
MAX_COUNT_COMBINATIONS = 200_000  # product of (count + 1): the planner's state space grows with it
MAX_SWEEP_CELLS = 2_000
MAX_PRIMITIVE_SAMPLES = 50_000  # samples of one manoeuvre: a speed of 0.001 m/s asks for millions


def _as_float(value: object, option: str, unit: str, error: type[UserError]) -> float:
    if isinstance(value, bool):
        raise error(f"{option}: expected a number{_u(unit)}, got {value!r}")
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise error(f"{option}: expected a number{_u(unit)}, got {value!r}") from None
    if not math.isfinite(x):
        raise error(f"{option}: must be a finite number{_u(unit)}, got {value!r}")
    return x


def _u(unit: str) -> str:
    return f" in {unit}" if unit else ""


def finite(value: object, option: str, unit: str = "", error: type[UserError] = UserError) -> float:
    """``value`` as a finite float, else a one-line error naming ``option`` and ``unit``."""
    return _as_float(value, option, unit, error)


def positive(
    value: object, option: str, unit: str = "", error: type[UserError] = UserError, *, allow_zero: bool = False
) -> float:
    """A finite number > 0 (>= 0 with ``allow_zero``)."""
    x = _as_float(value, option, unit, error)
    if x < 0 or (x == 0 and not allow_zero):
        raise error(f"{option}: must be {'>= 0' if allow_zero else '> 0'}{_u(unit)}, got {value!r}")
    return x


def in_range(value: object, option: str, lo: float, hi: float, unit: str = "", error: type[UserError] = UserError) -> float:
    """A finite number in [lo, hi]."""
    x = _as_float(value, option, unit, error)
    if not lo <= x <= hi:
        raise error(f"{option}: must lie in {lo:g}..{hi:g}{_u(unit)}, got {value!r}")
    return x


def whole(value: object, option: str, lo: int, hi: int, what: str = "", error: type[UserError] = UserError) -> int:
    """An integer in [lo, hi]; ``what`` names the unit (runs, samples, ...)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise error(f"{option}: expected a whole number{' of ' + what if what else ''}, got {value!r}")
    if not lo <= value <= hi:
        raise error(f"{option}: must be {lo}..{hi}{' ' + what if what else ''}, got {value}")
    return value


def one_of(value: str, option: str, choices: tuple[str, ...] | list[str], error: type[UserError] = UserError) -> str:
    if value not in choices:
        raise error(f"{option}: {value!r} is not one of {', '.join(map(str, choices))}")
    return value


def _nearest(key: object, known: list[str]) -> str | None:
    """The known key ``key`` is most likely a misspelling of, if any is close."""
    import difflib

    near = difflib.get_close_matches(str(key), known, n=1, cutoff=0.5)
    return near[0] if near else None


def unknown_key(keys: Iterable[object], allowed: Iterable[object]) -> tuple[str, str] | None:
    """The first key not in ``allowed`` and a hint ("; did you mean X?" or the known keys), or None.
    A misspelt key must be refused, never silently fall back to a default."""
    known = list(allowed)
    for k in keys:
        if k not in known:
            near = _nearest(k, known)
            return str(k), (f"; did you mean {near}?" if near else f"; known: {', '.join(known)}")
    return None


def check_table_keys(
    table: Iterable[object], accepted: Iterable[object], file: str, where: str, error: type[UserError] = UserError
) -> None:
    """Refuse the first key of ``table`` that is not ``accepted``, in one line naming the ``file``,
    the table (``where``: "[rigid_body]", "[[pods]] number 1", "the top level"), the key, the nearest
    accepted key and every accepted key: a stray or misspelt key is never silently ignored."""
    accepted = [str(a) for a in accepted]
    for k in table:
        if k not in accepted:
            near = _nearest(k, accepted)
            hint = f" (did you mean {near!r}?)" if near else ""
            raise error(f"{file}: unknown key {str(k)!r} in {where}{hint}; accepted keys: {', '.join(accepted) or 'none'}")


def available_memory_bytes() -> int:
    """Memory the kernel says is available now (MemAvailable), or 4 GiB when it cannot tell."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 4 << 30


def human_bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} TiB"  # pragma: no cover


def human_seconds(s: float) -> str:
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.0f} min"
    if s < 172800:
        return f"{s / 3600:.1f} h"
    return f"{s / 86400:.0f} days"


# -- size estimates ---------------------------------------------------------------------------------


def monte_carlo_estimate(runs: int, samples: int, designs: int = 4, workers: int | None = None) -> dict[str, float]:
    """CPU time, wall time and peak memory of a Monte Carlo evaluation (see MC_SECONDS_PER_RUN_SAMPLE).

    Memory: each worker holds one experiment of ``samples`` rows of states, inputs, noise and
    regressors (about 64 float64 per row, generous) plus per-run metrics.
    """
    workers = workers or os.cpu_count() or 1
    cpu_s = MC_SECONDS_PER_RUN_SAMPLE * runs * samples * designs
    mem = workers * samples * 64 * 8 + runs * designs * 8 * 8
    return {"cpu_s": cpu_s, "wall_s": cpu_s / workers, "memory_bytes": mem}


def check_monte_carlo(runs: int, samples: int, designs: int = 4, error: type[UserError] = UserError) -> dict[str, float]:
    """Refuse a Monte Carlo evaluation beyond the stated limits or the machine's memory."""
    whole(runs, "--monte-carlo", 0, 10**9, "runs", error)
    whole(samples, "--mc-samples", 10, MAX_MC_SAMPLES, "samples per experiment", error)
    est = monte_carlo_estimate(runs, samples, designs)
    if runs * samples > MAX_MC_RUN_SAMPLES:
        raise error(
            f"--monte-carlo {runs} x --mc-samples {samples} = {runs * samples:.3g} run-samples per design would take about "
            f"{human_seconds(est['wall_s'])} on this machine ({human_seconds(est['cpu_s'])} of CPU for {designs} designs); "
            f"the limit is {MAX_MC_RUN_SAMPLES:.0e}: lower --monte-carlo (500 is the thesis's) or --mc-samples"
        )
    avail = available_memory_bytes()
    if est["memory_bytes"] > 0.8 * avail:
        raise error(
            f"--monte-carlo {runs} x --mc-samples {samples} needs about {human_bytes(est['memory_bytes'])}, more than the "
            f"{human_bytes(avail)} available: lower --mc-samples"
        )
    return est


def check_counts(counts: Mapping[str, int], option: str = "--counts", error: type[UserError] = UserError) -> int:
    """Refuse counts whose combinations (product of count + 1) would blow up the planner's search.

    The A* state holds how many of each manoeuvre are done, so the state space is the lattice
    times prod(count_i + 1). Returns that product.
    """
    combos = 1
    for name, n in counts.items():
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise error(f"{option}: {name}={n!r} must be a whole number >= 0")
        combos *= n + 1
        if combos > MAX_COUNT_COMBINATIONS:
            total = sum(counts.values())
            raise error(
                f"{option}: {total} manoeuvres in all give more than {MAX_COUNT_COMBINATIONS:,} count combinations "
                f"(product of count + 1), each a copy of the planning lattice; plan fewer per primitive (the design gives 1-5)"
            )
    return combos


def check_sweep_size(n_cells: int, src: str, error: type[UserError] = UserError) -> None:
    if n_cells > MAX_SWEEP_CELLS:
        raise error(
            f"{src}: the sweep has {n_cells:,} cells (ships x speeds x criteria x modes), over the limit of {MAX_SWEEP_CELLS:,}; "
            "split it into several sweep files"
        )


def manoeuvre_samples(distance_m: float, speed_mps: float, sample_time_s: float) -> float:
    """Samples to sail ``distance_m`` at ``speed_mps``: the length of one manoeuvre at that speed."""
    return distance_m / speed_mps / sample_time_s
