"""The field readers every table of a ship profile document is read with (:mod:`primitives.profile_document`):
a required field of a given type, a per-DOF table of lists, and a ship name that names files. Each refuses a bad field
in one line naming the file, the field and what to give."""

from __future__ import annotations

from typing import Any

from primitives.ship import DOFS, ProfileError
from primitives.validate import check_table_keys


def check_file_stem(name: str, what: str, err: type[Exception]) -> None:
    """A ship's name names the files written for it (``<name>-trial.gpx``, the plan cache's entries): text that
    stays one file name in the output directory, never a path out of it."""
    if not name.strip() or name.strip(".") == "" or any(c in name for c in "/\\") or any(ord(c) < 32 for c in name):
        raise err(
            f"{what} {name!r} names the files written for the ship: give a plain name (no '/', '\\', control "
            "characters; not empty, '.' or '..'), e.g. 'my-ship'"
        )


def need(d: dict, key: str, src: str, kind: type | tuple[type, ...], hint: str) -> Any:
    if key not in d:
        raise ProfileError(f"{src}: missing field '{key}' ({hint})")
    val = d[key]
    if not isinstance(val, kind) or isinstance(val, bool):
        raise ProfileError(f"{src}: field '{key}' must be {hint}, got {val!r}")
    return val


def per_dof(
    d: dict,
    key: str,
    src: str,
    item: type,
    hint: str,
    dofs: tuple[str, ...] = DOFS,
    table_of: tuple[str, str] | None = None,
    accept: tuple[str, ...] | None = None,
) -> tuple[tuple, ...]:
    """The lists of a per-DOF table; ``table_of`` (file, table name) refuses keys other than
    ``accept`` (default the DOFs)."""
    table = need(d, key, src, dict, f"a table with {', '.join(dofs)} lists")
    if table_of is not None:
        check_table_keys(table, accept or dofs, table_of[0], f"[{table_of[1]}]", ProfileError)
    out = []
    for dof in dofs:
        vals = need(table, dof, f"{src} [{key}]", list, hint)
        for v in vals:
            if not isinstance(v, item) or isinstance(v, bool):
                raise ProfileError(f"{src}: field '{key}.{dof}' must hold only {hint}, got {v!r}")
        out.append(tuple(float(v) if item is not str else v for v in vals))
    return tuple(out)
