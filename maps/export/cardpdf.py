"""The printable trial card as PDF, written with fpdf2: the words and layout of
:mod:`maps.export.card` (the look of the matplotlib pages the card was first drawn with), the map
and states page drawn straight into the PDF (:mod:`maps.export.pdfmap`,
:mod:`maps.export.pdfstates`), in a fraction of the time.

Why not matplotlib's PDF backend for the whole card: it lays out and draws text glyph by glyph
through FreeType (about 3 ms a line), and the card's tables and orders are some 600 lines, so the
text pages cost more CPU than every other output of ``plan-trial`` together. fpdf2 writes a line
from the font's advance widths. The two figures (the map of page 1 and the states over time) are
drawn straight into the PDF as vector paths (:mod:`maps.export.pdfmap`,
:mod:`maps.export.pdfstates`), as matplotlib draws them, not through matplotlib and an SVG that
fpdf2 reads back (half the card's CPU). Text is DejaVu Sans (regular and bold, matplotlib's
bundled TrueType fonts), embedded as TrueType subsets; no creation date, so the same plan gives
the same bytes.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from maps.export.card import (
    A4,
    CELL_PAD,
    DESIGN_COLS,
    ROWS_PER_PAGE,
    STEPS_NOTE_PDF,
    TABLE_COLS,
    TABLE_PAD,
    TABLE_WIDTHS,
    _table_rows,
    design_rows,
    detail_pages,
    page1_layout,
    step_sheets,
)
from maps.export.pdfmap import draw_page1_map
from maps.export.pdfstates import draw_states_page
from maps.plan import Plan

PT = 72.0  # points per inch
W, H = A4[0] * PT, A4[1] * PT
RED, GREY = (160, 0, 0), (77, 77, 77)
ASCENT = 0.76  # DejaVu Sans cap height plus a little, as a fraction of the font size: matplotlib's va="top" box
FONT = "DejaVu Sans"  # the font of the matplotlib figures too


def _fonts() -> tuple[str, str]:
    """Paths of matplotlib's DejaVu Sans and DejaVu Sans Bold (always shipped with matplotlib)."""
    from matplotlib import font_manager as fm

    reg = fm.findfont(fm.FontProperties(family="DejaVu Sans"), fallback_to_default=False)
    bold = fm.findfont(fm.FontProperties(family="DejaVu Sans", weight="bold"), fallback_to_default=False)
    return reg, bold


EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


def _without_date(pdf: bytes) -> bytes:
    """The PDF with fpdf2's creation date (always written; here the fixed ``EPOCH``) blanked out
    byte for byte, so the cross-reference offsets stay right: the same plan gives the same bytes
    and the file claims no date."""
    key = b"/CreationDate (D:19700101000000Z)"
    if pdf.count(key) != 1:
        raise RuntimeError("fpdf2 wrote the creation date in an unexpected form: cannot make the card reproducible")
    return pdf.replace(key, b" " * len(key))


class _Card:
    """An fpdf2 document in points with the card's text styles; positions are given as matplotlib
    figure fractions (x from the left, y from the bottom) so that the pages match the figures."""

    def __init__(self) -> None:
        from fpdf import FPDF

        # plan-trial's drawer imports fpdf without cryptography (cli/drawer_imports.py): a card signed or
        # AES-encrypted would need it taken off that list
        self.pdf = pdf = FPDF(unit="pt", format=(W, H))
        pdf.set_auto_page_break(False)
        pdf.set_margins(0, 0, 0)
        pdf.set_creation_date(EPOCH)
        pdf.set_producer("shiptrial")
        reg, bold = _fonts()
        pdf.add_font(FONT, "", reg)
        pdf.add_font(FONT, "B", bold)
        self.h = H

    def page(self, size: tuple[float, float] = A4) -> None:
        self.pdf.add_page(format=(size[0] * PT, size[1] * PT))
        self.h = size[1] * PT

    def text(
        self,
        fx: float,
        fy: float,
        s: str,
        size: float,
        *,
        bold: bool = False,
        colour: tuple[int, int, int] = (0, 0, 0),
        va: str = "top",
    ) -> None:
        """``s`` at figure fraction (fx, fy) with matplotlib's vertical alignment ``va``."""
        p = self.pdf
        p.set_font(FONT, "B" if bold else "", size)
        p.set_text_color(*colour)
        y = (1.0 - fy) * self.h
        if va == "top":
            y += ASCENT * size
        elif va == "center":
            y += 0.5 * ASCENT * size - 0.08 * size
        p.text(fx * W, y, s)


