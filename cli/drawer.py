"""The figures of ``shiptrial plan`` drawn beside the computation.

Drawing (the PDF trial card, the card's map and time-series figures, plan.png, the design
ratios) needs matplotlib and fpdf, about half a second of imports, and about half a second of
rendering. A :class:`Drawer` is forked when the command starts: it first runs the command's
``early`` function (the design of the ship's library, which needs nothing from the map) and pipes
the result back while the parent loads the map and builds the basic moves, then imports the
drawing modules on the other core while the parent plans (and draws what it can ahead: the design
ratios of its design, the PDF card's empty document with its fonts read), then receives the
finished plan (pickled through a pipe, with the route and sea room every export shares) and draws
it in two processes (itself and one forked child) while the parent writes the text exports. The
figures and bytes are those of one process. A drawer cancelled before it was sent a plan (the
command refused) is ended at once (SIGTERM, on which it unwinds: see :class:`Cancelled`).

``plan-trial`` forks its drawer before it parses its options (:func:`start_early`, deferred: the
drawing modules imported first, the early function given later by :meth:`Drawer.begin`), so that
a run whose plan is read from the plan cache does not wait for those imports. With ``--no-cache`` the plan is made
for sure and the drawer is forked later, once the parent has imported the planner: the two share those imports.

On platforms without ``fork`` the figures are drawn in the calling process (:func:`draw_here`). The forked
processes' plumbing (their guarded life, cancellation, reaping, errors named by file) is :mod:`cli.forkjobs`.
"""

from __future__ import annotations

import gc
import os
import pickle
import select
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from cli.drawer_imports import leave_out_unused
from cli.forkjobs import Failed, end_child, on_sigterm, reap_child, run_child, run_jobs

CAN_FORK = sys.platform.startswith("linux")


def beside(jobs: list[tuple[Path, str, Callable[[], object]]]) -> Callable[..., list[Path]]:
    """Start writing ``jobs`` ((path, what, writer) each); returns a function that waits for them
    and returns their paths (raising the first writer's error, naming its file).

    On Linux a forked child writes them while the caller writes everything else: the outputs
    are drawn on both cores at once (the same figures and bytes as in one process). Elsewhere
    they are written here.
    """
    from maps.export import ExportError

    paths = [p for p, _, _ in jobs]
    if not CAN_FORK:
        try:
            run_jobs(jobs)
        except Failed as exc:
            raise ExportError(str(exc)) from None
        return lambda quiet=False: paths
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: write the files, report an error through the pipe, never return
        try:  # whatever is raised before run_child's own guard (a Ctrl-C, the drawer's SIGTERM handler)
            os.close(read)
            run_child(write, lambda: run_jobs(jobs))
        finally:
            os._exit(1)
    os.close(write)
    state: dict[str, str | None] = {}

    def wait(quiet: bool = False) -> list[Path]:
        if "msg" not in state:  # reaped once; a second call (after the first raised) reports nothing new
            state["msg"] = reap_child(pid, read)
        elif quiet:
            return paths
        msg = state["msg"]
        if msg is not None and not quiet:
            raise ExportError(msg or f"{paths[0].name}: writing it failed")
        return paths

    return wait


def _compute_early(early: Callable[[], object], fd: int) -> object | None:
    """Run ``early`` and write its pickled result to ``fd`` (nothing when it fails: the parent
    then computes it itself and reports its own error); returns the result (None if it failed)."""
    try:
        result = early()
        data = pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - the parent meets the same error, worded by its own code
        result, data = None, b""
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
    except OSError:  # the parent no longer waits for it
        pass
    return result


def _prepare(ahead: Callable[[Any], dict[str, Any]] | None, result: object | None) -> dict[str, Any]:
    """What ``ahead`` draws from the early result while the parent still plans ({} when there is
    nothing to draw or it fails: the figure is then drawn from the plan as usual)."""
    if ahead is None or result is None:
        return {}
    try:
        return ahead(result)
    except Exception:  # noqa: BLE001 - drawn again from the plan, where an error is reported
        return {}


def _same(a: object, b: object) -> bool:
    """``a`` and ``b`` are of one type and their fields pickle to the same bytes, field by field
    (:func:`maps.plancache.fields_digest`: the design sent with the plan is the early one; the whole
    objects' pickles can differ in which strings they share)."""
    from maps.plancache import fields_digest

    try:
        return type(a) is type(b) and fields_digest(a) == fields_digest(b)
    except Exception:  # noqa: BLE001 - not comparable: drawn again
        return False


# what drawing needs, the modules the writers import when first called included (fpdf, matplotlib's Agg
# backend), in the order the deferred drawer imports them (:meth:`Drawer._serve_deferred`): the trial cards' first
# (none imports pyplot: :mod:`maps.export.figures`), which are all a cached plan at another start time draws
_CARD_MODULES = ("fpdf", "maps.export.cardpdf", "maps.export.card")
_DRAWING_MODULES = (
    *_CARD_MODULES,
    "matplotlib.backends.backend_agg",
    "matplotlib.pyplot",
    "expdesign.report",
    "maps.output",
)


