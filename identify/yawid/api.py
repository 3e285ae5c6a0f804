"""Library entry points of the yaw identification (the CLI's ``shiptrial yawid`` calls these)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from identify.yawid.estimate import YawFit, fit_yaw
from identify.yawid.experiment import Noise, check_forward, measure
from identify.yawid.model import MODELS, true_parameters
from identify.yawid.montecarlo import clean_recording
from identify.yawid.recording import read_yaw_csv, write_yaw_csv
from primitives.errors import UserError
from primitives.ship import ShipProfile, load_profile


def _model(name: str):
    if name not in MODELS:
        raise UserError(f"--model {name!r}: choose 'full' (2.17) or 'simplified' (2.18)")
    return MODELS[name]


def identify_file(
    path: str | Path, model: str = "full", ship: str | ShipProfile = "naval-vessel", prefilter_hz: float | None = None
) -> tuple[YawFit, dict[str, float]]:
    """Fit the yaw model to one recording; start values are the ship profile's lumped parameters
    (2.19), as the thesis starts from its simulation parameters (L1784-1785). Returns the fit and
    those start values."""
    profile = ship if isinstance(ship, ShipProfile) else load_profile(ship)
    m = _model(model)
    start = true_parameters(profile)
    data = read_yaw_csv(path, m, profile)
    check_forward(data, str(path))
    if prefilter_hz is not None and not 0 < prefilter_hz < 0.5 / data.sample_time:  # also NaN
        raise UserError(
            f"--prefilter {prefilter_hz:g}: must be between 0 and the Nyquist frequency {0.5 / data.sample_time:g} Hz"
        )
    return replace(fit_yaw(data, m, start, prefilter_hz=prefilter_hz), notes=data.notes), start


SIM_SOURCE = "shiptrial yawid-sim"  # opens its '# source:' header line: how its recordings are known


def is_simulated_recording(path: Path) -> bool:
    """A recording :func:`simulate_file` wrote: a '# source: shiptrial yawid-sim' line among its header lines (a
    real recording, never written by it, is not replaced unasked)."""
    from primitives.io import first_lines

    head = [line for line in first_lines(path, 12) if line.startswith("#")]
    return any(line.startswith(f"# source: {SIM_SOURCE} ") for line in head)


def simulate_file(
    path: str | Path,
    seed: int = 0,
    noise_scale: float = 1.0,
    manoeuvre_seed: int = 0,
    ship: str = "naval-vessel",
    *,
    force: bool = False,
    option: str = "path",
) -> Path:
    """A 10-minute, 10 Hz recording of the forward-only identification run with Table 4.1 noise
    scaled by ``noise_scale`` (example input of :func:`identify_file`). An existing file is replaced
    only if it is one this function wrote (:func:`is_simulated_recording`) or ``force``; otherwise
    refused in one line naming it (``option``: ``yawid-sim`` passes its ``OUT``), before any simulation."""
    from primitives.io import check_out_file

    check_out_file(path, (".csv",), option, "recording", replace=force, ours=is_simulated_recording, writer=SIM_SOURCE)
    if noise_scale < 0:
        raise UserError(f"--noise {noise_scale:g}: must be >= 0 (a multiple of Table 4.1's levels)")
    profile = load_profile(ship)
    clean = clean_recording(profile, manoeuvre_seed)
    data = measure(clean, Noise().scaled(noise_scale), 1, seed)
    meta = {
        "ship": profile.name,
        "source": f"{SIM_SOURCE} (the podded-ship MSc thesis, chapter 4 experiment, ours)",
        "sample_time": f"{profile.sample_time:g}",
        "noise": f"{noise_scale:g} x Table 4.1",
        "seed": str(seed),
    }
    return write_yaw_csv(data, path, meta)
