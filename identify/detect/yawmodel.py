"""Yaw-row prior models, full (2.17) and simplified (2.18) of "Estimating a ship's dynamics during
operation" (MSc thesis): the prior (its fit: :mod:`identify.detect.priorfit`; the no-change records
simulated from it: :mod:`identify.detect.nullsim`), its predictor and the change signatures.

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

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from identify.detect.noiseread import A_MAX
from identify.detect.noiseread import robust_sigma as robust_sigma  # its home before stop 55: still importable here
from identify.detect.vessel import base_profile
from identify.yawid.estimate import prefilter, simulate_yaw
from identify.yawid.model import FULL, FULL_P, MODELS, true_parameters
from primitives.errors import UserError

#: the prior file's format tags: /1 main's (white noise), /2 with the sensors' low-pass corners ``noise_tau`` (stop 55)
PRIOR_FORMATS = ("shiptrial-yaw-prior/1", "shiptrial-yaw-prior/2")
#: the noise readers a prior file's ``noise_model`` may name (:data:`identify.detect.priorfit.NOISE_MODELS`, and
#: "lowpass": retired as an option at stop 57, its files still load with the noise levels they hold)
NOISE_READERS = ("white", "lowpass", "spectral")


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
    #: innovation sd of the block-mean fit residual beyond what that noise explains (misfit, and noise the reading
    #: misses: sensor-filtered when read as white, or coloured); every record the prior simulates carries it
    model_error: float = 0.0
    #: apparent relative change along each candidate (CANDIDATES) that the structure's misfit makes on a
    #: manoeuvre the prior was not fitted on (split-half cross-validation beyond noise; :func:`identify.detect.priorfit.structural_spread`)
    structure: np.ndarray = field(default_factory=lambda: np.zeros(len(CANDIDATES)))
    #: time (s) the measured moment is advanced by against the measured yaw rate (:func:`shift_moment`): the
    #: sensors' different lags (load cell against gyro) fitted on the nominal run (:func:`identify.detect.api.fit_prior`)
    moment_shift_s: float = 0.0
    #: time constant (s) of the first-order low-pass each signal's white noise ``noise`` passed through, read with it
    #: (:func:`identify.detect.noisespec.spectral_noise`; stop 55's retired lowpass reader in older files); a signal
    #: not in it (every signal of a prior written before stop 55) has white noise (:func:`identify.detect.priorfit.
    #: white_noise_sd`'s reading)
    noise_tau: dict[str, float] = field(default_factory=dict)
    #: the reader that read ``noise_tau`` ("lowpass": stop 55, "spectral": stop 56; :data:`NOISE_READERS`), written
    #: beside it in a /2 file so a user can tell the two apart; "" when not known (a file written before the review of
    #: stop 56) or when no corner was read
    noise_model: str = ""

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
            # /2 only with a sensor low-pass read (stop 55): there ``noise`` is the sd before the filter, which an
            # older reader would draw as white noise; it refuses /2. A white prior stays /1, main's file to the byte
            "format": PRIOR_FORMATS[1] if self.noise_tau else PRIOR_FORMATS[0],
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
            "moment_shift_s": self.moment_shift_s,
            **({"noise_tau": self.noise_tau} if self.noise_tau else {}),
            **({"noise_model": self.noise_model} if self.noise_tau and self.noise_model else {}),
        }

    @classmethod
    def from_dict(cls, d: dict, where: str = "prior") -> YawPrior:
        """The prior :meth:`to_dict` wrote (file ``where``), refused in one line (UserError) when a field is
        missing or malformed (:meth:`_read`) or holds a value no fit gives (:meth:`_check`)."""
        try:
            p = cls._read(d)
        except (KeyError, TypeError, ValueError, AttributeError) as e:
            raise UserError(
                f"{where}: not a yaw prior written by 'shiptrial detect-prior' (field {e}); "
                "make one with: shiptrial detect-prior NOMINAL.csv --out PRIOR.json"
            ) from None
        p._check(where)
        return p

    @classmethod
    def _read(cls, d: dict) -> YawPrior:
        """The fields of ``d``, typed and shaped (the optional ones, absent from older files, at their defaults)."""
        if d.get("format") not in PRIOR_FORMATS:
            raise KeyError("format")
        kind = d["kind"]
        names = PARAMS[kind]
        # values and cov read before the rest, as before the split: a file with several bad fields names the same one
        values = {k: float(d["values"][k]) for k in names}
        cov = np.asarray(d["cov"], float).reshape(len(names), len(names))
        return cls(
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
            float(d.get("moment_shift_s", 0.0)),
            {str(k): float(v) for k, v in d.get("noise_tau", {}).items()},
            str(d.get("noise_model", "")),
        )

    def _check(self, where: str) -> None:
        """Refuse (UserError naming ``where``) a prior holding non-finite or non-physical values, or read by a
        noise reader this version does not know."""
        ok = [
            np.isfinite(list(self.values.values())).all(),
            np.isfinite(self.cov).all(),
            np.isfinite(self.ar).all(),
            np.isfinite(self.boot).all(),
            np.isfinite(list(self.noise.values())).all(),
            # a corner beyond noisespec's grid (a > A_MAX: about 10 s at 10 Hz) would filter the noise away
            all(np.isfinite(t) and 0 <= t <= -self.dt / math.log(A_MAX) for t in self.noise_tau.values()),
            self.model_error >= 0,
            np.isfinite(self.structure).all(),
            np.all(self.structure >= 0),
            self.sigma > 0,
            self.sigma_w > 0,
            self.block >= 1,
            self.dt > 0,
            self.values["I_r"] > 0,
            0 <= self.prefilter_hz < 0.5 / self.dt,
        ]
        if not all(ok):
            raise UserError(
                f"{where}: the prior holds non-finite or non-physical values (I_r, sigma and dt must be > 0, "
                "prefilter_hz below Nyquist); refit it"
            )
        if self.noise_model not in ("", *NOISE_READERS):  # "": a file without the field (before stop 56), read as written
            raise UserError(
                f"{where}: field noise_model {self.noise_model!r} names no noise reader this version knows "
                "(white, spectral; lowpass files of stops 55-56 still load); "
                f"refit it: shiptrial detect-prior NOMINAL.csv --out {where} --noise-model spectral"
            )


def shift_moment(sig: dict[str, np.ndarray], shift_s: float, dt: float) -> dict[str, np.ndarray]:
    """``sig`` with the moment ``tau_r`` advanced by ``shift_s`` seconds (linear interpolation along axis 0,
    the last value held): a load cell that lags the gyro by ``shift_s`` puts the yaw row's inertia
    balance out of phase at the roll frequency, so a run's inertia reading follows its roll level."""
    if shift_s == 0.0:
        return sig
    tau = np.asarray(sig["tau_r"], float)
    t = np.arange(len(tau)) * dt
    cols = tau.reshape(len(tau), -1)
    out = np.column_stack([np.interp(t + shift_s, t, c) for c in cols.T]).reshape(tau.shape)
    return sig | {"tau_r": out}


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
    from primitives.zerophase import filtfilt, lowpass  # scipy's, compiled for the no-change records' rows (the same bits)

    iv = np.cumsum(v_dot, axis=axis) - v_dot  # the integral up to the sample before
    iv *= dt
    b, a = lowpass(2, crossover_hz, 1.0 / dt)
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
    kind: str,
    theta: dict | np.ndarray,
    sig: dict[str, np.ndarray],
    dt: float,
    gain: float | np.ndarray = 1.0,
    r0: float | np.ndarray = 0.0,
    extra: dict[str, np.ndarray] | None = None,
) -> np.ndarray:
    """Yaw rate predicted by (2.17)/(2.18) from the measured signals ``sig``, from ``r0``.

    yawid's simulator (:func:`identify.yawid.estimate.simulate_yaw`, the explicit Euler step of
    the shared kernel ``primitives.simulate``, seed 001 (3.60)) on this module's layout: the prior
    is the yaw row of the same discrete-time model, so with the profile's parameters and the
    kernel's own v' and tau_r it reproduces the kernel's yaw rate to rounding.

    Signals are (n,) or (n, cols) (time on axis 0); parameter values (and the actuator ``gain``,
    which scales tau_r) scalars or (cols,): one simulated column per parameter set; ``r0`` a scalar or (cols,).
    ``extra`` (signals of the same layout) is added to ``sig``'s as the simulation reads them, a block of
    samples at a time (:func:`identify.yawid.estimate.simulate_yaw`): the signals ``sig + extra``, to the bit,
    without their sums held whole (a no-change job's (n, runs) inputs, :func:`identify.detect.nullsim.null_records`).
    """
    th = _theta(kind, theta)
    model = YAW_MODELS[kind]
    names = tuple(map(prior_name, model.params))
    # only the signals the model reads: an extra entry for another must not change the shape (nor fail it)
    extra = {k: x for k, x in (extra or {}).items() if k in (*model.signals, "tau_r")}
    # x * 1.0 is x for float64 (no (n, cols) product to make); another dtype is made float64 by it, as before
    unit = np.ndim(gain) == 0 and float(gain) == 1.0 and np.asarray(sig["tau_r"]).dtype == np.float64
    tau = sig["tau_r"]
    if not unit:  # the gain scales tau_r's sum: that one formed whole, as before; the others added in the loop
        tau = np.asarray(gain) * ((tau + extra.pop("tau_r")) if "tau_r" in extra else tau)
    shapes = [np.shape(x) for x in (tau, *(sig[k] for k in model.signals), *extra.values())]
    shape = np.broadcast_shapes(*shapes, *(np.shape(th[k]) for k in names))
    cols = shape[1] if len(shape) == 2 else 1

    def batch(a: np.ndarray) -> np.ndarray:  # (cols, n): yawid's batch-first layout
        a = np.broadcast_to(a, shape)
        return a.T if a.ndim == 2 else a[None]

    w = {k: batch(sig[k]) for k in model.signals} | {"tau_r": batch(tau)}
    theta_b = np.stack([np.broadcast_to(np.asarray(th[k], float), (cols,)) for k in names], axis=1)
    r0s = np.full(cols, float(r0)) if np.ndim(r0) == 0 else np.array(r0, dtype=float).reshape(cols)
    more = {k: batch(x) for k, x in extra.items()}
    r_hat, _ = simulate_yaw(model, theta_b, w, r0s, dt, sensitivities=False, extra=more)
    return np.ascontiguousarray(r_hat.T) if len(shape) == 2 else r_hat[0]


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


