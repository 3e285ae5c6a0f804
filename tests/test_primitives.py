"""The primitive library: state ranges (BRIEF section 4), end poses, footprints, information."""

import numpy as np
import pytest
from shapely.geometry import Point

from primitives.footprint import hull_at, hull_outline
from primitives.information import excitation_hint, library_information, unidentified_parameters
from primitives.library import basic_moves, build_library, by_name, full_scale_thesis, model_ship_thesis
from primitives.ship import load_profile

# BRIEF section 4 ranges. Tolerances: speeds within 0.05 m/s (model ship) / 0.1 m/s (full scale),
# amplitudes of v within 0.02 m/s and of r within 0.01 rad/s (model ship) -- zig-zags reverse
# before sway has fully settled, so the reached amplitude is a little below the target.
MODEL_SHIP = {
    "tau1": dict(u=(0.0, 1.0), v=(0.0, 0.0), r=(0.0, 0.0)),
    "tau2": dict(u=(0.0, 1.0), v=(0.0, 0.0), r=(0.0, 0.0)),
    "tau3": dict(u=(0.35, 0.35), v=(-0.1, 0.1), r=(-0.2, 0.2)),
    "tau4": dict(u=(0.8, 0.8), v=(-0.1, 0.1), r=(-0.2, 0.2)),
    "tau5": dict(u=(1.15, 1.15), v=(-0.1, 0.1), r=(-0.2, 0.2)),
    "tau6": dict(u=(0.35, 0.35), v=(-0.15, 0.15), r=(-0.35, 0.35)),
    "tau7": dict(u=(0.7, 0.7), v=(-0.15, 0.15), r=(-0.35, 0.35)),
    "tau8": dict(u=(1.0, 1.0), v=(-0.15, 0.15), r=(-0.35, 0.35)),
    "tau9": dict(u=(0.4, 0.4), v=(0.05, 0.05), r=(-0.6, 0.0)),
    "tau10": dict(u=(0.75, 0.75), v=(0.125, 0.125), r=(-0.6, 0.0)),
    "tau11": dict(u=(1.0, 1.0), v=(0.2, 0.2), r=(-0.6, 0.0)),
}
FULL_SCALE = {
    "tau12": dict(u=(0.0, 3.5), v=(0.0, 0.0), r=(0.0, 0.0)),
    "tau13": dict(u=(0.0, 0.0), v=(-1.0, 1.0), r=(0.0, 0.0)),
    "tau14": dict(u=(0.0, 0.0), v=(-0.65, 0.65), r=(0.0, 0.0)),
    "tau15": dict(u=(0.0, 0.0), v=(-0.9, 0.9), r=(0.0, 0.0)),
    "tau16": dict(u=(0.0, 0.0), v=(-1.15, 1.15), r=(0.0, 0.0)),
    "tau17": dict(u=(3.0, 3.0), v=(-0.5, 0.5), r=(-0.03, 0.03)),
    "tau18": dict(u=(4.0, 4.0), v=(-0.5, 0.5), r=(-0.03, 0.03)),
    "tau19": dict(u=(3.0, 3.0), v=(-0.5, 0.5), r=(-0.03, 0.03)),
    "tau20": dict(u=(4.0, 4.0), v=(-0.5, 0.5), r=(-0.03, 0.03)),
}


@pytest.fixture(scope="module")
def ms():
    return load_profile("model-ship")


@pytest.fixture(scope="module")
def ms_lib(ms):
    return model_ship_thesis(ms)


@pytest.fixture(scope="module")
def fs_lib():
    return full_scale_thesis(load_profile("full-scale"))


def _check_ranges(prims, table, tol):
    for p in prims:
        got = p.ranges()
        for s, (lo, hi) in table[p.name].items():
            assert got[s][0] == pytest.approx(lo, abs=tol[s]), (p.name, s, got[s])
            assert got[s][1] == pytest.approx(hi, abs=tol[s]), (p.name, s, got[s])


def test_model_ship_primitive_ranges(ms_lib):
    assert [p.name for p in ms_lib] == [f"tau{i}" for i in range(1, 12)]
    assert all(p.n_samples == 300 for p in ms_lib)
    _check_ranges(ms_lib, MODEL_SHIP, dict(u=0.05, v=0.02, r=0.01))


def test_full_scale_primitive_ranges(fs_lib):
    assert [p.name for p in fs_lib] == [f"tau{i}" for i in range(12, 21)]
    _check_ranges(fs_lib, FULL_SCALE, dict(u=0.1, v=0.03, r=0.005))


