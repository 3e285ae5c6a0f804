"""Stop 62: which files an export may replace, without a record beside a single file.

Stop 61 recorded every export's files in ``.shiptrial-exported`` beside them: beside ``--out ~/Desktop/route.gpx``
too, and written after the files, so a failed record write left files the next export refused. Now a file is
known by an export's mark in its own content (maps.export.ownership.is_export_file), a directory export's record
is published with its files, and a re-export hashes each file once."""

from __future__ import annotations

import collections
import os
from pathlib import Path

import pytest

import maps.export.ownership as ownership
from maps.export import FORMATS, export_all, export_plan
from maps.export._common import ExportError
from maps.export._testing import synthetic_plan

START = "2026-06-01T08:00:00Z"


@pytest.fixture(scope="module")
def plan():
    return synthetic_plan("model-ship", ("straight", "zigzag_20_20_p", "turn_s"))


def _snapshot(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in d.iterdir()} if d.exists() else {}


def test_a_single_format_export_leaves_no_record_and_replaces_only_its_own_file(plan, tmp_path):
    """Every format to a file on the user's 'Desktop': no record file beside it, the second export replaces the
    first's file (known by its mark), and a file of the user's of that name (no mark) is refused, untouched."""
    desk = tmp_path / "Desktop"
    desk.mkdir()
    (desk / "notes.txt").write_text("mine")
    for fmt, suffix in FORMATS.items():
        path = desk / f"route{suffix}"
        first = export_plan(plan, fmt, path, start=START)
        assert export_plan(plan, fmt, path, start="2026-06-02T08:00:00Z") == first, fmt
    assert sorted(p.name for p in desk.iterdir()) == sorted(["notes.txt", "route.pdf", *(f"route{s}" for s in FORMATS.values())])
    assert all(ownership.is_export_file(p) for p in desk.glob("route.*"))
    for fmt, suffix in FORMATS.items():
        mine = tmp_path / f"mine{suffix}"
        mine.write_text(f"the user's own {fmt}")
        with pytest.raises(ExportError, match=f"{mine}: exists and was not written by an export.*--force"):
            export_plan(plan, fmt, mine, start=START)
        assert mine.read_text() == f"the user's own {fmt}"
    (tmp_path / "card.pdf").write_text("the user's own pdf")  # the card's PDF beside its HTML
    with pytest.raises(ExportError, match="card.pdf: exists and was not written by an export"):
        export_plan(plan, "card", tmp_path / "card.html", start=START)
    assert not (tmp_path / ownership.MANIFEST).exists() and not (tmp_path / "card.html").exists()


def test_a_failed_record_write_leaves_the_destination_as_it_was_and_the_next_export_runs(plan, tmp_path, monkeypatch):
    """The record written after the files: when it failed (disk full) the files were published without it, and the
    next export refused them as 'not written by an export' until --force. Now it is published with them."""
    out = tmp_path / "exp"
    export_all(plan, out, start=START, plots=False)
    before = _snapshot(out)

    def full(*_a, **_k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ownership, "atomic_write_text", full)
    with pytest.raises(OSError, match="No space"):
        export_all(plan, out, start="2026-06-02T08:00:00Z", plots=False)
    assert _snapshot(out) == before  # all or nothing: the files with their record
    monkeypatch.undo()
    export_all(plan, out, start="2026-06-02T08:00:00Z", plots=False)  # not refused
    assert _snapshot(out) != before


def test_a_re_export_hashes_each_file_once_and_still_sees_an_edit_that_keeps_the_mark(plan, tmp_path, monkeypatch):
    """A re-export of every format read each old file's digest in the check and each new one's in the record (16
    digests for 8 files); now each file once. A hand edit that keeps the export's mark (the GPX's creator) is
    still refused through the record; a file only touched (same bytes, new time) is not."""
    calls: collections.Counter = collections.Counter()
    digest = ownership._digest

    def counted(path):
        calls[Path(path).name] += 1
        return digest(path)

    monkeypatch.setattr(ownership, "_digest", counted)
    out = tmp_path / "exp"
    export_all(plan, out, start=START)
    calls.clear()
    written = export_all(plan, out, start="2026-06-02T08:00:00Z")
    assert sorted(calls) == sorted(p.name for p in written.values()) and set(calls.values()) == {1}, calls
    gpx = written["gpx"]
    os.utime(gpx, ns=(0, 0))  # touched: the digest decides, and it is the export's
    export_plan(plan, "gpx", gpx, start=START)
    gpx.write_text(gpx.read_text().replace("</gpx>", "<!-- a waypoint moved by hand --></gpx>"))
    assert ownership.is_export_file(gpx)
    with pytest.raises(ExportError, match="was changed after an export wrote it"):
        export_all(plan, out, start=START)
