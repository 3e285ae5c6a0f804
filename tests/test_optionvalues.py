"""cli.optionvalues: the plain option values it converts itself are the ones typer and pydantic give;
every other value, good or bad, reaches typer's own converter (same values, same error, same exit
code); and a plan's options are parsed without importing pydantic."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import typer.core
from typer import _coercion
from typer.models import OptionInfo

import cli.app
import cli.plan_cmd
from cli.optionvalues import _UNCONVERTED, install, plain_value

TEXTS = "0 7 -3 007 -0 123456789012345 1234567890123456789 1.5 -2.25 0.1 3.14159265358979 1e3 +4 1_000 inf nan".split()
TEXTS += ["", " 4", "4 ", "abc", "1.", ".5", "0x10", "\u0661\u0662", "true", "no", "-"]


def _typer_converter(annotation):
    original = _coercion.build_runtime_param  # typer's own, whatever cli.app installed over typer.core's
    return original(_coercion.resolve_type_descriptor(annotation, OptionInfo()))


@pytest.mark.parametrize("annotation", [str, int, float, Path])
def test_the_values_converted_here_are_typers(annotation):
    full = _typer_converter(annotation)
    here = 0
    for text in TEXTS:
        mine = plain_value(annotation, text)
        if mine is _UNCONVERTED:
            continue
        here += 1
        theirs = full._coerce_value(text, param=None, ctx=None)
        assert type(mine) is type(theirs) and mine == theirs, text
    assert here >= {str: len(TEXTS), int: 5, float: 9, Path: len(TEXTS) - 1}[annotation]


def _parsed(argv, capsys, monkeypatch):
    """What `shiptrial plan ARGV` hands to plan_and_write (or its exit code and words when refused)."""
    seen = {}

    def capture(*args, **kwargs):
        seen["args"] = repr((args, kwargs))
        raise typer.Exit(0)

    monkeypatch.setattr(cli.plan_cmd, "plan_and_write", capture)
    rc = cli.app._run_app(["plan", *argv])
    out = capsys.readouterr()
    return rc, seen.get("args"), out.out, out.err


ARGVS = [
    [],
    ["--out", "d", "--seed", "5", "--headings", "8", "--margin", "25.5", "--resolution", "300", "--max-memory", "1"],
    ["--map", "open-sea", "--ship", "kvlcc2", "--criterion", "A", "--trial-length", "30min", "--no-cache", "--json"],
    ["--prior-spread", "0.2", "--prior-draws", "40", "--run-in", "90", "--size", "40x40", "--vessel-name", "Aurora"],
    ["--seed", "abc"],
    ["--seed", "1.5"],
    ["--seed", " 5"],
    ["--headings", "+8"],
    ["--margin", "x"],
    ["--margin", "1e1"],
    ["--margin", "inf"],
    ["--resolution", ""],
    ["--max-memory", "-0"],
    ["--out", ""],
    ["--prior-draws", "1_000"],
    ["--seed"],
    ["--bogus", "1"],
]


@pytest.mark.parametrize("argv", ARGVS, ids=[" ".join(a) or "defaults" for a in ARGVS])
def test_plan_options_parse_as_typers_own_converters_do(argv, capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    assert install()  # cli.app installed it: the typer of this project is of the expected shape
    here = _parsed(argv, capsys, monkeypatch)
    monkeypatch.setattr(typer.core, "build_runtime_param", _coercion.build_runtime_param)
    theirs = _parsed(argv, capsys, monkeypatch)
    assert here == theirs
    assert here[0] != 0 or here[1] is not None


def test_a_plans_options_are_parsed_without_pydantic(tmp_path):
    """pydantic (0.14 s) and its 29 adapters cost 0.41-0.45 s of CPU at every plan-trial's start."""
    code = (
        "import sys, typer, cli.app, cli.plan_cmd\n"
        "def stop(*a, **k):\n    raise typer.Exit(0)\n"
        "cli.plan_cmd.plan_and_write = stop\n"
        f"rc = cli.app._run_app(['plan', '--out', {str(tmp_path / 'o')!r}, '--no-cache', '--seed', '3', '--margin', '30'])\n"
        "print(rc, 'pydantic' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["0", "False"]
