"""primitives.powers.int_power: a term's integer power by the association its docstring states, the
same bits on a Python float, a numpy array and in the compiled loops (stop 44: integer powers as
products), pow() for the others."""

from __future__ import annotations

import math

import numpy as np

from primitives.powers import PRODUCT_POWERS, int_power
from primitives.terms import parse_factor


def test_powers_are_the_stated_products_on_floats_and_arrays():
    x = np.random.default_rng(4).uniform(0.3, 3.0, 2000)
    x2 = x * x
    products = {1: x, 2: x2, 3: x2 * x, 4: x2 * x2, -1: 1.0 / x, -2: 1.0 / x2}
    assert set(products) == PRODUCT_POWERS
    for k, want in products.items():
        assert np.array_equal(int_power(x, k), want), k
        assert [int_power(float(v), k) for v in x] == want.tolist(), k
        assert np.array_equal(parse_factor(f"U^{k}").value({"U": x}), want), k


def test_other_powers_call_pow():
    assert int_power(1.7, 5) == math.pow(1.7, 5.0)
    assert int_power(2.0, -3) == 0.125
    assert parse_factor("v_r^5").scalar_exact is False and parse_factor("v_r^3").scalar_exact is True


def test_the_generated_increment_function_gives_the_factor_values():
    from primitives.terms import TermSet

    terms = TermSet([["v_r^3*U^-2"], ["|v_r@-2.5|^4"], ["r^3*U^-1"]])
    rng = np.random.default_rng(9)
    sig = {"v_r": rng.normal(0, 0.3, 50), "U": rng.uniform(0.5, 2.0, 50), "r": rng.normal(0, 0.02, 50)}
    got = terms.increment_function()(sig, [1.0, 1.0, 1.0])
    for i in range(terms.n_dof):
        assert np.array_equal(got[i], 1.0 * terms.evaluate_dof(i, sig)[..., 0])
    one = terms.increment_function()({k: float(v[7]) for k, v in sig.items()}, [1.0, 1.0, 1.0])
    assert one == [float(g[7]) for g in got]
