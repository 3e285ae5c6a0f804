"""The ``shiptrial`` application: one typer app, one module per subcommand."""

from __future__ import annotations

import sys

import typer

from cli.errors import user_error_types

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Plan ship sea trials for system identification and diagnose model mismatch.",
)


@app.callback()
def _root() -> None:
    """Plan ship sea trials for system identification and diagnose model mismatch."""


# Each command module registers its subcommand(s) on the app.
from cli import design_cmd, diagnose_cmd, export_cmd, mass_cmd, plan_cmd, primitives_cmd, sweep_cmd  # noqa: E402

for _module in (primitives_cmd, design_cmd, plan_cmd, export_cmd, diagnose_cmd, sweep_cmd, mass_cmd):
    _module.register(app)


def _run(argv: list[str] | None = None) -> int:
    try:
        rc = app(args=argv, prog_name="shiptrial", standalone_mode=False)
    except user_error_types() as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"error: {msg}", file=sys.stderr)
        return 2
    except typer.Exit as exc:
        return exc.exit_code
    except SystemExit as exc:
        return int(exc.code or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        # click (vendored by typer) usage errors carry their own message and exit code
        if hasattr(exc, "show") and hasattr(exc, "exit_code"):
            exc.show()
            return int(exc.exit_code)
        if type(exc).__name__ == "Abort":
            return 1
        raise
    return rc if isinstance(rc, int) else 0


def main() -> None:
    sys.exit(_run())


def plan_main() -> None:
    """``plan-trial`` is ``shiptrial plan``."""
    sys.exit(_run(["plan", *sys.argv[1:]]))
