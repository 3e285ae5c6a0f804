"""The ship's informative library and its information kept on disk between commands, as the lattice
moves are (:mod:`maps.movecache`, whose key and entries it uses): simulating the library's primitives
and their sensitivities is half of the first design (:func:`maps.trialdesign.first_design`), which
``plan-trial``'s parent waits for while its drawer computes it, and depends only on the profile, the
code and the machine, not on the map or the design options. The first design itself is kept too
(:func:`kept_first_design`): the other half is the design's solve, whose import of ``scipy.optimize``
alone costs 0.5-0.7 s of CPU in a fresh process; it depends on the design options as well, which its
key adds. So is its design ratios figure (:func:`kept_ratios_png`), which ``plan-trial``'s drawer drew again on
every run while the parent planned (0.16-0.27 s of its CPU, least to median of one process's draws)."""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from typing import Any

from expdesign.robust import DrawInformation
from maps import movecache, plancache
from maps.trialdesign import FirstDesign, TrialDesign, first_design, ship_library
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


def _kept(
    k: str | None, profile: ShipProfile, valid: Callable[[Any], bool], make: Callable[[], Any], refs: Sequence[Any] = ()
) -> Any:
    """The value kept under key ``k`` when there is one and it is ``valid``, else ``make()`` kept there (an
    entry of another shape, a damaged one or one this code cannot read is no entry; ``refs``: objects
    written as references, :func:`maps.movecache.dumps`)."""
    kept = movecache.load(k, profile, refs)
    if valid(kept):
        return kept
    value = make()
    movecache.store(k, value, profile, refs)
    return value


def kept_first_design(profile: ShipProfile, parameter_prior: Any = None, **options: Any) -> FirstDesign:
    """:func:`maps.trialdesign.first_design` of the ship's own library with the design ``options``
    (criterion, mean_subtraction, trial_length_s, seed: plain values) and ``parameter_prior`` (None, or a
    robust criterion's prior, keyed by the digest of its pickle): read from the move cache when it holds
    it (the key as :func:`kept_library`'s, the options and the prior added: the same bits), else made
    (from :func:`kept_library`) and kept there. A design that raises (a trial too short for any manoeuvre)
    is never kept: the next command meets the same error.

    The entry holds only what :func:`first_design` computes on top of the library (:func:`_design_part`):
    the library and its information, kept under their own key, are written as references and the design
    read is given :func:`kept_library`'s lists, as :func:`first_design` is."""

    def make() -> FirstDesign:
        return first_design(profile, parameter_prior=parameter_prior, **options)

    try:
        prior = None if parameter_prior is None else hashlib.sha256(movecache.dumps(parameter_prior, profile)).hexdigest()
    except Exception:  # noqa: BLE001 - a prior pickle cannot write is not keyed: designed every time
        return make()
    k = movecache.key(profile, "first-design", tuple(sorted(options.items())) + (("prior", prior),))
    if k is None:  # no cache: first_design reads no library either
        return make()
    lib, infos = kept_library(profile)

    def made() -> tuple:  # first_design's own path with the library read here (not computed twice)
        return _design_part(first_design(profile, lib, infos=infos, parameter_prior=parameter_prior, **options))

    part = _kept(k, profile, lambda v: _is_design_part(v, lib, infos), made, [*lib, *infos])
    return FirstDesign(lib, infos, *part[1:])


def _design_part(first: FirstDesign) -> tuple:
    """What :func:`kept_first_design` keeps of ``first``: the library's names (which library its references
    point into) and every field of :class:`FirstDesign` but the library and its information, in order."""
    return (tuple(p.name for p in first.library), first.design, first.baseline, first.draws)


def _is_design_part(kept: Any, lib: list[Primitive], infos: list[PrimitiveInfo]) -> bool:
    """Whether ``kept`` is a :func:`_design_part` of a design made from ``lib`` and ``infos`` (an entry of
    another shape, or one whose library had other primitives, is no entry)."""
    return (
        isinstance(kept, tuple)
        and len(kept) == 4
        and isinstance(kept[0], tuple)  # (an array here would make == elementwise)
        and kept[0] == tuple(p.name for p in lib)
        and len(infos) == len(lib)
        and isinstance(kept[1], TrialDesign)
        and isinstance(kept[2], float)
        and (kept[3] is None or isinstance(kept[3], DrawInformation))
    )


# the settings of the backend, which cannot change the figure's bytes (:func:`primitives.io.figure_png`
# renders through Agg whatever the backend) and change as a process chooses one: reading "backend" makes
# matplotlib pick one (a GUI toolkit's with a display), and matplotlib.use sets "backend_fallback" off
_NOT_DRAWING = frozenset({"backend", "backend_fallback", "interactive"})


def _drawing_state() -> tuple[tuple[str, str], ...]:
    """What else sets the PNG's bytes: the matplotlib version (its fonts ship with it), the FreeType it was
    built with (the glyphs' pixels), Pillow's and Pillow's zlib's versions (the encoding) and the digest of
    every matplotlib setting in force (a user's matplotlibrc) but :data:`_NOT_DRAWING`."""
    import matplotlib
    import PIL
    from matplotlib import ft2font
    from PIL import features

    rc = matplotlib.rcParams
    settings = repr([(name, rc[name]) for name in rc if name not in _NOT_DRAWING])  # iterating reads no value
    return (
        ("matplotlib", matplotlib.__version__),
        ("freetype", ft2font.__freetype_version__),
        ("pillow", PIL.__version__),
        ("zlib", str(features.version_codec("zlib"))),
        ("rc", hashlib.sha256(settings.encode()).hexdigest()),
    )


def kept_ratios_png(profile: ShipProfile, design: Any) -> bytes:
    """:func:`expdesign.report.ratios_png` of ``design`` (the kept first design's: the same figure every warm
    ``plan-trial``): read from the move cache when it holds it, else drawn and kept there. The key is
    :func:`maps.movecache.key`'s (the project's code, the numerical libraries, the machine, the profile) plus
    the design's field-by-field digest (:func:`maps.plancache.fields_digest`: the same for a design made
    afresh and one read back from the cache) and :func:`_drawing_state`. A design that cannot be pickled is
    drawn every time."""
    from expdesign.report import ratios_png

    try:
        content = plancache.fields_digest(design, lambda v: movecache.dumps(v, profile))
    except Exception:  # noqa: BLE001 - not keyed: drawn every time
        return ratios_png(design)
    k = movecache.key(profile, "design-ratios-png", (("design", content), *_drawing_state()))
    return _kept(k, profile, lambda v: isinstance(v, bytes) and v.startswith(b"\x89PNG\r\n\x1a\n"), lambda: ratios_png(design))
