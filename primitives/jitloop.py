"""The compiled simulation kernel's switch and loader: whether a call runs the numba-compiled time
loop (:mod:`primitives.jittime`) or the pure-numpy loop of :func:`primitives.simulate._time_loop`,
the decorators that compile a loop (:class:`compiled`, cached on disk) and the helpers inlined
into it (:func:`inlined`), and the two term-program helpers expdesign's passes inline
(:func:`_times_factor`, :func:`_increments`). The term program itself is made by
:mod:`primitives.jitprogram`; ``time_loop`` and ``open_loop`` are :mod:`primitives.jittime`'s,
reached through this module.

Every compiled operation is the numpy path's, in the same order, on the same IEEE doubles (no
fast-math, so no fused multiply-add): the same bits, except where numpy's own vectorised routines
may round differently from the C library the compiled code calls, namely ``hypot`` (the speed U,
the wind terms, pods), ``arctan2`` (pods), powers outside :data:`primitives.powers.PRODUCT_POWERS`
(numpy's vectorised power against the C library's pow, which differ on some CPUs; the powers of
the project's structures, v_r^3, U^-2, are products on both paths, :func:`primitives.powers.int_power`) and the 4x4
product by M^-1 of rigid-body profiles (BLAS's order of summation). Those differ in the last bit
of a step and stay within the tolerance tests/test_jitloop.py checks.

The pure-numpy loop is kept: it is used when numba cannot be imported or when the environment
sets ``SHIPTRIAL_KERNEL=numpy``, and for small calls in a process that has not loaded the
compiled code, or for every call of a job its caller declared too small to pay for loading it
(:func:`use`, :func:`job`). Compiled code is cached on disk (``cache=True``) so that a warm
process loads it instead of compiling it again.
"""

from __future__ import annotations

import contextlib
import contextvars
import importlib.util
import math
import os
import threading
import warnings
from collections.abc import Iterator

from primitives import powers
from primitives.jitprogram import (  # noqa: F401  (the term program's names, read through this module)
    _IDX,
    _STATE,
    CALM_STATE,
    N_STATE,
    POD_TAUS,
    _factors,
    _program,
    pod_arrays,
    program,
    rigid_arrays,
    writable,
)

# The compiler is optional: without it (or with SHIPTRIAL_KERNEL=numpy) the numpy loops run. It is
# imported, and the cached machine code loaded, on the first call that is worth it (:func:`use`):
# that costs about a second of CPU per process, more than a command that only steps single ships
# (plan-trial, the library build) would save.
AVAILABLE = os.environ.get("SHIPTRIAL_KERNEL", "").strip().lower() != "numpy" and importlib.util.find_spec("numba") is not None
# Work (batch members x steps) of one call from which the compiled loop is loaded: a 20-member
# batch of 1000 steps costs about 20 ms in the numpy loop, 1 ms compiled.
MIN_WORK = 20_000
# Work of a whole job (the sum of its calls' batch members x steps, :func:`job`) from which loading
# pays: ``shiptrial detect`` (CPU, load 8, stop 42) on one 500 s recording (2.0M member-steps of
# no-change records) 4.4 s numpy against 5.8-6.7 s compiled; two 6.0-6.1 against 5.5-6.2; three
# 6.8-8.0 against 7.1-7.4. The break-even lies between two and three such recordings.
JOB_MIN_WORK = 5_000_000
_JOB: contextvars.ContextVar[int | None] = contextvars.ContextVar("jitloop_job", default=None)
_LOADED = False
_LOCK = threading.RLock()  # two threads of a Dask worker must not load (and jit-decorate) twice


def kernel_name() -> str:
    """Which time loop a large simulation runs: 'numba' or 'numpy'."""
    return "numba" if AVAILABLE else "numpy"


def loaded() -> bool:
    """Whether the compiled code is loaded in this process and usable (a call of :func:`use`
    loaded it): callers whose own work never pays for the load run compiled only then."""
    return AVAILABLE and _LOADED


@contextlib.contextmanager
def job(work: int) -> Iterator[None]:
    """Within the block, the caller's whole job is ``work`` batch members x steps (the sum over the
    calls it will make): :func:`use` loads the compiled code only if that reaches
    :data:`JOB_MIN_WORK`, whatever the size of one call. A job of many similar calls (detect on
    40 recordings) loads it at its first call; a smaller one (detect on one or two 500 s recordings) runs
    the numpy loop throughout and does not pay numba's load (about 1.3 s CPU). Code loaded already
    is used either way. The hint is per thread and per asyncio task (a context variable); a job
    inside a job replaces the outer hint for its block."""
    token = _JOB.set(int(work))
    try:
        yield
    finally:
        _JOB.reset(token)


