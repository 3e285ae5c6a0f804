"""User-facing errors: one line naming the file, field and fix; non-zero exit, no traceback."""

from __future__ import annotations


class UserError(Exception):
    """A mistake in the user's input. The message is shown as is, on one line."""


def user_error_types() -> tuple[type[BaseException], ...]:
    """Exception types that carry a user-facing message from the library packages."""
    from primitives.ship import ProfileError
    from primitives.terms import TermError

    types: list[type[BaseException]] = [UserError, ProfileError, TermError, FileNotFoundError]
    for mod, name in (("maps.geo", "MapError"), ("diagnose.recording", "RecordingError"), ("expdesign.errors", "DesignError"), ("expdesign.sweep", "SweepError")):
        try:
            module = __import__(mod, fromlist=[name])
            types.append(getattr(module, name))
        except (ImportError, AttributeError):
            pass
    return tuple(types)
