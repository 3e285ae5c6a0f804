"""Monte Carlo study of the yaw identification, as section 4.4 of the podded-ship MSc thesis (Fig. 4.3-4.4).

One manoeuvre (:func:`identify.yawid.experiment.identification_run`), simulated once without
noise by the shared kernel; each run adds an independent Table 4.1 noise realisation (run i's
noise depends on (seed, i) only) and estimates the full (2.17) and simplified (2.18) models from
the true values (as the thesis does, L1231-1236). A noise-free fit isolates the bias a model's
structure causes (the thesis's grey line in Fig. 4.4). Runs that do not converge are counted and
left out of the statistics, never averaged in.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from identify.yawid.estimate import YawFit, fit_yaw
from identify.yawid.experiment import Noise, YawData, check_forward, identification_run, measure, true_signals
from identify.yawid.model import MODELS, true_parameters
from primitives.ship import ShipProfile

# What the podded-ship MSc thesis says of each model's Monte Carlo (its numbers are in figures only, L1296-1321).
THESIS_NOTES = {
    "full": {
        "I_r": "barely affected by noise",
        "N_phiuv": "large relative variance and bias",
        "*": "bias and variance differ greatly between parameters",
    },
    "simplified": {
        "I_r": "more accurate than with the full model",
        "*": "every bias larger than the full model's, variance much smaller",
    },
}


@dataclass
class MonteCarlo:
    model: str
    truth: dict[str, float]
    fits: YawFit  # one row per run
    noise_free: YawFit  # one row

    def rows(self) -> list[dict[str, float | str]]:
        """Per parameter: true value, mean and std over the converged runs, relative bias and
        spread (4.5), the noise-free (structural) relative error, and the thesis's remark."""
        ok = self.fits.ok
        notes = THESIS_NOTES[self.model]
        out = []
        for j, name in enumerate(self.fits.model.params):
            th0 = self.truth[name]
            est = self.fits.theta[ok, j]
            out.append(
                {
                    "param": name,
                    "true": th0,
                    "mean": float(est.mean()) if est.size else float("nan"),
                    "std": float(est.std(ddof=1)) if est.size > 1 else float("nan"),
                    "rel_bias": float((est.mean() - th0) / th0) if est.size else float("nan"),
                    "rel_std": float(est.std(ddof=1) / abs(th0)) if est.size > 1 else float("nan"),
                    "noise_free_rel": float((self.noise_free.theta[0, j] - th0) / th0),
                    "thesis": notes.get(name, notes["*"]),
                }
            )
        return out


def clean_recording(profile: ShipProfile, manoeuvre_seed: int = 0, duration_s: float = 600.0) -> YawData:
    """The noise-free 10-minute identification recording (forward-only, checked)."""
    data = true_signals(profile, identification_run(profile.sample_time, manoeuvre_seed, duration_s))
    check_forward(data, f"identification run (manoeuvre seed {manoeuvre_seed})")
    return data


def run_monte_carlo(
    profile: ShipProfile,
    runs: int = 50,
    seed: int = 0,
    noise: Noise | None = None,
    models: tuple[str, ...] = ("full", "simplified"),
    manoeuvre_seed: int = 0,
    chunk: int = 25,
    prefilter_hz: float | None = None,
) -> dict[str, MonteCarlo]:
    """Estimates of each model over ``runs`` noise realisations, in chunks of ``chunk`` runs (a
    run's result does not depend on the chunk it is fitted in). ``prefilter_hz``: see
    :func:`identify.yawid.estimate.prefilter`."""
    clean = clean_recording(profile, manoeuvre_seed)
    truth = true_parameters(profile)
    noise = noise or Noise()
    out = {}
    for name in models:
        model = MODELS[name]
        parts = []
        for start in range(0, runs, chunk):
            data = measure(clean, noise, min(chunk, runs - start), seed, first=start)
            parts.append(fit_yaw(data, model, truth, prefilter_hz=prefilter_hz))
        fits = _concat(parts)
        out[name] = MonteCarlo(name, truth, fits, fit_yaw(clean, model, truth))
    return out


def _concat(parts: list[YawFit]) -> YawFit:
    """One fit of the runs of ``parts`` (chunks of one model): per-run arrays joined, the most iterations."""
    per_run = {
        f.name: np.concatenate([getattr(p, f.name) for p in parts])
        for f in fields(YawFit)
        if f.name not in ("model", "iterations", "notes")
    }
    return replace(parts[0], iterations=max(p.iterations for p in parts), **per_run)
