"""Yaw-row prior models, full (2.17) and simplified (2.18) of "Estimating a ship's dynamics during
operation" (MSc thesis), fitted by output error (its ch. 4).

    I_r r' = -M_v v' + A u r + N_r|r| r|r| + N_r|v| r|v| + N_phiu|r| phi u|r|
             + N_|u|v |u| v + N_phi|uv| phi|uv| + N_phiu|u| phi u|u| + tau_r,act          (2.17)
    I_r r' = A u r + N_r|r| r|r| + N_r|v| r|v| + N_|u|v |u| v + tau_r,act                  (2.18)

The predictor simulates ``r`` from the measured u, v, v', phi and tau_r (L1215-1216): everything
but ``r`` is an input. Parameters are scales ``x`` of the nominal values of the digest's section
3.3, so every column of a vectorised simulation can carry its own parameter set (the Jacobian
and the signatures are one call each).

The nominal values (the scale of every parameter) are the lumped yaw parameters (2.19) of the
shared kernel's ``naval-vessel`` profile (:func:`identify.yawid.model.true_parameters`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import lfilter, savgol_filter

from identify.detect.vessel import base_profile
from identify.yawid.estimate import fit_yaw, prefilter, simulate_yaw
from identify.yawid.experiment import YawData
from identify.yawid.model import FULL, FULL_P, MODELS, true_parameters
from primitives.errors import UserError


def prior_name(name: str) -> str:
    """The prior's name of a yawid parameter: N_phiu|r|, N_phiu|u|, N_phi|uv| are N_fur, N_fuu, N_fuv."""
    return name.replace("N_phi", "N_f")


_TRUE = true_parameters(base_profile())
#: the yaw rows a prior can have: yawid's (2.17), (2.18), and (2.17) with the roll-rate term N_p p
YAW_MODELS = MODELS | {FULL_P.name: FULL_P}
#: scale (and fit start) of N_p, N m s: the profile has no roll-rate term in its yaw row; this is
#: the order of a 50 m hull's (Blanke and Christensen 1993 give K_p ~ -0.5e6 N m s), not a value
N_P_SCALE = -1.0e6
#: (2.19) of the profile, in the order of the full model (2.17), then the roll-rate term's scale
NOMINAL = {prior_name(k): _TRUE[k] for k in FULL.params} | {"N_p": N_P_SCALE}
PARAMS = {kind: tuple(map(prior_name, m.params)) for kind, m in YAW_MODELS.items()}
DAMPING = ("A", "N_rr", "N_rv", "N_fur", "N_uv", "N_fuu", "N_fuv")
SIGNALS = {
    "full": ("u", "v", "v_dot", "phi", "tau_r"),
    "full-p": ("u", "v", "v_dot", "phi", "p", "tau_r"),
    "simplified": ("u", "v", "tau_r"),
}
PREFILTER_HZ = 0.5  # the model inputs' low-pass (manoeuvres are slower than 0.2 Hz, roll ~0.13 Hz)
#: the candidate changes a detector names (BRIEF effect ``inertia_change`` is "yaw_inertia")
CANDIDATES = ("yaw_inertia", "yaw_damping", "pod_gain")
# Recomputes derived inputs from a simulated record: derive(signals, yaw rate) -> signals
Derive = Callable[[dict[str, np.ndarray], np.ndarray], dict[str, np.ndarray]]


