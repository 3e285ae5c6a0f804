"""The ship's informative library and its information kept on disk between commands, as the lattice
moves are (:mod:`maps.movecache`, whose key and entries it uses): simulating the library's primitives
and their sensitivities is half of the first design (:func:`maps.trialdesign.first_design`), which
``plan-trial``'s parent waits for while its drawer computes it, and depends only on the profile, the
code and the machine, not on the map or the design options."""

from __future__ import annotations

from maps import movecache
from maps.trialdesign import ship_library
from primitives.information import PrimitiveInfo, library_information
from primitives.library import Primitive
from primitives.ship import ShipProfile


def kept_library(profile: ShipProfile) -> tuple[list[Primitive], list[PrimitiveInfo]]:
    """The informative primitives of :func:`maps.trialdesign.ship_library` and their
    :func:`primitives.information.library_information`: read from the move cache when it holds them
    (keyed by the code, the machine, the kernel's state and the profile: the same bits), else
    computed and kept there."""
    k = movecache.key(profile, "library", ())
    kept = movecache.load(k, profile)
    if isinstance(kept, tuple) and len(kept) == 2 and all(isinstance(v, list) for v in kept):
        return kept
    lib = [p for p in ship_library(profile) if p.kind == "informative"]
    infos = library_information(profile, lib)
    movecache.store(k, (lib, infos), profile)
    return lib, infos
