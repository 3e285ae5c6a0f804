"""What one oe fit of the basin truth leaves for the coverage bench (:mod:`benchmarks.bench_rollmass_coverage`): the
fit's last covariance call and final problem captured (:func:`capture`), its scores stored (:func:`store`), and the
truth's switches that take a noise source out or change the sea (each replaces a :mod:`tests.physics.basin_truth`
function, its random draws unchanged)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from identify.rollmass import oe_fit
from tests.physics import basin_truth as bt


def capture() -> dict:
    """Wrap oe_fit's covariance call (the fit's last, at its final point) to keep its arguments and result."""
    seen: dict = {}
    orig = oe_fit.load_interval

    def wrapped(basis, f, lengths, lags):
        lengths = list(lengths)
        out = orig(basis, f, lengths, lags)
        seen.update(J=basis.J, f=f, lengths=lengths, lags=lags, rho=out.rho, nu=out.dof)
        return out

    oe_fit.load_interval = wrapped
    finish = oe_fit._gauss_newton

    def finished(prob, x, steps, lags):
        out = finish(prob, x, steps, lags)
        # the final point (the last _fit's, as the covariance's); the sample time, since the captured window is the
        # interval's (output_error.INTERVAL_LAG_S, 20 s since stop 62), not the stationarity check's 5 s
        seen.update(x=out[0], free=prob.free, prob=prob, T=prob.datasets[0].T)
        return out

    oe_fit._gauss_newton = finished
    return seen


def store(seen: dict, path: Path, **extra) -> None:
    """The scores, residuals and products of one fit (see the module docstring) in ``path``."""
    J, f, lengths = seen["J"], seen["f"], seen["lengths"]
    out, i = {}, 0
    for k, n in enumerate(lengths):
        rows = slice(i, i + 3 * n)
        out[f"h{k}"] = (J[rows] * f[rows, None]).reshape(n, 3, -1).sum(axis=1)
        out[f"f{k}"] = f[rows].reshape(n, 3)
        i += 3 * n
    out.update(A=J.T @ J, Jp=J[i:], fp=f[i:], lengths=np.array(lengths), lags=seen["lags"], T=seen["T"])
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **out, **{k: np.asarray(v) for k, v in extra.items()})
    tmp.replace(path)


def load_fields(e, m_true: float, z_true: float) -> dict[str, float]:
    """A fit's load, its reported sds and the truth's, as the stored files name them."""
    return {"m": e.m, "z": e.zbar_m, "m_sd": e.m_sd, "z_sd": e.zbar_m_sd, "m_true": m_true, "z_true": z_true}


def sensor_noise_off() -> None:
    """The truth's waves kept and its IMU noise and bias switched off (its ``_measure``'s noise scale 0; the
    filters stay): with the ``quiet`` and the full fits it splits the noise's part into waves and sensor."""
    measure = bt._measure

    def quiet_sensor(*args):
        return measure(*args[:14], 0.0, *args[15:])

    bt._measure = quiet_sensor


def waves_off() -> None:
    """The truth's IMU noise kept and its sea (JONSWAP or narrow-band disturbance) switched off."""
    for name in ("_jonswap", "_narrowband"):
        draw = getattr(bt, name)
        setattr(bt, name, lambda *args, _draw=draw: 0.0 * _draw(*args))  # drawn, so the rng stream is unchanged


def sea_without_common() -> None:
    """The truth's base disturbance (:func:`basin_truth._narrowband`, its draws unchanged) without the component
    it shares across sway, roll and yaw: each degree of freedom only its own resonance, same sd."""

    def own(n: int, rng: np.random.Generator, runs: int) -> np.ndarray:
        out = np.empty((runs, n, 3))
        for j in range(runs):
            f0, zeta = rng.uniform(1.0, 1.4), rng.uniform(0.15, 0.35)
            w0, T = 2 * np.pi * f0, 1 / bt.FS
            r = np.exp(-zeta * w0 * T)
            a = [1.0, -2 * r * np.cos(w0 * T * np.sqrt(1 - zeta**2)), r * r]
            x = lfilter([1.0, -1.0], a, rng.standard_normal((n + 400, 4)), axis=0)[400:, 1:]
            out[j] = x / x.std(axis=0)
        return out * np.array([0.015, 0.002, 0.002])

    bt._narrowband = own


def sea_scaled(k: float) -> None:
    """The truth's sea (JONSWAP or base disturbance, draws unchanged) times ``k``."""
    for name in ("_jonswap", "_narrowband"):
        draw = getattr(bt, name)
        setattr(bt, name, lambda *args, _draw=draw: k * _draw(*args))


def drop_column(path: Path, name: str) -> Path:
    """Rewrite a recording written by :func:`basin_truth.write_csv` without its column ``name`` (its
    ``# key: value`` lines and the other columns' text unchanged)."""
    lines = path.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    j = lines[head].split(",").index(name)
    keep = lines[:head] + [",".join(c for k, c in enumerate(line.split(",")) if k != j) for line in lines[head:]]
    path.write_text("\n".join(keep) + "\n")
    return path
