"""No-change records simulated from a yaw prior alone (a parametric bootstrap of the detection):
the ship as the prior with one of its parameter errors undone, measured with the nominal data's
noise levels and the prior's misfit beyond them (:func:`null_records`); the detector's
thresholds are quantiles over them (:func:`identify.detect.glr.calibrate`)."""

from __future__ import annotations

import numpy as np

from identify.detect import noisecache
from identify.detect.noiseread import stationary_lowpass
from identify.detect.yawmodel import NOMINAL, Derive, YawPrior, simulate_r
from primitives import jitloop
from primitives.iir import lfilter  # scipy.signal's, without its 2 s import
from primitives.savgol import savgol_filter


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
    prior: YawPrior,
    sig: dict[str, np.ndarray],
    runs: int,
    seed: int = 0,
    derive: Derive | None = None,
    r0: float = 0.0,
    draws: dict | None = None,
) -> np.ndarray:
    """No-change residuals ``r - r_hat`` (n, runs) on the manoeuvre ``sig`` (a parametric bootstrap
    of the detection, from the prior's own data only).

    In each run the ship is the prior's model with one of its bootstrap parameter errors undone
    (``x - delta_b``: what the true ship may be, given the prior's estimate), driven by the
    smoothed measured inputs; its yaw rate and inputs are then measured with white noise at the
    levels read from the nominal data (``prior.noise``; through each sensor's first-order low-pass
    where the prior read one, ``prior.noise_tau``: :func:`sensor_filtered`), ``derive`` recomputes derived inputs as
    for the recording, and the prior predicts r from them as it does on the recording. So noise
    on every input, its path through the yaw dynamics and the prior's parameter error are all in;
    the structure's own misfit is added as AR-coloured 1 s block offsets (``prior.model_error``);
    its apparent change along each candidate (``prior.structure``) is added per candidate by
    :func:`identify.detect.glr.calibrate`.

    The records' noise is the same for every recording of the same length given the same
    ``seed`` (:func:`normals`): ``draws``, a dict a caller keeps over a job of many recordings
    (:func:`identify.detect.batch.detect_all`), holds the last recording's draws for the next.

    When ``derive`` is linear in the signals (``derive.linear``: the recording measures the pod yaw
    moment; or no ``derive``) the noise's share of the prior's inputs is filtered apart from the
    signals', once per job (:func:`_linear_inputs`; the same records to rounding); else signal and
    noise are filtered together, as measured. A ``derive`` without ``linear`` is taken as nonlinear."""
    x = np.array([prior.values[k] / NOMINAL[k] for k in prior.names])
    deltas = parameter_draws(prior, runs, seed)
    # the bootstrap's B refits are cycled over the runs: B distinct ships, each simulated once (a column's
    # simulation does not depend on the others: the same bits as simulating all ``runs``)
    ships = min(runs, len(prior.boot)) if len(prior.boot) else runs
    truth_x = x[:, None] - (deltas[:ships] * np.maximum(np.abs(x), 1e-6)).T
    clean = smooth(sig, prior.dt)
    n = len(sig["u"])
    r_true = simulate_r(prior.kind, truth_x, {k: s[:, None] for k, s in prior.inputs(clean).items()}, prior.dt, r0=r0)
    r_true = r_true[:, np.arange(runs) % ships]
    blocks = n // prior.block if prior.model_error > 0 else 0
    sds = (prior.noise.get("r", 0.0), *(prior.noise.get(k, 0.0) for k in clean))
    taus = noise_taus(prior, ("r", *clean))
    if derive is None or getattr(derive, "linear", False):
        r_noise, innovations, noise = _linear_noise(prior, tuple(clean), n, runs, seed, blocks, sds, derive, draws, taus)
        signal = _linear_inputs(prior, clean, r_true, derive)
        # the records' inputs are signal + noise, summed by blocks as the loop reads them (no 5 x 16 MB of sums);
        # before _measured: it may write the yaw rate's noise over r_noise
        r_hat = simulate_r(prior.kind, prior.values, signal, prior.dt, r0=r0, extra=noise)
        out = _measured(r_true, r_noise)
        out -= r_hat  # in place: the same bits as (measured - r_hat) + offsets, without the (n, runs) temporaries
        return add_misfit(out, prior, innovations)
    z = normals(seed, runs, n, len(clean), blocks, draws, scale=sds)  # the noise itself: scaled once per job
    offsets = misfit_offsets(prior, n, runs, None, z[-1] if blocks else np.zeros((0, runs)))
    z = sensor_filtered(z, taus, prior.dt)
    r_meas = _measured(r_true, z[0])
    noisy = {k: _measured(s[:, None], zk) for (k, s), zk in zip(clean.items(), z[1:])}
    return r_meas - prior.predict(derive(noisy, r_meas), r0=r0) + offsets


