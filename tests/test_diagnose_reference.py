"""Reference runs (issue 13, ``diagnose.reference``): the baseline's structure extension leaves
the profile's own model unchanged, and a candidate acts on the diagnosed runs only, never on a
reference (calm-water) run."""

from __future__ import annotations

import numpy as np

from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.model import AugmentedModel, prepare
from diagnose.reference import ReferencedModel, extend
from primitives.ship import load_profile


def test_extension_adds_only_missing_terms_and_keeps_the_model():
    prof = load_profile("kvlcc2-linear")
    ext, added = extend(prof)
    assert "surge:v_r*r" in added and "yaw:r*|r|" in added and "sway:delta*n^2" in added
    assert not any(a.endswith(":u_r*r") or a.endswith(":delta*u_r^2") for a in added)  # already in the profile
    for have, now in zip(prof.model_terms, ext.model_terms):
        assert now[: len(have)] == have
    assert extend(ext)[1] == []  # nothing left to add
    assert extend(prof, declared=True) == (prof, [])  # no [diagnosis] table: no declared structure, not the generic one
    full = load_profile("kvlcc2")
    assert "surge:v_r*r" not in extend(full)[1]  # the nonlinear profile already has the speed loss in turns
    sc = scenario((), 1, profile=load_profile("model-ship"))
    ms = load_profile("model-ship")
    ems, _ = extend(ms)
    th = np.concatenate(
        [
            np.concatenate([ms.params()[ms.model.dof_slice(i)], np.zeros(len(ems.model_terms[i]) - len(ms.model_terms[i]))])
            for i in range(3)
        ]
    )
    p, pe = prepare(ms, sc.diagnose[0]), prepare(ems, sc.diagnose[0])
    y0 = AugmentedModel(ms, ms.params(), []).simulate(p, AugmentedModel(ms, ms.params(), []).p0())
    me = AugmentedModel(ems, th, [])
    assert np.allclose(me.simulate(pe, me.p0()), y0)


def test_candidates_act_on_diagnosed_runs_only():
    prof = load_profile("model-ship")
    sc = scenario((), 2, profile=prof)
    cands, _ = build_library(prof, sc.diagnose)
    diag, ref = prepare(prof, sc.diagnose[0], 0), prepare(prof, sc.validate[0], 1)
    model = ReferencedModel(prof, prof.params(), [c for c in cands if c.effect == "current"], n_rec=2, reference=[ref])
    plain = AugmentedModel(prof, prof.params(), [c for c in cands if c.effect == "current"], n_rec=2)
    P = model.p0()
    P[model.slot_of["current"]] = (0.05, -0.03)
    on = model.simulate_many([diag, ref], np.stack([model.p0(), P]))
    assert np.allclose(on[1][0], on[1][1])  # the reference run ignores the current
    assert not np.allclose(on[0][0], on[0][1])  # the diagnosed run feels it
    assert np.allclose(on[0], plain.simulate_many([diag], np.stack([model.p0(), P]))[0])
