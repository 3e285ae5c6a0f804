"""cli.plainparams converts plain option values as typer's pydantic adapters do, on every parameter of
the app, and `shiptrial detect` then runs without importing pydantic (stop 49: 0.35 s CPU a command)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = [
    "1", "-2", "007", "+1", " 1", "1_000", "1.", ".5", "-.5", "0.02", "1e-3", "1E3", "2.5e-07", "1e400",
    "nan", "inf", "0x10", "1.0", "-0", "", "abc", "run.csv", "dir/x.json", "99999999999999999999",
]  # fmt: skip


def _parameters():
    """(command, click parameter) of every command of the app, typer's own coercion kept aside."""
    import typer.main

    from cli.app import app

    group = typer.main.get_command(app)
    for name, cmd in sorted(group.commands.items()):
        for param in cmd.params:
            if hasattr(param, "type_descriptor"):
                yield name, param


def _coerced(runtime, value, param):
    """(value, its type) or ("error", message) of one coercion."""
    try:
        out = runtime.coerce(value, param=param, ctx=None)
    except Exception as exc:  # typer's BadParameter: the message the user sees
        return "error", str(exc)
    return out, type(out), [type(v) for v in out] if isinstance(out, list) else None


def test_plain_conversion_is_typers_on_every_parameter() -> None:
    from typer import _coercion

    from cli.plainparams import plain_runtime_param

    plain_seen = 0
    for name, param in _parameters():
        desc = param.type_descriptor
        mine = plain_runtime_param(desc, _coercion.build_runtime_param)
        if mine is None:
            continue
        plain_seen += 1
        theirs = _coercion.build_runtime_param(desc)
        multi = param.multiple or param.nargs == -1
        values = [param.default] + ([tuple(SAMPLES[i : i + 2]) for i in range(0, len(SAMPLES), 2)] if multi else SAMPLES)
        for v in values:
            got, want = _coerced(mine, v, param), _coerced(theirs, v, param)
            assert repr(got) == repr(want), (name, param.name, v, got, want)  # repr: nan is nan
    assert plain_seen > 50  # most of the app's options are plain: a change that made none plain would pass unseen


@pytest.mark.parametrize("args", [["detect", "missing.csv", "--prior", "missing.json", "--false-alarm", "0.02"]])
def test_detect_parses_its_options_without_pydantic(args: list[str], tmp_path: Path) -> None:
    code = (
        "import sys\n"
        "from cli.app import _run\n"
        f"rc = _run({args!r})\n"
        "print(rc, sorted(m for m in sys.modules if m.split('.')[0] in ('pydantic', 'matplotlib', 'scipy', 'numba')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env={"PYTHONPATH": str(ROOT), "PATH": "", "SHIPTRIAL_DETECT_CACHE_DIR": ""},
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "2 []", (out.stdout, out.stderr)
    assert "missing" in out.stderr  # the options were parsed and the command ran up to its input error


def test_a_malformed_number_gets_typers_message(tmp_path: Path) -> None:
    code = (
        "from cli.app import _run\nimport sys\nrc = _run(['detect', 'x.csv', '--prior', 'p.json', '--seed', '1.5'])\nprint(rc)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env={"PYTHONPATH": str(ROOT), "PATH": ""},
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "2" and "--seed" in out.stderr and "integer" in out.stderr, out.stderr