def _linear_noise(
    prior: YawPrior,
    names: tuple[str, ...],
    n: int,
    runs: int,
    seed: int,
    blocks: int,
    sds: tuple[float, ...],
    derive: Derive | None,
    draws: dict | None,
    taus: tuple[float, ...] = (),
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The recording-independent part of the linear path's no-change records: the yaw rate's noise
    (runs, n), the misfit's block innovations (``blocks``, runs; (0, runs) without) and the noise alone's
    share of the prior's inputs (n, runs) per input (added to :func:`_linear_inputs`' clean share inside the
    simulation), from the scaled draws of :func:`normals`, each signal's through its sensor's low-pass ``taus``
    (:func:`sensor_filtered`; none: white). They depend on the seed, ``runs``, the length ``n``, the noise levels ``sds`` and low-passes, the
    prior's sample time and input filter, the derivation's form and which loop filters (compiled or numpy) only: kept in ``draws`` over a job
    and, inside ``shiptrial detect``, on disk over commands (:mod:`identify.detect.noisecache`, read
    back memory-mapped and read-only: the numbers drawing and filtering them again gives, to the bit)."""
    form = (names, prior.dt, prior.prefilter_hz, None if derive is None else derive.form)
    lags = tuple(map(float, taus)) if any(taus) else ()  # white noise: main's key, main's entries
    full = (seed, runs, n, blocks, tuple(map(float, sds)), form, *((lags,) if lags else ()))
    if draws is not None and draws.get("linear_key") == full:
        return draws["linear"]
    if draws is not None:
        draws.clear()  # another length's arrays are not held beside this one's
    # the input filters' compiled loop gives scipy's bits, the numpy one scipy's to rounding (primitives.zerophase),
    # and which runs follows the job's size: an entry of a 40-recording call is not a one-recording call's noise
    name = noisecache.key(*full, jitloop.use(runs * n)) if noisecache.active() else ""
    hit = noisecache.load(name, runs, n, blocks) if name else None
    if hit is not None:
        r_noise, noise, innovations = hit
    else:
        z = sensor_filtered(normals(seed, runs, n, len(names), blocks, draws, scale=sds), taus, prior.dt)
        e = {k: zk.T for k, zk in zip(names, z[1:])}
        noise = prior.inputs(e if derive is None else derive(e, z[0].T))
        r_noise, innovations = z[0], z[-1] if blocks else np.zeros((0, runs))
        if name:
            noisecache.store(name, r_noise, noise, innovations)
    if draws is not None:
        for a in (r_noise, *noise.values()):  # shared with the next recordings of this length (the filtered yaw
            a.flags.writeable = False  # rate's noise is a new array, not normals' read-only draw: _measured would write on it)
        draws.update(linear_key=full, linear=(r_noise, innovations, noise))
    return r_noise, innovations, noise


def _linear_inputs(
    prior: YawPrior,
    clean: dict[str, np.ndarray],
    r_true: np.ndarray,
    derive: Derive | None,
) -> dict[str, np.ndarray]:
    """The prior's inputs of the clean signals (n, 1) or (n, runs): the no-change records' inputs less
    the noise's share (:func:`_linear_noise`), which :func:`null_records` adds as the simulation reads them.

    The records' inputs are ``F(D(s + e, r + e_r))``: D the derivation (``derive``, identity when
    None) and F the prior's input filter (:meth:`YawPrior.inputs`: the complementary sway filter
    and the zero-phase 4th-order Butterworth low-pass, :func:`identify.detect.yawmodel.model_inputs`),
    linear maps of the signal: the cumulative sum, the recursions, and filtfilt's edge handling too
    (the odd extension 2 x_0 - x_i and the initial state zi x_0 are linear in x). When D is linear
    too (``derive.linear``: the pod yaw moment measured, not computed from the motion by the pods'
    model (2.12)), ``F(D(s + e)) = F(D(s)) + F(D(e))``: the
    noise's share is the same for every recording of one length and derivation (the same draws),
    filtered once per job (and kept on disk by the command: :func:`_linear_noise`); only the clean
    signals' one column is filtered per recording. The yaw row (2.17) is nonlinear in its inputs, so the sum is taken before it, never
    after. The two sums differ by rounding only: records within 1e-10 of their rms and thresholds
    within 1e-10 relative of filtering ``s + e`` (tests/test_detect_nullsim.py; 8.7e-13 on 40
    strong-roll recordings)."""
    cols = {k: s[:, None] for k, s in clean.items()}
    return prior.inputs(cols if derive is None else derive(cols, r_true))


def normals(
    seed: int,
    runs: int,
    n: int,
    signals: int,
    blocks: int,
    draws: dict | None = None,
    scale: tuple[float, ...] | None = None,
) -> list[np.ndarray]:
    """The standard normal draws of :func:`null_records`, in the order it uses them: (runs, n) for the
    yaw rate and each of ``signals`` inputs, then (``blocks``, runs) for :func:`misfit_offsets` (none
    when 0), from the generator seeded ``[seed, 1]``; with ``scale`` (one sd per (runs, n) draw) those
    are multiplied by their sd (in place: the same bits as ``z * sd``), the measurement noise itself.
    Kept in ``draws`` (when given) for the next call with the same arguments: the same numbers, drawn
    and scaled once (a quarter of a 500 s recording's CPU in ``detect``; 16 MB each for 400 records of
    5,000 samples, the last arguments' only)."""
    key = (seed, runs, n, signals, blocks, None if scale is None else tuple(map(float, scale)))
    if draws is not None:
        if draws.get("key") == key:
            return draws["normals"]
        draws.clear()  # before drawing: another length's 7 x 16 MB are not held beside this one's
    rng = np.random.default_rng([seed, 1])
    z = [rng.standard_normal((runs, n)) for _ in range(1 + signals)]
    if scale is not None:
        for a, sd in zip(z, scale, strict=True):
            np.multiply(a, sd, out=a)
    if blocks:
        z.append(rng.standard_normal((blocks, runs)))
    if draws is not None:
        for a in z:  # shared with the next recordings: an in-place change would alter their records
            a.flags.writeable = False
        draws.update(key=key, normals=z)
    return z


def noise_taus(prior: YawPrior, names: tuple[str, ...]) -> tuple[float, ...]:
    """The low-pass time constants (s) of the signals ``names``' noise (``prior.noise_tau``; 0: white)."""
    return tuple(float(prior.noise_tau.get(k, 0.0)) for k in names)


def sensor_filtered(z: list[np.ndarray], taus: tuple[float, ...], dt: float) -> list[np.ndarray]:
    """The scaled white draws of :func:`normals` (each (runs, n)) through their sensors' first-order
    low-passes ``taus`` (one per draw, in order; :func:`identify.detect.noiseread.stationary_lowpass`,
    stationary from the first sample): the noise a low-passing sensor records. A draw with no
    time constant (or 0), and the block innovations after them, are returned as they are (the same
    object: white noise, main's records to the bit)."""
    return [stationary_lowpass(zk, taus[i], dt, axis=1) if i < len(taus) and taus[i] > 0 else zk for i, zk in enumerate(z)]


def _measured(x: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """``x`` ((n, runs), or (n, 1) broadcast over ``runs``) plus the white noise ``noise`` (runs, n)
    (scaled normals, :func:`normals`), (n, runs) with time along the contiguous axis: the no-change
    records' filters then run along contiguous memory. The sum is written over ``noise`` unless it is
    kept for other recordings (read-only): a recording alone needs no second copy."""
    if noise.flags.writeable:
        out = noise.T
        out += x
        return out
    out = np.empty(noise.shape).T
    return np.add(noise.T, x, out=out)


def misfit_offsets(
    prior: YawPrior, n: int, runs: int, rng: np.random.Generator | None, z: np.ndarray | None = None
) -> np.ndarray:
    """(n, runs) residual the white noise at ``prior.noise`` does not explain (``prior.model_error``):
    1 s block offsets coloured by the prior's AR filter (its innovation sd ``model_error``), so a
    simulated record's whitened block residual has the nominal fit's level; zeros without it. The
    innovations are ``z`` (n // block, runs) standard normals when given, else drawn from ``rng``."""
    out = np.zeros((n, runs))
    if prior.model_error > 0:
        w = _misfit_blocks(prior, n // prior.block, runs, rng, z)
        out[: len(w) * prior.block] = np.repeat(w, prior.block, axis=0)
    return out


def _misfit_blocks(prior: YawPrior, nb: int, runs: int, rng: np.random.Generator | None, z: np.ndarray | None) -> np.ndarray:
    """The (nb, runs) block offsets of :func:`misfit_offsets`: the innovations through the prior's AR filter."""
    return lfilter(
        [1.0], np.r_[1.0, -prior.ar], prior.model_error * (rng.standard_normal((nb, runs)) if z is None else z), axis=0
    )


def add_misfit(out: np.ndarray, prior: YawPrior, z: np.ndarray) -> np.ndarray:
    """``out + misfit_offsets(prior, n, runs, None, z)`` written over ``out`` (n, runs), to the bit, without the
    (n, runs) offsets (two arrays of fresh pages, 16 MB each for 400 records of 5,000 samples): each block's offset
    added to its samples through a (runs, nb, block) view of ``out``'s time-contiguous memory, and 0.0 to the
    samples after the last whole block (as the offsets' zeros: ``-0.0 + 0.0`` is ``+0.0``)."""
    n, runs = out.shape
    nb = n // prior.block if prior.model_error > 0 else 0
    if nb:  # splitting one axis is a view whatever the layout; checked: a copy would lose the sum silently
        view = out.T[:, : nb * prior.block].reshape(runs, nb, prior.block)
        if not np.shares_memory(view, out):
            raise RuntimeError("add_misfit: the (runs, blocks, block) reshape copied the records")
        view += _misfit_blocks(prior, nb, runs, None, z).T[:, :, None]
    out[nb * prior.block :] += 0.0
    return out
