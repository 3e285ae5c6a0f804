"""Optional dependencies of the drawing libraries that ``plan-trial``'s drawer never uses, kept out of its imports.

fpdf2 and fontTools each import, when installed, a package that the drawer (:mod:`cli.drawer`, a forked process
that only draws a plan's figures and ends) has no use for, and each handles that package's absence itself, as on
a machine without it. :func:`leave_out_unused` marks them absent in ``sys.modules`` (a ``None`` entry: Python's
own way to make an import raise ``ImportError``) before the drawer imports the drawing modules. The files are the
same bytes (``tests/test_drawer_imports.py``); the imports cost about 0.04 s less of the drawer's CPU (0.50 ->
0.46 s, review of stop 60), which is on ``plan-trial``'s critical path: the plan usually reaches the drawer before
its imports are done (docs/kernel-speed.md, Stop 60).

Only in the forked drawer and its children (called in :class:`cli.drawer.Drawer`'s fork, never in ``_serve``,
which tests call in their own process): a process that calls the drawing functions itself (another platform,
:func:`cli.drawer.draw_here`; a notebook; the test session) imports these libraries as they are. fpdf2 2.8 and
fontTools 4 have no setting that leaves them out (read in their sources: the imports are at module level, in
``try``/``except ImportError``). Should the cards ever be signed or encrypted (fpdf2's ``sign_pkcs12``,
``set_encryption`` with AES), drop ``cryptography`` here: fpdf2 would otherwise say it is not installed.
matplotlib's 3D toolkit is not left out: matplotlib 3.7 to 3.8.0, which ``pyproject.toml`` allows, import it
without a ``try`` (the guard came in 3.8.1), so its absence would break every figure there."""

from __future__ import annotations

import sys

# (module, who imports it and what for, and why the drawer never needs it)
UNUSED: tuple[tuple[str, str], ...] = (
    (
        "cryptography",
        "fpdf2 (fpdf.fpdf, fpdf.encryption; try/except ImportError): signing a PDF (which also needs endesive, not "
        "a dependency) and AES encryption; the trial cards are neither signed nor encrypted",
    ),
    (
        "lxml",
        "fontTools (fontTools.misc.etree, fontTools.subset.svg; try/except ImportError): its preferred XML "
        "backend, xml.etree otherwise; fpdf2 subsets the PDF card's fonts without XML (it drops the SVG "
        "table before subsetting: fpdf.output, drop_tables)",
    ),
)


def leave_out_unused() -> list[str]:
    """Mark each :data:`UNUSED` module absent unless it is imported already (then it stays: some code of this
    process uses it); returns the names marked. For the drawer process only (module docstring)."""
    marked = []
    for name, _ in UNUSED:
        if name not in sys.modules:
            sys.modules[name] = None  # type: ignore[assignment]  # import raises ImportError (Python's import system)
            marked.append(name)
    return marked
