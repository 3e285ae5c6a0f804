"""The output-error estimator where it cannot run (issue 14): a one-line error that names the model's
limit and the fix, the IV estimator (``--mc-estimator iv``)."""

import numpy as np
import pytest

from expdesign.errors import DesignError
from expdesign.estimators import OEData, output_error
from primitives.ship import load_profile
from primitives.terms import TermSet


def _heading_terms(p):
    return TermSet([list(p.model.terms[0]), list(p.model.terms[1]) + ["psi"], list(p.model.terms[2])])


@pytest.mark.parametrize("case", ["roll", "heading term"])
def test_output_error_error_tells_the_user_to_use_the_iv_estimator(case):
    p = load_profile("naval-vessel" if case == "roll" else "model-ship")
    terms = _heading_terms(p) if case == "heading term" else p.predictor
    n = 10
    data = OEData(np.zeros((1, n, len(p.inputs))), np.zeros((1, 3)), np.zeros((1, n + 1, 3)))
    with pytest.raises(DesignError) as err:
        output_error(p, [data], np.zeros((1, terms.n_params)), terms=terms)
    msg = str(err.value)
    assert "--mc-estimator iv" in msg and p.name in msg and ("planar" if case == "roll" else "heading") in msg
    assert "\n" not in msg
