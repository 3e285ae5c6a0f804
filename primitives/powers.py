"""A model term's integer power of a signal, |x|^k of a factor (:class:`primitives.terms.Factor`),
evaluated by one rule everywhere it is formed: the numpy path on arrays, the generated increment
function on Python floats, and the compiled loops (:mod:`primitives.jitloop`, :mod:`primitives.jitfactors`,
:mod:`primitives.regkernel`, :mod:`primitives.jitsens`, and through them :mod:`expdesign.oekernel`
and :mod:`expdesign.ivsolve`), which inline this same function.

The powers of the project's structures (v_r^3, r^3, delta^3 and U^-2 of the MMG structure, v_r^4, u^2)
are products, not pow(): ``x^2 = x*x``, ``x^3 = (x*x)*x``, ``x^4 = (x*x)*(x*x)``, ``x^-1 = 1/x``,
``x^-2 = 1/(x*x)``, each multiplication and the division one correctly rounded IEEE operation.
So an array, a Python float and the compiled code give the same bits, where numpy's vectorised
power and the C library's pow could differ in the last bit, and the compiled time loop does not
spend half its time in pow() (stop 44, thrust-loss-20 of issue 26). Any other power keeps pow():
``x ** float(k)``, the C library's pow in the compiled code and on a float, numpy's power on an array.
"""

from __future__ import annotations

# The powers :func:`int_power` forms as products (the others call pow()).
PRODUCT_POWERS = frozenset({1, 2, 3, 4, -1, -2})


def int_power(x, power):
    """x^power by the products of the module doc for the :data:`PRODUCT_POWERS`, pow() otherwise;
    ``x`` a float or an array (compiled into the numba loops as it stands)."""
    if power == 1:
        return x
    if power == 2:
        return x * x
    if power == 3:
        return x * x * x
    if power == 4:
        x2 = x * x
        return x2 * x2
    if power == -1:
        return 1.0 / x
    if power == -2:
        return 1.0 / (x * x)
    return x ** float(power)
