"""Zero-phase IIR filtering (forward-backward, :func:`scipy.signal.filtfilt` with its default odd
padding) of many rows at once, compiled with numba (:mod:`primitives.jitloop`).

A change detector low-passes the inputs of its 400 no-change records of each recording (eight
filters of 400 x 5,000 samples, :mod:`identify.detect.nullsim`); scipy's ``filtfilt`` spends
nearly as long copying (the padded signal, the reversed passes, the initial states) as its two
``lfilter`` passes take, and each pass is one long chain of dependent operations per row. Here a
group of rows is filtered side by side (independent chains, which the processor overlaps) without
the copies. Every operation is scipy's, in its order, on the same IEEE doubles (no fast-math, so
no fused multiply-add): the odd extension ``2 x_0 - x_i``, the initial state ``zi * x_0`` from
:func:`scipy.signal.lfilter_zi`, and the transposed direct form II step of scipy's
``_linear_filter`` (y = z_0 + b_0 x; z_i = z_(i+1) + x b_(i+1) - y a_(i+1); the last
z = x b_n - y a_n) -- the same bits (tests/test_zerophase.py).

Without the compiled loop (numba not installed or not loaded, a small call, a 3-D array) the
filter is :func:`primitives.iir.filtfilt`, not scipy's: ``import scipy.signal`` costs about 2 s of
CPU, half of a ``shiptrial detect`` on one recording. That path equals scipy's to rounding (1e-12
of the output's largest value for the detector's low-passes, tests/test_iir.py; scipy's bits for a
high order or a low cutoff, which it filters sample by sample); the design
(:func:`lowpass`) and the initial state are scipy's bits either way (:mod:`primitives.iir`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from primitives import iir, jitloop

#: rows filtered side by side in the compiled loop: enough independent chains to hide the latency
#: of one step's dependent multiply-adds, few enough that their padded rows stay in cache
GROUP = 8


def filtfilt(b: np.ndarray, a: np.ndarray, x: np.ndarray, axis: int = -1) -> np.ndarray:
    """``scipy.signal.filtfilt(b, a, x, axis=axis)`` (odd padding of 3 max(len(a), len(b))
    samples), to the bit and in scipy's memory layout (the reversed view of a padded buffer, so a
    reduction over the result sums in the same order); compiled for a large float64 array of one or
    two dimensions when :func:`primitives.jitloop.use` says so, :func:`primitives.iir.filtfilt`
    otherwise (scipy's to rounding; also for a denominator not starting with 1, b and a of
    different lengths, too short a signal, with its checks and messages)."""
    b, a, x = np.asarray(b), np.asarray(a), np.asarray(x)
    edge = 3 * max(len(a), len(b))
    ok = (
        x.dtype == np.float64
        and x.ndim in (1, 2)
        and b.dtype == np.float64
        and a.dtype == np.float64
        and len(a) == len(b) >= 2
        and a[0] == 1.0
        and x.shape[axis] > edge
    )
    if not (ok and jitloop.use(x.size)):
        return iir.filtfilt(b, a, x, axis=axis)
    ax = axis % x.ndim
    shape = list(x.shape)
    shape[ax] += 2 * edge
    buf = np.empty(shape)  # scipy's second lfilter output: the result reversed along ``ax``, padded
    rows, out = (x[None], buf[None]) if x.ndim == 1 else (np.moveaxis(x, ax, -1), np.moveaxis(buf, ax, -1))
    _rows(np.ascontiguousarray(b), np.ascontiguousarray(a), _initial_state(b.tobytes(), a.tobytes()), rows, edge, out)
    return np.flip(buf, axis=ax)[(slice(None),) * ax + (slice(edge, -edge),)]


def lowpass(order: int, cutoff_hz: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.butter(order, cutoff_hz, fs=fs)`` (b, a; :func:`primitives.iir.butter`, the same bits), designed once per arguments and kept
    read-only: a change detector designs the same few low-passes for every recording and every
    prediction (about 11 a recording, a tenth of its CPU in scipy's design code)."""
    return _designed(int(order), float(cutoff_hz), float(fs))


@lru_cache(maxsize=32)
def _designed(order: int, cutoff_hz: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    b, a = iir.butter(order, cutoff_hz, fs=fs)
    b.flags.writeable = False
    a.flags.writeable = False
    return b, a


@lru_cache(maxsize=32)
def _initial_state(b: bytes, a: bytes) -> np.ndarray:
    """``lfilter_zi(b, a)`` of float64 coefficients given as bytes (C-contiguous, read-only): the same
    bits as computing it per call, which costs as much as filtering a 5,000-sample row."""
    zi = np.ascontiguousarray(iir.lfilter_zi(np.frombuffer(b), np.frombuffer(a)))
    zi.flags.writeable = False
    return zi


@jitloop.compiled
def _rows(b, a, zi, x, edge, out):  # pragma: no cover - compiled
    m, n = x.shape
    order = b.shape[0] - 1
    length = n + 2 * edge
    ext = np.empty((length, GROUP))  # the group's rows side by side: each step's operations vectorise across them
    y = np.empty((length, GROUP))
    z = np.empty((order, GROUP))
    yn = np.empty(GROUP)
    for m0 in range(0, m, GROUP):
        g = min(GROUP, m - m0)
        for j in range(g):  # scipy's odd_ext
            x0 = x[m0 + j, 0]
            xl = x[m0 + j, n - 1]
            for i in range(edge):
                ext[i, j] = 2 * x0 - x[m0 + j, edge - i]
            for i in range(n):
                ext[edge + i, j] = x[m0 + j, i]
            for i in range(edge):
                ext[edge + n + i, j] = 2 * xl - x[m0 + j, n - 2 - i]
        for j in range(g, GROUP):  # a short last group: the unused lanes filtered as zeros, never read
            for i in range(length):
                ext[i, j] = 0.0
        for q in range(order):
            for j in range(GROUP):
                z[q, j] = zi[q] * ext[0, j]
        _pass(b, a, z, yn, ext, y, 0, length, 1)  # forward
        for q in range(order):
            for j in range(GROUP):
                z[q, j] = zi[q] * y[length - 1, j]
        _pass(b, a, z, yn, y, ext, length - 1, -1, -1)  # backward: its output at k is the reversed result's
        for j in range(g):  # stored reversed, as scipy's backward pass stores it
            for k in range(length):
                out[m0 + j, length - 1 - k] = ext[k, j]
    return out


@jitloop.inlined
def _pass(b, a, z, yn, src, dst, start, stop, step):  # pragma: no cover - compiled
    """One lfilter pass over ``src``'s rows k = start, start + step, ... (the group's columns side by
    side) into ``dst``: scipy's transposed direct form II step, per column."""
    order = b.shape[0] - 1
    group = src.shape[1]
    for k in range(start, stop, step):
        for j in range(group):
            yn[j] = z[0, j] + b[0] * src[k, j]
        for q in range(order - 1):
            for j in range(group):
                z[q, j] = z[q + 1, j] + src[k, j] * b[q + 1] - yn[j] * a[q + 1]
        for j in range(group):
            z[order - 1, j] = src[k, j] * b[order] - yn[j] * a[order]
            dst[k, j] = yn[j]