def _warm(until: int = -1, modules: Sequence[str] = _DRAWING_MODULES) -> None:
    """Import ``modules`` (what drawing needs: the child's work while the parent plans), one after the other; with
    ``until`` (a pipe's read end), stop before the next module once that pipe is readable (written or closed)."""
    import importlib

    for name in modules:
        if until >= 0 and select.select([until], [], [], 0)[0]:
            return
        importlib.import_module(name)


def _warm_frozen(modules: Sequence[str] = _DRAWING_MODULES) -> None:
    """:func:`_warm` in the drawer, then everything alive (the drawing modules: some 100k objects)
    out of the collector's sight: the full collections that importing and drawing trigger would
    walk them all (two a run, 0.09-0.11 s of CPU measured under load; the drawer ends with
    ``os._exit``, so nothing is ever given back)."""
    gc.disable()  # importing makes next to no garbage: no full collection half-way through the imports
    try:
        _warm(modules=modules)
    finally:
        gc.freeze()
        gc.enable()


def draw_here(job: dict[str, Any], prepared: dict[str, Any] | None = None) -> None:
    """Write every figure of ``job`` (see :meth:`Drawer.send`) in two processes, each figure drawn
    once: a forked child (:func:`beside`) writes the PDF trial card and the states PNG; this
    process writes plan.png, the design ratios and the track PNG, then the HTML trial card with
    both PNGs. ``prepared``: figures drawn ahead from the early result (``"ratios"``: the design
    and its ratios PNG), used when the job's design is that design. ``job["png"]`` (optional): PNG
    bytes by file name (:func:`cli.plan_cache.saved_sets`), written instead of drawn."""
    from maps.export import _write, default_path
    from maps.export.card import write_card_pdf
    from maps.export.figures import PlanFigures
    from maps.export.plots import plot_states, plot_track  # imported by the PDF card already; pyplot only when drawing
    from maps.output import plot_plan
    from primitives.io import atomic_write_bytes

    plan, sea, chart, design, t0, tmp = (job[k] for k in ("plan", "sea", "chart", "design", "t0", "dir"))
    given = dict(job.get("png") or {})  # figures kept for this plan at another start time: written, not drawn
    html = default_path(plan, "card", tmp)
    stem = default_path(plan, "csv", tmp).with_suffix("")
    track, states = Path(f"{stem}-track.png"), Path(f"{stem}-states.png")

    def drawn_or_given(path: Path, draw: Callable[[], object]) -> Callable[[], object]:
        return (lambda: atomic_write_bytes(path, given[path.name])) if path.name in given else draw

    def card_pdf() -> None:  # the PDF draws its own map and states page: no figure shared with the PNGs
        run_jobs(
            [
                (
                    html.with_suffix(".pdf"),
                    "the PDF trial card",
                    lambda: write_card_pdf(plan, html.with_suffix(".pdf"), chart, t0),
                ),
                (states, "the states figure", drawn_or_given(states, lambda: plot_states(plan, states))),
            ]
        )

    wait = beside([(html.with_suffix(".pdf"), "the PDF trial card", card_pdf)])
    try:
        plot = tmp / "plan.png"
        jobs = [(plot, "the plan picture", drawn_or_given(plot, lambda: plot_plan(plan, sea, plot)))]
        if design is not None:
            ratios = tmp / "design-ratios.png"
            ahead = (prepared or {}).get("ratios")
            if ahead is not None and _same(ahead[0], design):  # drawn while the parent planned
                given.setdefault(ratios.name, ahead[1])
            jobs.append((ratios, "the design ratios figure", drawn_or_given(ratios, lambda: _design_ratios(design, tmp))))
        run_jobs(jobs)
        with PlanFigures(plan, chart) as figs:  # the card's images are the PNG exports
            if track.name in given:
                figs.adopt_png("track", given[track.name])
            run_jobs([(track, "the track figure", drawn_or_given(track, lambda: plot_track(plan, track, chart, figures=figs)))])
            wait()
            figs.adopt_png("states", states.read_bytes())
            run_jobs(
                [
                    (
                        html,
                        "the trial card",
                        lambda: _write(plan, "card", html, sea_map=chart, start=t0, vessel=None, pdf=False, figures=figs),
                    )
                ]
            )
    except BaseException:
        wait(quiet=True)  # no child outlives the drawing; the first error is the one to report
        raise


def _design_ratios(design: Any, out: Path) -> Path:
    from expdesign.report import plot_ratios

    plot_ratios(design, out / "design-ratios.png")
    return out / "design-ratios.png"


