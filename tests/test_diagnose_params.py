"""``shiptrial diagnose --params``: a parameter set of the ship by name, and a bad name that says
which flag is wrong and which names are valid."""

from __future__ import annotations

import numpy as np

from cli.app import _run
from cli.diagnose_cmd import _load_params
from diagnose.battery import scenario
from diagnose.recording import write_csv
from primitives.ship import load_profile


def test_bad_params_name_names_the_flag_and_the_valid_names(tmp_path, capsys):
    rec = write_csv(scenario((), 43, n_prims=2).diagnose[0], tmp_path / "run.csv")
    rc = _run(["diagnose", str(rec), "--ship", "model-ship", "--params", "nomnal"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "--params 'nomnal'" in err and "nominal, true" in err and "model-ship" in err


def test_params_accepts_a_parameter_set_or_a_builtin_profile_by_name():
    ship = load_profile("model-ship")
    np.testing.assert_array_equal(_load_params("nominal", ship), ship.params("nominal"))
    assert not np.array_equal(ship.params("nominal"), ship.params("true"))
    kv = load_profile("kvlcc2-linear")
    np.testing.assert_array_equal(_load_params("kvlcc2-linear", kv), kv.params())
