"""Plain option values converted without pydantic, for typer 0.2x's option parsing.

typer 0.2x converts every option's value, its default included, through a pydantic ``TypeAdapter``
built for that option the first time it is parsed: ``plan-trial``'s 29 options cost 0.41-0.45 s of
CPU (importing pydantic, 0.14 s, and building 29 adapters) before the command's own work starts,
on every run (stop 46's profile). Most values need no validation at all: an absent option
(None), a default of the option's own type, a string for a ``str`` option, a plain decimal for an
``int`` or ``float`` option, a path for a ``Path`` option.

:func:`install` wraps typer's ``build_runtime_param`` so that each option gets a :class:`Lazy`
converter: it returns those plain values itself (the values pydantic gives for them:
tests/test_optionvalues.py compares the two) and hands every other value to the converter typer
would have built, built then. So a value that is wrong is refused by typer and pydantic
themselves, with their words and exit code. Where typer is not of that shape (an older release
without ``typer._coercion``, a newer one whose converters differ) nothing is installed, and the
options are converted as typer does it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path, PurePath
from typing import Any

_INT = re.compile(r"-?[0-9]{1,15}\Z")  # decimal integers well inside float and int range
_FLOAT = re.compile(r"-?[0-9]{1,15}(\.[0-9]{1,15})?\Z")
_UNCONVERTED = object()


def plain_value(annotation: Any, value: Any) -> Any:
    """``value`` as a ``bool``, ``str``, ``int``, ``float`` or ``Path`` option holds it, when it needs no
    validation (see the module doc); ``_UNCONVERTED`` otherwise."""
    kind = type(value)
    if annotation is bool:
        return value if kind is bool else _UNCONVERTED
    if annotation is str:
        return value if kind is str else _UNCONVERTED
    if annotation is int:
        if kind is int:
            return value
        return int(value) if kind is str and _INT.match(value) else _UNCONVERTED
    if annotation is float:
        if kind is float:
            return value
        return float(value) if kind is str and _FLOAT.match(value) else _UNCONVERTED
    if annotation is Path:
        if isinstance(value, PurePath):
            path = value
        elif kind is str and value and "\0" not in value:
            path = Path(value)
        else:
            return _UNCONVERTED
        try:
            os.stat(path)
        except OSError:
            return path
        return path if os.access(path, os.R_OK) else _UNCONVERTED  # typer refuses an unreadable one, in its words
    return _UNCONVERTED


class Lazy:
    """An option's converter: plain values here, any other the converter typer builds (built once,
    when first needed)."""

    def __init__(self, build: Any, descriptor: Any, annotation: Any, simple: bool) -> None:
        self._build, self._descriptor = build, descriptor
        self.annotation, self._simple = annotation, simple
        self._full: Any = None

    def full(self) -> Any:
        if self._full is None:
            self._full = self._build(self._descriptor)
        return self._full

    def coerce(self, value: Any, *args: Any, **kwargs: Any) -> Any:
        param = kwargs.get("param", args[0] if args else None)
        multiple, nargs = getattr(param, "multiple", None), getattr(param, "nargs", None)
        if isinstance(multiple, bool) and isinstance(nargs, int):
            many = multiple or nargs == -1
            if value is None:  # an absent option: typer's own first step, whatever the type
                return () if many else None
            if self._simple and not many and nargs == 1:
                out = plain_value(self.annotation, value)
                if out is not _UNCONVERTED:
                    return out
        return self.full().coerce(value, *args, **kwargs)

    def __getattr__(self, name: str) -> Any:  # anything else typer asks of its converter
        return getattr(self.full(), name)


def _simple(descriptor: Any) -> bool:
    """An option whose values :func:`plain_value` may convert: a plain ``bool``, ``str``, ``int``,
    ``float`` or ``Path`` with no parser, bounds or path checks of its own."""
    info = getattr(descriptor, "parameter_info", None)
    if info is None or getattr(descriptor, "file_annotation", 1) is not None:
        return False
    if getattr(descriptor, "annotation", None) not in (bool, str, int, float, Path):
        return False
    unset = ("parser", "min", "max", "clamp", "path_type", "click_type")
    if any(getattr(info, k, None) not in (None, False) for k in unset):
        return False
    if descriptor.annotation is Path:  # typer checks a path only when asked to (exists, file_okay=False, ...)
        asked = dict(
            exists=False, file_okay=True, dir_okay=True, readable=True, writable=False, resolve_path=False, allow_dash=False
        )
        return all(getattr(info, k, v) == v for k, v in asked.items())
    return True


def install() -> bool:
    """Give typer's options :class:`Lazy` converters (see the module doc); False, with nothing
    changed, where typer is not of the shape this was written for."""
    try:
        import typer.core as core
        from typer import _coercion
    except ImportError:
        return False
    original = getattr(core, "build_runtime_param", None)
    if original is None or getattr(original, "_lazy", False) or original is not getattr(_coercion, "build_runtime_param", None):
        return bool(getattr(original, "_lazy", False))

    def build_runtime_param(descriptor: Any, *args: Any, **kwargs: Any) -> Any:
        if args or kwargs:
            return original(descriptor, *args, **kwargs)
        return Lazy(original, descriptor, getattr(descriptor, "annotation", None), _simple(descriptor))

    build_runtime_param._lazy = True  # type: ignore[attr-defined]
    core.build_runtime_param = build_runtime_param
    return True