_STARTED: list[Drawer] = []  # the drawer started with the command (start_early), until taken


def start_early(args: Sequence[str] = ()) -> None:
    """Fork a drawer now, before the command's options are parsed (``plan-trial``): it imports the
    drawing modules (0.6-0.9 s of CPU, measured under load) while this process parses, reads the plan cache or plans.
    The command takes it (:func:`take_early`) and gives it its early function (:meth:`Drawer.begin`);
    :func:`drop_early` ends one left untaken (the command refused, or writes no figures).

    Not with ``--no-cache`` among ``args`` (the command line's words): that command plans here for sure, and its
    drawer is forked later (:func:`cli.plan_cmd.plan_and_write`), once this process has imported the planner,
    so that the two share those imports (numpy, shapely, pyproj, the project's modules: about 0.3 s of the
    drawer's CPU) rather than each paying for them. Since the planner imports no scipy (stop 47), the drawer's early
    design imports scipy.optimize itself (0.78-0.88 s of its CPU from the fork to the design, 0.44-0.50 s before,
    load 11), and the parent asks for the design 0.13-0.21 s of CPU after the fork: on idle cores that is what the
    parent waits for."""
    if CAN_FORK and not _STARTED and "--no-cache" not in args:
        # what both processes import in every such command (the plan's and the map's modules: shapely, pyproj),
        # imported once before the fork (about 0.09 s of CPU the drawer would repeat)
        import maps.export._common  # noqa: F401
        import maps.geo  # noqa: F401

        _STARTED.append(Drawer(deferred=True))


def take_early() -> Drawer | None:
    """The drawer :func:`start_early` started (None if none); the caller now ends it."""
    return _STARTED.pop() if _STARTED else None


def drop_early() -> None:
    """End a drawer started early and never taken."""
    while _STARTED:
        _STARTED.pop().cancel()


