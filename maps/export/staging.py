"""A set of export files written all-or-nothing: never some of them left behind by a failed writer.

Each writer already writes its own file atomically; a set of files (every format, or a card's
HTML and PDF) needs more: they are written under their final names into a hidden temporary
directory inside the destination (the same file system, so a rename moves them) and renamed into
place only once every writer has succeeded. On an error the temporary directory goes and the
destination is left as it was, files of the same names included.

A process killed mid-export (SIGKILL, power loss) cannot clean up: its staging directory stays.
Each one carries an owner file that its export holds locked (``flock``, released by the kernel
when the process dies); the next export into the destination removes those that are older than
its own process and no longer locked (:func:`remove_stale`), and nothing else. The versions
before the owner file left directories without one; those are removed only when everything in
them is what such an export wrote and nothing in them has changed for :data:`OLD_STALE_S`.
"""

from __future__ import annotations

import os
import re
import stat
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from maps.export._common import ExportError
from primitives import owned_dirs
from primitives.io import staged_write_error
from primitives.owned_dirs import OWNER, owned_tempdir


@contextmanager
def staged_outputs(out_dir: str | Path) -> Iterator[Path]:
    """Yield a temporary directory in ``out_dir`` to write files into under their final names;
    on success move them all into ``out_dir`` (replacing files of the same names), on any error
    remove them and the directories this call created."""
    out_dir = Path(out_dir)
    created = [d for d in (out_dir, *out_dir.parents) if not d.exists()]
    out_dir.mkdir(parents=True, exist_ok=True)
    remove_stale(out_dir)
    try:
        with owned_tempdir(out_dir, PREFIX, OWNER_TEXT) as tmp:
            (tmp / "new").mkdir()
            try:
                yield tmp / "new"
                _publish(tmp, out_dir)
            except OSError as exc:  # named as the file in out_dir it was for, not the staging file
                raise (staged_write_error(exc, tmp / "new", out_dir) or exc) from exc
    except BaseException:
        for d in created:  # innermost first; only while empty
            try:
                d.rmdir()
            except OSError:
                break
        raise


PREFIX = ".shiptrial-export."
OWNER_TEXT = b"shiptrial export staging directory\n"
# A staging directory of a version before the owner file (no lock to ask) is stale once nothing in
# it has changed for a day: its export wrote a file every few seconds while it ran.
OLD_STALE_S = 86400.0
_MKDTEMP_NAME = re.compile(re.escape(PREFIX) + owned_dirs.MKDTEMP_CHARS)
# What an export writes into new/: its formats, the card's PDF, the plots, and (hidden) the atomic writers' temporaries
_EXPORT_SUFFIXES = (".geojson", ".gpx", ".rtz", ".csv", ".html", ".pdf", ".png")


def remove_stale(out_dir: Path) -> list[Path]:
    """Remove the staging directories a killed export left in ``out_dir``
    (:func:`primitives.owned_dirs.remove_stale`: owner file with shiptrial's text, written before
    this process started, not locked by a running export; nothing but ``new/`` and ``old/`` in
    it). A destination file its publishing had moved aside (``old/``) is put back when its name
    is free again; while such a file cannot go back, the directory stays. A directory without an
    owner file (an earlier version's), or with an empty one, goes only when
    :func:`_old_version_stale` proves it one and stale. Returns the directories removed."""
    return owned_dirs.remove_stale(
        out_dir,
        PREFIX,
        OWNER_TEXT,
        contents=("new", "old"),
        put_back=lambda d: _put_back(d / "old", out_dir),
        legacy=_old_version_stale,
    )


def _old_version_stale(d: Path, owner: bool = False) -> bool:
    """Whether ``d``, a staging directory without an owner file (``owner``: with an empty one), is
    provably one an earlier version's export left and stale: named by ``tempfile.mkdtemp``, this
    user's, holding only ``new/`` (regular files with an export's suffix, or hidden temporaries)
    and ``old/`` (the destination's files it moved aside: regular files, put back before it goes),
    and nothing in it changed for :data:`OLD_STALE_S`. Anything else (a look-alike, a link, a
    sub-directory, another file, a recent change: an export just begun) keeps it."""
    if not _MKDTEMP_NAME.fullmatch(d.name):
        return False
    st = d.lstat()
    if st.st_uid != os.geteuid():
        return False
    newest = st.st_mtime
    for sub in d.iterdir():
        if owner and sub.name == OWNER:
            newest = max(newest, sub.lstat().st_mtime)
            continue
        if sub.name not in ("new", "old") or sub.is_symlink() or not sub.is_dir():
            return False
        newest = max(newest, sub.lstat().st_mtime)
        for f in sub.iterdir():
            fs = f.lstat()
            if not stat.S_ISREG(fs.st_mode):
                return False
            if sub.name == "new" and not (f.name.startswith(".") or f.suffix.lower() in _EXPORT_SUFFIXES):
                return False
            newest = max(newest, fs.st_mtime)
    return time.time() - newest > OLD_STALE_S


def _put_back(old: Path, out_dir: Path) -> bool:
    """Move the files a killed publish had moved aside back to free names; True when none is left."""
    if not old.is_dir() or old.is_symlink():
        return not old.exists()
    left = False
    for f in old.iterdir():
        if os.path.lexists(out_dir / f.name):
            left = True  # the export's new file took its place: keep the old one, it is the user's
        else:
            os.replace(f, out_dir / f.name)
    return not left


def _publish(tmp: Path, out_dir: Path) -> None:
    """Rename every file of ``tmp/new`` into ``out_dir``; a rename that fails puts back what the
    earlier ones replaced (kept in ``tmp/old`` meanwhile)."""
    new, old = tmp / "new", tmp / "old"
    names = sorted(p.name for p in new.iterdir())
    for name in names:
        if (out_dir / name).is_dir():
            raise ExportError(
                f"{out_dir / name}: is a directory, where the export writes a file; move it or choose another output"
            )
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
