"""The ``shiptrial`` application: one typer app, one module per subcommand."""

from __future__ import annotations

import io
import os
import sys
from contextlib import contextmanager

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


@contextmanager
def _pure_json_stdout(argv: list[str]):
    """With --json, stdout carries the JSON document and nothing else.

    C-level writes to file descriptor 1 (a LAPACK routine's warning) go to stderr for the whole
    command; Python-level output is held back and, once the command ends, the trailing JSON
    document goes to stdout and anything printed before it to stderr.
    """
    if "--json" not in argv:
        yield
        return
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    old, buf = sys.stdout, io.StringIO()
    sys.stdout = buf
    try:
        yield
    finally:
        sys.stdout = old
        os.dup2(saved, 1)
        os.close(saved)
        noise, doc = _split_json(buf.getvalue())
        if noise:
            sys.stderr.write(noise)
        old.write(doc)
        old.flush()


def _split_json(text: str) -> tuple[str, str]:
    """(what comes before the trailing JSON document, the document); ("", text) when none is found."""
    import json

    starts = [0] + [i + 1 for i, c in enumerate(text) if c == "\n" and text[i + 1 : i + 2] in ("{", "[")]
    for i in starts:
        try:
            json.loads(text[i:])
        except ValueError:
            continue
        return text[:i], text[i:]
    return "", text


def _run(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)
    if _draws(args):  # the figures' drawer starts now: it imports matplotlib and fpdf while the options are parsed
        from cli.drawer import start_early
        from cli.plan_cache import expect_kept_files

        if not expect_kept_files(args):  # unless the last such run's files are kept: nothing to draw then
            start_early(args)
    try:
        with _pure_json_stdout(args):
            return _run_app(argv)
    finally:
        from cli.drawer import drop_early
        from cli.plan_cache import forget_command

        drop_early()
        forget_command()


def _draws(args: list[str]) -> bool:
    """``shiptrial plan`` that will write the figures (a plan with exports, not a resume, not help)."""
    skip = {"--no-export", "--resume", "--help", "-h"}
    return bool(args) and args[0] == "plan" and not skip.intersection(args)


def _run_app(argv: list[str] | None) -> int:
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
