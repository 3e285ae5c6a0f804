"""Which path an output-error fit took and what it cost (stop 55): the exact-Jacobian path of
:func:`identify.rollmass.oe_fit.fit_output_error`, its continuation (stops 56, 59), or its forward-difference redo, with each path's
Levenberg-Marquardt calls and residual / Jacobian evaluations counted, so a family's split between
the two paths is exact rather than read off a CPU threshold."""

from __future__ import annotations

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
    evaluations are added to a :class:`PathTally`; everything else is the problem's."""

    def __init__(self, prob: object, tally: PathTally):
        self._prob, self._tally = prob, tally

    def __getattr__(self, name: str) -> object:
        return getattr(self._prob, name)

    def recounted(self, tally: PathTally) -> Counted:
        """The same problem, its evaluations added to ``tally`` instead (the exact path's continuation)."""
        return Counted(self._prob, tally)

    def residual(self, x: np.ndarray) -> np.ndarray:
        self._tally.residuals += 1
        return self._prob.residual(x)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        self._tally.jacobians += 1
        return self._prob.jacobian(x)
