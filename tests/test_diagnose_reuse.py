"""What a diagnosis reuses instead of simulating again (issues 26 and 30: 10 s a case), and the
forward-sensitivity Gram matrices that replace finite differences where no candidate is on: the
same bits where only reused, the stated tolerance where exact sensitivities replace differences."""

from __future__ import annotations

import numpy as np
import pytest

from diagnose import fitting as dm
from diagnose import recording, search, search_limits
from diagnose.battery import scenario
from diagnose.candidates import build_library
from diagnose.heldout import Parts, grams
from diagnose.model import AugmentedModel, prepare, residuals
from diagnose.recording import RecordingError, read_csv
from diagnose.sensitivity import residual_jacobian
from diagnose.uncertainty import FindingCov, finding_cov, finding_pairs, sensitivities
from diagnose.within_interval import with_within
from primitives import jitloop
from primitives.ship import load_profile

needs_numba = pytest.mark.skipif(not jitloop.AVAILABLE, reason="numba not installed or SHIPTRIAL_KERNEL=numpy")


def _setup(n_rec: int = 2):
    prof = load_profile("model-ship")
    sc = scenario(("current",), 5, profile=prof)
    recs = [sc.diagnose[0].window(0, 400), sc.validate[0].window(0, 300)][:n_rec]
    cands, _ = build_library(prof, recs)
    model = AugmentedModel(prof, prof.params(), cands, n_rec=len(recs))
    preps = [prepare(prof, r, i) for i, r in enumerate(recs)]
    cur = model.slot_of[next(c.key for c in cands if c.effect == "current")]
    return model, preps, cur


def test_escaped_members_is_escaped_of_each_member():
    """fit's divergence verdict is read off its accepted trial (escaped_members) instead of a new
    simulation of P (diverges): the same test, member by member, a NaN or a blown-up one included."""
    model, preps, _cur = _setup(1)
    p = preps[0]
    yh = np.repeat(model.simulate(p, model.p0()), 4, axis=0)
    yh[1, 10, 2] = np.nan
    yh[2, 50, 0] = 1e9
    yh[3] *= 1.5
    got = dm.escaped_members(p, yh)
    assert got.tolist() == [dm.escaped(p, yh[b]) for b in range(4)] == [False, True, True, False]


def test_fit_does_not_simulate_its_result_again(monkeypatch):
    """A refit whose steps were accepted judges divergence on the accepted trial's simulation: the
    same answer as before, without the one more simulation of every run (diverges) at its end."""
    model, preps, cur = _setup()
    P = model.p0()
    P[cur] = [0.02, -0.01]
    free = [*cur, *model.x0_params()]
    ref = dm.fit(model, preps, P, free, np.array([10.0, 20.0, 300.0]), max_iter=4)
    calls = []
    monkeypatch.setattr(dm, "diverges", lambda *a: calls.append(1) or False)
    got = dm.fit(model, preps, P, free, np.array([10.0, 20.0, 300.0]), max_iter=4)
    assert not calls and np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1]) and got[2] == ref[2]
    assert not np.array_equal(got[0], P)  # a step was accepted (else diverges is asked, as before)


@needs_numba
def test_mixed_sensitivities_exact_baseline_columns_differenced_slots():
    """sensitivities(analytic=True) with a candidate's slots among the columns at a point where no
    candidate is on: the baseline's columns and initial states are the forward sensitivities, the
    slots' the finite differences, each the same bits as computed alone, in the order asked."""
    model, preps, cur = _setup()
    P = model.p0()
    w = np.array([10.0, 20.0, 300.0])
    cols = [cur[1], 0, 3, model.x0_params()[0], cur[0], 5]
    got = sensitivities(model, preps, P, cols, w, analytic=True)
    exact = residual_jacobian(
        model, preps, P, [0, 3, model.x0_params()[0], 5], w, [q[0] for q in residuals(model, preps, P[None])]
    )
    fd = sensitivities(model, preps, P, [cur[1], cur[0]], w)
    for (R, J), (Re, Je), (Rf, Jf) in zip(got, exact, fd):
        assert np.array_equal(R, Re) and np.array_equal(R, Rf)
        assert np.array_equal(J[[1, 2, 3, 5]], np.moveaxis(Je, 2, 0))
        assert np.array_equal(J[[0, 4]], Jf)


def test_with_within_reads_the_covariance_sensitivities_bit_for_bit():
    """with_within given finding_cov's sensitivities (free's columns first, then the held ones) is
    with_within simulating its own: the same misfit term."""
    model, preps, cur = _setup()
    P = model.p0()
    P[cur] = [0.02, -0.01]
    w = np.array([10.0, 20.0, 300.0])
    free, held = [*cur, *model.x0_params()], [0, 3]
    held_cov = np.diag([1e-6, 1e-6])
    pairs = finding_pairs(model, preps, w, P, free, held, held_cov)
    cov = finding_cov(model, preps, w, P, free, None, held, held_cov, pairs)
    assert cov.n_runs == 2

    def copy(c: FindingCov) -> FindingCov:
        return FindingCov(c.noise.copy(), c.model.copy(), c.n_runs)

    a = with_within(copy(cov), model, preps, w, P, free, None, pairs)
    b = with_within(copy(cov), model, preps, w, P, free)
    assert a.within is not None and np.array_equal(a.within, b.within)


