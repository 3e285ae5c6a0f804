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

import fcntl
import os
import re
import shutil
import stat
import tempfile
import time
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
    remove_stale(out_dir)
    tmp = Path(tempfile.mkdtemp(prefix=PREFIX, dir=out_dir))
    try:
        owner = _own(tmp)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    try:
        (tmp / "new").mkdir()
        yield tmp / "new"
        _publish(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        os.close(owner)
        for d in created:  # innermost first; only while empty
            try:
                d.rmdir()
            except OSError:
                break
        raise
    shutil.rmtree(tmp, ignore_errors=True)
    os.close(owner)


PREFIX = ".shiptrial-export."
OWNER = ".owner"  # inside a staging directory: names its creator, locked while the export runs
OWNER_TEXT = b"shiptrial export staging directory\n"
# A staging directory of a version before the owner file (no lock to ask) is stale once nothing in
# it has changed for a day: its export wrote a file every few seconds while it ran.
OLD_STALE_S = 86400.0
_MKDTEMP_NAME = re.compile(re.escape(PREFIX) + r"[a-z0-9_]{8}")  # tempfile.mkdtemp's 8 random characters
# What an export writes into new/: its formats, the card's PDF, the plots, and (hidden) the atomic writers' temporaries
_EXPORT_SUFFIXES = (".geojson", ".gpx", ".rtz", ".csv", ".html", ".pdf", ".png")


def _own(tmp: Path) -> int:
    """Create and lock the owner file of a staging directory; the open descriptor holds the lock.
    The text is written only once the lock is held, so a file with the text is never unlocked
    while its export runs."""
    fd = os.open(tmp / OWNER, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.write(fd, OWNER_TEXT)
    return fd


def _process_start() -> float:
    """Wall-clock time this process started, to 10 ms (Linux: its start in clock ticks since boot
    from /proc, against the boot clock now), else when this module was imported."""
    try:
        ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        return time.time() - (time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return _IMPORTED


_IMPORTED = time.time()


def remove_stale(out_dir: Path) -> list[Path]:
    """Remove the staging directories a killed export left in ``out_dir``: a hidden
    ``.shiptrial-export.*`` directory (not a link) whose owner file holds shiptrial's text, was
    written before this process started, and is not locked by a running export. A destination
    file its publishing had moved aside (``old/``) is put back when its name is free again; while
    such a file cannot go back, the directory stays. A directory without an owner file (an earlier
    version's) goes only when :func:`_old_version_stale` proves it one and stale. Returns the
    directories removed."""
    removed = []
    started = _process_start()
    for d in sorted(out_dir.glob(PREFIX + "*")):
        try:
            if d.is_symlink() or not d.is_dir():
                continue
            if not os.path.lexists(d / OWNER):
                if _old_version_stale(d) and _put_back(d / "old", out_dir):
                    shutil.rmtree(d, ignore_errors=True)
                    removed.append(d)
                continue
            fd = os.open(d / OWNER, os.O_RDONLY | os.O_NOFOLLOW)
        except OSError:
            continue  # an owner file this process cannot open (a link, another user's): not ours to judge
        try:
            text = os.read(fd, 256)
            if os.fstat(fd).st_mtime >= started or text not in (OWNER_TEXT, b""):
                continue
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                continue  # an export is running in it
            if not {e.name for e in d.iterdir()} <= {OWNER, "new", "old"}:
                continue  # something else was put in it: not all of it is ours to delete
            if not text and not _old_version_stale(d, owner=True):
                continue  # an owner file without its text (killed between creating and writing it): judged as an old one
            if _put_back(d / "old", out_dir):
                shutil.rmtree(d, ignore_errors=True)
                removed.append(d)
        except OSError:
            continue  # never let another run's leftovers fail this export
        finally:
            os.close(fd)
    return removed


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
