"""Typer's coercion of plain option values without importing pydantic.

typer (0.2x) converts every command-line value through a pydantic ``TypeAdapter`` built on first
use; importing pydantic and building the adapters cost about 0.35 s CPU of every command (measured
on ``shiptrial detect``, a third of it; stop 49, docs/detect-accuracy.md). The project's options are
mostly ``str``, ``int``, ``float`` and ``Path`` (and lists of them) without constraints, which need
no schema: for those, a value in a form both agree on is converted here (``"0.02"`` -> 0.02,
``"64"`` -> 64, ``"run.csv"`` -> ``Path("run.csv")``) and anything else (a malformed number, an
unreadable path, any other type or constraint) goes to typer's own adapter, built then, so its
values and error messages are typer's (tests/test_cli_plainparams.py compares both on every
parameter of the app). Without typer's internals (another typer version) nothing is changed.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any, get_args, get_origin

_INT = re.compile(r"-?[0-9]{1,18}")
_FLOAT = re.compile(r"-?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]{1,3})?")
_PATH_DEFAULTS = {
    "exists": False,
    "file_okay": True,
    "dir_okay": True,
    "writable": False,
    "resolve_path": False,
    "allow_dash": False,
    "path_type": None,
}
_FALLBACK = object()  # "not a form this module converts": typer's adapter decides


def install() -> None:
    """Route typer's plain parameters through :func:`plain_runtime_param` (a no-op on other typer versions)."""
    try:
        from typer import _coercion, core
    except ImportError:  # pragma: no cover - another typer
        return
    original = getattr(core, "build_runtime_param", None)
    if original is None or getattr(original, "_plain", False) or not hasattr(_coercion, "RuntimeParam"):
        return

    def build(descriptor: Any) -> Any:
        return plain_runtime_param(descriptor, original) or original(descriptor)

    build._plain = True  # type: ignore[attr-defined]
    core.build_runtime_param = build


def plain_runtime_param(descriptor: Any, original: Any) -> Any:
    """A typer ``RuntimeParam`` converting ``descriptor``'s plain values, or None when it is not plain."""
    from typer._coercion import RuntimeParam

    conv = converter(descriptor.annotation, descriptor.parameter_info)
    if conv is None or descriptor.file_annotation is not None:
        return None

    class Plain(RuntimeParam):
        def _coerce_value(self, value: Any, param: Any, ctx: Any) -> Any:
            out = conv(value)
            if out is _FALLBACK:  # typer's own conversion and error message, pydantic loaded only now
                return original(descriptor)._coerce_value(value, param=param, ctx=ctx)
            return out

    return Plain(parameter_info=descriptor.parameter_info, annotation=descriptor.annotation)


def converter(annotation: Any, info: Any) -> Any:
    """The conversion of one value of ``annotation`` (lists of one: element by element, into a list as
    typer returns), or None when the annotation or its options are not plain."""
    if getattr(info, "parser", None) is not None:
        return None
    if get_origin(annotation) is list:
        args = get_args(annotation)
        leaf = converter(args[0], info) if len(args) == 1 else None
        if leaf is None:
            return None

        def each(value: Any) -> Any:
            items = value if isinstance(value, (list, tuple)) else [value]
            out = [leaf(v) for v in items]
            return _FALLBACK if any(v is _FALLBACK for v in out) else out

        return each
    if annotation is str:
        return lambda v: v if type(v) is str else _FALLBACK
    if annotation is bool:  # a flag's value is a bool already; a string ("yes", "0") is typer's to read
        return lambda v: v if type(v) is bool else _FALLBACK
    if annotation in (int, float):
        if any(getattr(info, k, None) is not None for k in ("min", "max")):
            return None
        return _to_int if annotation is int else _to_float
    if annotation is Path and all(getattr(info, k, d) == d for k, d in _PATH_DEFAULTS.items()):
        return _to_path
    return None


def _to_int(v: Any) -> Any:
    if type(v) is int:
        return v
    return int(v) if type(v) is str and _INT.fullmatch(v) else _FALLBACK


def _to_float(v: Any) -> Any:
    if type(v) is float:
        return v if math.isfinite(v) else _FALLBACK
    if type(v) is int:
        return float(v)
    if type(v) is str and _FLOAT.fullmatch(v):
        x = float(v)
        return x if math.isfinite(x) else _FALLBACK
    return _FALLBACK


def _to_path(v: Any) -> Any:
    """``Path(v)``; typer's checks with default options: an existing path must be readable."""
    if type(v) is not str and not isinstance(v, Path):
        return _FALLBACK
    p = v if isinstance(v, Path) else Path(v)
    if os.path.exists(p) and not os.access(p, os.R_OK):
        return _FALLBACK
    return p
