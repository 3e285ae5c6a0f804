"""The user-error base every package raises for a mistake in the user's input.

The CLI turns any :class:`UserError` into one line ``error: ...`` on stderr and exit code 2; a
notebook user catches it like any ``ValueError``. Subclasses name the input kind (profile, map,
recording, design, sweep, export) so callers can tell them apart.
"""

from __future__ import annotations


class UserError(ValueError):
    """A mistake in the user's input. The message is one line naming the file, field and fix."""
