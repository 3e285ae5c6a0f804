"""Regressor terms written as products of named signals.

A model in this project is ``nu(k+1) = nu(k) + Phi(k)^T theta`` (seed 001, (3.60) and (9.1)),
where each degree of freedom has its own list of regressor terms. A term is written as a
product of factors separated by ``*``; a factor is a signal name (``u_r``), its modulus
(``|u_r|``) or a small integer power (``u^2``). Examples: ``u_r*|u_r|``, ``v_r*r``, ``tau_x``,
``u_r*tau_x``, ``delta*u^2``.

Keeping the structure as data lets ship profiles, the estimators and the diagnosis (which
augments a model with extra terms) share one definition of every model.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from primitives.errors import UserError

Signals = Mapping[str, np.ndarray]
_FACTOR = re.compile(r"^(\|)?([A-Za-z_][A-Za-z0-9_]*)(\|)?(?:\^([0-9]+))?$")


class TermError(UserError):
    """A term string cannot be parsed."""


def _factor_fn(factor: str) -> tuple[str, Callable[[np.ndarray], np.ndarray]]:
    m = _FACTOR.match(factor.strip())
    if not m or bool(m.group(1)) != bool(m.group(3)):
        raise TermError(f"term factor {factor!r} is not a signal name, |name| or name^k (e.g. 'u_r', '|v_r|', 'u^2')")
    name, power = m.group(2), int(m.group(4) or 1)
    if m.group(1):
        return name, (lambda x, p=power: np.abs(x) ** p)
    if power == 1:
        return name, (lambda x: x)
    return name, (lambda x, p=power: x**p)


def compile_term(term: str) -> tuple[tuple[str, ...], Callable[[Signals], np.ndarray]]:
    """Return (signal names used, function signals -> values) for one term string."""
    factors = [_factor_fn(f) for f in term.split("*")]
    names = tuple(dict.fromkeys(n for n, _ in factors))

    def evaluate(sig: Signals) -> np.ndarray:
        out = factors[0][1](sig[factors[0][0]])
        for name, fn in factors[1:]:
            out = out * fn(sig[name])
        return out

    return names, evaluate


def signals_used(terms: Sequence[Sequence[str]]) -> set[str]:
    """Every signal name any term of any DOF reads."""
    used: set[str] = set()
    for dof_terms in terms:
        for t in dof_terms:
            used.update(compile_term(t)[0])
    return used


class TermSet:
    """Compiled regressor terms per DOF: surge, sway, yaw, and optionally roll (a fourth list)."""

    def __init__(self, terms: Sequence[Sequence[str]]):
        if len(terms) not in (3, 4):
            raise TermError("a model needs three term lists (surge, sway, yaw) or four (surge, sway, yaw, roll)")
        self.terms: tuple[tuple[str, ...], ...] = tuple(tuple(t) for t in terms)
        self._fns = [[compile_term(t)[1] for t in dof] for dof in self.terms]
        self.sizes = tuple(len(d) for d in self.terms)
        self.offsets = tuple(int(x) for x in np.cumsum((0,) + self.sizes))

    def __getstate__(self) -> dict:
        # compiled closures do not pickle (process pools, clusters): ship the term strings only
        return {"terms": self.terms}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["terms"])

    @property
    def n_dof(self) -> int:
        return len(self.terms)

    @property
    def n_params(self) -> int:
        return self.offsets[-1]

    def dof_slice(self, i: int) -> slice:
        return slice(self.offsets[i], self.offsets[i + 1])

    def evaluate_dof(self, i: int, sig: Signals) -> np.ndarray:
        """Regressor block of DOF i: array of shape (..., n_terms_i)."""
        return np.stack([fn(sig) for fn in self._fns[i]], axis=-1)

    def increment_function(self):
        """Increment function generated once from the term strings: one Python expression per
        DOF instead of a loop over factor closures (this is the simulators' inner loop)."""
        fn = getattr(self, "_inc_fn", None)
        if fn is not None:
            return fn
        names = sorted(signals_used(self.terms))
        lines = ["def _inc(sig, c):"]
        lines += [f"    s_{n} = sig[{n!r}]" for n in names]
        j = 0
        for i, dof in enumerate(self.terms):
            parts = []
            for t in dof:
                factors = []
                for f in t.split("*"):
                    m = _FACTOR.match(f.strip())
                    expr = f"s_{m.group(2)}"
                    if m.group(1):
                        expr = f"abs({expr})"
                    if m.group(4) and int(m.group(4)) != 1:
                        expr = f"{expr}**{int(m.group(4))}"
                    factors.append(expr)
                parts.append(f"c[{j}]*" + "*".join(factors))
                j += 1
            lines.append(f"    d{i} = " + (" + ".join(parts) if parts else "0.0"))
        lines.append("    return [" + ", ".join(f"d{i}" for i in range(len(self.terms))) + "]")
        scope: dict = {}
        exec("\n".join(lines), {}, scope)  # noqa: S102 - source built from validated term strings
        self._inc_fn = scope["_inc"]
        return self._inc_fn

    def increments(self, sig: Signals, theta: np.ndarray) -> list[np.ndarray]:
        """Phi^T theta per DOF, i.e. the velocity increments of (3.60).

        ``theta`` is (n_params,) for one model or (B, n_params) for one model per realisation
        of a batch (signals then have a leading batch axis of length B).
        """
        theta = np.asarray(theta, dtype=float)
        coef = theta.tolist() if theta.ndim == 1 else [theta[:, j] for j in range(theta.shape[-1])]
        out = self.increment_function()(sig, coef)
        shape = np.shape(sig["u"])
        return [np.broadcast_to(d, shape) if np.shape(d) != shape else d for d in out]