def use(work: int) -> bool:
    """Whether a call of ``work`` batch members x steps runs compiled: when numba is available and
    either the compiled code is loaded already or loading it pays: inside a :func:`job`, when the
    job's work reaches :data:`JOB_MIN_WORK`; outside one, when the call alone reaches
    :data:`MIN_WORK`. Both loops give the same numbers to the tolerance tests/test_jitloop.py
    states, so which one a small call takes may depend on what the process ran before (last-bit
    differences only). A numba that is installed but cannot be loaded (built for another numpy,
    no writable cache) is said once in a warning and the numpy loop runs."""
    global AVAILABLE
    if not AVAILABLE:
        return False
    hint = _JOB.get()
    if not _LOADED and (work < MIN_WORK if hint is None else hint < JOB_MIN_WORK):
        return False
    with _LOCK:
        if not _LOADED:
            try:
                _load()
            except Exception as e:  # an unusable compiler is no reason to stop: the numpy loop gives the same numbers
                AVAILABLE = False
                warnings.warn(
                    f"compiled simulation kernel unavailable ({type(e).__name__}: {e}); using the numpy loop "
                    "(set SHIPTRIAL_KERNEL=numpy to skip the attempt)",
                    RuntimeWarning,
                    stacklevel=2,
                )
                return False
    return True


_INLINED: list[tuple[dict, str]] = []  # (the helper's module globals, its name)
_COMPILED: list = []  # every compiled function, given its dispatcher by _load
# The compiled code's form of primitives.powers.int_power (compiled loops call jitloop.int_power;
# the numpy path calls the powers module's own, which stays a Python function).
int_power = powers.int_power
_INLINED.append((globals(), "int_power"))


class compiled:
    """``fn`` compiled by numba (cached on disk: a warm process loads the machine code instead of
    compiling it), with the helpers marked :func:`inlined` compiled into it. Its dispatcher is made
    when :func:`use` first loads numba, so a compiler that cannot work is found there, before a
    caller has chosen the compiled path. Called only when :func:`use` says so. With ``signature``
    (:func:`typed`) that one signature is compiled (or loaded from the disk cache) at the first call
    and no other: arguments are converted to it where numba converts safely (C or F layout to 'A',
    writable to read-only), and a call it cannot convert (float32 for float64) raises TypeError."""

    def __init__(self, fn, signature: str | None = None):
        self.fn, self.jit, self.signature = fn, None, signature
        self.pending = signature is not None  # a signature to compile at the first call
        self.__doc__, self.__name__ = fn.__doc__, fn.__name__
        _COMPILED.append(self)

    def __call__(self, *args):
        if self.jit is None or self.pending:
            with _LOCK:
                _load()
                if self.jit is None:  # a function defined after numba was loaded
                    from numba import njit

                    self._dispatch(njit)
                if self.pending:  # compiled (or loaded from the disk cache) at its first call, not at numba's load
                    self.jit.compile(self.signature)
                    self.jit.disable_compile()
                    self.pending = False
        return self.jit(*args)

    def _dispatch(self, njit) -> None:
        # error_model="numpy": a division by zero gives inf or NaN as numpy's does, without a check that stops vectorising
        try:
            self.jit = njit(cache=True, nogil=True, error_model="numpy")(self.fn)
        except RuntimeError:  # no writable cache directory (read-only install, no home): compile in memory
            self.jit = njit(nogil=True, error_model="numpy")(self.fn)
            return
        _stamp_shared_helpers(self.jit)


def typed(signature: str):
    """:class:`compiled` with one signature (numba's type expression, e.g. ``"void(Array(float64, 2, 'A',
    readonly=True))"``): every call converts its arguments to it instead of compiling a variant per
    memory layout, so a loop can read strided views (transposed, reversed, broadcast) without copies."""
    return lambda fn: compiled(fn, signature)


# The files whose inlined helpers are compiled into other files' functions (expdesign.oekernel
# inlines _increments and _times_factor, expdesign.ivsolve regkernel._factor);
# primitives.jittime inlines jitfactors' helpers and reads jitprogram's N_STATE, a constant frozen
# into the machine code.
SHARED_HELPER_FILES = tuple(
    os.path.join(os.path.dirname(__file__), f)
    for f in ("jitloop.py", "regkernel.py", "jitfactors.py", "jitprogram.py", "powers.py")
)