@needs_numba
def test_marginal_variances_by_sensitivities_within_1e3_of_differences():
    """held_by_fit_on's marginal variances from forward sensitivities against the finite
    differences they replace: within 1e-3 relative, and the same parameters held."""
    model, preps, _cur = _setup()
    w = np.array([10.0, 20.0, 300.0])
    ref, idx = model.p0(), list(range(model.n_base))
    got, fd = search_limits._marginal_var(model, preps, w, ref, idx), _differenced_var(model, preps, w, ref, idx)
    ok = fd < np.inf
    assert got is not None and np.all(np.isfinite(got[ok]))
    assert np.max(np.abs(got[ok] / fd[ok] - 1.0)) < 1e-3  # 3.8e-4 here: the differences' truncation error
    one, two = [preps[0]], [preps[1]]
    held = search.held_by_fit_on(model, one, two, w, ref, idx)
    a, b = _differenced_var(model, one, w, ref, idx), _differenced_var(model, two, w, ref, idx)
    assert held == [j for j, x, y in zip(idx, a, b) if x <= y]  # the set the differences hold


def _differenced_var(model, preps, w, ref, idx) -> np.ndarray:
    """held_by_fit_on's marginal variances as main computed them: finite-difference Gram matrices."""
    parts = Parts(list(range(len(preps))), [np.ones(p.n, bool) for p in preps], [p.rec.source for p in preps], [], [])
    g = grams(model, preps, parts, ref, idx, w, model.steps(preps, ref))
    r = np.concatenate([res[0, 1:] * w for res in residuals(model, preps, ref[None])])
    scale = float(np.mean(r**2)) * search.inflation(r.ravel())
    var = np.diag(np.linalg.pinv(g.G.sum(axis=(0, 1)))) * scale
    return np.where(np.isfinite(var) & (var > 0), var, np.inf)


CSV = "# sample_time: 1\nt,x,y,psi,u,v,r,delta,n\n" + "".join(
    f"{k},{k * 1.5:.6g},{0.01 * k:.6g},{0.001 * k:.6g},1.5,{0.01 * np.sin(k):.9g},{0.001 * np.cos(k):.9g},{0.1 * np.sin(0.1 * k):.9g},1.2\n"
    for k in range(60)
)


def test_csv_columns_read_at_once_are_the_cells_read_one_by_one(tmp_path, monkeypatch):
    """A CSV whose rows are all whole is read a column at a time (numpy reads each cell with
    Python's float): the same numbers as the cell-by-cell reading an empty cell falls back to, the
    empty cell NaN; a bad cell still refused with its row and column."""
    whole, holed, bad = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    whole.write_text(CSV, encoding="utf-8")
    lines = CSV.splitlines()
    cells = lines[12].split(",")
    holed.write_text("\n".join(lines[:12] + [",".join(cells[:7] + [" ", cells[8]])] + lines[13:]) + "\n", encoding="utf-8")
    bad.write_text("\n".join(lines[:12] + [",".join(cells[:7] + ["0.1o", cells[8]])] + lines[13:]) + "\n", encoding="utf-8")
    read = []  # the columns as parsed, before the recording is built from them
    build = recording.build_recording
    monkeypatch.setattr(recording, "build_recording", lambda src, cols, **kw: read.append(cols) or build(src, cols, **kw))
    read_csv(whole), read_csv(holed)
    a, b = read
    assert a.keys() == b.keys() and len(a["t"]) == 60
    for k in a:
        same = np.arange(60) != 10 if k == "delta" else np.ones(60, bool)
        assert np.array_equal(a[k][same], b[k][same]), k
        assert np.array_equal(a[k], [float(line.split(",")[list(a).index(k)]) for line in lines[2:]]), k
    assert np.isnan(b["delta"][10])
    with pytest.raises(RecordingError, match=r"row 12, column 'delta': '0.1o' is not a number"):
        read_csv(bad)


def test_without_the_compiler_the_marginal_variances_are_the_differences(monkeypatch):
    """No numba (or SHIPTRIAL_KERNEL=numpy): held_by_fit_on's variances come from the finite
    differences they came from before, bit for bit (the numpy path CI runs without the compiler)."""
    monkeypatch.setattr(jitloop, "AVAILABLE", False)
    model, preps, _cur = _setup()
    w = np.array([10.0, 20.0, 300.0])
    ref, idx = model.p0(), list(range(model.n_base))
    assert np.array_equal(search_limits._marginal_var(model, preps, w, ref, idx), _differenced_var(model, preps, w, ref, idx))


def test_steady_wind_loads_of_a_batch_are_each_members_bit_for_bit():
    """The unrecorded wind's loads, computed once per distinct air velocity of a batch, are each
    member's own to the bit: a member whose wind is -0.0 where another's is 0.0 keeps its own
    (arctan2 puts a following wind at -pi or pi by the sign of zero; np.unique would merge them)."""
    from diagnose import windload

    prof = load_profile("kvlcc2")
    rng = np.random.default_rng(1)
    y = np.column_stack([rng.normal(7.0, 1.0, 51), rng.normal(0.0, 0.1, 51), rng.normal(0.0, 0.01, 51)])
    y[::3, 1], y[1::3, 1], y[::5, 0] = -0.0, 0.0, 0.0  # the ship at rest, no sway: the wind's own sign of zero decides
    psi = np.where(np.arange(51) % 2, 0.0, np.pi)
    wind = np.array(
        [[3.0, 0.0, 0.1, 0.0], [3.0, -0.0, 0.1, 0.0], [0.0, 3.0, 0.1, 0.0], [-0.0, 3.0, 0.1, 0.0], [0.0, 3.0, 0.3, 0.2]]
    )
    got = windload.steady_increments(prof, y, psi, wind, 1.0)
    each = np.concatenate([windload.steady_increments(prof, y, psi, wind[k : k + 1], 1.0) for k in range(len(wind))])
    assert np.array_equal(got.view(np.uint64), each.view(np.uint64))
