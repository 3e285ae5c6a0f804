"""Which files in an export's destination an export may replace: only those it wrote itself.

``export --format all --out DIR`` writes eight files of fixed names (``<ship>-trial.gpx``, ...), and
``--format gpx --out FILE`` one file of the user's choosing; a file of such a name the user wrote
(a ``trial.gpx`` from a route planner) must not be replaced without being asked, as
:func:`primitives.io.check_replaceable_dir` refuses to replace a directory holding files shiptrial
did not write. An existing file may be replaced when

- it carries an export's mark in its own content (:func:`is_export_file`: the GPX ``creator``, the
  RTZ extension namespace, the GeoJSON and HTML ``generator``, the CSV schedule's header row, the
  PDF ``/Producer``), so a single file needs no record beside it (stop 62: stop 61's record landed
  on the user's Desktop beside ``--out ~/Desktop/route.gpx``);
- the destination is a plan-trial output directory (its marker file): plan-trial writes its exports
  itself and replaces that directory whole, so its files count as shiptrial's, as
  :func:`primitives.io.check_replaceable_dir` counts them.

A directory export (:func:`maps.export.export_all`) also records its files, with their SHA-256, size
and modification time, in :data:`MANIFEST`: the record is written into the staging directory and
published with the files (:mod:`maps.export.staging`), so the files never exist without it (stop 61
wrote it after them: a failed write left files an export then refused until ``--force``). A file
the record lists must still have its digest (a hand edit keeps the mark: "was changed after an
export wrote it"); its size and time equal to the record's stand for the digest, so a re-export
reads each old file once at most and hashes each new file once. A single-format export records its
file only where a record is kept (a directory export's destination, or a plan-trial directory), never
starting one beside a file of the user's choosing.

Anything else is refused, naming the file, unless the caller passes ``replace`` (``--force``).
Files of other names are never touched.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path

from maps.export._common import HTML_GENERATOR_META, RTZ_EXT_NS, TOOL, ExportError
from primitives.io import OUTPUT_MARKER, atomic_write_text, file_head

MANIFEST = ".shiptrial-exported"  # not ".shiptrial-export.*": that prefix names the staging directories

# An export's mark in its own content, by suffix: bytes in the file's first 4 kB (the PDF's at its end, where
# fpdf writes the document information). PNG plots have none: only a directory export writes them, and records them.
SCHEDULE_HEAD = "time_s,time_from_start,utc,lat,lon,x_north_m,y_east_m,heading_deg,speed_mps,speed_kn,manoeuvre,"
_MARKS = {
    ".gpx": f' creator="{TOOL}"'.encode(),
    ".rtz": f'xmlns:st="{RTZ_EXT_NS}"'.encode(),
    ".geojson": f'{{"type":"FeatureCollection","properties":{{"generator":"{TOOL}",'.encode(),
    ".html": HTML_GENERATOR_META.encode(),
    ".csv": SCHEDULE_HEAD.encode(),  # csv.plan_csv's header row
}
_PDF_MARK, _PDF_TAIL = f"/Producer ({TOOL})".encode(), 1 << 16


def is_export_file(path: Path) -> bool:
    """Whether ``path`` carries an export's mark (:data:`_MARKS`); False for a file that cannot be read."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".pdf":
            with open(path, "rb") as f:
                f.seek(max(0, path.stat().st_size - _PDF_TAIL))
                return _PDF_MARK in f.read()
        mark = _MARKS.get(suffix)
        return mark is not None and mark in file_head(path)
    except OSError:
        return False


def _stamp(path: Path) -> dict[str, int]:
    st = path.stat()
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns}


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def read_record(out_dir: str | Path) -> dict[str, dict] | None:
    """The record's {name: {"sha256", "size", "mtime_ns"}} (stop 61's {name: sha256} read as such), or None
    without a readable one."""
    try:
        files = json.loads((Path(out_dir) / MANIFEST).read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(files, dict):
        return None
    return {str(k): v if isinstance(v, dict) else {"sha256": str(v)} for k, v in files.items()}


def _unchanged(path: Path, entry: dict) -> bool:
    """The file is as the record has it: the same size and time (as written and renamed), else the same digest."""
    if all(entry.get(k) == v for k, v in _stamp(path).items()):
        return True
    return entry.get("sha256") == _digest(path)


def check_replaceable(out_dir: str | Path, names: Iterable[str], replace: bool = False) -> dict[str, dict] | None:
    """Refuse, before any work, to replace a file in ``out_dir`` of one of ``names`` that is not an export's or
    that changed since its export recorded it (``replace``: the user asked to replace them). Returns the record
    kept there, for :func:`write_record`: the one read, empty in a plan-trial directory without one (shiptrial's
    directory: an export into it is recorded), else None (no record is started beside a single file)."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return None
    plan_trial = (out_dir / OUTPUT_MARKER).is_file()
    recorded = read_record(out_dir)
    recorded = {} if recorded is None and plan_trial else recorded
    if replace:
        return recorded
    for name in names:
        path = out_dir / name
        if not path.is_file():
            continue  # absent (written new) or a directory (refused by the publishing, naming it)
        entry = (recorded or {}).get(name)
        if entry is not None:
            if _unchanged(path, entry):
                continue
            why = "was changed after an export wrote it"
        elif plan_trial or is_export_file(path):
            continue  # plan-trial's own file, or one marked by an export
        else:
            why = "was not written by an export"
        raise ExportError(
            f"{path}: exists and {why}; move it, choose another --out, or pass --force to replace it "
            "(files of other names are never touched)"
        )
    return recorded


def write_record(staged: Path, recorded: dict[str, dict] | None, written: Iterable[Path]) -> None:
    """The record of ``staged`` (the staging directory, published with it): ``recorded`` (the destination's, see
    :func:`check_replaceable`; None: none is kept there) with the files just written, each hashed once."""
    if recorded is None:
        return
    files = dict(recorded)
    for path in written:
        files[path.name] = {"sha256": _digest(path), **_stamp(path)}  # os.replace keeps size and time
    if files:
        doc = {"written_by": "shiptrial export: the files it may replace (SHA-256, size, time of each as written)"}
        atomic_write_text(staged / MANIFEST, json.dumps({**doc, "files": files}, indent=1, sort_keys=True) + "\n")