def test_end_pose_and_footprint_follow_the_track(ms, ms_lib):
    for p in ms_lib + basic_moves(ms):
        np.testing.assert_allclose(p.end_pose, p.track[-1])
        np.testing.assert_allclose(p.track[0], [0, 0, 0])
        fp = p.footprint.buffer(1e-6)
        # every hull vertex at every pose lies in the swept footprint
        hulls = hull_at(hull_outline(ms.length_m, ms.beam_m), p.track[:: max(1, p.n_samples // 60)])
        assert all(fp.contains(Point(*xy)) for xy in hulls.reshape(-1, 2)), p.name
        # and the footprint is not much larger than the swept track needs
        minx, miny, maxx, maxy = p.footprint.bounds
        assert maxx - minx <= np.ptp(p.track[:, 0]) + 2 * ms.length_m


def test_footprints_of_tracks_that_begin_alike_are_their_own_footprints(ms, ms_lib):
    """The planner's moves share a run-in and manoeuvre and differ in their settling legs: their
    footprints, made with the shared part's union formed once, cover the same area with the
    same bounds as each made alone."""
    import shapely

    from primitives.footprint import swept_footprint, swept_footprints

    head = ms_lib[5].track  # a zig-zag
    tracks = []
    for turn in (0.0, 0.3, -0.5):
        x, y, psi = head[-1]
        k = np.arange(1, 40)[:, None]
        tail = np.column_stack(
            [x + 0.5 * k[:, 0] * np.cos(psi + turn), y + 0.5 * k[:, 0] * np.sin(psi + turn), np.full(len(k), psi + turn)]
        )
        tracks.append(np.vstack([head, tail]))
    for alone, shared in zip(
        [swept_footprint(t, ms.length_m, ms.beam_m) for t in tracks], swept_footprints(tracks, ms.length_m, ms.beam_m)
    ):
        assert alone.bounds == pytest.approx(shared.bounds, abs=1e-9)
        assert shapely.symmetric_difference(alone, shared).area <= 1e-9 * alone.area
    assert len(swept_footprints(tracks[:1], ms.length_m, ms.beam_m)) == 1


def test_pieces_recompose_the_track(ms_lib):
    zz = ms_lib[5]  # tau6, zig-zag with half-period splits
    pieces = zz.pieces()
    assert len(pieces) == len(zz.split_points) + 1
    assert sum(p.n_samples for p in pieces) == zz.n_samples
    # chaining the pieces' end poses reproduces the whole end pose
    x = np.zeros(3)
    for p in pieces:
        c, s = np.cos(x[2]), np.sin(x[2])
        dx, dy, dpsi = p.end_pose
        x = x + [c * dx - s * dy, s * dx + c * dy, dpsi]
    np.testing.assert_allclose(x, zz.end_pose, atol=1e-9)


def test_basic_moves_end_where_the_planner_expects(ms):
    moves = {p.name: p for p in basic_moves(ms)}
    assert moves["straight"].end_pose == pytest.approx([5 * ms.length_m, 0, 0], abs=0.05 * ms.length_m)
    for name, sign in (("spot_turn_s", 1), ("spot_turn_p", -1), ("turn_s", 1), ("turn_p", -1)):
        assert moves[name].end_pose[2] == pytest.approx(sign * np.pi / 2, abs=np.radians(1.5)), name
    assert np.hypot(*moves["spot_turn_s"].end_pose[:2]) < 0.05 * ms.length_m


def test_standard_trials_behave_like_their_names(ms):
    lib = {p.name: p for p in build_library(ms, basic=False)}
    zz = lib["zigzag_20_20_s"]
    psi = np.degrees(zz.track[:, 2])
    assert psi.max() > 20 and psi.min() < -20  # overshoot past the switching heading both ways
    assert zz.nu[5, 2] > 0  # first rudder to starboard turns to starboard
    assert lib["zigzag_20_20_p"].nu[5, 2] < 0
    tc = lib["turning_circle_35_s"]
    assert tc.end_pose[2] == pytest.approx(2 * np.pi, abs=0.1)
    assert np.ptp(tc.track[:, 1]) == pytest.approx(3 * ms.length_m, rel=0.35)  # tactical diameter ~ 3 L


def test_information_full_rank_library_vs_pure_surge(ms, ms_lib):
    infos = library_information(ms, ms_lib)
    total = sum(i.gamma("batchwise") for i in infos)
    assert np.linalg.matrix_rank(total) == 10
    assert unidentified_parameters(ms, total) == []
    surge = infos[0].gamma("batchwise")  # tau1, pure deceleration
    assert np.linalg.matrix_rank(surge) < 10
    dead = unidentified_parameters(ms, surge)
    assert {"Yv", "Ytau", "Nr", "Ntau", "Xtau"} <= set(dead)
    assert "Xu" not in dead
    msg = excitation_hint(ms, dead)
    assert "Yv" in msg and "sway" in msg


def test_by_name_reports_unknown(ms_lib):
    with pytest.raises(KeyError, match="tau99"):
        by_name(ms_lib, ["tau1", "tau99"])


def test_user_profile_without_a_dictionary_still_designs(tmp_path):
    """A generalized-force profile with no thesis dictionary: the design chooses among the
    standard trials plus sway steps and excitation zig-zags, and the library holds them all."""
    from expdesign.api import default_library, run_design
    from primitives.ship import PROFILE_DIR

    text = (PROFILE_DIR / "model-ship.toml").read_text(encoding="utf-8")
    path = tmp_path / "my-model.toml"
    path.write_text(text.replace('library = "thesis-model-ship"\n', "").replace('name = "model-ship"', 'name = "my-model"'))
    prof = load_profile(path)
    assert prof.library == ""
    lib = default_library(prof)
    names = {p.name for p in lib}
    assert {"zigzag_10_10_s", "sway_steps", "sway_steps_rest", "zz_exc_60", "zz_exc_100"} <= names
    assert names <= {p.name for p in build_library(prof)}
    d = run_design(prof, lib)
    assert d.efficiency_vs_uniform > 1.0 and sum(d.rounded.values()) > 0
