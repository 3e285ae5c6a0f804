"""Drawing on an fpdf2 page with raw PDF operators: the shared low level of the trial card's
map (:mod:`maps.export.pdfmap`) and states page (:mod:`maps.export.pdfstates`).

Paths are written as PDF operators inside ``q``/``Q`` (so fpdf2's record of the current colours
and line width stays true): fpdf2's own polygon calls stroke or fill each ring alone, cannot fill
a polygon with holes (even-odd rule) in one path, and write one call per point. Text goes through
fpdf2 (the card's embedded TrueType font). Coordinates are PDF points from the page's bottom left.
"""

from __future__ import annotations

from typing import Any

import numpy as np

BOLD, REG = "B", ""
LINE_HEIGHT = 1.17  # DejaVu Sans ascent + descent per point of font size (matplotlib's text box)


def rgb(colour: Any) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    return to_rgb(colour)


def col(colour: Any, op: str) -> str:
    """The operator setting a matplotlib colour: ``op`` "rg" (fill) or "RG" (stroke)."""
    r, g, b = rgb(colour)
    return f"{r:.3f} {g:.3f} {b:.3f} {op}"


def rings_ops(rings: list[np.ndarray], close: bool = True) -> str:
    """Subpaths (arrays of PDF points) as path construction operators, each closed with ``close``."""
    out = []
    for r in rings:
        pts = [f"{x:.2f} {y:.2f}" for x, y in r]
        out.append(f"{pts[0]} m " + " l ".join(pts[1:]) + (" l h" if close else " l"))
    return "\n".join(out)


class Painter:
    """Paths and text on the current page of an fpdf2 document (unit pt) in the font ``font``
    (regular and bold added to the document)."""

    def __init__(self, pdf: Any, font: str) -> None:
        self.pdf, self.font = pdf, font
        self.page_h = pdf.h * pdf.k

    def out(self, ops: str) -> None:
        self.pdf._out(ops)  # noqa: SLF001 - raw operators inside q/Q (see the module docstring)

    def text(
        self,
        x: float,
        y: float,
        s: str,
        size: float,
        *,
        bold: bool = False,
        ha: str = "left",
        va: str = "baseline",
        colour: tuple[int, int, int] = (0, 0, 0),
    ) -> float:
        """``s`` at PDF point (x, y up) aligned as matplotlib's ha/va; returns its width."""
        p = self.pdf
        p.set_font(self.font, BOLD if bold else REG, size)
        p.set_text_color(*colour)
        w = p.get_string_width(s)
        x -= {"left": 0.0, "center": 0.5 * w, "right": w}[ha]
        y_base = {"baseline": y, "bottom": y + 0.24 * size, "top": y - 0.76 * size, "center": y - 0.28 * size}[va]
        p.text(x, self.page_h - y_base, s)
        return w

    def text_width(self, s: str, size: float, bold: bool = False) -> float:
        self.pdf.set_font(self.font, BOLD if bold else REG, size)
        return self.pdf.get_string_width(s)

    def polyline(self, pts: np.ndarray, colour: Any, lw: float, dash: tuple[float, float] | None = None, cap: int = 0) -> None:
        d = f"[{dash[0]:.2f} {dash[1]:.2f}] 0 d" if dash else "[] 0 d"
        self.out(f"{col(colour, 'RG')} {lw:.2f} w {cap} J 1 j {d}\n" + rings_ops([pts], close=False) + " S")