def _page1(doc: _Card, plan: Plan, t0: datetime, sea_map: Any, vessel: str) -> None:
    doc.page()
    lines, abort, y_abort, top = page1_layout(plan, t0, sea_map, vessel)
    # the map's box, (0.1, 0.2, 0.85, top - 0.22) of the page, in points from the bottom left
    draw_page1_map(doc.pdf, FONT, plan, sea_map, (0.1 * W, 0.2 * H, 0.85 * W, (top - 0.22) * H))
    doc.text(0.05, 0.965, f"SEA TRIAL CARD  -  {vessel}", 15, bold=True)
    for k, line in enumerate(lines):
        doc.text(0.05, 0.935 - 0.017 * k, line, 8.5)
    # the abort box: matplotlib's round box with pad 0.4 font sizes around 1.2-spaced lines
    size, lead = 8.5, 1.2 * 8.5 * 1.17
    pdf = doc.pdf
    pdf.set_font(FONT, "", size)
    width = max(pdf.get_string_width(a) for a in abort)
    pad = 0.4 * size
    x0, y0 = 0.05 * W, (1.0 - y_abort) * H
    pdf.set_draw_color(*RED)
    pdf.set_fill_color(255, 243, 243)
    pdf.set_line_width(1.0)
    pdf.rect(
        x0 - pad,
        y0 - pad,
        width + 2 * pad,
        lead * (len(abort) - 1) + ASCENT * size + 0.24 * size + 2 * pad,
        style="DF",
        round_corners=True,
        corner_radius=pad,
    )
    for k, a in enumerate(abort):
        pdf.set_text_color(*RED)
        pdf.text(x0, y0 + ASCENT * size + k * lead, a)
    doc.text(
        0.05,
        0.02,
        "Manoeuvres in sailing order: next page(s). Numbers on the map are step numbers; stars are execute points.",
        7.5,
        colour=GREY,
        va="baseline",
    )


TABLE_FS = 6.5
LINE_PITCH = 1.2 * TABLE_FS  # a wrapped cell's further lines
ROW_H = 0.92 * H / (ROWS_PER_PAGE + 1)  # a one-line row (as matplotlib.table drew 44 rows and a header in the box)
TABLE_TOP = 0.03 * H + 0.92 * H * TABLE_PAD  # below the page title, from the top of the page
TABLE_BOTTOM = H - 0.03 * H


def _inset(width: float) -> float:
    """Text inset of a cell ``width`` points wide: matplotlib.table's tenth of the width, at most 4 pt."""
    return min(CELL_PAD * width, 4.0)


def _wrap_cell(doc: _Card, text: str, width: float, bold: bool) -> list[str]:
    """``text`` broken at spaces into lines no wider than ``width`` points (a word wider than
    the cell stays whole on its line): a name is wrapped, never cut."""
    pdf = doc.pdf
    pdf.set_font(FONT, "B" if bold else "", TABLE_FS)
    lines: list[str] = []
    for word in text.split(" "):
        if lines and pdf.get_string_width(f"{lines[-1]} {word}") <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


