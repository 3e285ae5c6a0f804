"""numpy's median and (linear) quantile of real float arrays, the same numbers, without importing ``numpy.ma``.

``np.median`` checks its result for NaN through ``np.ma.isMaskedArray`` and ``np.quantile`` sorts its indexes with
``np.unique``, which asks ``np.ma.is_masked``: the attribute's first use imports ``numpy.ma``, 15-22 ms of CPU (stop
52, load 4) in a ``shiptrial detect`` process that needs nothing else of it (the recording loader's medians, the
thresholds' quantiles). These follow numpy 2's ``_median`` and ``_quantile`` (method "linear", Hyndman and Fan's 7th)
step by step: the same partition, order statistics and interpolation ``_lerp``, so the same bits
(tests/test_orderstats.py against numpy on odd and even sizes, ties, signed zeros, infinities and NaN). Anything else
(another dtype, an array subclass, a 0-d or empty array, an array of quantiles) is numpy's own call, and so is
every call under a numpy older than the one whose steps these follow (:data:`FOLLOWS_NUMPY`): ``_lerp``'s ``out=...``
is numpy >= 2.3's, and the bits were checked against numpy 2.4.
"""

from __future__ import annotations

import numpy as np

# the numpy whose _median / _quantile steps these repeat (checked to the bit on 2.4.6); older ones get their own call
FOLLOWS_NUMPY = np.lib.NumpyVersion(np.__version__) >= "2.4.0"


def _plain(a: np.ndarray) -> bool:
    return FOLLOWS_NUMPY and type(a) is np.ndarray and a.ndim > 0 and a.size > 0 and a.dtype.kind == "f"


def median(x: np.ndarray) -> np.floating:
    """``np.median(x)`` over the whole array: the middle order statistic, or the ``np.mean`` of the two middle
    ones, of a partition with numpy's ``kth`` (the last position too: a NaN sorts there and is the result)."""
    a = np.asanyarray(x)
    if not _plain(a):
        return np.median(a)
    sz = a.size
    kth = [sz // 2 - 1, sz // 2] if sz % 2 == 0 else [(sz - 1) // 2]
    part = np.partition(a, [*kth, -1], axis=None)
    if np.isnan(part[-1]):
        return part[-1]
    return np.mean(part[kth[0] : kth[-1] + 1], axis=0)


def quantile(a: np.ndarray, q: float, axis: int | None = None) -> np.ndarray | np.floating:
    """``np.quantile(a, q, axis=axis)`` (method "linear") for one float level ``q`` in [0, 1]: the virtual index
    ``(n - 1) q``, its neighbours (both the last element from ``n - 1`` on), the partition at them, and numpy's
    ``_lerp`` of the two order statistics with ``gamma`` the index's fractional part; NaN where a slice holds one."""
    arr = np.asanyarray(a)
    if not _plain(arr) or not isinstance(q, (float, np.floating)) or not 0 <= q <= 1:
        return np.quantile(arr, q, axis=axis)
    weak = type(q) is float  # numpy's weak promotion of a Python number
    qa = np.asanyarray(q)
    arr = arr.flatten() if axis is None else np.moveaxis(arr.copy(), axis, 0)  # numpy's copy: partitioned in place
    n = arr.shape[0]
    virtual = np.asanyarray((n - 1) * qa)
    if virtual >= n - 1:
        prev = nxt = -1
    else:  # 0 <= q: never below 0
        prev = int(np.floor(virtual))
        nxt = prev + 1
    arr.partition(sorted({0, -1, prev, nxt}), axis=0)  # numpy's np.unique of the same indexes
    nans = np.isnan(arr[-1, ...])
    lo, hi = arr[prev], arr[nxt]
    gamma = np.asanyarray(virtual - prev, dtype=virtual.dtype)
    gamma = float(gamma) if weak else gamma.reshape(gamma.shape + (1,) * (arr.ndim - 1))
    result = _lerp(lo, hi, gamma)
    if np.any(nans):
        if np.ndim(result) == 0:
            return arr[-1]
        np.copyto(result, arr[-1, ...], where=nans)
    return result


def _lerp(a, b, t):
    """numpy's ``_lerp``: ``a + (b - a) t``, and ``b - (b - a)(1 - t)`` where ``t >= 0.5``."""
    diff = b - a
    out = np.add(a, diff * t, out=...)
    np.subtract(b, diff * (1 - t), out=out, where=t >= 0.5, casting="unsafe", dtype=type(out.dtype))
    return out[()] if out.ndim == 0 else out
