"""What ``plan-trial``'s drawer computes before the plan is made (:meth:`cli.drawer.Drawer.begin`): the first design
of the ship's library and its design ratios figure.

A module of its own, importing neither typer nor the command modules: the drawer receives these functions pickled,
by module and name, and unpickling one of :mod:`cli.plan_cmd` made it import typer, pydantic and the command's
modules (0.021-0.032 s of its CPU once the drawing modules are in, which share most of typer's imports; wasted
when the drawer was forked before the parent imports them, as on a plan-cache miss without ``--no-cache``: stop 59).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # annotations only
    from maps.trialdesign import FirstDesign


def early_design(ship: str, **design: Any) -> FirstDesign:
    """The design of ``ship``'s library before the map is consulted (run in the drawer process), read from
    the move cache when it was made before (:func:`maps.librarycache.kept_first_design`)."""
    from maps.librarycache import kept_first_design
    from primitives.ship import load_profile

    return kept_first_design(load_profile(ship), **design)


def ratios_ahead(ship: str, first: FirstDesign) -> dict[str, Any]:
    """The design ratios figure of the early design, drawn in the drawer while the parent plans
    (used when the plan's design is that one: nothing was dropped for the map), or read from the move
    cache where it was kept with that design (:func:`maps.librarycache.kept_ratios_png`). The profile is the
    one the design was made from, which its primitives hold (loaded again only for an empty library)."""
    from maps.librarycache import kept_ratios_png
    from primitives.ship import load_profile

    profile = first.library[0].profile if first.library else load_profile(ship)
    return {"ratios": (first.design.design, kept_ratios_png(profile, first.design.design))}