class _Tables:
    """Tables flowed down the pages: header row grey and bold, 1 pt black cell edges, 6.5 pt
    text wrapped in its cell, a row never split; a table that does not fit under the one
    before it continues on a new page with its header repeated."""

    def __init__(self, doc: _Card, plan: Plan, first_page: int) -> None:
        self.doc, self.plan, self.page_no = doc, plan, first_page - 1
        self.y = TABLE_BOTTOM  # no page yet

    def new_page(self, title: str, bold: bool) -> None:
        self.doc.page()
        self.page_no += 1
        self.doc.text(0.04, 0.975, f"{self.plan.ship}: {title} (page {self.page_no})", 10, bold=bold)
        self.y = TABLE_TOP

    def table(self, title: str, cols: list[str], rows: list[list[str]], widths: list[float]) -> None:
        if not rows:
            return
        ax_w = 0.94 * W
        left = 0.03 * W + ax_w * (0.5 - sum(widths) / 2)
        edges = [left]
        for w in widths:
            edges.append(edges[-1] + w * ax_w)
        cells = [
            [_wrap_cell(self.doc, str(t), widths[c] * ax_w - 2 * _inset(widths[c] * ax_w), r == 0) for c, t in enumerate(row)]
            for r, row in enumerate([cols, *rows])
        ]
        heights = [ROW_H + LINE_PITCH * (max(len(c) for c in row) - 1) for row in cells]
        k, first = 1, True
        while k < len(cells):
            # under the table before (with its own title) when its header and first row fit there
            fresh = not first or self.y + 2.0 * ROW_H + heights[0] + heights[1] > TABLE_BOTTOM
            ys = [TABLE_TOP if fresh else self.y + 2.0 * ROW_H]
            ys.append(ys[0] + heights[0])
            m = k
            while m < len(cells) and (ys[-1] + heights[m] <= TABLE_BOTTOM or m == k):
                ys.append(ys[-1] + heights[m])
                m += 1
            head = f"{title}{'' if first else ' (continued)'}, rows {k}-{m - 1} of {len(rows)}"
            if fresh:
                self.new_page(head, first)
            else:
                self.doc.text(0.04, 1.0 - (self.y + 1.0 * ROW_H) / H, f"{self.plan.ship}: {head}", 10, bold=True)
            self._draw(edges, [cells[0], *cells[k:m]], ys, widths, ax_w)
            self.y, k, first = ys[-1], m, False

    def _draw(self, edges: list[float], cells: list[list[list[str]]], ys: list[float], widths: list[float], ax_w: float) -> None:
        pdf = self.doc.pdf
        pdf.set_fill_color(232, 232, 232)
        pdf.rect(edges[0], ys[0], edges[-1] - edges[0], ys[1] - ys[0], style="F")
        pdf.set_draw_color(0, 0, 0)
        pdf.set_line_width(1.0)
        for y in ys:
            pdf.line(edges[0] - 0.5, y, edges[-1] + 0.5, y)  # projecting caps, as matplotlib's grid
        for x in edges:
            pdf.line(x, ys[0] - 0.5, x, ys[-1] + 0.5)
        pdf.set_text_color(0, 0, 0)
        for r, row in enumerate(cells):
            pdf.set_font(FONT, "B" if r == 0 else "", TABLE_FS)
            n = max(len(c) for c in row)
            for c, lines in enumerate(row):
                for i, text in enumerate(lines):
                    # one-line rows centred as before; a wrapped row's lines from the top of its cell
                    base = ys[r] + 0.5 * ROW_H + 0.5 * ASCENT * TABLE_FS - 0.08 * TABLE_FS + LINE_PITCH * i
                    if n == 1:
                        base = ys[r] + 0.5 * (ys[r + 1] - ys[r]) + 0.5 * ASCENT * TABLE_FS - 0.08 * TABLE_FS
                    pdf.text(edges[c] + _inset(widths[c] * ax_w), base, text)


def _detail_pages(doc: _Card, plan: Plan, pages: list[list[tuple[str, dict]]], first: int) -> None:
    for n, lines in enumerate(pages):
        doc.page()
        doc.text(0.05, 0.975, f"{plan.ship}: orders per step in sailing order (page {first + n})", 10, colour=GREY)
        for i, (text, style) in enumerate(lines):
            if text:
                size, bold = style.get("fontsize", 8.5), style.get("fontweight") == "bold"
                y = 0.95 - i * 0.0148
                doc.text(0.05, y, text, size, bold=bold, colour=RED if style.get("color") == "#a00000" else (0, 0, 0))
                if style.get("code"):  # the design's code in small print after the name
                    doc.pdf.set_font(FONT, "B" if bold else "", size)
                    x = 0.05 + (doc.pdf.get_string_width(text) + 0.6 * size) / W
                    doc.text(x, y - 0.002, style["code"], 7.0, colour=GREY)


_SPARE: list[_Card] = []  # an empty document made ahead (prepare_document), used by the next card


def prepare_document() -> None:
    """Make the next card's empty document now (reading the two TrueType fonts is most of its
    cost): ``plan-trial``'s drawer does it while the plan is still being made, and the process
    that writes the card, forked from it, starts from it."""
    if not _SPARE:
        _SPARE.append(_Card())


def card_pdf_bytes(plan: Plan, t0: datetime, sea_map: Any, vessel: str) -> bytes:
    """The card's pages (page 1, the tables, the orders per step, the states) as PDF bytes;
    ``sea_map``: the plan's chart (:func:`maps.export.chart.plan_chart`)."""
    doc = _SPARE.pop() if _SPARE else _Card()  # a prepared document is a new one: same bytes
    sheets = step_sheets(plan, t0, sea_map)
    _page1(doc, plan, t0, sea_map, vessel)
    tables = _Tables(doc, plan, 2)
    tables.table(f"steps in sailing order ({STEPS_NOTE_PDF})", TABLE_COLS, _table_rows(sheets), TABLE_WIDTHS)
    tables.table("experiment design", DESIGN_COLS, design_rows(plan)[1], [0.55, 0.15, 0.15, 0.15])
    _detail_pages(doc, plan, detail_pages(sheets), tables.page_no + 1)
    draw_states_page(doc.pdf, FONT, plan)
    return _without_date(bytes(doc.pdf.output()))
