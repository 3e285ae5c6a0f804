"""plan-trial's drawer leaves out the drawing libraries' optional dependencies it never uses
(cli.drawer_imports): the trial cards and figures are the same bytes, and nothing is printed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from cli.drawer_imports import UNUSED
from maps.export.ownership import MANIFEST

ROOT = Path(__file__).resolve().parent.parent

# draws a synthetic plan's PDF card, states and track PNGs and HTML card into argv[1], with the guard when argv[2]
# is "guard"; prints what each guarded module is in sys.modules at the end (None: left out, absent, or imported)
_DRAW = """
import json, sys
from pathlib import Path
if sys.argv[2] == "guard":
    from cli.drawer_imports import leave_out_unused
    marked = leave_out_unused()
else:
    marked = []
from maps.export import export_plan
from maps.export._testing import synthetic_plan
from maps.export.plots import plot_states, plot_track

out = Path(sys.argv[1])
plan = synthetic_plan("full-scale")
export_plan(plan, "card", out / "card.html", start="2026-06-01T08:00Z")  # and card.pdf beside it
plot_states(plan, out / "states.png")
plot_track(plan, out / "track.png")
from cli.drawer_imports import UNUSED
state = {n: ("left out" if sys.modules.get(n, 0) is None else "absent" if n not in sys.modules else "imported")
         for n, _ in UNUSED}
print(json.dumps({"marked": marked, "modules": state}))
"""


def _draw(out: Path, mode: str) -> tuple[dict, str]:
    out.mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    run = subprocess.run(
        [sys.executable, "-c", _DRAW, str(out), mode], capture_output=True, text=True, cwd=ROOT, env=env, timeout=300
    )
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout.strip().splitlines()[-1]), run.stderr


def test_cards_and_figures_are_the_same_bytes_without_the_unused_imports(tmp_path):
    """With the guard (as in the drawer) the PDF card, the HTML card and both PNGs are byte for byte those drawn
    with every optional package importable; the guarded modules were never imported, and no warning was printed."""
    guarded, err = _draw(tmp_path / "guard", "guard")
    plain, _ = _draw(tmp_path / "plain", "plain")
    names = [n for n, _ in UNUSED]
    assert guarded["marked"] == names and set(guarded["modules"].values()) == {"left out"}
    assert err == ""
    # a single format's export leaves no record (maps.export.ownership.MANIFEST) beside its files (stop 62)
    files = sorted(p.name for p in (tmp_path / "plain").iterdir())
    assert files == ["card.html", "card.pdf", "states.png", "track.png"] and MANIFEST not in files
    changed = [f for f in files if (tmp_path / "guard" / f).read_bytes() != (tmp_path / "plain" / f).read_bytes()]
    assert changed == []


_IN_DRAWER = """
import json, sys
import cli.drawer as drawer
from cli.drawer_imports import UNUSED

d = drawer.Drawer(lambda: {n: sys.modules.get(n, 0) is None for n, _ in UNUSED})
seen = d.early()
d.cancel()
print(json.dumps({"drawer": seen, "here": {n: sys.modules.get(n, 0) is None for n, _ in UNUSED}}))
"""


# _serve run in this process, as tests do (tests/test_plancache.py): sent nothing, so it imports and returns
_SERVE_HERE = """
import json, os, sys
from cli.drawer import Drawer
from cli.drawer_imports import UNUSED

job_r, job_w = os.pipe()
os.close(job_w)
Drawer._serve(job_r)
print(json.dumps({n: sys.modules.get(n, 0) is None for n, _ in UNUSED}))
"""


def test_serving_in_the_calling_process_leaves_nothing_out():
    """Drawer._serve called in a process (not forked) leaves its imports as they are: the guard is set in the fork
    only, so a test session that calls it can still import lxml (the export tests do) afterwards."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    run = subprocess.run([sys.executable, "-c", _SERVE_HERE], capture_output=True, text=True, cwd=ROOT, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout.strip().splitlines()[-1]) == {n: False for n, _ in UNUSED}


def test_the_drawer_leaves_them_out_and_the_calling_process_does_not():
    """The guard runs in the drawer process (before its early work and its imports), never in the process that
    started it: a notebook or command that draws itself imports the libraries as they are."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, "-c", _IN_DRAWER], capture_output=True, text=True, cwd=ROOT, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    seen = json.loads(run.stdout.strip().splitlines()[-1])
    names = [n for n, _ in UNUSED]
    assert seen["drawer"] == dict.fromkeys(names, True)
    assert seen["here"] == dict.fromkeys(names, False)


def test_a_module_imported_already_is_left_as_it_is(monkeypatch):
    """A guarded module that the process imported before (some code of it uses it) is not taken away."""
    import cli.drawer_imports as di

    sentinel = object()
    for name, _ in di.UNUSED:  # every one imported (a stand-in where it is not): nothing marked in this process
        monkeypatch.setitem(sys.modules, name, sys.modules.get(name) or sentinel)  # restored after the test
    monkeypatch.setitem(sys.modules, "lxml", sentinel)
    assert di.leave_out_unused() == [] and sys.modules["lxml"] is sentinel
