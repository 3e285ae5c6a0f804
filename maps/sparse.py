"""scipy's sparse-graph routines the planner uses (the relaxed heuristic's Dijkstra, the reachable
moves' breadth-first search), imported without the numpy submodules scipy never calls.

scipy (1.17 here) builds its array-API namespace for numpy by copying every public name of
``numpy``, which imports numpy's lazily loaded submodules: ``numpy.f2py`` (with
``charset_normalizer``), ``numpy.testing``, ``numpy.ma``, ``numpy.polynomial`` and the rest. The
planner uses none of them, yet paid for them at the start of every ``plan-trial`` (about 0.15 s
of CPU measured under load, before the drawer is forked: see :mod:`cli.drawer`). While scipy is
imported here, each such submodule not loaded yet stands as a :class:`_Deferred` placeholder
that imports the real module on its first attribute read, so nothing changes for a caller that
does use one; once scipy is imported the placeholders leave ``sys.modules`` and ``numpy``'s
namespace, and a later ``import numpy.f2py`` loads the real module as usual.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

# numpy's lazily loaded submodules that scipy's namespace copy touches (numpy 2.x: ``numpy.__getattr__``)
DEFERRED = ("f2py", "testing", "ma", "polynomial", "rec", "ctypeslib", "char", "strings")


class _Deferred(types.ModuleType):
    """Stands for ``numpy.<name>`` while scipy is imported: the first attribute read imports the
    real module (and puts it in the placeholder's stead) and returns the attribute from it."""

    def __getattr__(self, attr: str) -> object:  # any attribute, ``__path__`` (a submodule imported) included
        return getattr(_real(self.__name__), attr)


def _real(name: str) -> types.ModuleType:
    """The real module ``name``, imported now if a placeholder stood for it."""
    if isinstance(sys.modules.get(name), _Deferred):
        del sys.modules[name]
        sub = name.rpartition(".")[2]
        if isinstance(vars(np).get(sub), _Deferred):
            delattr(np, sub)
    return importlib.import_module(name)


@contextmanager
def numpy_submodules_deferred() -> Iterator[None]:
    """Placeholders for numpy's unloaded :data:`DEFERRED` submodules for the duration (in
    ``sys.modules`` and as ``numpy``'s attributes, so that ``from numpy import *`` finds them),
    removed after (a placeholder already replaced by its real module is left alone)."""
    placed: list[tuple[str, _Deferred]] = []
    for sub in DEFERRED:
        name = f"numpy.{sub}"
        if name in sys.modules or sub in vars(np):
            continue
        mod = _Deferred(name)
        sys.modules[name] = mod
        setattr(np, sub, mod)
        placed.append((sub, mod))
    try:
        yield
    finally:
        for sub, mod in placed:
            if sys.modules.get(f"numpy.{sub}") is mod:
                del sys.modules[f"numpy.{sub}"]
            if vars(np).get(sub) is mod:
                delattr(np, sub)


with numpy_submodules_deferred():
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import breadth_first_order, dijkstra

__all__ = ["breadth_first_order", "csr_matrix", "dijkstra", "numpy_submodules_deferred"]
