"""Parameter priors for robust design: draws of the ship's model parameters around its profile.

A robust design (Chaloner & Verdinelli 1995, "Bayesian experimental design: a review"; Pronzato &
Walter 1985, "Robust experiment design via stochastic approximation") needs the parameters it is
robust against as draws theta_1 .. theta_K. They come from

* a relative spread: theta_k,i = theta0_i (1 + s u_k,i), u ~ U(-1, 1) independent per parameter
  and draw, 0 < s <= 1, so no parameter changes sign (a parameter that is 0 in the profile stays 0);
* a prior file (JSON): ``{"parameter_names": [...], "draws": [[...], ...]}`` (used as given), or
  ``{"parameter_names": [...], "covariance": [[...]], "mean": [...]}`` (Gaussian draws; the mean
  defaults to the profile's values); a diagnosed ``model.json`` is read the same way when it
  holds such a table as ``parameter_covariance`` (at its top level or in ``diagnosed_model``;
  ``shiptrial diagnose`` does not write one yet).

theta0 is the profile's simulation set: the parameters the local design is computed at.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from expdesign.errors import DesignError
from primitives.ship import ShipProfile

DEFAULT_DRAWS = 200
# Independent seed streams of one --seed (SeedSequence spawn keys, namespaced by this 28 so
# they meet no other stream of the project's): the draws a robust mix is optimised on, the fresh
# draws it is scored on, and the Monte Carlo's truths (held out from both).
DESIGN, EVALUATION, TRUTHS = (28, 0), (28, 1), (28, 2)


def stream(seed: int, key: tuple[int, ...]) -> np.random.Generator:
    """The generator of one of the streams above (or a sub-stream: ``key`` extended)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=key))


@dataclass(frozen=True)
class ParameterPrior:
    """K draws (K, p) of the model parameters (the profile's order) around ``centre``
    (p,), and where they come from (one phrase for reports)."""

    centre: np.ndarray
    draws: np.ndarray
    source: str
    sampler: Callable[[int, np.random.Generator], np.ndarray] | None = None  # fresh draws; None: a file's fixed draws
    seed: int = 0

    @classmethod
    def sampled(
        cls, centre: np.ndarray, sampler: Callable[[int, np.random.Generator], np.ndarray], n_draws: int, seed: int, source: str
    ) -> ParameterPrior:
        """A prior whose ``draws`` are ``sampler``'s first ``n_draws`` from the DESIGN stream of ``seed``."""
        return cls(centre, sampler(int(n_draws), stream(seed, DESIGN)), source, sampler, seed)

    def fresh(self, n_draws: int, key: tuple[int, ...]) -> np.ndarray | None:
        """``n_draws`` new draws from the stream ``key`` of the prior's seed, independent of
        ``draws``; None for a file's fixed draws (nothing to draw from but them: in-sample)."""
        return None if self.sampler is None else self.sampler(int(n_draws), stream(self.seed, key))

    def held_out(self) -> ParameterPrior | None:
        """As many fresh draws as ``draws`` from the EVALUATION stream (None for a file's draws)."""
        d = self.fresh(self.n_draws, EVALUATION)
        return None if d is None else ParameterPrior(self.centre, d, self.source, None, self.seed)

    @property
    def n_draws(self) -> int:
        return int(self.draws.shape[0])

    def to_dict(self) -> dict:
        rel = np.abs(self.draws - self.centre) / np.where(self.centre != 0, np.abs(self.centre), 1.0)
        return {"source": self.source, "draws": self.n_draws, "max_relative_deviation": float(rel.max(initial=0.0))}


def make_prior(
    profile: ShipProfile, spread: float | None, path: str | Path | None, n_draws: int | None, seed: int
) -> ParameterPrior | None:
    """The prior of ``--prior-spread`` or ``--prior-file`` (None when neither is given);
    ``n_draws`` None: the default count (a file's own draws are used as given)."""
    if spread is not None:
        return spread_prior(profile, spread, DEFAULT_DRAWS if n_draws is None else n_draws, seed)
    if path is not None:
        return file_prior(profile, path, n_draws, seed)
    return profile_prior(profile, DEFAULT_DRAWS if n_draws is None else n_draws, seed) if profile.prior_std is not None else None


def profile_prior(profile: ShipProfile, n_draws: int = DEFAULT_DRAWS, seed: int = 0) -> ParameterPrior:
    """Independent Gaussian draws with the profile's own ``[prior] std`` (1 sigma per coefficient, as
    ``shiptrial profile new`` writes it from the regressions' scatter) around its simulation set."""
    if profile.prior_std is None:
        raise DesignError(f"ship {profile.name!r} has no [prior] std: give --prior-spread FRACTION or --prior-file PATH")
    _check_count(n_draws)
    centre = profile.params(profile.simulation_set)
    std = np.asarray(profile.prior_std, float)

    def sample(n: int, rng: np.random.Generator) -> np.ndarray:
        return centre + std * rng.standard_normal((n, centre.size))

    return ParameterPrior.sampled(centre, sample, n_draws, seed, "the profile's [prior] std (Gaussian)")


def _check_count(n_draws: int) -> None:
    if not 2 <= int(n_draws) <= 100_000:
        raise DesignError(f"--prior-draws {n_draws}: give 2 to 100000 parameter draws")


