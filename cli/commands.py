"""The ``shiptrial`` typer app: one module per subcommand, each registering its own (``register(app)``).

Kept out of :mod:`cli.app` (the entry points), which ``plan-trial`` imports before it forks its drawer.
"""

from __future__ import annotations

import typer

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Plan ship sea trials for system identification and diagnose model mismatch.",
)


@app.callback()
def _root() -> None:
    """Plan ship sea trials for system identification and diagnose model mismatch."""


# Each command module registers its subcommand(s) on the app.
from cli import (  # noqa: E402
    design_cmd,
    detect_cmd,
    diagnose_cmd,
    export_cmd,
    mass_cmd,
    plan_cmd,
    primitives_cmd,
    profile_cmd,
    steering_cmd,
    sweep_cmd,
    yawid_cmd,
)

for _module in (
    profile_cmd,
    primitives_cmd,
    design_cmd,
    plan_cmd,
    export_cmd,
    diagnose_cmd,
    sweep_cmd,
    mass_cmd,
    yawid_cmd,
    detect_cmd,
    steering_cmd,
):
    _module.register(app)
