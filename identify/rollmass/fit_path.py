"""Which path an output-error fit took and what it cost (stop 55): the exact-Jacobian path of
:func:`identify.rollmass.oe_fit.fit_output_error`, its continuation (stops 56, 59), or its forward-difference redo, with each path's
Levenberg-Marquardt calls and residual / Jacobian evaluations counted, so a family's split between
the two paths is exact rather than read off a CPU threshold."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np


@dataclass
class PathTally:
    """One path's cost: each LM call's (evaluations as scipy counts them, status; 0 = its evaluation cap, -1 = unknown: a result without one), and
    every residual and Jacobian evaluation of the path (forward-difference columns and the Gauss-Newton finish
    included). The two counts differ in kind: ``lm`` holds MINPACK's ``nfev``, the residuals the problem's own
    evaluations. scipy (1.17) returns its cached residual where MINPACK asks again at the point it has just evaluated,
    so an LM's evaluations of the problem are its ``nfev`` less such repeats and ``residuals`` can fall short of the
    LMs' ``nfev`` plus the finish's: on the basin truth's waves/6/case1 the continuation's LM has ``nfev`` 116, one at a
    repeated point, so 115 reached the problem, and the finish's 1 makes 116 (stop 56 review, measured by wrapping
    MINPACK's calls)."""

    lm: list[tuple[int, int]] = field(default_factory=list)
    residuals: int = 0
    jacobians: int = 0


@dataclass
class FitPath:
    """The path a fit took: ``"exact"``, ``"geodesic"`` (the exact path's end continued by the geodesic LM, stop 59),
    ``"continued"`` (continued by an exact LM, stop 56; ``oe_fit.CONTINUATION = "exact"``) or ``"redo"`` (forward
    differences), why the exact path's end was not kept (``""`` when it was), and each path's tally (``continued`` and
    ``redo`` are None when not taken)."""

    path: str = "exact"
    why: str = ""
    exact: PathTally = field(default_factory=PathTally)
    redo: PathTally | None = None
    # the exact path's continuation from where it ended unconverged (stop 56; None when it was not tried), either LM's
    # (its one call: scipy's nfev, or the geodesic LM's residuals, status 0 at its cap). ``path`` is ``"geodesic"`` or
    # ``"continued"`` when the continuation converged, ``"redo"`` when it did not either
    continued: PathTally | None = None

    def record(self) -> dict[str, object]:
        """A JSON-ready summary (the truth bench's dump)."""
        out: dict[str, object] = {"path": self.path, "why": self.why}
        for name, t in (("exact", self.exact), ("continued", self.continued), ("redo", self.redo)):
            if t is not None:
                out[name] = {"lm": [list(c) for c in t.lm], "residuals": t.residuals, "jacobians": t.jacobians}
        return out


class Counted:
    """A problem (:class:`identify.rollmass.output_error._Problem`) whose residual and Jacobian
    evaluations are added to a :class:`PathTally`; every other attribute, read or written, is the problem's.

    Copies behave as the problem's (stop 61): ``copy.copy`` gives the problem's shallow copy, counted in the same
    tally (an attribute set on the copy does not reach the original; its evaluations are the path's cost as the
    original's are); ``copy.deepcopy`` and pickling copy the problem and the tally (an independent problem whose own
    tally starts from the counts so far). The wrapper's own attributes are slots, and ``__getattr__`` answers a dunder
    or a slot not yet set with AttributeError, so a copy or an unpickling under way never recurses through ``_prob``."""

    __slots__ = ("_prob", "_tally")

    def __init__(self, prob: object, tally: PathTally):
        object.__setattr__(self, "_prob", prob)
        object.__setattr__(self, "_tally", tally)

    def __getattr__(self, name: str) -> object:
        if name in Counted.__slots__ or (name.startswith("__") and name.endswith("__")):
            raise AttributeError(name)
        return getattr(self._prob, name)

    def __setattr__(self, name: str, value: object) -> None:
        if name in Counted.__slots__:  # unpickling sets the slots
            object.__setattr__(self, name, value)
        else:
            setattr(self._prob, name, value)

    def __copy__(self) -> Counted:
        return Counted(copy.copy(self._prob), self._tally)

    def __deepcopy__(self, memo: dict) -> Counted:
        return Counted(copy.deepcopy(self._prob, memo), copy.deepcopy(self._tally, memo))

    def recounted(self, tally: PathTally) -> Counted:
        """The same problem, its evaluations added to ``tally`` instead (the exact path's continuation)."""
        return Counted(self._prob, tally)

    def residual(self, x: np.ndarray) -> np.ndarray:
        self._tally.residuals += 1
        return self._prob.residual(x)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        self._tally.jacobians += 1
        return self._prob.jacobian(x)
