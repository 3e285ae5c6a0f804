"""plan-trial draws its figures in a drawer process forked when the command starts (cli.drawer):
the files are those of drawing in one process, a drawing error is the command's one-line error
with nothing written, and no process outlives the command, whatever happened."""

from __future__ import annotations

import os

import pytest

import cli.drawer as drawer
from cli.app import _run
from tests.procs import children

START = "2026-06-01T08:00Z"
COUNTS = "steep_zigzag_surge=1"


def _files(d):
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


@pytest.fixture(scope="module")
def forked(tmp_path_factory):
    out = tmp_path_factory.mktemp("forked") / "out"
    assert _run(["plan", "--counts", COUNTS, "--out", str(out), "--start-time", START]) == 0
    return out


def test_drawer_writes_what_one_process_writes(forked, tmp_path, monkeypatch, capsys):
    """Without fork (other platforms) every figure is drawn in the command's process: the same
    files, byte for byte (plan.json up to its timings)."""
    monkeypatch.setattr(drawer, "CAN_FORK", False)
    out = tmp_path / "here"
    assert _run(["plan", "--counts", COUNTS, "--out", str(out), "--start-time", START]) == 0
    a, b = _files(forked), _files(out)
    assert (
        a.keys() == b.keys()
        and {
            "plan.png",
            "full-scale-trial.pdf",
            "full-scale-trial.html",
            "full-scale-trial-track.png",
            "full-scale-trial-states.png",
        }
        <= a.keys()
    )
    assert [k for k in a if k != "plan.json" and a[k] != b[k]] == []
    capsys.readouterr()


