"""Optional dependencies of the drawing libraries that ``plan-trial``'s drawer never uses, kept out of its imports.

fpdf2, fontTools and matplotlib each import, when installed, a package that the drawer (:mod:`cli.drawer`, a
forked process that only draws a plan's figures and ends) has no use for, and each handles that package's absence
itself, as on a machine without it. :func:`leave_out_unused` marks them absent in ``sys.modules`` (a ``None``
entry: Python's own way to make an import raise ``ImportError``) before the drawer imports the drawing modules.
The files are the same bytes (``tests/test_drawer_imports.py``); the imports cost about 0.05 s less of the
drawer's CPU (0.52 -> 0.47 s), which is on ``plan-trial``'s critical path: the plan usually reaches the drawer before its imports
are done (docs/kernel-speed.md, Stop 60).

Only in the drawer and its children: a process that calls the drawing functions itself (another platform,
:func:`cli.drawer.draw_here`; a notebook) imports these libraries as they are. fpdf2 2.8 and fontTools 4 have
no setting that leaves them out (read in their sources: the imports are at module level, in ``try``/``except
ImportError``)."""

from __future__ import annotations

import sys
import warnings

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
        "backend, xml.etree otherwise; the PDF card's fonts (matplotlib's DejaVu Sans) are subset without XML "
        "(they have no SVG table)",
    ),
    (
        "mpl_toolkits.mplot3d",
        "matplotlib (matplotlib.projections; try/except Exception, with a UserWarning): the '3d' projection; "
        "no figure of the drawer is 3D",
    ),
)
# matplotlib's warning when mplot3d cannot be imported (meant for a broken install): not shown in the drawer
_MPLOT3D_WARNING = "Unable to import Axes3D"


def leave_out_unused() -> list[str]:
    """Mark each :data:`UNUSED` module absent unless it is imported already (then it stays: some code of this
    process uses it); returns the names marked. For the drawer process only (module docstring)."""
    marked = []
    for name, _ in UNUSED:
        if name not in sys.modules:
            sys.modules[name] = None  # type: ignore[assignment]  # import raises ImportError (Python's import system)
            marked.append(name)
    if "mpl_toolkits.mplot3d" in marked:
        warnings.filterwarnings("ignore", message=_MPLOT3D_WARNING, category=UserWarning)
    return marked
