"""User-facing errors: one line naming the file, field and fix; non-zero exit, no traceback."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from primitives.errors import UserError

if TYPE_CHECKING:
    from primitives.ship import ShipProfile

__all__ = ["UserError", "user_error_types", "warn_ship"]


def warn_ship(profile: ShipProfile) -> None:
    """The ship's load warnings (a diagnosed model.json's findings its profile cannot hold) on
    stderr, one line each, for the commands whose results do not carry them."""
    for w in profile.load_warnings:
        print(f"warning: {w}", file=sys.stderr)


def user_error_types() -> tuple[type[BaseException], ...]:
    """Exception types that carry a user-facing message from the library packages."""
    return (UserError, FileNotFoundError)
