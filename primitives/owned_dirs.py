"""Hidden temporary directories a killed process cannot leave behind for good.

A process killed mid-write (SIGKILL, power loss) cannot remove its temporary directory. Each one
made here carries an owner file that the process holds locked (``flock``, released by the kernel
when the process dies) and that names its kind; the next run into the same place removes those
that are older than its own process and no longer locked (:func:`remove_stale`), and nothing
else: never a directory of a run still going, nor one shiptrial did not make.
"""

from __future__ import annotations

import fcntl
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from pathlib import Path

OWNER = ".owner"  # inside an owned directory: names its creator, locked while the creator runs
# An owner file without its text (killed between creating and writing it) has no kind to read: such a
# directory goes once nothing in it has changed for a day, as a run writes every few seconds.
UNWRITTEN_STALE_S = 86400.0
MKDTEMP_CHARS = r"[a-z0-9_]{8}"  # tempfile.mkdtemp's 8 random characters after the prefix


@contextmanager
def owned_tempdir(parent: str | Path, prefix: str, text: bytes) -> Iterator[Path]:
    """Yield a new hidden directory ``parent/prefix<8 characters>`` whose owner file holds
    ``text`` (the kind of directory) and stays locked until the directory is removed on exit,
    whether the body succeeded or not."""
    tmp = Path(tempfile.mkdtemp(prefix=prefix, dir=parent))
    try:
        fd = own(tmp, text)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    try:
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        os.close(fd)


def own(tmp: Path, text: bytes) -> int:
    """Create and lock the owner file of ``tmp``; the open descriptor holds the lock. The text is
    written only once the lock is held, so a file with the text is never unlocked while its
    creator runs."""
    fd = os.open(tmp / OWNER, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        os.write(fd, text)
    except BaseException:
        os.close(fd)
        raise
    return fd


def process_start() -> float:
    """Wall-clock time this process started, to 10 ms (Linux: its start in clock ticks since boot
    from /proc, against the boot clock now), else when this module was imported."""
    try:
        ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        return time.time() - (time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return _IMPORTED


_IMPORTED = time.time()


def _put_back_nothing(d: Path) -> bool:
    return True


def unwritten_owner_stale(d: Path, owner: bool) -> bool:
    """Whether ``d`` is a directory killed between creating its owner file and writing the text
    (``owner``: the file is there, empty): nothing else in it, this user's, unchanged for
    :data:`UNWRITTEN_STALE_S`. A directory without an owner file is never judged stale here."""
    if not owner or {e.name for e in d.iterdir()} != {OWNER}:
        return False
    st, fs = d.lstat(), (d / OWNER).lstat()
    return st.st_uid == os.geteuid() and time.time() - max(st.st_mtime, fs.st_mtime) > UNWRITTEN_STALE_S


def remove_stale(
    parent: str | Path,
    prefix: str,
    text: bytes,
    *,
    contents: Collection[str],
    put_back: Callable[[Path], bool] = _put_back_nothing,
    legacy: Callable[[Path, bool], bool] = unwritten_owner_stale,
) -> list[Path]:
    """Remove the directories killed runs left in ``parent``: named ``prefix`` and mkdtemp's 8
    characters, not a link, whose owner file holds ``text``, was written before this process
    started and is not locked by a running process, and that hold nothing but the owner file and
    entries named in ``contents``. ``put_back(d)`` restores what the killed run had moved aside
    into ``d`` and says whether ``d`` may go (False keeps it). A directory without an owner file,
    or with an empty one, goes only when ``legacy(d, owner_file_exists)`` proves it stale.
    Returns the directories removed."""
    parent = Path(parent)
    started = process_start()
    named = re.compile(re.escape(prefix) + MKDTEMP_CHARS)
    try:
        candidates = sorted(p for p in parent.iterdir() if named.fullmatch(p.name))
    except OSError:
        return []
    return [d for d in candidates if _remove_if_stale(d, text, started, contents, put_back, legacy)]


def _remove_if_stale(
    d: Path,
    text: bytes,
    started: float,
    contents: Collection[str],
    put_back: Callable[[Path], bool],
    legacy: Callable[[Path, bool], bool],
) -> bool:
    """Remove ``d`` if :func:`remove_stale` may (judged with its owner file locked, then put back
    and removed under that lock); whether it was removed. An OSError keeps it: never let another
    run's leftovers fail this run."""
    try:
        if d.is_symlink() or not d.is_dir():
            return False
        if not os.path.lexists(d / OWNER):
            return bool(legacy(d, False)) and _put_back_and_remove(d, put_back)
        fd = os.open(d / OWNER, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return False  # an owner file this process cannot open (a link, another user's): not ours to judge
    try:
        return _owner_says_stale(d, fd, text, started, contents, legacy) and _put_back_and_remove(d, put_back)
    except OSError:
        return False
    finally:
        os.close(fd)


def _owner_says_stale(
    d: Path, fd: int, text: bytes, started: float, contents: Collection[str], legacy: Callable[[Path, bool], bool]
) -> bool:
    """Whether the owner file open at ``fd`` marks ``d`` stale: ``text`` (or empty, then
    ``legacy`` judges), written before this process ``started``, now locked by this process (its
    creator is gone), and ``d`` holding nothing but it and ``contents``."""
    found = os.read(fd, 256)
    if os.fstat(fd).st_mtime >= started or found not in (text, b""):
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False  # its creator is running
    if not {e.name for e in d.iterdir()} <= {OWNER, *contents}:
        return False  # something else was put in it: not all of it is ours to delete
    return bool(found) or bool(legacy(d, True))  # an owner file without its text: judged as one without


def _put_back_and_remove(d: Path, put_back: Callable[[Path], bool]) -> bool:
    """``put_back(d)``, then remove ``d`` unless it said to keep it; whether it was removed."""
    if not put_back(d):
        return False
    shutil.rmtree(d, ignore_errors=True)
    return True