@dataclass
class YawPrior:
    """A fitted yaw row: its structure, parameter values, and what the fit says about its error."""

    kind: str  # "full" (2.17) or "simplified" (2.18)
    values: dict[str, float]
    sigma: float  # robust standard deviation of the fit residual, rad/s
    cov: np.ndarray  # second moment of the relative parameter errors (bootstrap; or the fit Jacobian's covariance)
    ar: np.ndarray = field(default_factory=lambda: np.zeros(0))  # AR whitening filter of the block-mean fit residual
    sigma_w: float = 0.0  # robust standard deviation of the whitened block-mean fit residual
    block: int = 10  # samples per block mean (1 s at 10 Hz)
    dt: float = 0.1
    source: str = ""
    prefilter_hz: float = 0.0  # zero-phase low-pass of the model inputs (0: as measured)
    boot: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (B, P) bootstrap relative errors
    noise: dict[str, float] = field(default_factory=dict)  # white measurement noise sd per signal, read from the nominal data
    #: innovation sd of the block-mean fit residual beyond what that white noise explains (misfit, and noise the
    #: second difference misses: sensor-filtered or coloured); every record the prior simulates carries it
    model_error: float = 0.0
    #: apparent relative change along each candidate (CANDIDATES) that the structure's misfit makes on a
    #: manoeuvre the prior was not fitted on (split-half cross-validation beyond noise; :func:`structural_spread`)
    structure: np.ndarray = field(default_factory=lambda: np.zeros(len(CANDIDATES)))

    @property
    def names(self) -> tuple[str, ...]:
        return PARAMS[self.kind]

    def inputs(self, sig: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The measured model inputs as the prior was fitted on them (low-passed along time, axis 0)."""
        return model_inputs(sig, self.dt, self.prefilter_hz)

    def predict(self, sig: dict[str, np.ndarray], r0: float = 0.0) -> np.ndarray:
        """``r_hat`` of this prior driven by the measured inputs ``sig`` ((n,) or (n, runs) each)."""
        return simulate_r(self.kind, self.values, self.inputs(sig), self.dt, r0=r0)

    def to_dict(self) -> dict:
        return {
            "format": "shiptrial-yaw-prior/1",
            "kind": self.kind,
            "values": self.values,
            "sigma": self.sigma,
            "cov": self.cov.tolist(),
            "ar": self.ar.tolist(),
            "sigma_w": self.sigma_w,
            "block": self.block,
            "dt": self.dt,
            "source": self.source,
            "prefilter_hz": self.prefilter_hz,
            "boot": self.boot.tolist(),
            "noise": self.noise,
            "model_error": self.model_error,
            "structure": self.structure.tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict, where: str = "prior") -> YawPrior:
        try:
            if d.get("format") != "shiptrial-yaw-prior/1":
                raise KeyError("format")
            kind = d["kind"]
            names = PARAMS[kind]
            values = {k: float(d["values"][k]) for k in names}
            cov = np.asarray(d["cov"], float).reshape(len(names), len(names))
            p = cls(
                kind,
                values,
                float(d["sigma"]),
                cov,
                np.asarray(d["ar"], float).ravel(),
                float(d["sigma_w"]),
                int(d["block"]),
                float(d["dt"]),
                str(d.get("source", "")),
                float(d.get("prefilter_hz", 0.0)),
                np.asarray(d.get("boot", []), float).reshape(-1, len(names)),
                {str(k): float(v) for k, v in d.get("noise", {}).items()},
                float(d.get("model_error", 0.0)),
                np.asarray(d.get("structure", [0.0] * len(CANDIDATES)), float).reshape(len(CANDIDATES)),
            )
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise UserError(
                f"{where}: not a yaw prior written by 'shiptrial detect-prior' (field {e}); "
                "make one with: shiptrial detect-prior NOMINAL.csv --out PRIOR.json"
            ) from None
        ok = [
            np.isfinite(list(values.values())).all(),
            np.isfinite(cov).all(),
            np.isfinite(p.ar).all(),
            np.isfinite(p.boot).all(),
            np.isfinite(list(p.noise.values())).all(),
            p.model_error >= 0,
            np.isfinite(p.structure).all(),
            np.all(p.structure >= 0),
            p.sigma > 0,
            p.sigma_w > 0,
            p.block >= 1,
            p.dt > 0,
            values["I_r"] > 0,
            0 <= p.prefilter_hz < 0.5 / p.dt,
        ]
        if not all(ok):
            raise UserError(
                f"{where}: the prior holds non-finite or non-physical values (I_r, sigma and dt must be > 0, "
                "prefilter_hz below Nyquist); refit it"
            )
        return p


def model_inputs(sig: dict[str, np.ndarray], dt: float, prefilter_hz: float) -> dict[str, np.ndarray]:
    """The measured inputs ``sig`` as the prior uses them (time on axis 0): with ``prefilter_hz`` > 0,
    v fused with the measured v' when there is one (:func:`fuse_sway`), then every input low-passed
    at ``prefilter_hz`` (:func:`identify.yawid.estimate.prefilter`); as measured with 0 (the thesis)."""
    if prefilter_hz <= 0:
        return sig
    # filtered along the last axis of the time-last views: filtfilt's padding copies to C order, so the
    # no-change records' (n, runs) arrays are then filtered along contiguous memory (about half the time)
    out = {k: np.asarray(x).T for k, x in sig.items()}
    if "v_dot" in out and "v" in out:
        out["v"] = fuse_sway(out["v"], out["v_dot"], dt, axis=-1)
    return {k: x.T for k, x in prefilter(out, dt, prefilter_hz, axis=-1).items()}


def fuse_sway(v: np.ndarray, v_dot: np.ndarray, dt: float, crossover_hz: float = 0.05, axis: int = 0) -> np.ndarray:
    """Sway velocity from the measured v (below ``crossover_hz``) and the integral of the measured
    sway acceleration (above it): zero-phase complementary filter (2nd-order Butterworth).

    v enters the yaw row through |v| and the pods' drift angle, nonlinearly, so its noise biases
    (errors in variables); at Table 4.1 noise (v 0.15 m/s, v' 0.015 m/s^2, 10 Hz) the fused v
    errs by about 0.016 m/s rms against 0.045 m/s for v low-passed at 0.5 Hz. Time along ``axis``."""
    from scipy.signal import butter, filtfilt

    iv = np.cumsum(v_dot, axis=axis) - v_dot  # the integral up to the sample before
    iv *= dt
    b, a = butter(2, crossover_hz, fs=1.0 / dt)
    return filtfilt(b, a, v, axis=axis) + iv - filtfilt(b, a, iv, axis=axis)


def _theta(kind: str, x: np.ndarray | dict) -> dict[str, np.ndarray]:
    """Parameter values from scales ``x`` (shape (P,) or (P, cols)) or a dict of values."""
    if isinstance(x, dict):
        return {k: np.asarray(x.get(k, 0.0), float) for k in NOMINAL}
    th = {k: np.asarray(0.0) for k in NOMINAL}
    for i, k in enumerate(PARAMS[kind]):
        th[k] = NOMINAL[k] * np.asarray(x[i], float)
    return th


def simulate_r(
    kind: str, theta: dict | np.ndarray, sig: dict[str, np.ndarray], dt: float, gain: float | np.ndarray = 1.0, r0: float = 0.0
) -> np.ndarray:
    """Yaw rate predicted by (2.17)/(2.18) from the measured signals ``sig``, from ``r0``.

    yawid's simulator (:func:`identify.yawid.estimate.simulate_yaw`, the explicit Euler step of
    the shared kernel ``primitives.simulate``, seed 001 (3.60)) on this module's layout: the prior
    is the yaw row of the same discrete-time model, so with the profile's parameters and the
    kernel's own v' and tau_r it reproduces the kernel's yaw rate to rounding.

    Signals are (n,) or (n, cols) (time on axis 0); parameter values (and the actuator ``gain``,
    which scales tau_r) scalars or (cols,): one simulated column per parameter set.
    """
    th = _theta(kind, theta)
    model = YAW_MODELS[kind]
    names = tuple(map(prior_name, model.params))
    tau = np.asarray(gain) * sig["tau_r"]
    shape = np.broadcast_shapes(tau.shape, *(np.shape(sig[k]) for k in model.signals), *(np.shape(th[k]) for k in names))
    cols = shape[1] if len(shape) == 2 else 1

    def batch(a: np.ndarray) -> np.ndarray:  # (cols, n): yawid's batch-first layout
        a = np.broadcast_to(a, shape)
        return a.T if a.ndim == 2 else a[None]

    w = {k: batch(sig[k]) for k in model.signals} | {"tau_r": batch(tau)}
    theta_b = np.stack([np.broadcast_to(np.asarray(th[k], float), (cols,)) for k in names], axis=1)
    r_hat, _ = simulate_yaw(model, theta_b, w, np.full(cols, float(r0)), dt, sensitivities=False)
    return np.ascontiguousarray(r_hat.T) if len(shape) == 2 else r_hat[0]


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
) -> YawPrior:
    """Output-error fit of (2.17)/(2.18) (ch. 4, eq. 4.1-4.4; yawid's batched Levenberg-Marquardt
    from the nominal values, with section 4.3's sign constraints) on the inputs low-passed at
    ``prefilter_hz`` (:func:`model_inputs`), with the residual's robust sigma and whitening filter.
    ``estimate=False`` keeps the nominal values (seed 000's "model 0") and only measures the
    residual on this data.

    The prior's parameter error is described by ``bootstrap`` parametric-bootstrap refits
    (:func:`bootstrap_deviations`: noise on every input, so the errors-in-variables part is in)
    kept as they are (``YawPrior.boot``, for the detector's no-change simulation) and as their
    second moment (``cov``); ``bootstrap=0`` gives only the fit's Jacobian covariance, which
    knows the noise on r alone."""
    raw, sig = sig, model_inputs(sig, dt, prefilter_hz)
    p = len(PARAMS[kind])
    x = (
        _fit_scales(kind, {k: v[None] for k, v in raw.items()}, r_meas[None], dt, np.ones(p), prefilter_hz)[0]
        if estimate
        else np.ones(p)
    )
    block = max(1, int(round(1.0 / dt)))
    r0 = float(np.mean(r_meas[:block]))
    e = simulate_r(kind, x, sig, dt, r0=r0) - r_meas if np.all(np.isfinite(x)) else np.full(len(r_meas), np.nan)
    if not np.all(np.isfinite(e)):
        raise UserError(f"{source}: the yaw-row fit diverged; the recording does not excite yaw enough for a prior")
    e_blocks = block_mean(e, block)
    ar = ar_fit(e_blocks)
    sigma_w = robust_sigma(whiten(e_blocks, ar))
    values = {k: float(NOMINAL[k] * xi) for k, xi in zip(PARAMS[kind], x)}
    noise = {k: white_noise_sd(v) for k, v in raw.items()} | {"r": white_noise_sd(r_meas)}
    prior = YawPrior(
        kind, values, robust_sigma(e), np.zeros((p, p)), ar, sigma_w, block, dt, source, prefilter_hz, np.zeros((0, p)), noise
    )
    prior.model_error = model_error(prior, raw, r0, derive, seed)
    if estimate and bootstrap > 0:
        # the refits see the nominal residual's whole level: white noise at the levels read, plus what
        # those levels do not explain (coloured or sensor-filtered noise, misfit), as the null records do
        offsets = misfit_offsets(prior, len(r_meas), bootstrap, np.random.default_rng([seed, 7])).T
        prior.boot = bootstrap_deviations(kind, raw, r_meas, dt, x, bootstrap, seed, derive, prefilter_hz, offsets)
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
            eps = rt - half.predict(test, r0=float(np.mean(rt[: prior.block])))
            Sw = whiten(block_mean(signatures(half, test), prior.block), prior.ar)
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
) -> np.ndarray:
    """How far the prior's structure alone moves the detector's change estimates on a manoeuvre it
    was not fitted on: rms over the two split-half cross-validations of the nominal record
    (:func:`_split_theta`), less (in quadrature) the 95 % point of what the same two estimates give
    on records that the prior's own structure generates with the nominal data's noise and model-error
    term (``synthetic`` of them: what noise and the half fits' parameter error alone give). Zero for a structure that
    fits, and where the half fits diverged (no estimate: ``detect`` then warns that its alarms are
    not calibrated); the detector's calibration adds it as a random apparent change along each
    candidate's own signature (:func:`glr.calibrate`)."""
    real = _split_theta(prior, {k: v[None] for k, v in sig.items()}, r_meas[None], x)
    clean = smooth(sig, prior.dt)
    n = len(r_meas)
    rng = np.random.default_rng([seed, 5])
    r_true = simulate_r(prior.kind, x, prior.inputs(clean), prior.dt, r0=float(np.mean(r_meas[:10])))
    # the same residual the no-change records carry (noise, and what the nominal residual has beyond it):
    # without the latter, coloured sensor noise that the white-noise reading misses passed for structure
    r_b = r_true + prior.noise.get("r", 0.0) * rng.standard_normal((synthetic, n)) + misfit_offsets(prior, n, synthetic, rng).T
    s_b = {k: clean[k] + prior.noise.get(k, 0.0) * rng.standard_normal((synthetic, n)) for k in sig}
    if derive is not None:
        rows = [derive({k: s_b[k][i] for k in sig}, r_b[i]) for i in range(synthetic)]
        s_b = {k: np.stack([row[k] for row in rows]) for k in rows[0]}
    noise = _split_theta(prior, s_b, r_b, x)
    ms_real = np.nanmean(real**2, axis=(0, 1))
    ms_noise = np.nanmean(noise**2, axis=(0, 1))
    # two held-out estimates give a mean square that is ms_noise * chi2(2)/2 for a structure that
    # fits: count only what exceeds its 95 % point (3.0 ms_noise), so noise does not pass for misfit
    return np.nan_to_num(np.sqrt(np.maximum(ms_real - 3.0 * ms_noise, 0.0)), nan=0.0)


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


def _covariance(
    kind: str, sig: dict, dt: float, x: np.ndarray, r0: float, block: int, ar: np.ndarray, sigma_w: float
) -> np.ndarray:
    """``sigma_w^2 (Jw^T Jw)^-1`` of the whitened 1 s block means, ``J = d r_hat / d ln(theta)``."""
    Jw = whiten(block_mean(_jacobian(kind, x, sig, dt, r0=r0) * x[None, :], block), ar)
    return sigma_w**2 * np.linalg.pinv(Jw.T @ Jw)


def white_noise_sd(x: np.ndarray) -> float:
    """Standard deviation of the white measurement noise on a signal that is smooth at its sample
    rate: robust sigma of the second difference / sqrt(6) (the signal's own curvature is far below
    the noise at 10 Hz)."""
    return robust_sigma(np.diff(np.asarray(x, float), 2)) / np.sqrt(6.0)


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
    rates (:func:`misfit_offsets`: the residual the white-noise levels do not explain). Only nominal
    data enter."""
    clean = smooth(sig, dt)
    sd = {k: white_noise_sd(s) for k, s in sig.items()}
    n = len(r_meas)
    r_true = simulate_r(kind, x, model_inputs(clean, dt, prefilter_hz), dt, r0=float(np.mean(r_meas[:10])))
    rng = np.random.default_rng(seed)
    r_b = r_true + white_noise_sd(r_meas) * rng.standard_normal((runs, n)) + (0.0 if offsets is None else offsets)
    s_b = {k: clean[k] + sd[k] * rng.standard_normal((runs, n)) for k in sig}
    if derive is not None:
        rows = [derive({k: s_b[k][i] for k in sig}, r_b[i]) for i in range(runs)]
        s_b = {k: np.stack([row[k] for row in rows]) for k in rows[0]}
    xb = _fit_scales(kind, s_b, r_b, dt, x, prefilter_hz)
    d = (xb - x) / np.maximum(np.abs(x), 1e-6)
    d = d[np.all(np.isfinite(d), axis=1)]
    if len(d) < max(2, runs // 2):
        raise UserError("the prior's bootstrap refits diverged; the recording does not excite yaw enough for a prior")
    return d


def parameter_draws(prior: YawPrior, runs: int, seed: int = 0) -> np.ndarray:
    """(runs, P) relative parameter errors of the prior: its bootstrap refits cycled, or Gaussian
    draws from ``cov`` when it has none."""
    if len(prior.boot):
        return prior.boot[np.arange(runs) % len(prior.boot)]
    return np.random.default_rng(seed).multivariate_normal(np.zeros(len(prior.cov)), prior.cov, size=runs, method="eigh")


def smooth(sig: dict[str, np.ndarray], dt: float) -> dict[str, np.ndarray]:
    """Savitzky-Golay smoothing (2 s, quadratic) along time: the bootstraps' stand-in for the true inputs."""
    win = 2 * int(1.0 / dt) + 1
    return {k: savgol_filter(s, win, 2, axis=0) if len(s) > win else s for k, s in sig.items()}


def null_records(
    prior: YawPrior, sig: dict[str, np.ndarray], runs: int, seed: int = 0, derive: Derive | None = None, r0: float = 0.0
) -> np.ndarray:
    """No-change residuals ``r - r_hat`` (n, runs) on the manoeuvre ``sig`` (a parametric bootstrap
    of the detection, from the prior's own data only).

    In each run the ship is the prior's model with one of its bootstrap parameter errors undone
    (``x - delta_b``: what the true ship may be, given the prior's estimate), driven by the
    smoothed measured inputs; its yaw rate and inputs are then measured with white noise at the
    levels read from the nominal data (``prior.noise``), ``derive`` recomputes derived inputs as
    for the recording, and the prior predicts r from them as it does on the recording. So noise
    on every input, its path through the yaw dynamics and the prior's parameter error are all in;
    the structure's own misfit is added as AR-coloured 1 s block offsets (``prior.model_error``);
    its apparent change along each candidate (``prior.structure``) is added per candidate by
    :func:`identify.detect.glr.calibrate`."""
    x = np.array([prior.values[k] / NOMINAL[k] for k in prior.names])
    truth_x = x[:, None] - (parameter_draws(prior, runs, seed) * np.maximum(np.abs(x), 1e-6)).T
    clean = smooth(sig, prior.dt)
    n = len(sig["u"])
    r_true = simulate_r(prior.kind, truth_x, {k: s[:, None] for k, s in prior.inputs(clean).items()}, prior.dt, r0=r0)
    rng = np.random.default_rng([seed, 1])
    r_meas = _measured(r_true, prior.noise.get("r", 0.0), rng, runs)
    noisy = {k: _measured(s[:, None], prior.noise.get(k, 0.0), rng, runs) for k, s in clean.items()}
    if derive is not None:
        noisy = derive(noisy, r_meas)
    return r_meas - prior.predict(noisy, r0=r0) + misfit_offsets(prior, n, runs, rng)


def _measured(x: np.ndarray, sd: float, rng: np.random.Generator, runs: int) -> np.ndarray:
    """``x`` ((n, runs), or (n, 1) broadcast over ``runs``) plus white noise of ``sd``, (n, runs) with
    time along the contiguous axis: the no-change records' filters then run along contiguous memory."""
    z = rng.standard_normal((runs, len(x))).T
    z *= sd
    z += x
    return z


def misfit_offsets(prior: YawPrior, n: int, runs: int, rng: np.random.Generator) -> np.ndarray:
    """(n, runs) residual the white noise at ``prior.noise`` does not explain (``prior.model_error``):
    1 s block offsets coloured by the prior's AR filter (its innovation sd ``model_error``), so a
    simulated record's whitened block residual has the nominal fit's level; zeros without it."""
    out = np.zeros((n, runs))
    if prior.model_error > 0:
        nb = n // prior.block
        w = lfilter([1.0], np.r_[1.0, -prior.ar], prior.model_error * rng.standard_normal((nb, runs)), axis=0)
        out[: nb * prior.block] = np.repeat(w, prior.block, axis=0)
    return out


def robust_sigma(e: np.ndarray) -> float:
    """1.4826 median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(e - np.median(e))))


def block_mean(x: np.ndarray, block: int) -> np.ndarray:
    """Means of consecutive ``block`` samples along axis 0 (a trailing partial block is dropped).

    The change signatures are slower than 0.5 Hz, so 1 s means keep their information, while the
    noise that the yaw dynamics low-pass (input noise through the model) becomes short-memory
    enough for a low-order AR whitening filter."""
    x = np.asarray(x, float)
    nb = len(x) // block
    return x[: nb * block].reshape(nb, block, *x.shape[1:]).mean(axis=1)


def ar_fit(e: np.ndarray, order: int = 4) -> np.ndarray:
    """AR(order) coefficients ``a`` of ``e_t = sum a_i e_{t-i} + w_t`` by least squares."""
    e = np.asarray(e, float) - np.mean(e)
    X = np.column_stack([e[order - i - 1 : len(e) - i - 1] for i in range(order)])
    a, *_ = np.linalg.lstsq(X, e[order:], rcond=None)
    return a


def whiten(x: np.ndarray, ar: np.ndarray) -> np.ndarray:
    """``x_t - sum a_i x_{t-i}`` along axis 0 (the innovation filter of ``ar_fit``); first samples as is."""
    x = np.asarray(x, float)
    out = x.copy()
    for i, a in enumerate(ar, start=1):
        out[i:] -= a * x[:-i]
    return out


def signatures(prior: YawPrior, sig: dict[str, np.ndarray], rel: float = 0.05) -> np.ndarray:
    """``S`` (n, 3): the change of r_hat per unit relative change of each candidate in CANDIDATES
    (yaw inertia, all damping terms together, actuator gain) on the manoeuvre ``sig``."""
    names = prior.names
    base = np.array([prior.values[k] / NOMINAL[k] for k in names])
    cols = np.repeat(base[:, None], 4, axis=1)
    cols[names.index("I_r"), 1] *= 1 + rel
    cols[[names.index(k) for k in DAMPING if k in names], 2] *= 1 + rel
    gain = np.array([1.0, 1.0, 1.0, 1 + rel])
    r = simulate_r(prior.kind, cols, {k: s[:, None] for k, s in prior.inputs(sig).items()}, prior.dt, gain=gain)
    return (r[:, 1:] - r[:, :1]) / rel