def test_drawing_error_is_one_line_and_nothing_is_written(tmp_path, monkeypatch, capsys):
    """The track figure (drawn in the drawer itself, not its child) fails: exit 2 with the file
    and the cause, no output directory, no process left."""
    import maps.export.plots as plots

    def broken(*a, **k):
        raise RuntimeError("no ink")

    monkeypatch.setattr(plots, "plot_track", broken)
    before = children()
    out = tmp_path / "bad"
    assert _run(["plan", "--counts", COUNTS, "--out", str(out), "--start-time", START]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: full-scale-trial-track.png: writing the track figure failed: RuntimeError: no ink"]
    assert not out.exists() and children() <= before


def test_failed_planning_ends_the_drawer(tmp_path, capsys):
    """--counts naming no primitive of the library fails inside the planning, after the drawer
    started: the one-line error, nothing written, the drawer ended and reaped."""
    out = tmp_path / "none"
    before = children()
    assert _run(["plan", "--counts", "nosuch=1", "--out", str(out), "--start-time", START]) == 2
    assert capsys.readouterr().err.startswith("error: --counts: unknown primitive(s) nosuch for full-scale")
    assert not out.exists() and children() <= before


def test_early_result_comes_from_the_drawer_and_a_failure_is_none():
    """Drawer(early) runs ``early`` in the drawer process: early() returns its result (here a
    payload larger than a pipe's buffer, and the drawer's pid, not ours); a failing ``early``
    gives None (the command then computes it, and meets the error, itself)."""
    big = drawer.Drawer(lambda: (os.getpid(), b"x" * 300_000))
    pid, payload = big.early()
    big.cancel()
    assert pid != os.getpid() and payload == b"x" * 300_000

    def fails():
        raise RuntimeError("no design")

    bad = drawer.Drawer(fails)
    assert bad.early() is None
    bad.cancel()


def test_unread_early_result_does_not_hang_the_drawer():
    """A command that fails before reading the early result (a payload larger than a pipe's
    buffer) still ends and reaps its drawer."""
    before = children()
    d = drawer.Drawer(lambda: b"x" * 1_000_000)
    d.cancel()
    assert children() <= before


def test_design_in_the_drawer_gives_the_plan_of_the_design_here(tmp_path, capsys):
    """The default command (the design made in the drawer process) writes the files of
    the same command without the drawer (design, planning and figures in one process)."""
    outs = []
    for name, fork in (("forked", True), ("here", False)):
        old = drawer.CAN_FORK
        drawer.CAN_FORK = fork
        try:
            out = tmp_path / name
            assert _run(["plan", "--out", str(out), "--start-time", START]) == 0
        finally:
            drawer.CAN_FORK = old
        outs.append(_files(out))
    a, b = outs
    assert "design-ratios.png" in a and a.keys() == b.keys()
    assert [k for k in a if k != "plan.json" and a[k] != b[k]] == []
    capsys.readouterr()


def test_cancel_ends_a_drawer_that_has_nothing_to_draw_at_once():
    """A refused run cancels its drawer before sending it a plan: the drawer is ended there and
    then (not left to finish its design and drawing imports) and reaped."""
    import time

    before = children()
    d = drawer.Drawer(lambda: time.sleep(60))  # a design that would take a minute
    t0 = time.monotonic()
    d.cancel()
    assert time.monotonic() - t0 < 30 and children() <= before


def _deaf_design():
    """A design stuck where no Python signal handler runs (as in C code waiting on a lock another
    thread of the parent held when it forked): SIGTERM blocked, then a minute's sleep."""
    import signal
    import time

    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
    time.sleep(60)


def test_cancel_ends_a_drawer_deaf_to_sigterm_at_once():
    """A drawer that cannot unwind on SIGTERM is killed after the grace period, not waited for
    (a refused run in a test process with threads hung 30-60 s)."""
    import time

    before = children()
    d = drawer.Drawer(_deaf_design)
    time.sleep(0.2)  # let it block the signal
    t0 = time.monotonic()
    d.cancel()
    assert time.monotonic() - t0 < 10 and children() <= before


def test_a_drawer_cancelled_at_its_start_never_returns_into_the_callers_code(monkeypatch):
    """SIGTERM can reach the drawer before it is inside its own guard (a run refused at once):
    the forked child must exit there, never unwind into the caller's code and go on running it
    as a second copy of the command (or of the test session, as it once did in CI)."""
    import os
    import time

    # widen the window between the fork and the child's guard (the child's first steps include gc.freeze)
    monkeypatch.setattr(drawer.gc, "freeze", lambda: time.sleep(0.3))
    me = os.getpid()
    r, w = os.pipe()
    try:
        for _ in range(3):
            try:
                d = drawer.Drawer(lambda: None)
            finally:
                if os.getpid() != me:  # an escaped child, returning or raising: tell the test, then leave
                    os.write(w, b"x")
                    os._exit(0)
            time.sleep(0.1)  # the child is now past its handler's installation, inside the widened window
            d.cancel()
    finally:
        os.close(w)
    with os.fdopen(r, "rb") as fh:
        assert fh.read() == b""


def test_cancel_lets_the_drawer_remove_the_lock_file_it_holds(tmp_path):
    """A drawer cancelled while it writes under matplotlib's lock file (its font cache, built by
    the first import on a machine) removes the lock on its way out: a lock left behind made every
    later run wait 5 s for it and then do without the cache."""
    import time

    from matplotlib import cbook

    lock = tmp_path / "fontlist.json.matplotlib-lock"
    inside = tmp_path / "inside"

    def writes_under_lock():
        with cbook._lock_path(tmp_path / "fontlist.json"):
            inside.touch()
            time.sleep(60)

    before = children()
    d = drawer.Drawer(writes_under_lock)
    deadline = time.monotonic() + 30
    # wait until the drawer is inside the lock's block, not merely until the lock file exists:
    # matplotlib creates the file a few bytecodes before its try/finally, and a SIGTERM in that
    # window leaves it behind whatever the drawer does (a loaded CI machine hit it once)
    while not inside.exists() and time.monotonic() < deadline:
        time.sleep(0.005)
    assert lock.exists()
    d.cancel()
    assert not lock.exists() and children() <= before


def _doctored(d):
    import dataclasses

    return dataclasses.replace(d, weights={k: (1.0 if i == 0 else 0.0) for i, k in enumerate(d.weights)})


def _wrong_ratios(ship, first):
    """A doctored figure drawn ahead (module level: the drawer started early receives it pickled, as
    ``partial(cli.plan_early.ratios_ahead, ship)``)."""
    from expdesign.report import ratios_png

    other = _doctored(first.design.design)
    return {"ratios": (other, ratios_png(other))}


def test_ratios_drawn_ahead_only_for_the_design_planned(tmp_path, monkeypatch, capsys):
    """The drawer draws the design ratios of its early design while the parent plans; when the
    plan's design is another (a manoeuvre dropped for the map, here: a doctored early figure),
    the figure is drawn from the plan's design: the file is that of the plan's design."""
    import pickle

    import cli.plan_early as plan_early
    from maps.trialdesign import first_design
    from primitives.ship import load_profile

    design = first_design(load_profile("full-scale")).design.design
    assert drawer._same(design, pickle.loads(pickle.dumps(design))) and not drawer._same(design, _doctored(design))

    drawn = []
    real = drawer._prepare

    def spy(ahead, result):  # runs in the drawer: what it drew ahead is reported through a file
        out = real(ahead, result)
        (tmp_path / "ahead").write_text(str(sorted(out)))
        return out

    monkeypatch.setattr(drawer, "_prepare", spy)
    monkeypatch.setattr(plan_early, "ratios_ahead", _wrong_ratios)
    out = tmp_path / "doctored"
    assert _run(["plan", "--out", str(out), "--start-time", START]) == 0
    drawn.append((tmp_path / "ahead").read_text())
    assert drawn == ["['ratios']"]  # the doctored figure was drawn ahead, and not used
    here = tmp_path / "here"
    monkeypatch.setattr(drawer, "CAN_FORK", False)
    assert _run(["plan", "--out", str(here), "--start-time", START]) == 0
    assert (out / "design-ratios.png").read_bytes() == (here / "design-ratios.png").read_bytes()
    capsys.readouterr()


def _pid_and_payload():
    """An early function the deferred drawer receives pickled (a module-level function)."""
    return os.getpid(), b"x" * 300_000


def test_drawer_started_before_the_options_computes_what_begin_gives_it():
    """plan-trial forks its drawer before parsing (start_early): begin() later hands it the early
    function, whose result early() returns from the drawer process; without begin() it computes
    nothing and early() is None (the command designs itself)."""
    before = children()
    d = drawer.Drawer(deferred=True)
    d.begin(_pid_and_payload)
    pid, payload = d.early()
    assert pid == d.pid and payload == b"x" * 300_000
    d.cancel()
    idle = drawer.Drawer(deferred=True)
    idle.begin(None)
    assert idle.early() is None
    idle.cancel()
    local = drawer.Drawer(deferred=True)  # a function pickle cannot send: nothing early, the command designs itself
    local.begin(lambda: 1)
    assert local.early() is None
    local.cancel()
    never = drawer.Drawer(deferred=True)  # refused before begin(): ended and reaped
    never.cancel()
    assert children() <= before


@pytest.mark.parametrize(
    "args, draws",
    [
        (["plan", "--out", "x"], True),
        (["plan", "--no-export"], False),
        (["plan", "--resume", "p.json"], False),
        (["plan", "--help"], False),
        (["design", "--ship", "model-ship"], False),
        ([], False),
    ],
)
def test_drawer_starts_early_only_for_a_plan_with_figures(args, draws):
    from cli.app import _draws

    assert _draws(args) is draws


def test_refused_options_end_the_early_drawer(tmp_path, capsys):
    """An option refused while parsing (after the drawer was forked): the one-line error, nothing
    written, no process left."""
    before = children()
    out = tmp_path / "bad"
    assert _run(["plan", "--headings", "5", "--out", str(out), "--start-time", START]) == 2
    assert capsys.readouterr().err.startswith("error: --headings")
    assert not out.exists() and children() <= before and drawer._STARTED == []


_FORK_FIRST = """
import os, sys
import cli.drawer

seen = []
real = cli.drawer.start_early


def spy(args=()):
    seen.append([m for m in ("typer", "click", "cli.commands", "cli.plan_cmd") if m in sys.modules])
    real(args)
    seen.append(len(cli.drawer._STARTED))


cli.drawer.start_early = spy
from cli.app import _run

rc = _run(["plan", "--headings", "5", "--out", sys.argv[1], "--start-time", "2026-06-01T08:00Z"])
try:
    os.waitpid(-1, os.WNOHANG)
    left = True
except ChildProcessError:
    left = False
print(rc, seen, left, cli.drawer._STARTED)
"""


def test_plan_trial_forks_its_drawer_before_the_typer_app_is_imported(tmp_path):
    """The drawer is forked before typer and the command modules are imported (cli.commands, after the fork), so
    its imports overlap theirs; a refused option then still gives its one-line error, writes nothing and leaves
    no process (the drawer ended and reaped)."""
    import subprocess
    import sys

    out = tmp_path / "bad"
    env = {**os.environ, "SHIPTRIAL_CACHE_DIR": str(tmp_path / "cache")}
    run = subprocess.run([sys.executable, "-c", _FORK_FIRST, str(out)], capture_output=True, text=True, env=env)
    assert run.stdout.strip() == "2 [[], 1] False []", run.stdout + run.stderr
    assert run.stderr.startswith("error: --headings") and len(run.stderr.strip().splitlines()) == 1
    assert not out.exists()


_BEGUN = """
import pickle, sys

import cli.drawer
from cli.app import _run


class Begun(Exception):
    pass


def begin(self, early=None, ahead=None, cards_only=False):  # what the drawer would be sent, kept for the test
    with open(sys.argv[2], "wb") as fh:
        pickle.dump((early, ahead), fh)
    raise Begun


cli.drawer.Drawer.begin = begin
try:
    _run(["plan", "--out", sys.argv[1], "--start-time", "2026-06-01T08:00Z"])  # a plan-cache miss: early work sent
except Begun:
    pass
"""


def test_drawer_unpickles_its_early_work_without_typer(tmp_path):
    """The early design and the ratios drawn ahead reach the drawer pickled, by module and name: read in a fresh
    interpreter they import neither typer nor the command modules (the drawer, forked before the parent imports
    them on a plan-cache miss, would import them itself: 0.02-0.03 s of its CPU, measured)."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(root), SHIPTRIAL_CACHE_DIR=str(tmp_path / "cache"))
    spec = tmp_path / "spec.pickle"
    run = subprocess.run(
        [sys.executable, "-c", _BEGUN, str(tmp_path / "out"), str(spec)], capture_output=True, text=True, cwd=root, env=env
    )
    assert spec.exists(), run.stderr
    read = "import pickle, sys; e, a = pickle.load(open(sys.argv[1], 'rb')); print(e is not None and a is not None, sorted(m for m in ('typer', 'click', 'pydantic', 'cli.commands', 'cli.plan_cmd') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", read, str(spec)], capture_output=True, text=True, cwd=root, env=env)
    assert out.stdout.strip() == "True []", out.stdout + out.stderr


def test_no_cache_forks_no_drawer_before_parsing():
    """plan-trial --no-cache plans for sure: its drawer is forked later, once the planner is imported (the two
    processes then share those imports); any other plan-trial forks it before parsing."""
    before = children()
    drawer.start_early(["plan", "--no-cache", "--out", "x"])
    assert drawer.take_early() is None
    drawer.start_early(["plan", "--out", "x"])
    early = drawer.take_early()
    assert early is not None and early.pid
    early.cancel()
    assert children() <= before


_SPY = """
import sys
from pathlib import Path

import cli.drawer
from cli.plan_cmd import plan_and_write
from cli.plan_inputs import DesignChoice
from maps.planoptions import PlanOptions


class Forked(Exception):
    pass


class Spy:  # stands for the drawer: records what this process had imported and hashed when it would fork
    def __init__(self, *args, **kwargs):
        from maps import plancache

        print("code version hashed:", plancache.code_version.cache_info().currsize)
        print(sorted(m for m in ("maps.planner", "scipy.sparse") if m in sys.modules))
        raise Forked


cli.drawer.Drawer = Spy
design = DesignChoice(criterion="D", mean_subtraction="complete", trial_length_s=None, seed=0, parameter_prior=None)
try:
    plan_and_write("full-scale", None, PlanOptions(), design, counts=None, scenario=None, start=None, goal=None,
                   vessel_name=None, out=Path(sys.argv[1]), start_time=None, no_export=False, json_out=True, cache=False)
except Forked:
    pass
"""


def test_drawer_of_a_plan_made_here_forks_after_the_planner_imports(tmp_path):
    """A plan made here (not read from the plan cache): the drawer is forked once this process has imported the
    planner, so that the drawer's design and drawing share those pages instead of importing them again
    (about 0.3 s of its CPU); the planner imports no scipy (maps.graphsearch), which the drawer's design imports
    itself. A fresh interpreter: this one has imported everything already."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(root), SHIPTRIAL_CACHE_DIR=str(tmp_path / "cache"))  # the caches on
    out = subprocess.run(
        [sys.executable, "-c", _SPY, str(tmp_path / "out")], capture_output=True, text=True, cwd=root, env=env, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "['maps.planner']"
    # the code's digest made before the fork, so the drawer's library and design keys do not hash it again
    assert out.stdout.strip().splitlines()[-2] == "code version hashed: 1"
