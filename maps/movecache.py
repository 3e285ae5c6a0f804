"""The ship's lattice moves kept on disk between commands, as compiled code is: the basic moves and
each informative primitive's moves (run-in, manoeuvre, settling leg, swept footprints) depend on the
ship, the lattice options and the code, not on the map, start or goal, so a second plan of the same
ship on another map, or from another start, reads them instead of running the helm again.

The key is a SHA-256 digest of :func:`maps.plancache.code_version` (every source and data file of the
project, Python's and the numerical libraries' versions, ``SHIPTRIAL_KERNEL``), the machine (:func:`machine`:
numpy's vectorised routines dispatch on the CPU's features and may round differently on another CPU, so a
cache directory shared between machines keeps one entry per kind of CPU), whether this process has the
compiled loop loaded (:func:`primitives.jitloop.loaded`: a small simulation runs the numpy loop until it is,
and the two may differ in the last bit for pods and rigid-body profiles), the profile's fields, the
options the moves are built with and, for an informative move, the primitive's fields. The entries
live beside the plan cache's (:func:`maps.plancache.default_dir`, ``*.moves``, at most
:data:`maps.plancache.MOVES_BYTES` bytes of them, least recently used removed first) in its checked format,
the key inside the payload: a missing, truncated, unreadable or misnamed entry is built again, never an error.
``SHIPTRIAL_CACHE_DIR=""`` keeps no cache (the tests' setting). ``plan-trial --no-cache`` still reads and
writes them: it plans afresh (design, search, verification), and the moves read are the bits it would build.

The moves' primitives hold the caller's profile: the profile is pickled by reference (a persistent
id) and the loaded moves point at the profile object of the command that reads them. A value may leave
other objects out the same way (``refs``: the kept first design leaves out the library it was made
from, kept under its own key, :mod:`maps.librarycache`): each is written as its place in ``refs`` and
read back as the object at that place in the reader's ``refs``.
"""

from __future__ import annotations

import hashlib
import io
import pickle
import platform
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any

from maps import plancache
from primitives import jitloop
from primitives.ship import ShipProfile

PROFILE = "profile"  # the persistent id of the caller's profile inside an entry


class _Pickler(pickle.Pickler):
    def __init__(self, fh: io.BytesIO, profile: ShipProfile, refs: Sequence[Any] = ()):
        super().__init__(fh, protocol=pickle.HIGHEST_PROTOCOL)
        self.profile = profile
        # by identity, not equality: an equal copy elsewhere in the value is written out
        self.places = {id(obj): i for i, obj in enumerate(refs)}
        self.refs = refs  # alive while pickling: the ids stay theirs

    def persistent_id(self, obj: Any) -> str | int | None:
        if obj is self.profile:
            return PROFILE
        return self.places.get(id(obj)) if self.places else None  # the moves: no refs, no look-up


class _Unpickler(pickle.Unpickler):
    def __init__(self, fh: io.BytesIO, profile: ShipProfile, refs: Sequence[Any] = ()):
        super().__init__(fh)
        self.profile, self.refs = profile, refs

    def persistent_load(self, pid: Any) -> Any:
        if pid == PROFILE:
            return self.profile
        if type(pid) is int and 0 <= pid < len(self.refs):
            return self.refs[pid]
        raise pickle.UnpicklingError(f"unknown persistent id {pid!r}")


def dumps(value: Any, profile: ShipProfile, refs: Sequence[Any] = ()) -> bytes:
    """``value`` pickled with ``profile`` (wherever it is referenced) left out as a reference, and each
    object of ``refs`` as its place there."""
    buf = io.BytesIO()
    _Pickler(buf, profile, refs).dump(value)
    return buf.getvalue()


def loads(data: bytes, profile: ShipProfile, refs: Sequence[Any] = ()) -> Any:
    """:func:`dumps`' value, its profile references pointing at ``profile`` and its others at the objects
    at their places in ``refs`` (a place ``refs`` lacks: :class:`pickle.UnpicklingError`)."""
    return _Unpickler(io.BytesIO(data), profile, refs).load()


