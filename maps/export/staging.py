"""A set of export files written all-or-nothing: never some of them left behind by a failed writer.

Each writer already writes its own file atomically; a set of files (every format, or a card's
HTML and PDF) needs more: they are written under their final names into a hidden temporary
directory inside the destination (the same file system, so a rename moves them) and renamed into
place only once every writer has succeeded. On an error the temporary directory goes and the
destination is left as it was, files of the same names included.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from maps.export._common import ExportError


@contextmanager
def staged_outputs(out_dir: str | Path) -> Iterator[Path]:
    """Yield a temporary directory in ``out_dir`` to write files into under their final names;
    on success move them all into ``out_dir`` (replacing files of the same names), on any error
    remove them and the directories this call created."""
    out_dir = Path(out_dir)
    created = [d for d in (out_dir, *out_dir.parents) if not d.exists()]
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".shiptrial-export.", dir=out_dir))
    try:
        (tmp / "new").mkdir()
        yield tmp / "new"
        _publish(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        for d in created:  # innermost first; only while empty
            try:
                d.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(tmp, ignore_errors=True)


def _publish(tmp: Path, out_dir: Path) -> None:
    """Rename every file of ``tmp/new`` into ``out_dir``; a rename that fails puts back what the
    earlier ones replaced (kept in ``tmp/old`` meanwhile)."""
    new, old = tmp / "new", tmp / "old"
    names = sorted(p.name for p in new.iterdir())
    for name in names:
        if (out_dir / name).is_dir():
            raise ExportError(f"{out_dir / name}: is a directory, where the export writes a file; move it or choose another output")
    old.mkdir()
    done: list[str] = []
    try:
        for name in names:
            if os.path.lexists(out_dir / name):
                os.replace(out_dir / name, old / name)
            done.append(name)
            os.replace(new / name, out_dir / name)
    except BaseException:
        for name in reversed(done):
            if os.path.lexists(old / name):
                os.replace(old / name, out_dir / name)
            elif not os.path.lexists(new / name):  # it was moved in: there was no file of that name before
                os.unlink(out_dir / name)
        raise