def _stamp_shared_helpers(jit) -> None:
    """Make ``jit``'s disk cache stale when a file of :data:`SHARED_HELPER_FILES` changes, not only
    its own file. numba keeps a cached function while its own source file's modification time and
    size are those recorded in the cache index (numba.core.caching.IndexDataCacheFile): a changed
    helper inlined from another file would otherwise leave the old machine code in use. The
    helpers' files' (mtime, size) are added to the stamp the index is checked against (a private
    numba attribute: where it is missing, only the function's own file is checked, as before)."""
    cache_file = getattr(getattr(jit, "_cache", None), "_cache_file", None)
    if cache_file is None or not hasattr(cache_file, "_source_stamp"):
        return
    try:
        shared = tuple((st.st_mtime, st.st_size) for st in map(os.stat, SHARED_HELPER_FILES))
    except OSError:
        return
    cache_file._source_stamp = (cache_file._source_stamp, shared)


def _load() -> None:
    """Import numba, replace the :func:`inlined` helpers by their compiled form and make every
    :class:`compiled` function's dispatcher, once (the caller holds ``_LOCK``)."""
    global _LOADED
    if _LOADED:
        return
    from numba import njit

    for g, name in _INLINED:
        if not hasattr(g[name], "py_func"):
            # inlined into the loop at compile time: a call per step would pass every array argument
            # through the reference counter, more than the arithmetic's cost for a small batch
            g[name] = njit(inline="always", error_model="numpy")(g[name])
    for c in _COMPILED:
        if c.jit is None:
            c._dispatch(njit)
    _LOADED = True


def inlined(fn):
    """Mark the module-level helper ``fn`` to be compiled into the :class:`compiled` functions that
    call it. numba's disk cache sees a change to the caller's own file only: a helper called from
    another file must be in a file of :data:`SHARED_HELPER_FILES`. Compiled at once when numba is
    loaded already."""
    if _LOADED:
        from numba import njit

        return njit(inline="always", error_model="numpy")(fn)
    _INLINED.append((fn.__globals__, fn.__name__))
    return fn


@inlined
def _times_factor(acc, sig, idx, station, modulus, power, batch):
    """acc[b] *= |sig[idx, b] + station * r|^power over the batch: one factor of a term (the
    numpy expression of primitives.terms.Factor.code, the power by primitives.powers.int_power)."""
    has_station = not math.isnan(station)
    if not has_station and power == 1:  # the common factors, as loops without branches (they vectorise)
        if modulus:
            for b in range(batch):
                acc[b] = acc[b] * abs(sig[idx, b])
        else:
            for b in range(batch):
                acc[b] = acc[b] * sig[idx, b]
        return
    for b in range(batch):
        x = sig[idx, b]
        if has_station:
            x = x + station * sig[2, b]
        if modulus:
            x = abs(x)
        acc[b] = acc[b] * int_power(x, power)


@inlined
def _increments(inc, tmp, sig, coef, batch, dof_first, dof_n, t_first, t_n, f_sig, f_mod, f_sta, f_pow):
    """inc[i, b] = Phi_i^T theta per DOF i: each term c_j * f_1 * f_2 ... and their sum, left to
    right, as the generated increment function (primitives.terms.TermSet.increment_function);
    the term program's branches once per step, the arithmetic in loops over the batch."""
    per_member = coef.shape[1] > 1
    for i in range(dof_first.shape[0]):
        if dof_n[i] == 0:
            for b in range(batch):
                inc[i, b] = 0.0
            continue
        for t in range(dof_first[i], dof_first[i] + dof_n[i]):
            for b in range(batch):
                tmp[b] = coef[t, b] if per_member else coef[t, 0]
            for f in range(t_first[t], t_first[t] + t_n[t]):
                _times_factor(tmp, sig, f_sig[f], f_sta[f], f_mod[f], f_pow[f], batch)
            if t == dof_first[i]:
                for b in range(batch):
                    inc[i, b] = tmp[b]
            else:
                for b in range(batch):
                    inc[i, b] = inc[i, b] + tmp[b]


def __getattr__(name: str):
    """``time_loop`` and ``open_loop``, :mod:`primitives.jittime`'s (imported on first use: that
    module imports this one for its decorators)."""
    if name in ("time_loop", "open_loop"):
        from primitives import jittime

        return getattr(jittime, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
