"""The ``shiptrial`` entry points (:func:`main`, :func:`plan_main`): the typer app itself, one module per
subcommand, is :mod:`cli.commands`, imported when the command line is parsed (``cli.app.app`` imports it too).

Why not here: ``plan-trial`` forks its figures' drawer before anything the drawer does not use is imported
(:func:`cli.drawer.start_early`), so that the drawer's imports (fpdf: about 0.3 s of CPU) overlap the parent's
typer and command modules (0.07-0.17 s of CPU, measured) rather than wait for them.
"""

from __future__ import annotations

import io
import os
import sys
from contextlib import contextmanager
from typing import Any


def __getattr__(name: str) -> Any:
    """``cli.app.app``: the typer app, from :mod:`cli.commands` (imported on first use; PEP 562)."""
    if name == "app":
        from cli.commands import app

        return app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    import typer  # after the drawer's fork (_run): the drawer uses neither typer nor the command modules

    from cli.commands import app
    from cli.errors import user_error_types
    from primitives.io import WriteError

    try:
        rc = app(args=argv, prog_name="shiptrial", standalone_mode=False)
    except WriteError as exc:  # before user_error_types: not FileNotFoundError's wording
        print(f"error: {exc.filename}: cannot be written ({exc.strerror}); nothing was written to it", file=sys.stderr)
        return 1
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
    except BrokenPipeError:  # not a file the user named: _main stops quietly
        raise
    except OSError as exc:  # any other file the OS refused: its name and the OS's reason, not a traceback
        print(f"error: {exc.filename or type(exc).__name__}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    except Exception as exc:
        # click (vendored by typer) usage errors carry their own message and exit code
        if hasattr(exc, "show") and hasattr(exc, "exit_code"):
            exc.show()
            return int(exc.exit_code)
        if type(exc).__name__ == "Abort":
            return 1
        raise
    return rc if isinstance(rc, int) else 0


def _pipe_closed() -> int:
    """stdout's reader went away (``--json | head``): stop quietly, as Unix tools do, with the status a shell
    reports for a tool its pipe closed (128 + SIGPIPE); stdout onto /dev/null so the interpreter's last flush
    cannot fail again."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 141


def _main(argv: list[str] | None) -> None:
    """Run the command and exit with its status once stdout's buffer is written; a closed pipe, met while the
    command prints, when ``--json``'s document is written or at that last flush, ends it quietly."""
    try:
        rc = _run(argv)
        sys.stdout.flush()
    except BrokenPipeError:
        rc = _pipe_closed()
    sys.exit(rc)


def main() -> None:
    _main(None)


def plan_main() -> None:
    """``plan-trial`` is ``shiptrial plan``."""
    _main(["plan", *sys.argv[1:]])
