"""Regressor terms written as products of named signals.

A model in this project is ``nu(k+1) = nu(k) + Phi(k)^T theta`` (Ljungberg 2022, (3.60) and (9.1)),
where each degree of freedom has its own list of regressor terms. A term is written as a
product of factors separated by ``*``; a factor is a signal name (``u_r``), its modulus
(``|u_r|``) or an integer power (``u^2``; negative for the speed ``U``, ``U^-1``); a lateral
velocity may be taken at a station ``v_r@x`` = v_r + x r. Examples: ``u_r*|u_r|``, ``v_r*r``,
``tau_x``, ``u_r*tau_x``, ``delta*u^2``, ``v_r^3*U^-1``, ``u_r*|v_r@-227|``.

Keeping the structure as data lets ship profiles, the estimators and the diagnosis (which
augments a model with extra terms) share one definition of every model.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from primitives.errors import UserError
from primitives.powers import PRODUCT_POWERS, int_power

Signals = Mapping[str, np.ndarray]


class TermError(UserError):
    """A term string cannot be parsed."""


_FACTOR = re.compile(
    r"^(\|)?([A-Za-z_][A-Za-z0-9_]*)(?:@([-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?))?(\|)?"
    r"(?:\^(-?[0-9]+))?$"
)
# Signals a negative power may divide by: positive by construction (the speed through the water,
# floored, primitives.velocitystep.relative_signals). 1/v_r would blow up at every zero crossing.
POSITIVE_SIGNALS = frozenset({"U"})
# Lateral velocities that may be taken at a station x metres forward of the origin: v@x = v + x r
# (the flow at the propeller or rudder of a turning ship, MMG beta_P, beta_R; Yasukawa & Yoshimura
# 2015 (16), (24)), e.g. '|v_r@-227|'.
STATION_SIGNALS = frozenset({"v", "v_r"})


@dataclass(frozen=True)
class Factor:
    """One factor of a term: ``|name@x|^power`` (modulus, station and power optional)."""

    name: str
    modulus: bool = False
    station: float | None = None
    power: int = 1

    @property
    def names(self) -> tuple[str, ...]:
        """The signals the factor reads (a station also reads the yaw rate r)."""
        return (self.name,) if self.station is None else (self.name, "r")

    def value(self, sig: Signals) -> np.ndarray:
        x = sig[self.name] if self.station is None else sig[self.name] + self.station * sig["r"]
        if self.modulus:
            x = np.abs(x)
        return int_power(x, self.power)

    def code(self) -> str:
        """The factor as a Python expression of the s_<name> locals of the increment function (the
        power by :func:`primitives.powers.int_power`, ``_pow`` in its scope), for arrays and Python
        floats alike."""
        expr = f"s_{self.name}" if self.station is None else f"(s_{self.name} + {self.station!r}*s_r)"
        if self.modulus:
            expr = f"abs({expr})"
        return expr if self.power == 1 else f"_pow({expr}, {self.power})"

    @property
    def scalar_exact(self) -> bool:
        """Whether :meth:`code` on Python floats gives the bits it gives on arrays: +, *, abs and
        the powers formed as products are IEEE operations either way; other powers call pow()
        (the C library's on a float, numpy's on an array)."""
        return self.power in PRODUCT_POWERS


def parse_factor(factor: str) -> Factor:
    """One ``*``-separated factor of a term string, checked: a negative power only of a
    :data:`POSITIVE_SIGNALS` signal, a station only on a :data:`STATION_SIGNALS` one."""
    m = _FACTOR.match(factor.strip())
    if not m or bool(m.group(1)) != bool(m.group(4)):
        raise TermError(
            f"term factor {factor!r} is not a signal name, |name| or name^k (e.g. 'u_r', '|v_r|', 'u^2', 'U^-1', '|v_r@-227|')"
        )
    name, power = m.group(2), int(m.group(5) or 1)
    if power < 0 and name not in POSITIVE_SIGNALS:
        raise TermError(
            f"term factor {factor!r}: a negative power is allowed only of {sorted(POSITIVE_SIGNALS)} "
            "(signals that cannot be zero)"
        )
    station = None if m.group(3) is None else float(m.group(3))
    if station is not None and name not in STATION_SIGNALS:
        raise TermError(f"term factor {factor!r}: a station '@x' (metres forward) applies only to {sorted(STATION_SIGNALS)}")
    return Factor(name, bool(m.group(1)), station, power)


def compile_term(term: str) -> tuple[tuple[str, ...], Callable[[Signals], np.ndarray]]:
    """Return (signal names used, function signals -> values) for one term string."""
    factors = [parse_factor(f) for f in term.split("*")]
    names = tuple(dict.fromkeys(n for f in factors for n in f.names))

    def evaluate(sig: Signals) -> np.ndarray:
        out = factors[0].value(sig)
        for f in factors[1:]:
            out = out * f.value(sig)
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

    def increment_function(self) -> Callable[[Signals, Sequence], list[np.ndarray]]:
        """Increment function generated once from the term strings: one Python expression per
        DOF instead of a loop over factor closures (this is the simulators' inner loop).

        The same function serves arrays and Python floats (one ship stepped alone): on floats it
        gives the bits it gives for one-element arrays when :attr:`scalar_exact` (powers as
        products, :mod:`primitives.powers`)."""
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
                factors = [parse_factor(f).code() for f in t.split("*")]
                parts.append(f"c[{j}]*" + "*".join(factors))
                j += 1
            lines.append(f"    d{i} = " + (" + ".join(parts) if parts else "0.0"))
        lines.append("    return [" + ", ".join(f"d{i}" for i in range(len(self.terms))) + "]")
        scope: dict = {}
        exec("\n".join(lines), {"_pow": int_power}, scope)  # noqa: S102 - source built from validated term strings
        self._inc_fn = scope["_inc"]
        return scope["_inc"]

    @property
    def scalar_exact(self) -> bool:
        """Whether the increment function gives on Python floats the bits it gives on arrays
        (one ship stepped alone, e.g. a closed-loop generator; see :meth:`Factor.scalar_exact`)."""
        return all(parse_factor(f).scalar_exact for dof in self.terms for t in dof for f in t.split("*"))

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