def signatures(
    prior: YawPrior, sig: dict[str, np.ndarray], rel: float = 0.05, inputs: dict[str, np.ndarray] | None = None
) -> np.ndarray:
    """``S`` (n, 3): the change of r_hat per unit relative change of each candidate in CANDIDATES
    (yaw inertia, all damping terms together, actuator gain) on the manoeuvre ``sig`` (``inputs``:
    ``prior.inputs(sig)`` when the caller has it already)."""
    cols, gain = _signature_columns(prior, rel)
    w = prior.inputs(sig) if inputs is None else inputs
    r = simulate_r(prior.kind, cols, {k: s[:, None] for k, s in w.items()}, prior.dt, gain=gain)
    return (r[:, 1:] - r[:, :1]) / rel


def predict_with_signatures(
    prior: YawPrior, inputs: dict[str, np.ndarray], r0: float = 0.0, rel: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """``(r_hat, S)``: ``simulate_r(prior.kind, prior.values, inputs, prior.dt, r0=r0)`` (the prior's
    prediction of a recording from its filtered ``inputs``) and :func:`signatures` on those inputs, in one
    simulation of five columns instead of two of one and four: each column's arithmetic is its own, so
    the same bits, and one time loop less (about 0.1 s CPU of a 500 s recording in numpy's loop)."""
    cols, gain = _signature_columns(prior, rel)
    sig_th, own = _theta(prior.kind, cols), _theta(prior.kind, prior.values)
    theta = {k: np.r_[own[k], np.broadcast_to(sig_th[k], (cols.shape[1],))] for k in NOMINAL}
    w = {k: s[:, None] for k, s in inputs.items()}
    r = simulate_r(prior.kind, theta, w, prior.dt, gain=np.r_[1.0, gain], r0=np.r_[float(r0), np.zeros(cols.shape[1])])
    return r[:, 0], (r[:, 2:] - r[:, 1:2]) / rel


def _signature_columns(prior: YawPrior, rel: float) -> tuple[np.ndarray, np.ndarray]:
    """The scaled parameters (P, 4) and actuator gains (4,) of :func:`signatures`' columns: the prior, then
    yaw inertia, the damping terms together and the gain each up by ``rel``."""
    names = prior.names
    base = np.array([prior.values[k] / NOMINAL[k] for k in names])
    cols = np.repeat(base[:, None], 4, axis=1)
    cols[names.index("I_r"), 1] *= 1 + rel
    cols[[names.index(k) for k in DAMPING if k in names], 2] *= 1 + rel
    return cols, np.array([1.0, 1.0, 1.0, 1 + rel])


PRIOR_WRITER = "shiptrial detect-prior"
_PRIOR_READ_MAX = 64 << 20  # a prior is kilobytes (its bootstrap refits); a larger file is not one


def is_prior_file(path: Path) -> bool:
    """A prior :func:`save_prior` wrote, known by its own fields: a JSON object whose ``format`` is a yaw-prior
    format and that holds ``kind``, ``values`` and ``sigma`` (not read further: an old prior is still ours)."""
    if path.stat().st_size > _PRIOR_READ_MAX:
        return False
    d = json.loads(path.read_bytes())
    return isinstance(d, dict) and d.get("format") in PRIOR_FORMATS and {"kind", "values", "sigma"} <= d.keys()


def check_prior_out(path: str | Path, option: str = "path", *, force: bool = False) -> Path:
    """A prior's output path (.json): an existing file is replaced only if it is a prior (:func:`is_prior_file`)
    or ``force``; else UserError naming it and the fix (``option``: the CLI's "--out", or the keyword's "path")."""
    from primitives.io import check_out_file

    return check_out_file(path, (".json",), option, "prior", replace=force, ours=is_prior_file, writer=PRIOR_WRITER)
