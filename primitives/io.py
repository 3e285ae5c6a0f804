"""Output helpers shared by every package: atomic writes and JSON encoding (I/O at the edges)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

_PLAIN_NUMBERS = frozenset({int, float, bool})


def to_jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        kinds = set(map(type, obj))
        # a list of plain finite numbers (a plan's samples, after tolist()) is already JSON: no call per element
        if kinds <= _PLAIN_NUMBERS and (float not in kinds or all(map(math.isfinite, obj))):
            return list(obj)
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        # whole arrays of numbers are already Python numbers after tolist(): no walk element by element
        # (a plan's tracks are tens of thousands of them); non-finite floats still become None
        if obj.dtype.kind in "iub" or (obj.dtype.kind == "f" and np.isfinite(obj).all()):
            return obj.tolist()
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if np.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def dumps(obj: Any) -> str:
    return json.dumps(to_jsonable(obj), indent=2)


def user_cache_dir(env_var: str, leaf: str) -> Path | None:
    """A cache directory of shiptrial's: ``$<env_var>`` if set (None when set to an empty string: no
    cache), else ``$XDG_CACHE_HOME/shiptrial/<leaf>`` (``~/.cache/shiptrial/<leaf>``); None when no home
    directory is known (no cache rather than a ``./~`` directory or a traceback)."""
    given = os.environ.get(env_var)
    if given is not None:
        try:
            return Path(given).expanduser() if given.strip() else None
        except RuntimeError:  # "~user/..." naming no user, or "~" with no home
            return None
    base = os.environ.get("XDG_CACHE_HOME")
    if not base:
        home = os.path.expanduser("~")
        if home == "~":
            return None
        base = os.path.join(home, ".cache")
    return Path(base) / "shiptrial" / leaf


def newest_first(directory: Path, suffix: str) -> list[tuple[Path, os.stat_result]]:
    """A cache's entries ending in ``suffix`` with their stat, most recently used (written or read) first; one
    removed by another process meanwhile is left out."""
    out = []
    for p in directory.glob(f"*{suffix}"):
        try:
            out.append((p, p.stat()))
        except FileNotFoundError:
            continue
    return sorted(out, key=lambda ps: ps[1].st_mtime_ns, reverse=True)


def prune_to_budget(directory: Path, suffix: str, budget: int) -> None:
    """Keep a cache's most recently used ``*suffix`` entries within ``budget`` bytes, the newest whatever its
    size (the entry just written)."""
    total = 0
    for i, (p, st) in enumerate(newest_first(directory, suffix)):
        total += st.st_size
        if i and total > budget:
            p.unlink(missing_ok=True)


def remove_stale_temporaries(directory: Path, suffixes: tuple[str, ...], age_s: float = 3600.0) -> None:
    """Remove the temporary files :func:`atomic_write_bytes` left for entries ending in ``suffixes``
    (``.NAME.XXXX``) when a writer was killed outright (SIGKILL, power loss): one ``age_s`` old (an hour) is no
    write in progress; one renamed into place meanwhile by its writer is skipped."""
    for tmp in [t for suffix in suffixes for t in directory.glob(f".*{suffix}.*")]:
        try:
            stale = time.time() - tmp.stat().st_mtime > age_s
        except FileNotFoundError:
            continue
        if stale:
            tmp.unlink(missing_ok=True)


def hash_sources(h: Any, root: Path, packages: Sequence[str], suffixes: Sequence[str] = (".py",)) -> Any:
    """``h`` (a hashlib object) updated with every file of ``packages`` under ``root`` whose suffix is in
    ``suffixes``, path and bytes, in sorted order, ``__pycache__`` left out: a cache's digest of the code
    its entries were computed with. Only regular files count (a directory or a dangling link whose name ends
    in a listed suffix is passed over, not read)."""
    for pkg in packages:
        for p in sorted((root / pkg).rglob("*")):
            if p.suffix in suffixes and "__pycache__" not in p.parts and p.is_file():
                h.update(str(p.relative_to(root)).encode() + b"\0" + p.read_bytes() + b"\0")
    return h


class WriteError(OSError):
    """An output that could not be written (a full disk, no permission, a file where a directory should be), its
    ``filename`` the output's path, never the temporary it was being written to; nothing of it is left behind."""


def write_error(exc: OSError, path: str | Path) -> WriteError:
    """``exc`` (the OS's reason) as a :class:`WriteError` naming ``path``."""
    return WriteError(exc.errno, exc.strerror or str(exc), str(path))


