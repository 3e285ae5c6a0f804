"""Which files in an export's destination an export may replace: only those it wrote itself.

``export --format all --out DIR`` writes eight files of fixed names (``<ship>-trial.gpx``, ...);
a file of such a name the user wrote by hand (a ``trial.gpx`` edited in a route planner) must not
be replaced without being asked, as :func:`primitives.io.check_replaceable_dir` refuses to replace
a directory holding files shiptrial did not write. Each export records the files it published,
with their SHA-256, in :data:`MANIFEST` in the destination; an existing file may be replaced when
the manifest lists it with its present digest (written by an export, unchanged since), or when the
destination is a plan-trial output directory (its marker file) and the manifest does not list it:
plan-trial writes its exports itself and replaces that directory whole, so its files count as
shiptrial's, as :func:`primitives.io.check_replaceable_dir` counts them, also after an export of
another format into that directory. Anything else is refused,
naming the file, unless the caller passes ``replace`` (``--force``). Files of other names are never
touched.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path

from maps.export._common import ExportError
from primitives.io import OUTPUT_MARKER, atomic_write_text

MANIFEST = ".shiptrial-exported"  # not ".shiptrial-export.*": that prefix names the staging directories


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _recorded(out_dir: Path) -> dict[str, str] | None:
    """The manifest's {name: sha256}, or None without a readable one."""
    try:
        doc = json.loads((out_dir / MANIFEST).read_text(encoding="utf-8"))
        files = doc["files"]
        return {str(k): str(v) for k, v in files.items()} if isinstance(files, dict) else None
    except (OSError, ValueError, KeyError, TypeError):
        return None


def check_replaceable(out_dir: str | Path, names: Iterable[str], replace: bool = False) -> None:
    """Refuse, before any work, to replace a file in ``out_dir`` of one of ``names`` that no export
    wrote there or that changed since (``replace``: the user asked to replace them)."""
    out_dir = Path(out_dir)
    if replace or not out_dir.is_dir():
        return
    recorded = _recorded(out_dir) or {}
    plan_trial = (out_dir / OUTPUT_MARKER).is_file()
    for name in names:
        path = out_dir / name
        if not path.is_file():
            continue  # absent (written new) or a directory (refused by the publishing, naming it)
        known = recorded.get(name)
        if known is None and plan_trial:
            continue  # a plan-trial directory's file no export replaced yet: plan-trial wrote it
        if known == _digest(path):
            continue
        why = "was changed after an export wrote it" if known else "was not written by an export"
        raise ExportError(
            f"{path}: exists and {why}; move it, choose another --out, or pass --force to replace it "
            "(files of other names are never touched)"
        )


def record_written(out_dir: str | Path, paths: Iterable[str | Path]) -> None:
    """Add the files just published in ``out_dir`` to its manifest (their present digests)."""
    out_dir = Path(out_dir)
    files = _recorded(out_dir) or {}
    for p in paths:
        path = out_dir / Path(p).name
        if path.is_file():
            files[path.name] = _digest(path)
    doc = {"written_by": "shiptrial export: the files it may replace (SHA-256 of each as written)", "files": files}
    atomic_write_text(out_dir / MANIFEST, json.dumps(doc, indent=1, sort_keys=True) + "\n")