class Drawer:
    """A forked process that imports the drawing modules now and draws a plan later.

    ``send(job)`` hands it the plan once planned; ``wait()`` waits for the figures (raising the
    first writer's error as an ExportError); ``cancel()`` ends it without drawing (nothing
    planned, or the command failed). Without ``fork`` nothing is started and ``send`` draws in
    the calling process."""

    def __init__(
        self,
        early: Callable[[], object] | None = None,
        ahead: Callable[[Any], dict[str, Any]] | None = None,
        deferred: bool = False,
    ) -> None:
        self.pid, self._early, self._spec = 0, -1, -1
        if not CAN_FORK:
            return
        job_r, self._job_w = os.pipe()
        self._report, report_w = os.pipe()
        if early is not None or deferred:
            self._early, early_w = os.pipe()
        if deferred:
            spec_r, self._spec = os.pipe()
        pid = os.fork()
        if pid == 0:
            try:  # the child never returns into the caller's code, whatever is raised before run_child's own guard
                signal.signal(signal.SIGTERM, on_sigterm)  # before it starts anything: cancel() unwinds it
                gc.freeze()  # the parent's objects out of the collector's sight: collections would copy the shared heap
                leave_out_unused()  # here, in the forked drawer only: _serve* run in the calling process too (tests)
                os.close(self._job_w)
                os.close(self._report)
                if deferred:
                    os.close(self._early)
                    os.close(self._spec)
                    run_child(report_w, lambda: self._serve_deferred(job_r, spec_r, early_w))
                if early is not None:
                    os.close(self._early)
                    run_child(report_w, lambda: self._serve(job_r, early, early_w, ahead))
                run_child(report_w, lambda: self._serve(job_r))
            finally:
                os._exit(1)
        os.close(job_r)
        os.close(report_w)
        if early is not None or deferred:
            os.close(early_w)
        if deferred:
            os.close(spec_r)
        self.pid, self._sender = pid, None

    def begin(
        self,
        early: Callable[[], object] | None = None,
        ahead: Callable[[Any], dict[str, Any]] | None = None,
        cards_only: bool = False,
    ) -> None:
        """Give a drawer started ``deferred`` (before the command knew its options) its ``early``
        function and ``ahead`` (as the constructor's; pickled, so module-level functions and
        partials of them). Without a call it computes nothing early. ``cards_only``: the PNG figures
        will be given with the job (:func:`draw_here`), so only the trial cards' modules are imported
        ahead (not pyplot nor the Agg backend: about 0.3 s of CPU); a figure drawn all the same imports its own."""
        fd, self._spec = self._spec, -1
        if fd < 0:
            return
        spec = pickle.dumps((None, None, cards_only), protocol=pickle.HIGHEST_PROTOCOL)
        for what in ((early, ahead, cards_only), (early, None, cards_only)) if early is not None else ():
            try:
                spec = pickle.dumps(what, protocol=pickle.HIGHEST_PROTOCOL)
                break
            except (pickle.PicklingError, AttributeError, TypeError):  # a local function: not drawn ahead, or designed here
                continue
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(spec)
        except OSError:  # the drawer died: wait() reports it
            pass

    @staticmethod
    def _serve_deferred(job_r: int, spec_r: int, early_w: int) -> None:
        """A drawer started before the command knew its options: the drawing modules imported until
        :meth:`begin` gives the early function, which is then computed at once (the parent waits for it
        after loading its map and basic moves; imported first, the design waited for all of them, 1.1 s of
        CPU measured at load 8), then the rest of the modules, then the plan drawn. No full collection while importing (as
        :func:`_warm_frozen`)."""
        gc.disable()
        try:
            _warm(until=spec_r)
        finally:
            gc.enable()
        with os.fdopen(spec_r, "rb") as fh:
            spec = fh.read()
        try:
            early, ahead, cards_only = pickle.loads(spec) if spec else (None, None, False)
        except Exception:  # noqa: BLE001 - not readable here: the parent designs itself
            early, ahead, cards_only = None, None, False
        modules = _CARD_MODULES if cards_only else _DRAWING_MODULES
        if early is None:
            os.close(early_w)  # early() reads nothing: the parent designs itself
            Drawer._serve(job_r, modules=modules)
        else:
            Drawer._serve(job_r, early, early_w, ahead, modules=modules)

    @staticmethod
    def _serve(
        job_r: int,
        early: Callable[[], object] | None = None,
        early_w: int = -1,
        ahead: Callable[[Any], dict[str, Any]] | None = None,
        modules: Sequence[str] = _DRAWING_MODULES,
    ) -> None:
        result = _compute_early(early, early_w) if early is not None else None
        _warm_frozen(modules)
        prepared = _prepare(ahead, result)  # while the parent still plans
        from maps.export.cardpdf import prepare_document

        try:
            prepare_document()  # the PDF card's fonts read now, in the process its writer is forked from
        except Exception:  # noqa: BLE001 - the card's writer reads them again and names its file in the error
            pass
        with os.fdopen(job_r, "rb") as fh:
            data = fh.read()
        if data:  # nothing sent: cancelled
            draw_here(pickle.loads(data), prepared)

    def early(self) -> Any:
        """The result of the ``early`` function given to the constructor, computed in the drawer
        while this process worked (waits for it); None when there is none (no fork, no function,
        or it failed: the caller computes it itself, and meets the error, if any, itself)."""
        fd, self._early = self._early, -1
        if fd < 0:
            return None
        with os.fdopen(fd, "rb") as fh:
            data = fh.read()
        try:
            return pickle.loads(data) if data else None
        except Exception:  # noqa: BLE001 - a truncated result (the drawer died): computed here instead
            return None

    def send(self, job: dict[str, Any]) -> None:
        """Draw ``job``: keys plan, sea (the SeaMap), chart, design (or None), t0 (start time),
        dir (the output directory), png (optional: figures' bytes by file name, written as they are).
        Returns at once; the pipe is written by a thread while the
        caller goes on (the drawer may still be importing)."""
        if not self.pid:
            try:
                draw_here(job)
            except Failed as exc:
                from maps.export import ExportError

                raise ExportError(str(exc)) from None
            return
        data = pickle.dumps(job, protocol=pickle.HIGHEST_PROTOCOL)
        fd, self._job_w = self._job_w, -1

        def push() -> None:
            try:
                with os.fdopen(fd, "wb") as fh:
                    fh.write(data)
            except OSError:  # the drawer died: wait() reports it
                pass

        self._sender = threading.Thread(target=push, daemon=True)
        self._sender.start()

    def wait(self, quiet: bool = False) -> None:
        """Wait for the drawer; raise its error (an ExportError) unless ``quiet``."""
        if not self.pid:
            return
        pid, self.pid = self.pid, 0
        if self._early >= 0:  # never read: the drawer's write fails instead of blocking
            os.close(self._early)
            self._early = -1
        if self._spec >= 0:  # deferred and never begun: it computes nothing early
            os.close(self._spec)
            self._spec = -1
        cancelled = self._job_w >= 0
        if cancelled:  # never sent
            os.close(self._job_w)
            self._job_w = -1
            # nothing to draw: end it now rather than let it finish its design and imports (CPU and wall
            # time of a refused run). SIGTERM first: it may be writing matplotlib's font cache under its
            # lock file, which Cancelled removes on the way out; it has started no process
            end_child(pid, self._report)
        if self._sender is not None:
            self._sender.join()
        msg = reap_child(pid, self._report)
        if msg is not None and not quiet and not cancelled:
            from maps.export import ExportError

            raise ExportError(msg or "drawing the figures failed")

    def cancel(self) -> None:
        """End the drawer without drawing (or wait quietly for one already drawing)."""
        self.wait(quiet=True)
