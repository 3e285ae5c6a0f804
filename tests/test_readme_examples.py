"""The README's example commands run as written (issue 29), and those of the command reference
(docs/commands/*.md, where the README's long sections moved at stop 62): every block of indented lines is
extracted (a block on both pages once), its ``shiptrial``, ``plan-trial`` and ``python -c`` commands run in order, in-process
(``cli.app._run``: this checkout's code, not an installed console script), in a scratch directory,
``/tmp/`` paths moved into it and ``$(python -c ...)`` substitutions evaluated. Exit 0 is required.
``pip install``, the test command (CI runs them) and benchmark scripts are not run; blocks that take longer than
a default test may are listed in ``SLOW`` with their measured time; a new README example is run
unless it is added there.
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

from cli.app import _run

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs" / "commands").glob("*.md"))]
# (substring of the example, why it is not run here: CPU time measured on the shared 2-core machine)
SLOW = {
    "plan-trial --out trial-out": "the quick start: tests/test_end_to_end.py runs the same plan --out and checks its exports "
    "(about 4 s CPU, not spent twice)",
    "plan-trial --ship kvlcc2 --map": "KVLCC2 on the 60 km open sea: 14 s CPU (106 s wall on the loaded machine)",
    "plan-trial --ship coaster.toml": "a ship from particulars planned on the open sea: 14 s CPU (34 s wall on the loaded machine); "
    "run by the slow test_the_readme_example_plans_a_ship_made_from_particulars",
    "plan-trial --resume": "a plan, then its resume with every export: about 8 s CPU; tests/test_resume.py runs "
    "the same resume end to end on a 15-minute plan, its recordings made by the example's example_recordings",
    "shiptrial mass ": "the roll mass estimate: 10 s CPU (its own tests run it)",
    "shiptrial steering diagnose/data": "the two 20/20 KVLCC2 zig-zags pooled, four models and estimators: 13 s CPU "
    "(tests/test_steering_cli.py runs the command on a simulated record)",
}
NOT_RUN = ("pip install", "python -m pytest", "python benchmarks/")  # CI's own steps; benchmarks print figures, minutes each


def _examples(pages: list[Path] = PAGES) -> list[list[str]]:
    """The pages' example blocks (consecutive indented lines), their lines split at ``&&`` into commands;
    a block found on two pages (the README's example repeated on its command's page) once."""
    out: list[list[str]] = []
    block: list[str] = []
    for line in [ln for page in pages for ln in [*page.read_text(encoding="utf-8").splitlines(), ""]]:
        if line.startswith("    ") and not line.lstrip().startswith(("|", "- ")):
            cmds = [re.sub(r"\s+#.*$", "", c.strip()) for c in line.strip().split(" && ")]
            block += [c for c in cmds if c.startswith(("shiptrial ", "plan-trial", "python ")) and not c.startswith(NOT_RUN)]
        elif block:
            if block not in out:
                out.append(block)
            block = []
    return out


EXAMPLES = _examples()


def _python(code: str) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(compile(code, "<README>", "exec"), {"__name__": "__readme__"})
    return buf.getvalue().strip()


def _substitute(cmd: str) -> str:
    """Evaluate each ``$(python -c '...')`` (balanced parentheses) in-process."""
    while (i := cmd.find("$(")) >= 0:
        depth, j = 0, i + 1
        for j in range(i + 1, len(cmd)):
            depth += {"(": 1, ")": -1}.get(cmd[j], 0)
            if depth == 0:
                break
        inner = shlex.split(cmd[i + 2 : j])
        assert inner[:2] == ["python", "-c"], inner
        cmd = cmd[:i] + _python(inner[2]) + cmd[j + 1 :]
    return cmd


def _run_line(cmd: str, tmp: Path) -> None:
    cmd = _substitute(cmd.replace("/tmp/", f"{tmp}/"))
    argv = shlex.split(cmd)
    if argv[0] == "python":
        assert argv[1] == "-c", argv
        _python(argv[2])
        return
    argv = ["plan", *argv[1:]] if argv[0] == "plan-trial" else argv[1:]
    assert _run(argv) == 0, f"README example failed: {cmd}"


def _skipped(cmds: list[str]) -> str | None:
    return next((why for key, why in SLOW.items() if any(key in c for c in cmds)), None)


def test_the_readme_has_examples_of_the_commands():
    text = " ".join(c for cmds in _examples([README]) for c in cmds)
    for cmd in ("plan-trial", "shiptrial diagnose", "shiptrial yawid", "shiptrial mass"):
        assert cmd in text, cmd


@pytest.mark.parametrize("cmds", [c for c in EXAMPLES if not _skipped(c)], ids=lambda c: c[-1][:60])
def test_readme_example_runs(cmds, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for cmd in cmds:
        _run_line(cmd, tmp_path)
    capsys.readouterr()


@pytest.mark.parametrize("ship", ["kvlcc2", "coaster.toml"])
def test_the_readme_examples_on_the_open_sea_name_a_shipped_map(ship, tmp_path, monkeypatch):
    """The open-sea examples are not run here (a minute each); their ``--map open-sea`` is a
    bundled map's name, which plan resolves as --ship resolves a bundled profile's."""
    from maps.geo import bundled_map_path, load_map

    monkeypatch.chdir(tmp_path)  # no file named open-sea where the user stands
    line = next(c for cmds in EXAMPLES for c in cmds if f"plan-trial --ship {ship} --map" in c)
    argv = shlex.split(line)
    name = argv[argv.index("--map") + 1]
    assert name == "open-sea"
    sea = load_map(name)
    assert sea.source == str(bundled_map_path("open-sea")) and sea.start is not None


@pytest.mark.slow
def test_the_readme_example_plans_a_ship_made_from_particulars(tmp_path, monkeypatch, capsys):
    """Issue 31's "plan-trial --ship ship.toml for a ship made from particulars plans on the
    open-sea map, design included": the quick start's line as written, with 2 prior draws instead
    of 12 (the plan does not read them): exit 0, the design's counts, every crew export written.
    Measured on the loaded 2-core machine: profile new 3.8 s CPU, the plan 11.8 s user + 1.9 s sys."""
    import json

    monkeypatch.chdir(tmp_path)
    cmds = next(c for c in EXAMPLES if any("plan-trial --ship coaster.toml" in x for x in c))
    for cmd in cmds:
        _run_line(cmd.replace(" --out coaster.toml", " --prior-draws 2 --out coaster.toml"), tmp_path)
    capsys.readouterr()
    out = tmp_path / "coaster-out"
    plan = json.loads((out / "plan.json").read_text())
    assert plan["ship"] == "coaster" and plan["feasible"] and plan["map_name"].startswith("open sea")
    assert sum(plan["counts"].values()) > 0 and plan["design"]
    for name in ("plan.png", "trajectory.geojson", "design-ratios.png", "coaster-trial-track.png", "coaster-trial-states.png"):
        assert (out / name).stat().st_size > 0, name
    for ext in ("geojson", "gpx", "rtz", "csv", "html", "pdf"):
        assert (out / f"coaster-trial.{ext}").stat().st_size > 0, ext