_PROFILE_DIGESTS: dict[int, tuple[ShipProfile, bytes]] = {}


def _profile_digest(profile: ShipProfile) -> bytes:
    hit = _PROFILE_DIGESTS.get(id(profile))
    if hit is None or hit[0] is not profile:
        if len(_PROFILE_DIGESTS) > 16:
            _PROFILE_DIGESTS.clear()
        # its fields: the pickle of the object also holds what its cached properties computed so far
        digest = hashlib.sha256(pickle.dumps(plancache.fields_of(profile), protocol=pickle.HIGHEST_PROTOCOL)).digest()
        hit = _PROFILE_DIGESTS[id(profile)] = (profile, digest)
    return hit[1]


@lru_cache(maxsize=1)
def machine() -> str:
    """The CPU architecture and the features numpy dispatches its vectorised routines on (empty when
    this numpy does not say)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # another numpy layout: the architecture alone
        features = {}
    return platform.machine() + ":" + ",".join(sorted(k for k, on in features.items() if on))


def key(profile: ShipProfile, what: str, options: tuple, primitive: Any = None) -> str | None:
    """The entry's key: the code, the machine, whether the compiled loop is loaded, the profile, ``what``
    ("basic" or "informative"), the ``options`` the moves are built with (a tuple of plain values) and the
    ``primitive`` (its content; the profile by reference). None when the cache is off."""
    if plancache.default_dir() is None:
        return None
    kernel = "compiled" if jitloop.loaded() else "numpy-until-loaded"
    # No BLAS thread count in the key: an entry's bits do not depend on it. The first design's SLSQP runs on one
    # BLAS thread (primitives.threads.one_blas_thread), the library's information moments are np.einsum without
    # optimize (numpy's own loops, no BLAS), the rudder autopilot's Riccati solve has 3 states (too small for
    # OpenBLAS to split); every .moves entry of plan-trial (default ship; --ship kvlcc2 --map open-sea) was
    # byte-identical built under OPENBLAS_NUM_THREADS=1 and 2 (stop 60); tests/test_design_threads.py guards the
    # design and the autopilot gain (not the moments, nor a whole entry).
    h = hashlib.sha256(f"moves\0{plancache.code_version()}\0{machine()}\0{kernel}\0{what}\0{options!r}\0".encode())
    h.update(_profile_digest(profile))
    if primitive is not None:  # the profile is in the key already
        content = [kv for kv in plancache.fields_of(primitive) if kv[0] != "profile"]
        h.update(hashlib.sha256(dumps(content, profile)).digest())
    return h.hexdigest()


def load(k: str | None, profile: ShipProfile, refs: Sequence[Any] = ()) -> Any:
    """The value stored under key ``k`` (None when there is none, it cannot be read or the cache is off;
    ``refs``: as :func:`loads`')."""
    directory = plancache.default_dir()
    if k is None or directory is None:
        return None
    entry = plancache.load_blob(Path(directory), f"{k}.moves")
    # the key inside the entry: a file copied or renamed onto another key's name is no entry
    if not (isinstance(entry, tuple) and len(entry) == 2 and entry[0] == k and isinstance(entry[1], bytes)):
        return None
    data = entry[1]
    try:
        return loads(data, profile, refs)
    except Exception:  # noqa: BLE001 - an entry this code cannot read is no entry: the moves are built
        return None


def store(k: str | None, value: Any, profile: ShipProfile, refs: Sequence[Any] = ()) -> None:
    """Keep ``value`` under key ``k`` (skipped without a word when the cache is off or cannot be written;
    ``refs``: as :func:`dumps`')."""
    directory = plancache.default_dir()
    if k is None or directory is None:
        return
    try:
        data = dumps(value, profile, refs)
    except Exception:  # noqa: BLE001 - moves holding something pickle cannot write are simply not kept
        return
    plancache.store_blob(Path(directory), f"{k}.moves", (k, data))
