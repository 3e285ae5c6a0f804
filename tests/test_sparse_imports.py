"""maps.sparse: scipy's sparse-graph routines imported without numpy's unused submodules (issue 30:
the planner's imports are on the critical path of every ``plan-trial``)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np


def _fresh(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_planner_import_leaves_numpy_f2py_and_testing_unloaded():
    out = _fresh(
        "import sys, maps.planner; "
        "print(sorted(m for m in ('numpy.f2py', 'numpy.testing', 'charset_normalizer') if m in sys.modules))"
    )
    assert out == "[]"


def test_deferred_submodules_load_for_real_when_used():
    out = _fresh(
        "import sys, types, maps.sparse, numpy; "
        "import scipy._lib.array_api_compat.numpy as xp; "
        "print(xp.testing.assert_allclose is __import__('numpy.testing').testing.assert_allclose, "
        "type(sys.modules['numpy.testing']).__name__, "
        "'f2py' in vars(numpy), type(numpy.f2py).__name__, numpy.f2py.__name__)"
    )
    # a placeholder left in scipy's namespace imports the real module on first use; numpy's own
    # attribute is the real module once imported, whatever scipy holds
    assert out == "True module False module numpy.f2py"


def test_graph_routines_are_scipys():
    from maps.sparse import breadth_first_order, csr_matrix, dijkstra

    g = csr_matrix((np.array([1.0, 2.0, 0.5]), (np.array([0, 1, 0]), np.array([1, 2, 2]))), shape=(3, 3))
    assert dijkstra(g, directed=True, indices=[0], min_only=True).tolist() == [0.0, 1.0, 0.5]
    assert sorted(breadth_first_order(g, 0, directed=True, return_predecessors=False).tolist()) == [0, 1, 2]
