"""Errors of the experiment-design package that carry a user-facing, one-line message."""

from __future__ import annotations

from primitives.errors import UserError


class DesignError(UserError):
    """Bad design input: unidentifiable library, infeasible constraints, unknown option.

    The message is one line and says what is wrong and how to fix it; the CLI maps it to
    ``error: ...`` and exit code 2.
    """
