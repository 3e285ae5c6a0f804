"""User-facing errors: one line naming the file, field and fix; non-zero exit, no traceback."""

from __future__ import annotations

from primitives.errors import UserError

__all__ = ["UserError", "user_error_types"]


def user_error_types() -> tuple[type[BaseException], ...]:
    """Exception types that carry a user-facing message from the library packages."""
    return (UserError, FileNotFoundError)
