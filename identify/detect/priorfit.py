"""The yaw prior's fit (ch. 4 of "Estimating a ship's dynamics during operation": output error,
eq. 4.1-4.4) on a nominal recording, with what describes its error: the parametric-bootstrap
refits, the misfit beyond noise (model error) and the structure's apparent change on held-out
data (split-half cross-validation). The prior itself, its predictor and the signatures are in
:mod:`identify.detect.yawmodel`; the no-change records in :mod:`identify.detect.nullsim`."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from identify.detect.noiseread import stationary_lowpass, white_noise_sd
from identify.detect.noisespec import spectral_noise
from identify.detect.nullsim import misfit_offsets, null_records, smooth
from identify.detect.yawmodel import (
    CANDIDATES,
    NOMINAL,
    PARAMS,
    PREFILTER_HZ,
    YAW_MODELS,
    Derive,
    YawPrior,
    ar_fit,
    block_mean,
    model_inputs,
    predict_with_signatures,
    prior_name,
    robust_sigma,
    simulate_r,
    whiten,
)
from identify.yawid.estimate import fit_yaw
from identify.yawid.experiment import YawData
from primitives.errors import UserError


def _jacobian(kind: str, x: np.ndarray, sig: dict[str, np.ndarray], dt: float, step: float = 1e-3, r0: float = 0.0) -> np.ndarray:
    """d r_hat / d x by forward differences, all columns in one vectorised simulation."""
    p = len(x)
    cols = np.repeat(x[:, None], p + 1, axis=1)
    cols[np.arange(p), np.arange(1, p + 1)] += step
    r = simulate_r(kind, cols, {k: s[:, None] for k, s in sig.items()}, dt, r0=r0)
    return (r[:, 1:] - r[:, :1]) / step


def fit(
    kind: str,
    sig: dict[str, np.ndarray],
    r_meas: np.ndarray,
    dt: float,
    source: str = "",
    estimate: bool = True,
    bootstrap: int = 64,
    seed: int = 0,
    derive: Derive | None = None,
    prefilter_hz: float = PREFILTER_HZ,
    scales: np.ndarray | None = None,
    noise_model: str | None = None,
) -> YawPrior:
    """Output-error fit of (2.17)/(2.18) (ch. 4, eq. 4.1-4.4; yawid's batched Levenberg-Marquardt
    from the nominal values, with section 4.3's sign constraints) on the inputs low-passed at
    ``prefilter_hz`` (:func:`model_inputs`), with the residual's robust sigma and whitening filter.
    ``estimate=False`` keeps the nominal values (seed 000's "model 0") and only measures the
    residual on this data. Each signal's measurement noise is read from the same data (:func:`read_noise`,
    ``noise_model``): white, or white through the sensor's first-order low-pass.

    The prior's parameter error is described by ``bootstrap`` parametric-bootstrap refits
    (:func:`bootstrap_deviations`: noise on every input, so the errors-in-variables part is in)
    kept as they are (``YawPrior.boot``, for the detector's no-change simulation) and as their
    second moment (``cov``); ``bootstrap=0`` gives only the fit's Jacobian covariance, which
    knows the noise on r alone. ``scales``: the fit's scales already found on this data (:func:`batch_fits`),
    so the fit is not repeated. ``noise_model``: how each signal's measurement noise is read
    (:func:`read_noise`; None: :data:`NOISE_MODEL`)."""
    raw, sig = sig, model_inputs(sig, dt, prefilter_hz)
    p = len(PARAMS[kind])
    if scales is not None:
        x = np.asarray(scales, float)
    elif estimate:
        x = _fit_scales(kind, {k: v[None] for k, v in raw.items()}, r_meas[None], dt, np.ones(p), prefilter_hz)[0]
    else:
        x = np.ones(p)
    block = max(1, int(round(1.0 / dt)))
    r0 = float(np.mean(r_meas[:block]))
    e = simulate_r(kind, x, sig, dt, r0=r0) - r_meas if np.all(np.isfinite(x)) else np.full(len(r_meas), np.nan)
    if not np.all(np.isfinite(e)):
        raise UserError(f"{source}: the yaw-row fit diverged; the recording does not excite yaw enough for a prior")
    e_blocks = block_mean(e, block)
    ar = ar_fit(e_blocks)
    sigma_w = robust_sigma(whiten(e_blocks, ar))
    values = {k: float(NOMINAL[k] * xi) for k, xi in zip(PARAMS[kind], x)}
    derived = getattr(derive, "derived", frozenset())  # a plain function as derive: nothing known to be derived
    noise_model = noise_model or NOISE_MODEL
    noise, taus = read_noise(raw | {"r": r_meas}, dt, noise_model, derived)
    prior = YawPrior(
        kind, values, robust_sigma(e), np.zeros((p, p)), ar, sigma_w, block, dt, source, prefilter_hz, np.zeros((0, p)), noise
    )
    prior.noise_tau = taus
    prior.noise_model = noise_model if taus else ""  # which reader read the corners (the file says)
    prior.model_error = model_error(prior, raw, r0, derive, seed)
    if estimate and bootstrap > 0:
        # the refits see the nominal residual's whole level: white noise at the levels read, plus what
        # those levels do not explain (coloured or sensor-filtered noise, misfit), as the null records do
        offsets = misfit_offsets(prior, len(r_meas), bootstrap, np.random.default_rng([seed, 7])).T
        prior.boot = bootstrap_deviations(kind, raw, r_meas, dt, x, bootstrap, seed, derive, prefilter_hz, offsets, prior)
        prior.cov = prior.boot.T @ prior.boot / len(prior.boot)
    elif estimate:
        prior.cov = _covariance(kind, sig, dt, x, r0, block, ar, sigma_w)
    if estimate and bootstrap > 0:
        prior.structure = structural_spread(prior, raw, r_meas, x, derive, seed)
    return prior


def _split_theta(prior: YawPrior, sig: dict[str, np.ndarray], r: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """Cross-validated apparent changes (halves, B, 3): the yaw row fitted on one half of each of
    the B records (signals (B, n), as measured) predicts the other half; the residual's GLR
    estimate along each candidate signature there (whitened 1 s block means) is what a detector
    would read as a change of a ship that did not change. NaN where a fit diverged."""
    n = r.shape[1]
    h = n // 2
    out = []
    for a, b in ((slice(0, h), slice(h, n)), (slice(h, n), slice(0, h))):
        xs = _fit_scales(prior.kind, {k: v[:, a] for k, v in sig.items()}, r[:, a], prior.dt, x0, prior.prefilter_hz)
        rows = []
        for i, x in enumerate(xs):
            if not np.all(np.isfinite(x)):
                rows.append(np.full(len(CANDIDATES), np.nan))
                continue
            half = replace(prior, values={k: float(NOMINAL[k] * xi) for k, xi in zip(prior.names, x)})
            test = {k: v[i, b] for k, v in sig.items()}
            rt = r[i, b]
            # the prediction and the signatures in one simulation, as screen's (the same bits as two)
            r_hat, S = predict_with_signatures(half, half.inputs(test), float(np.mean(rt[: prior.block])))
            eps = rt - r_hat
            Sw = whiten(block_mean(S, prior.block), prior.ar)
            ew = whiten(block_mean(eps, prior.block), prior.ar)
            rows.append(Sw.T @ ew / np.maximum(np.sum(Sw**2, axis=0), 1e-300))
        out.append(rows)
    return np.asarray(out)


def structural_spread(
    prior: YawPrior,
    sig: dict[str, np.ndarray],
    r_meas: np.ndarray,
    x: np.ndarray,
    derive: Derive | None = None,
    seed: int = 0,
    synthetic: int = 8,
    gate: float = 3.0,
) -> np.ndarray:
    """How far the prior's structure alone moves the detector's change estimates on a manoeuvre it
    was not fitted on: rms over the two split-half cross-validations of the nominal record
    (:func:`_split_theta`), less (in quadrature) the 95 % point of what the same two estimates give
    on records that the prior's own structure generates with the nominal data's noise and model-error
    term (``synthetic`` of them: what noise and the half fits' parameter error alone give). Zero for a structure that
    fits, and where the half fits diverged (no estimate: ``detect`` then warns that its alarms are
    not calibrated); the detector's calibration adds it as a random apparent change along each
    candidate's own signature (:func:`glr.calibrate`). ``gate`` is the multiple of the synthetic
    records' mean square taken off: 3.0, the 95 % point of the two estimates' ``chi2(2)/2`` for a
    structure that fits; 1.0 makes it a moment estimate (``benchmarks/bench_detect_calibration.py
    --structure gate=1``, stop 48: better calibrated levels, more misses; not the default)."""
    real = _split_theta(prior, {k: v[None] for k, v in sig.items()}, r_meas[None], x)
    clean = smooth(sig, prior.dt)
    n = len(r_meas)
    rng = np.random.default_rng([seed, 5])
    r_true = simulate_r(prior.kind, x, prior.inputs(clean), prior.dt, r0=float(np.mean(r_meas[:10])))
    # the same residual the no-change records carry (noise, and what the nominal residual has beyond it):
    # without the latter, coloured sensor noise that the white-noise reading misses passed for structure
    r_b = r_true + _noise(prior, "r", rng, (synthetic, n)) + misfit_offsets(prior, n, synthetic, rng).T
    s_b = {k: clean[k] + _noise(prior, k, rng, (synthetic, n)) for k in sig}
    if derive is not None:
        rows = [derive({k: s_b[k][i] for k in sig}, r_b[i]) for i in range(synthetic)]
        s_b = {k: np.stack([row[k] for row in rows]) for k in rows[0]}
    noise = _split_theta(prior, s_b, r_b, x)
    ms_real = np.nanmean(real**2, axis=(0, 1))
    ms_noise = np.nanmean(noise**2, axis=(0, 1))
    # two held-out estimates give a mean square that is ms_noise * chi2(2)/2 for a structure that
    # fits: count only what exceeds its 95 % point (gate 3.0: 3.0 ms_noise), so noise does not pass for misfit
    return np.nan_to_num(np.sqrt(np.maximum(ms_real - gate * ms_noise, 0.0)), nan=0.0)


def model_error(prior: YawPrior, sig: dict[str, np.ndarray], r0: float, derive: Derive | None = None, seed: int = 0) -> float:
    """Innovation sd of the part of the prior's own fit residual (whitened 1 s block means) that
    the measurement noise does not explain: ``sqrt(sigma_w^2 - s_noise^2)``, ``s_noise`` the same
    statistic of 32 no-change records simulated on the nominal data without parameter error. A
    structure that leaves dynamics out (the simplified model (2.18)) has it, and so has noise that
    the white-noise reading (:func:`white_noise_sd`) sees a fraction of (a sensor's low-pass,
    coloured noise): the records the prior simulates carry it (:func:`misfit_offsets`); 0 when ``sigma_w``
    is within two standard errors of the robust sigma (efficiency 0.37) of ``s_noise``."""
    exact = replace(prior, boot=np.zeros((0, len(prior.names))), cov=np.zeros_like(prior.cov), model_error=0.0)
    sim = whiten(block_mean(null_records(exact, sig, 32, seed, derive, r0), prior.block), prior.ar)
    s_noise = float(np.mean([robust_sigma(sim[:, j]) for j in range(sim.shape[1])]))
    if prior.sigma_w <= s_noise * (1 + 2 / np.sqrt(0.74 * len(sim))):
        return 0.0
    return float(np.sqrt(prior.sigma_w**2 - s_noise**2))


def _fit_scales(
    kind: str, sig: dict[str, np.ndarray], r_meas: np.ndarray, dt: float, x0: np.ndarray, prefilter_hz: float
) -> np.ndarray:
    """Scales (B, P) fitted to a batch of B records (signals (B, n), as measured: the fit sees them
    through :func:`model_inputs`, as the prediction does) by :func:`identify.yawid.estimate.fit_yaw`
    from the scales ``x0``; NaN rows did not converge."""
    model = YAW_MODELS[kind]
    scale = np.array([NOMINAL[prior_name(n)] for n in model.params])
    w = model_inputs({k: sig[k].T for k in ("tau_r", *model.signals)}, dt, prefilter_hz)  # time on axis 0 there
    data = YawData(np.arange(r_meas.shape[-1]) * dt, {"r": r_meas, **{k: x.T for k, x in w.items()}})
    f = fit_yaw(data, model, dict(zip(model.params, x0 * scale)))
    return np.where(f.ok[:, None], f.theta / scale, np.nan)


def batch_fits(
    kind: str, sigs: list[dict[str, np.ndarray]], r_meas: np.ndarray, dt: float, prefilter_hz: float = PREFILTER_HZ
) -> tuple[np.ndarray, np.ndarray]:
    """Output-error fits of one yaw-rate record ``r_meas`` (n,) on B versions of its inputs ``sigs``
    (each as :func:`fit` takes it), in one batch of :func:`_fit_scales` (each record's LM runs on its own,
    so a row is the fit :func:`fit` would make): the scales (B, P) and each fit's robust residual sigma
    (B,; inf where the fit diverged)."""
    batch = {k: np.stack([np.asarray(s[k], float) for s in sigs]) for k in sigs[0]}
    x = _fit_scales(kind, batch, np.broadcast_to(r_meas, (len(sigs), len(r_meas))), dt, np.ones(len(PARAMS[kind])), prefilter_hz)
    r0 = float(np.mean(r_meas[: max(1, int(round(1.0 / dt)))]))
    sd = np.full(len(sigs), np.inf)
    for i, (xi, s) in enumerate(zip(x, sigs)):
        if np.all(np.isfinite(xi)):
            e = simulate_r(kind, xi, model_inputs(s, dt, prefilter_hz), dt, r0=r0) - r_meas
            sd[i] = robust_sigma(e) if np.all(np.isfinite(e)) else np.inf
    return x, sd


def _covariance(
    kind: str, sig: dict, dt: float, x: np.ndarray, r0: float, block: int, ar: np.ndarray, sigma_w: float
) -> np.ndarray:
    """``sigma_w^2 (Jw^T Jw)^-1`` of the whitened 1 s block means, ``J = d r_hat / d ln(theta)``."""
    Jw = whiten(block_mean(_jacobian(kind, x, sig, dt, r0=r0) * x[None, :], block), ar)
    return sigma_w**2 * np.linalg.pinv(Jw.T @ Jw)


#: how :func:`fit` reads each signal's measurement noise by default (:func:`read_noise`): "white", main's reading.
#: "lowpass" (stop 55) reads the podded truth's low-passed sensors' noise at 1.0-1.1 of its sd on u, v, phi and p but
#: r at 1.1-1.4 and v_dot at 1.3-3 (means per variant; one record's range is wider). Re-screened as the default: on
#: ships 102-103 false alarms stayed at 1 %, the unchanged runs' levels went from too low to too high (KS p 8e-4
#: either way) and misses rose 34 -> 40 %; on ships 108-109 the levels became calibrated (KS p 1e-6 -> 0.56) and
#: false alarms fell 7 -> 0 % (20 % on strong-roll, 15 % on steering-lag-acting under white), but misses rose
#: 44 -> 57 %. "spectral" (stop 56) reads r at 0.93-0.99 and v_dot at 0.79-1.22 (means per variant over one recording
#: on each of 4 ships; per record r 0.82-1.04, and 0.95-1.09 on 8 more runs of ships 102-103; the ship's motion
#: fitted beside the noise); re-screened as the default on 102-103 the levels moved towards calibrated (pooled KS p
#: 8e-4 -> 0.015, the runs' misfit over their records' 0.99 as main's) but misses were higher (34 -> 39 %, 5 of
#: 100, not significant on 2 ships; 44 -> 51 %, 7 of 100, on 108-109) and detections came 26 s later. Kept white:
#: neither reading calibrates without costing misses (docs/detect-accuracy.md, stops 55-56)
#: "lowpass" was retired at stop 57 (the spectral reader reads every channel at least as well; its files still load)
NOISE_MODEL = "white"
NOISE_MODELS = ("white", "spectral")


def check_noise_model(name: str) -> None:
    """Refuse a noise model not in :data:`NOISE_MODELS`: the one check and wording of the CLI's option, the API and
    :func:`read_noise`."""
    if name == "lowpass":
        raise UserError(
            "--noise-model 'lowpass': retired at stop 57 (it read the ship's yaw acceleration as noise); "
            "use spectral (the same sensor low-pass read from the spectrum) or white"
        )
    if name not in NOISE_MODELS:
        raise UserError(f"--noise-model {name!r}: choose one of {', '.join(NOISE_MODELS)}")


def read_noise(
    sig: dict[str, np.ndarray], dt: float, model: str = NOISE_MODEL, derived: frozenset[str] = frozenset()
) -> tuple[dict[str, float], dict[str, float]]:
    """Each signal's measurement noise, read from the nominal data: the white noise's sd per signal and
    the time constant (s) of the sensor's first-order low-pass it passed through (``model`` "spectral", stop 56: read
    from the spectrum above the ship's own motion, :func:`identify.detect.noisespec.spectral_noise`), or white noise
    only (``model`` "white": :func:`white_noise_sd`, main's before stop 55, no time constants).
    The ``derived`` signals (computed, not sensed: :attr:`identify.detect.inputs.Deriver.derived`) read white under
    every model: a sensor's low-pass says nothing of them (a tau_r from the pod inputs read a 0.07 s corner at
    11 times its white level under "spectral", and made a white recording's prior a format /2 one)."""
    if model == "white":
        return {k: white_noise_sd(v) for k, v in sig.items()}, {}
    check_noise_model(model)
    read = {k: (white_noise_sd(v), 0.0) if k in derived else spectral_noise(v, dt) for k, v in sig.items()}
    # only the corners read: a channel that fell back to white (tau 0) is kept as a white prior keeps it
    return {k: sd for k, (sd, _) in read.items()}, {k: tau for k, (_, tau) in read.items() if tau > 0}


def _noise(prior: YawPrior, k: str, rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """Measurement noise (runs, n) of signal ``k`` at the prior's reading: white draws of its sd through its
    sensor's low-pass (``prior.noise_tau``; none: white)."""
    w = prior.noise.get(k, 0.0) * rng.standard_normal(shape)
    return stationary_lowpass(w, prior.noise_tau.get(k, 0.0), prior.dt, axis=1)


def bootstrap_deviations(
    kind: str,
    sig: dict[str, np.ndarray],
    r_meas: np.ndarray,
    dt: float,
    x: np.ndarray,
    runs: int,
    seed: int = 0,
    derive: Derive | None = None,
    prefilter_hz: float = PREFILTER_HZ,
    offsets: np.ndarray | None = None,
    prior: YawPrior | None = None,
) -> np.ndarray:
    """Relative parameter errors ``(x_b - x) / |x|`` (runs, P) of ``runs`` parametric-bootstrap
    refits, errors in variables included (the Jacobian covariance knows only the noise on r).

    Synthetic truth: the measured inputs ``sig`` (as measured, before the low-pass) smoothed
    (Savitzky-Golay, 2 s, quadratic), ``r`` simulated from them with the fitted ``x``. Synthetic
    data: truth plus white noise of each signal's own level estimated from the nominal data
    (:func:`white_noise_sd`), refitted from ``x`` exactly as the prior was (uncentred: the
    estimator's bias is part of the error). With ``derive(sig_b, r_b) -> sig_b`` derived inputs
    (v' from v, tau_r from the motion) are recomputed from the noisy synthetic signals, as they
    were from the measured ones. ``offsets`` (runs, n), when given, are added to the synthetic yaw
    rates (:func:`misfit_offsets`: the residual the white-noise levels do not explain). ``prior``, when
    given, supplies the noise read from the same data (``noise``, ``noise_tau``: white noise through each
    sensor's low-pass, :func:`_noise`) instead of :func:`white_noise_sd`'s white levels. Only nominal
    data enter."""
    clean = smooth(sig, dt)
    if prior is None:  # white noise at each signal's own level, read as the prior's white reading reads it
        noise = {k: white_noise_sd(s) for k, s in (sig | {"r": r_meas}).items()}
        prior = YawPrior(kind, {}, 1.0, np.zeros((0, 0)), dt=dt, noise=noise)  # the noise reading alone
    n = len(r_meas)
    r_true = simulate_r(kind, x, model_inputs(clean, dt, prefilter_hz), dt, r0=float(np.mean(r_meas[:10])))
    rng = np.random.default_rng(seed)
    # r first, then each signal in order (main's order: a white prior gives main's bits), each through its low-pass
    r_b = r_true + _noise(prior, "r", rng, (runs, n))
    s_b = {k: clean[k] + _noise(prior, k, rng, (runs, n)) for k in sig}
    r_b = r_b + (0.0 if offsets is None else offsets)
    if derive is not None:
        rows = [derive({k: s_b[k][i] for k in sig}, r_b[i]) for i in range(runs)]
        s_b = {k: np.stack([row[k] for row in rows]) for k in rows[0]}
    xb = _fit_scales(kind, s_b, r_b, dt, x, prefilter_hz)
    d = (xb - x) / np.maximum(np.abs(x), 1e-6)
    d = d[np.all(np.isfinite(d), axis=1)]
    if len(d) < max(2, runs // 2):
        raise UserError("the prior's bootstrap refits diverged; the recording does not excite yaw enough for a prior")
    return d