def staged_write_error(exc: OSError, staging: Path, dest: Path) -> WriteError | None:
    """A write into ``staging`` (a temporary directory published as ``dest``) that failed, as a :class:`WriteError`
    naming the output under ``dest`` (an atomic writer's temporary under the name it was for); None for an error
    about another file (an input read while writing: not a failed write)."""
    name = Path(str(exc.filename)) if exc.filename is not None else None
    if name is None or not (name == staging or staging in name.parents):
        return None
    return write_error(exc, dest / name.relative_to(staging))


def atomic_write_bytes(path: str | Path, data: bytes | Sequence[bytes | memoryview]) -> Path:
    """Write to a temporary file beside ``path`` and rename: never a half-written file. ``data`` may be a
    sequence of buffers, written one after another (a large cache entry is not joined in memory first).
    An OSError (disk full, ...) removes the temporary and is raised as a :class:`WriteError` naming ``path``."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as exc:
        raise write_error(exc, path) from exc
    try:
        with os.fdopen(fd, "wb") as fh:
            for part in [data] if isinstance(data, (bytes, bytearray, memoryview)) else data:
                fh.write(part)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; outputs are handed to crews and colleagues
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):  # the reason to report is the write's, not the clean-up's
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise write_error(exc, path) from exc
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


PNG_LEVEL = 1  # zlib level of figure_png: as RGB, about the size of matplotlib's RGBA at its level 6


def figure_png(fig: Any, dpi: float) -> bytes:
    """``fig`` as PNG bytes at ``dpi``: drawn by matplotlib's ``savefig`` (as raw RGBA, the pixels
    its PNG would hold), encoded here as RGB when every pixel is opaque (a figure on its white
    background: the same picture without an alpha channel to compress) at zlib level
    :data:`PNG_LEVEL`, with the text and resolution matplotlib writes (Software, dpi). Encoding
    matplotlib's RGBA at level 6 was 10-26 % of each of ``plan-trial``'s figures' CPU (py-spy);
    this halves it, the four PNGs 446 kB before, 451 kB after. A figure with a transparent pixel,
    or whose raw size is not its size in inches times ``dpi``, is written by matplotlib as before."""
    import io

    import matplotlib
    import numpy as np
    from PIL import Image, PngImagePlugin

    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=dpi)
    w_in, h_in = fig.get_size_inches()
    w, h = int(w_in * dpi), int(h_in * dpi)  # the Agg canvas's size (FigureCanvasAgg.get_width_height)
    rgba = np.frombuffer(buf.getbuffer(), np.uint8)
    if rgba.size != w * h * 4 or rgba[3::4].min() < 255:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        return buf.getvalue()
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/")
    out = io.BytesIO()
    Image.frombuffer("RGBA", (w, h), rgba, "raw", "RGBA", 0, 1).convert("RGB").save(
        out, format="png", pnginfo=info, dpi=(dpi, dpi), compress_level=PNG_LEVEL
    )
    return out.getvalue()


def atomic_savefig(fig: Any, path: str | Path, **kw: Any) -> Path:
    """Save a matplotlib figure atomically (format from the suffix)."""
    import io

    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", **kw)
    return atomic_write_bytes(path, buf.getvalue())


def check_out_path(path: str | Path, *, kind: str = "directory", option: str = "--out") -> Path:
    """Refuse, before any work, an output path that cannot be written.

    ``kind`` is "directory" (the path must be a directory or not exist, its parent writable) or
    "file" (the path must not be a directory).
    """
    from primitives.errors import UserError

    path = Path(path)
    if kind == "directory" and path.exists() and not path.is_dir():
        raise UserError(f"{option} {path}: is a file, not a directory; give a directory path")
    if kind == "file" and path.is_dir():
        raise UserError(f"{option} {path}: is a directory; give a file path")
    parent = path.parent if str(path.parent) else Path(".")
    probe = parent
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK) or not _can_create(probe):
        raise UserError(f"{option} {path}: {probe} is not a writable directory; choose another {option}")
    return path


def read_input_text(path: str | Path, error: type, what: str, encoding: str = "utf-8") -> str:
    """The text of an input file, or ``error`` with one line saying why not (missing, a directory,
    not text, unreadable); ``what`` names what the file should be ("a sweep TOML file")."""
    path = Path(path)
    try:
        return path.read_text(encoding=encoding)
    except FileNotFoundError:
        raise error(f"{path}: no such file; give {what}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory; give {what}") from None
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a UTF-8 text file (byte {exc.start}); give {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror}); give {what}") from None


def read_record_lines(path: str | Path, error: type, what: str, encoding: str = "utf-8") -> tuple[list[str], str | None]:
    """The lines of a recording file (:func:`read_input_text`'s refusals), and a note when its last row was left out.

    A file cut short (a truncated download, a logger stopped mid-write) ends inside its last row, and a number
    cut short in that row reads as another number ("0.0123" -> "0.01"). Loggers, csv modules and spreadsheets end
    every row with a line break, so a last line without one is read as cut short and left out, with the note saying so. Left out rather
    than refused: the rows before the cut are whole (for a stopped logger, all the data there is), and a complete
    file written without a final line break (``"\\n".join(rows)``) loses one sample, not the run."""
    text = read_input_text(path, error, what, encoding)
    lines = text.splitlines()
    last = lines[-1].strip() if lines else ""
    if len(lines) < 2 or text.endswith(("\n", "\r")) or not last or last.startswith("#"):  # a comment holds no sample
        return lines, None
    return lines[:-1], (
        f"the last line ({len(lines)}: {last[:40]!r}) has no line break at its end: read as cut short (a "
        "truncated download or a logger stopped mid-write) and left out; if the file is complete, end it with a line break"
    )


FIGURE_SUFFIXES = (".png", ".pdf", ".svg")
_FIGURE_READ_MAX = 64 << 20  # a command's figure is well under a megabyte; a larger file is not one


def figure_mark(suffix: str, writer: str) -> bytes | None:
    """The Creator field ``writer`` as each matplotlib backend writes it (``savefig(metadata={"Creator": writer})``):
    the field, not the words anywhere (a user's diagram of a workflow may well say "shiptrial sweep")."""
    marks = {
        ".png": b"tEXtCreator\x00" + writer.encode(),
        ".pdf": b"/Creator (" + writer.encode() + b")",
        ".svg": b"<dc:title>" + writer.encode() + b"</dc:title>",  # within <dc:creator><cc:Agent>
    }
    return marks.get(suffix.lower())


def is_written_figure(path: Path, writer: str) -> bool:
    """A figure saved with Creator metadata ``writer`` (:func:`figure_mark`; a PDF keeps it at the end): how a
    command knows its own plot and replaces it without ``--force``."""
    if path.stat().st_size > _FIGURE_READ_MAX:
        return False
    mark = figure_mark(path.suffix, writer)
    return mark is not None and mark in path.read_bytes()


def check_figure_file(path: str | Path, option: str, writer: str, *, force: bool = False) -> Path:
    """:func:`check_out_file` for a figure ``writer`` saves with its Creator mark: an existing figure is replaced
    only if it carries that mark (:func:`is_written_figure`) or ``force``."""
    return check_out_file(
        path, FIGURE_SUFFIXES, option, "figure", replace=force, ours=lambda p: is_written_figure(p, writer), writer=writer
    )


def check_out_file(
    path: str | Path,
    suffixes: tuple[str, ...],
    option: str,
    what: str,
    *,
    replace: bool = True,
    ours: Callable[[Path], bool] | None = None,
    writer: str = "shiptrial",
) -> Path:
    """An output file whose extension names its format (``what``: "table", "figure") and that can be written.

    ``replace=False`` (no ``--force``): an existing file is refused in one line naming it and ``--force``, unless
    ``ours(path)`` recognises it by its content as a file ``writer`` wrote (a sweep table by its header row, a
    recording by its '# source:' line), as ``export`` replaces only its own files (:mod:`maps.export.ownership`).
    Without ``ours`` any existing file is refused (a profile the user may have edited by hand). By default
    (``replace=True``) the command replaces its output file. ``option`` a plain word ("table", "path"): a library
    writer called from a notebook, whose fix is the keyword (``force=True``), not the command line's ``--force``."""
    from primitives.errors import UserError

    path = Path(path)
    fix = "--force" if option.startswith("-") or option.isupper() else "force=True"  # '--out', 'OUT': the CLI's
    if path.is_dir():  # said as such, not as a missing extension
        raise UserError(f"{option} {path}: is a directory; give a file path ending {' or '.join(suffixes)}")
    if path.suffix.lower() not in suffixes:
        raise UserError(f"{option} {path}: the extension must name the {what} format: {' or '.join(suffixes)}")
    if not replace and os.path.lexists(path):
        if ours is None:
            raise UserError(f"{option} {path}: the file exists; pass {fix} to replace it, or choose another {option}")
        if not _recognised(ours, path):
            raise UserError(
                f"{option} {path}: exists and was not written by {writer}; move it, choose another {option}, "
                f"or pass {fix} to replace it"
            )
    return check_out_path(path, kind="file", option=option)


def _recognised(ours: Callable[[Path], bool], path: Path) -> bool:
    """``ours(path)``, False for a file that cannot be read (a link to nowhere, no permission) or parsed (a JSON
    nested deeper than the parser recurses raises RecursionError, not ValueError): not shown ours."""
    try:
        return path.is_file() and bool(ours(path))
    except (OSError, ValueError, RecursionError):
        return False


def file_head(path: str | Path, size: int = 4096) -> bytes:
    """The first ``size`` bytes of a file (a writer's marker is looked for there, never in the whole file)."""
    with open(path, "rb") as f:
        return f.read(size)


def first_lines(path: str | Path, n: int, size: int = 4096) -> list[str]:
    """The first ``n`` lines of a text file (within its first ``size`` bytes; undecodable bytes replaced)."""
    return file_head(path, size).decode("utf-8", "replace").lstrip("\ufeff").splitlines()[:n]


def _can_create(directory: Path) -> bool:
    """Whether a file can be created there (os.access says yes to root on read-only or virtual file systems)."""
    try:
        with tempfile.TemporaryFile(dir=directory):
            return True
    except OSError:
        return False


OUTPUT_MARKER = ".shiptrial-output"  # written into every directory atomic_output_dir builds


def check_replaceable_dir(path: str | Path, option: str = "--out") -> Path:
    """Refuse to replace an existing directory that holds files shiptrial did not write there.

    :func:`atomic_output_dir` swaps the whole directory, so ``--out .`` or ``--out ~/docs`` would
    otherwise delete the user's files. An empty directory, or one a previous run wrote (it holds
    the marker file), may be replaced.
    """
    from primitives.errors import UserError

    path = check_out_path(path, option=option)
    ours = (OUTPUT_MARKER, "plan.json", "design.json", "diagnosis.json")  # marker, or a result of a run before it
    if path.is_dir() and any(path.iterdir()) and not any((path / n).exists() for n in ours):
        raise UserError(f"{option} {path}: the directory holds files shiptrial did not write; give a new or empty directory")
    return path


OUTPUT_OWNER_TEXT = b"shiptrial output staging directory\n"


@contextmanager
def atomic_output_dir(path: str | Path) -> Iterator[Path]:
    """Build an output directory in a temporary sibling and swap it into place on success.

    Yields the temporary directory to write into. On success the previous contents of ``path``
    (if any) are replaced as a whole; on any exception the temporary directory is removed and
    ``path`` is left exactly as it was: never a mix of an old and a new result.

    The temporary lives in a hidden owned directory beside ``path`` (``new/``, and ``old/`` for
    the previous result while the two swap); a run killed mid-write leaves it, and the next run
    into ``path`` removes it (:func:`primitives.owned_dirs.remove_stale`), after putting back a
    previous result the killed swap had moved aside.
    """
    from primitives.owned_dirs import owned_tempdir, remove_stale

    path = Path(path)
    check_replaceable_dir(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    prefix = f".{path.name}."
    remove_stale(
        path.parent, prefix, OUTPUT_OWNER_TEXT, contents=("new", "old"), put_back=lambda d: _put_back_dir(d / "old", path)
    )
    box: Path | None = None
    try:
        with owned_tempdir(path.parent, prefix, OUTPUT_OWNER_TEXT) as box:
            new, old = box / "new", box / "old"
            new.mkdir()
            (new / OUTPUT_MARKER).write_text("written by shiptrial; the next run into this directory replaces it whole\n")
            yield new
            os.chmod(new, 0o755)  # outputs are handed to crews and colleagues
            try:
                if os.path.lexists(path):
                    os.replace(path, old)
                os.replace(new, path)
            except BaseException:
                _put_back_dir(old, path)
                raise
    except OSError as exc:
        raise _dir_write_error(exc, box, path) from exc


def _dir_write_error(exc: OSError, box: Path | None, path: Path) -> OSError:
    """A failed write of :func:`atomic_output_dir` as a :class:`WriteError` naming the output (``path``, or the
    file under it); an OSError about another file (an input read meanwhile) as it was."""
    if box is None or exc.filename is None or Path(str(exc.filename)) in (path, path.parent):
        return write_error(exc, path)  # the temporary directory could not be made, or the swap failed
    staged = staged_write_error(exc, box / "new", path)
    if staged is None and staged_write_error(exc, box, path) is not None:
        return write_error(exc, path)  # the owner file, the swap's old/
    return exc if staged is None else staged


def _put_back_dir(old: Path, path: Path) -> bool:
    """Move a previous result a swap had moved aside back to ``path`` when that name is free
    (the swap did not finish); True when nothing is left in ``old`` to keep."""
    if not os.path.lexists(old):
        return True
    if old.is_symlink() or not old.is_dir():
        return False
    if not os.path.lexists(path):
        os.replace(old, path)
    return True  # the new result took its place: the previous one is what the run replaced
