"""Names moved out of a split module (stop 62's second cleanup) still import from where callers,
notebooks and pickled tasks found them (a pickle names a function or class by module and name)."""

import importlib

import pytest

# the module callers import from -> the names it must still hold: expdesign/report.py -> report_markdown.py,
# expdesign/estimators.py -> oerefine.py, primitives/simulate.py -> velocitystep.py
MOVED = {
    "expdesign.report": ("markdown", "mc_markdown", "sensitivity_summary"),
    "expdesign.estimators": ("OEData", "OEResult", "OE_TOL", "output_error", "output_error_unsupported"),
    "primitives.simulate": (
        "VelocityStep",
        "relative_signals",
        "model_signals",
        "signals_read",
        "body_from_ne",
        "SPEED",
        "WIND_EXCESS",
    ),
}


@pytest.mark.parametrize("module", sorted(MOVED))
def test_moved_names_import_from_the_old_module(module):
    mod = importlib.import_module(module)
    missing = [n for n in MOVED[module] if not hasattr(mod, n)]
    assert not missing, f"{module} no longer holds {missing}"