def spread_prior(profile: ShipProfile, spread: float, n_draws: int = DEFAULT_DRAWS, seed: int = 0) -> ParameterPrior:
    """Independent uniform relative deviations of every parameter by up to ``spread`` (module doc)."""
    if not (isinstance(spread, (int, float)) and np.isfinite(spread) and 0.0 < spread <= 1.0):
        raise DesignError(
            f"--prior-spread {spread}: give a fraction in (0, 1], e.g. 0.3 for parameters within +-30 % of the profile's"
        )
    _check_count(n_draws)
    centre = profile.params(profile.simulation_set)

    def sample(n: int, rng: np.random.Generator) -> np.ndarray:
        return centre * (1.0 + spread * rng.uniform(-1.0, 1.0, (n, centre.size)))

    return ParameterPrior.sampled(centre, sample, n_draws, seed, f"+-{100 * spread:g} % uniform spread")


def file_prior(profile: ShipProfile, path: str | Path, n_draws: int | None = None, seed: int = 0) -> ParameterPrior:
    """Draws from a prior file (module doc); a malformed file or one that does not match the
    profile's parameters is refused in one line naming the file, the field and the fix.
    ``n_draws`` (default 200) is for a covariance: a file's own draws are used as given."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise DesignError(
            f"{p}: not a readable prior file ({type(exc).__name__}: {str(exc).splitlines()[0][:80]}): give a JSON file "
            "with 'parameter_names' and 'draws' or 'covariance'"
        ) from None
    if isinstance(doc, dict) and isinstance(doc.get("diagnosed_model"), dict) and not {"draws", "covariance"} & set(doc):
        inner = doc.get("parameter_covariance", doc["diagnosed_model"].get("parameter_covariance"))
        if not isinstance(inner, dict):
            raise DesignError(
                f"{p}: this model.json holds no parameter covariance (no field 'parameter_covariance'): give a prior "
                "file with 'parameter_names' and 'covariance', or use --prior-spread"
            )
        doc = inner
    if not isinstance(doc, dict) or not ({"draws", "covariance"} & set(doc)):
        raise DesignError(f"{p}: a prior file needs the field 'draws' or 'covariance' (with 'parameter_names')")
    order = _order(profile, doc.get("parameter_names"), p)
    centre = profile.params(profile.simulation_set)
    if "draws" in doc:
        draws = _matrix(doc["draws"], p, "draws", (None, len(order)))[:, order]
        if not 2 <= draws.shape[0] <= 100_000:
            raise DesignError(f"{p}: field 'draws' has {draws.shape[0]} row(s): give 2 to 100000 parameter draws")
        if n_draws is not None:
            raise DesignError(
                f"--prior-draws {n_draws}: {p} gives its own {draws.shape[0]} draws, used as given: drop --prior-draws"
            )
        return ParameterPrior(centre, draws, f"{draws.shape[0]} draws from {p.name}")
    n_draws = DEFAULT_DRAWS if n_draws is None else n_draws
    _check_count(n_draws)
    cov = _matrix(doc["covariance"], p, "covariance", (len(order), len(order)))[np.ix_(order, order)]
    if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
        raise DesignError(f"{p}: field 'covariance' is not symmetric: give the parameters' covariance matrix")
    ev, vec = np.linalg.eigh(cov)
    if ev[0] < -1e-9 * max(ev[-1], 1e-300):
        raise DesignError(f"{p}: field 'covariance' is not positive semi-definite (eigenvalue {ev[0]:.3g}): fix the matrix")
    mean = centre if doc.get("mean") is None else _matrix([doc["mean"]], p, "mean", (1, len(order)))[0][order]
    root = np.sqrt(np.clip(ev, 0.0, None)) * vec  # x = mean + root @ z, z ~ N(0, I)

    def sample(n: int, rng: np.random.Generator) -> np.ndarray:
        return mean + rng.standard_normal((n, mean.size)) @ root.T

    # the centre stays the profile's simulation set (the module doc): the mean only moves the draws
    return ParameterPrior.sampled(centre, sample, n_draws, seed, f"Gaussian covariance from {p.name}")


def _order(profile: ShipProfile, names: object, p: Path) -> np.ndarray:
    """Column index in the file of each of the profile's parameters."""
    want = profile.param_names
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise DesignError(f"{p}: field 'parameter_names' must list the parameter names, e.g. {want}")
    if sorted(names) != sorted(want) or len(set(names)) != len(names):
        missing, extra = sorted(set(want) - set(names)), sorted(set(names) - set(want))
        raise DesignError(
            f"{p}: field 'parameter_names' does not match ship {profile.name!r}'s parameters"
            f"{f' (missing {missing})' if missing else ''}{f' (unknown {extra})' if extra else ''}: give exactly {want}"
        )
    return np.array([names.index(n) for n in want])


def _matrix(raw: object, p: Path, field: str, shape: tuple[int | None, int]) -> np.ndarray:
    """A finite float matrix of ``shape`` (None: any number of rows) from a JSON list of lists."""
    try:
        a = np.array(raw, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.ndim != 2 or (shape[0] is not None and a.shape[0] != shape[0]) or a.shape[1] != shape[1]:
        rows = "N" if shape[0] is None else shape[0]
        got = "not a table of numbers" if a is None or a.ndim != 2 else f"{a.shape[0]} x {a.shape[1]}"
        raise DesignError(
            f"{p}: field {field!r} must be a {rows} x {shape[1]} table of numbers (one column per parameter), got {got}"
        )
    if not np.isfinite(a).all():
        raise DesignError(f"{p}: field {field!r} holds a non-finite number: give finite values")
    return a
