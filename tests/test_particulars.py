"""A profile from main particulars (issue 31): the regressions against published values, the
build, and the KVLCC2 rebuilt from its particulars against MARIN's free-running tests.

Published values copied here, with their source:
- KVLCC2 MMG coefficients: Yasukawa & Yoshimura (2015), "Introduction of MMG standard method for
  ship maneuvering predictions", J. Mar. Sci. Technol. 20:37-52, Tables 2-4 (model L = 7 m).
- MARIN free-running KVLCC2 (SIMMAN 2008), full scale: 35 deg turning circles tactical diameter
  982 / 1068 m, 10/10 zig-zag first overshoots 9.4 / 8.0 deg (the bundled recordings in
  diagnose/data, as measured by tests/test_kvlcc2_model.py and quoted in kvlcc2.toml).
"""

from __future__ import annotations

import math
import tomllib
from functools import cache

import numpy as np
import pytest

from primitives.particulars import regressions as rg
from primitives.particulars.build import Particulars, build_profile
from primitives.particulars.propeller import BSeries
from primitives.particulars.trials import standard_trials

KVLCC2 = Particulars("kvlcc2-particulars", 320.0, 58.0, 20.8, 0.81, 15.5, rudder_area=142.0, prop_diameter=9.86)
MMG_KVLCC2 = {  # Yasukawa & Yoshimura (2015), Table 2
    "Yv": -0.315, "Yr": 0.083, "Nv": -0.137, "Nr": -0.049,
    "Yvvv": -1.607, "Yvvr": 0.379, "Yvrr": -0.391, "Yrrr": 0.008,
    "Nvvv": -0.030, "Nvvr": -0.294, "Nvrr": 0.055, "Nrrr": -0.013,
    "mx": 0.022, "my": 0.223, "Jz": 0.011, "R0": 0.022,
    "tP": 0.220, "aH": 0.312, "xH": -0.464, "eps": 1.09, "kappa": 0.50, "f_alpha": 2.747,
    "k0": 0.2931, "k1": -0.2753, "k2": -0.1385,
}  # fmt: skip
MARIN_TACTICAL_M = (982.0, 1068.0)
MARIN_OVERSHOOT_10 = (9.4, 8.0)


# A worked example computed by hand from the published formulas (L 100 m, B 20 m, T 5 m, Cb 0.5:
# Cb B/L = 0.1, k = 2T/L = 0.1, m' = 0.2, d/B = 0.25, B/d = 4, d/L = 0.05, B/L = 0.2,
# Clarke's c = pi (d/L)^2 = 0.0078540, x L/d = 20); each line is one formula.
WORKED = rg.Hull(100.0, 20.0, 5.0, 0.5)
BY_HAND = {
    rg.clarke_linear: {
        "Yv": -0.0078540 * (1 + 0.40 * 0.5 * 4) * 20,  # -0.28274
        "Yr": -0.0078540 * (-0.5 + 2.2 * 0.2 - 0.080 * 4) * 20 + 0.05 * 0.2,  # + m'_x: 0.06969
        "Nv": -0.0078540 * (0.5 + 2.4 * 0.05) * 20,  # -0.09739
        "Nr": -0.0078540 * (0.25 + 0.039 * 4 - 0.56 * 0.2) * 20,  # -0.04618
        "my": 0.0078540 * (1 + 0.16 * 0.5 * 4 - 5.1 * 0.04) * 20,  # 0.17530
        "Jz": 0.0078540 * (1 / 12 + 0.017 * 0.5 * 4 - 0.33 * 0.2) * 20,  # 0.00806
    },
    rg.kijima_linear: {"Yv": -0.29708, "Yr": 0.2 + 0.01 - 0.15, "Nv": -0.1, "Nr": -0.054 + 0.01},
    rg.kijima_nonlinear: {"Yrr": 0.343 * 0.25 * 0.5 - 0.07, "Nbbr": -(0.575 - 1.84 + 1.6), "Nbrr": -(0.0625 - 0.05)},
    rg.interaction: {  # Cb B/L 0.1 is finer than Kijima's eps maximum (0.133): Lee & Shin's 0.7844
        "tR": 0.31, "aH": 0.1605, "xH": -0.45, "gammaR": -0.222 + 0.002 + 0.68, "lR": -0.9,  # is under Kijima's:
        "eps": -1.565 + 4.16 - 1.76, "wP0": 0.2, "tP": 0.12,  # clipped up to Kijima's 0.835
    },
}  # fmt: skip


def test_each_eps_regression_reproduces_the_worked_example():
    """Kijima et al. (1990) and Lee & Shin (1998) at the worked example (Cb 0.5, Cb B/L 0.1, k 0.1)."""
    assert rg.kijima_eps(WORKED) == pytest.approx(-1.565 + 4.16 - 1.76, rel=1e-12)  # 0.835
    assert rg.lee_shin_eps(WORKED) == pytest.approx(0.7844, abs=5e-5)


def test_lee_shin_eps_reproduces_the_seiun_maru_value_of_mmgdynamics():
    """A transcription check, not a published worked example: the table of calibrated vessels in the
    mmgdynamics package gives eps 1.033 for the training ship Seiun Maru (L 105 m, B 17.91 m,
    d 5.966 m, Cb 0.508), and Lee & Shin's formula as transcribed there gives 1.0329 at those
    particulars, so the tabulated 1.033 is this regression's value, not a measured one."""
    assert rg.lee_shin_eps(rg.Hull(105.0, 17.91, 5.966, 0.508)) == pytest.approx(1.033, abs=5e-4)


def test_eps_switches_to_lee_shin_below_the_maximum_of_kijimas_quadratic():
    """Kijima's eps for KVLCC2 (Cb B/L 0.147, above its maximum at 0.133); Lee & Shin's for the
    Mariner (0.086), where Kijima's quadratic has fallen to 0.67 and Lee & Shin's 0.944 lies between
    it and Kijima's maximum 1.004; never chosen by name."""
    assert rg.KIJIMA_EPS_PEAK == pytest.approx(0.13291, abs=1e-5)
    assert rg.KIJIMA_EPS_MAX == pytest.approx(rg.kijima_eps(rg.Hull(100.0, 100.0 * rg.KIJIMA_EPS_PEAK, 6.0, 1.0)))
    assert rg.interaction(KVLCC2.hull)["eps"] == rg.kijima_eps(KVLCC2.hull)
    mariner = rg.Hull(160.93, 23.17, 7.47, 0.6)
    assert rg.kijima_eps(mariner) == pytest.approx(0.666, abs=1e-3)
    assert rg.interaction(mariner)["eps"] == rg.lee_shin_eps(mariner) == pytest.approx(0.944, abs=1e-3)
    assert rg.eps_source(mariner) == "Lee & Shin (1998)"
    assert rg.eps_source(KVLCC2.hull) == "Kijima et al. (1990)"
    assert rg.eps_source(WORKED) == "Kijima et al. (1990), Lee & Shin (1998)'s lower 0.784 raised to it"


# hulls of Cb 0.5-0.85 and T/L 0.02-0.07 (coasters, inland vessels, cargo ships, tankers)
HULL_FORMS = [(cb, t_l) for cb in (0.5, 0.6, 0.7, 0.8, 0.85) for t_l in (0.02, 0.03, 0.045, 0.06, 0.07)]


@pytest.mark.parametrize(("cb", "t_l"), HULL_FORMS)
def test_eps_is_continuous_across_the_switch_and_bounded(cb, t_l):
    """A hull a hair either side of Kijima's maximum gets (nearly) the same eps: unclipped, Lee &
    Shin's formula jumped from 1.004 to 1.25 (Cb 0.7, T/L 0.06) or 3.5 (Cb 0.85, T/L 0.02) for a
    0.1 % change of beam. No fine hull's eps exceeds Kijima's maximum (Lee & Shin gives 2.46 for a
    shallow full hull, a rudder wake of -50 %) or falls below Kijima's own value."""
    b_switch = rg.KIJIMA_EPS_PEAK * 100.0 / cb
    finer, fuller = (rg.Hull(100.0, b_switch * f, 100.0 * t_l, cb) for f in (0.999, 1.001))
    assert rg.fine_for_kijima_eps(finer) and not rg.fine_for_kijima_eps(fuller)
    assert rg.interaction(finer)["eps"] == pytest.approx(rg.interaction(fuller)["eps"], abs=1e-4)
    for f in (0.6, 0.75, 0.9, 0.999):
        h = rg.Hull(100.0, b_switch * f, 100.0 * t_l, cb)
        assert rg.kijima_eps(h) <= rg.interaction(h)["eps"] <= rg.KIJIMA_EPS_MAX


def test_the_turning_circle_does_not_jump_across_the_eps_switch():
    """What a user sees: a 100 m coaster (Cb 0.7, T 6 m) and a shallow full hull (Cb 0.8, T 4 m)
    1 % of beam either side of Cb B/L 0.133 turn alike. Before eps was clipped the profile's
    tactical diameter fell 23 % (3.63 -> 2.79 L) and 45 % (3.65 -> 2.01 L) for 0.5 % of beam."""
    for draught, cb, speed in ((6.0, 0.7, 13.0), (4.0, 0.8, 11.0)):
        b_switch = rg.KIJIMA_EPS_PEAK * 100.0 / cb
        td = [
            standard_trials(build_profile(Particulars("x", 100.0, b_switch * f, draught, cb, speed), oe_nfev=0, draws=2).profile)
            .tactical_l["starboard"]
            for f in (0.995, 1.005)
        ]  # fmt: skip
        assert td[0] == pytest.approx(td[1], rel=0.05), td


@pytest.mark.parametrize("formula", list(BY_HAND), ids=lambda f: f.__name__)
def test_each_regression_reproduces_the_worked_example(formula):
    got = formula(WORKED)
    for k, want in BY_HAND[formula].items():
        assert got[k] == pytest.approx(want, rel=1e-4, abs=1e-6), (k, got[k], want)


def test_yoshimura_surge_terms_reproduce_the_worked_example():
    """Yoshimura & Masumoto (2012), Table 3, at Cb B/L = 0.1 with m'_y = 0.2."""
    got = rg.yoshimura_surge(WORKED, 0.2)
    want = {"Xvv": 0.115 - 0.18, "Xvr": 0.2 - 0.191 + 0.08, "Xrr": -0.0085 + 0.008, "Xvvvv": -0.668 + 1.1}
    assert got == pytest.approx(want, abs=1e-9)


def test_linear_hull_derivatives_reproduce_the_published_kvlcc2():
    """Clarke et al. (1983) with Y'_r + m'_x, the model's linear derivatives, against KVLCC2's captive
    tests at fixed tolerances (measured: Y'_v +23 %, Y'_r -3 %, N'_v -2 %, N'_r +7 %); Kijima et al.
    (1990), the independent check, within 10 % except Y'_v (+30 %)."""
    cl, kj = rg.clarke_linear(KVLCC2.hull), rg.kijima_linear(KVLCC2.hull)
    for k, rel in (("Yv", 0.25), ("Yr", 0.05), ("Nv", 0.05), ("Nr", 0.10)):
        assert cl[k] == pytest.approx(MMG_KVLCC2[k], rel=rel), (k, cl[k])
    for k, rel in (("Yv", 0.35), ("Yr", 0.10), ("Nv", 0.10), ("Nr", 0.10)):
        assert kj[k] == pytest.approx(MMG_KVLCC2[k], rel=rel), (k, kj[k])


@pytest.mark.parametrize(("v", "r"), [(-0.2, 0.4), (-0.2, 0.6)])
def test_kijima_nonlinear_hull_forces_in_a_turn_match_the_published_kvlcc2(v, r):
    """Kijima's beta|beta|, r|r|, beta^2 r, beta r^2 form against the published cubic MMG terms at a
    turning-circle state (drift 0.2, r' 0.4-0.6): same sign, within 50 %."""
    k, m = rg.kijima_nonlinear(KVLCC2.hull), MMG_KVLCC2
    b = -v
    for dof in ("Y", "N"):
        kij = k[f"{dof}bb"] * b * abs(b) + k[f"{dof}rr"] * r * abs(r) + (k[f"{dof}bbr"] * b + k[f"{dof}brr"] * r) * b * r
        pub = m[f"{dof}vvv"] * v**3 + m[f"{dof}vvr"] * v * v * r + m[f"{dof}vrr"] * v * r * r + m[f"{dof}rrr"] * r**3
        assert np.sign(kij) == np.sign(pub)
        assert abs(kij - pub) <= 0.5 * abs(pub), (dof, kij, pub)


def test_added_mass_and_interaction_match_the_published_kvlcc2():
    """Within 20 % of KVLCC2's captive-test values: m'_y, J'_z, a_H, x'_H, eps, t_P. Not checked,
    because the regressions miss KVLCC2 by more (README): t_R 0.22 (0.39), gamma_R 0.20 (0.40 / 0.64),
    l'_R -0.9 (-0.71), m'_x 0.015 (0.022); kappa is not a regression (0.5 assumed)."""
    am, it = rg.added_mass(KVLCC2.hull), rg.interaction(KVLCC2.hull)
    assert am["my"] == pytest.approx(MMG_KVLCC2["my"], rel=0.15)
    assert am["Jz"] == pytest.approx(MMG_KVLCC2["Jz"], rel=0.20)
    for k in ("aH", "xH", "eps", "tP"):
        assert it[k] == pytest.approx(MMG_KVLCC2[k], rel=0.2), k
    # KVLCC2's rudder: span 15.8 m for 136.7 m^2 (model 0.345 m, scale 45.7) gives the published f_alpha
    assert rg.rudder_lift_slope(15.8**2 / 136.7) == pytest.approx(MMG_KVLCC2["f_alpha"], rel=0.01)


def test_bseries_thrust_reproduces_the_published_kvlcc2_open_water_curve():
    """KVLCC2's screw (P/D 0.721, A_E/A_0 0.431, 4 blades) against its measured K_T fit (Table 2)."""
    prop = BSeries(0.721, 0.431, 4)
    for j in (0.0, 0.2, 0.4):
        pub = MMG_KVLCC2["k0"] + MMG_KVLCC2["k1"] * j + MMG_KVLCC2["k2"] * j * j
        assert float(prop.kt(j)) == pytest.approx(pub, abs=0.02), j
    # zero thrust and efficiency below 1: the curve is a propeller's
    j0 = prop.zero_thrust_j()
    assert 0.6 < j0 < 0.9
    j = 0.4
    assert 0.3 < j * float(prop.kt(j)) / (2 * math.pi * float(prop.kq(j))) < 0.7


def test_resistance_reproduces_the_ittc_line_and_the_published_kvlcc2_model_within_its_spread():
    assert rg.friction_ittc57(1.0, 1e7 * rg.NU_WATER) == pytest.approx(0.003, rel=1e-9)  # log10 Re = 7
    model = rg.Hull(7.0, 7.0 * 58 / 320, 7.0 * 20.8 / 320, 0.81)  # the 7 m KVLCC2 model, fresh water
    est = rg.resistance_nd(model, 1.179, nu=1.139e-6)  # friction and form only: 0.0165, 25 % below
    assert est == pytest.approx(MMG_KVLCC2["R0"], rel=0.30)


@cache
def kvlcc2_built():
    return build_profile(KVLCC2, oe_nfev=0, draws=3, seed=1)


def test_built_profile_loads_with_sources_and_a_prior_spread():
    b = kvlcc2_built()
    doc = tomllib.loads(b.text)
    assert doc["particulars"]["rudder_area_m2"] == 142.0
    for source in ("Clarke", "Kijima", "Yoshimura & Masumoto", "Oosterveld", "ITTC-1957", "SOLAS"):
        assert source in b.text, source
    p = b.profile
    assert p.prior_std is not None and p.prior_std.shape == p.params().shape
    assert np.all(p.prior_std > 0) and np.all(np.isfinite(p.prior_std))
    th = dict(zip(p.param_names, p.params()))
    assert th["Xuu"] < 0 < th["Xnn"] and th["Nur"] < 0 and th["Yuv"] < 0  # resistance, thrust, damping
    assert p.engine.approach_rpm == pytest.approx(60 * b.approach_rps, abs=0.05)  # written to 0.1 rpm


def test_kvlcc2_from_particulars_turns_and_zigzags_like_marin():
    """The issue's check on the fast build (one-step least squares, no output-error polish;
    benchmarks/bench_profile_new.py measures the full build): tactical diameter within 20 % and the
    10/10 first overshoot within 4 deg of each MARIN run."""
    fig = standard_trials(kvlcc2_built().profile)
    for side in ("starboard", "port"):
        td = fig.tactical_l[side] * KVLCC2.length
        assert all(abs(td - m) <= 0.20 * m for m in MARIN_TACTICAL_M), td
        assert all(abs(fig.overshoot_10[side] - m) <= 4.0 for m in MARIN_OVERSHOOT_10), fig.overshoot_10
        assert fig.overshoot_20[side] > fig.overshoot_10[side]
    assert fig.warnings(KVLCC2.length) == []


def test_prior_spread_round_trips_and_bad_spreads_are_refused():
    from primitives.profile_document import profile_from_dict
    from primitives.ship import ProfileError

    b = kvlcc2_built()
    again = profile_from_dict(b.profile.to_dict(), "again")
    assert np.array_equal(again.prior_std, b.profile.prior_std)
    doc = tomllib.loads(b.text)
    doc["prior"]["std"]["yaw"] = doc["prior"]["std"]["yaw"][:-1]
    with pytest.raises(ProfileError, match="prior.std.yaw"):
        profile_from_dict(doc, "short.toml")
    doc = tomllib.loads(b.text)
    doc["prior"]["std"]["surge"][0] = -1.0
    with pytest.raises(ProfileError, match=">= 0"):
        profile_from_dict(doc, "negative.toml")


def test_manoeuvres_outside_the_range_ships_have_are_warned():
    from primitives.particulars.trials import TrialFigures

    def fig(td):
        return TrialFigures({"starboard": td, "port": 3.0}, {"starboard": 3.0, "port": 3.0}, {}, {}, "")

    assert fig(3.5).warnings(100.0) == []
    assert "9.0 L" in fig(9.0).warnings(100.0)[0] and "2-8 L" in fig(9.0).warnings(100.0)[0]
    assert "1.5 L" in fig(1.5).warnings(100.0)[0]
    assert "never turned 180 deg" in fig(None).warnings(100.0)[0]


def _figures(td=3.0, adv=3.0, os10=5.0, os20=10.0, track=None, os10b=8.0, init=1.5):
    from primitives.particulars.trials import TrialFigures

    side = ("starboard", "port")
    return TrialFigures(
        {s: td for s in side},
        {s: adv for s in side},
        {s: os10 for s in side},
        {s: os20 for s in side},
        "",
        track,
        {s: os10b for s in side},
        {s: init for s in side},
    )


def test_imo_10_10_overshoot_limit_follows_l_over_v():
    """MSC.137(76) 5.3.3.1: 10 deg below L/V 10 s, 20 deg from 30 s, 5 + (L/V)/2 between."""
    from primitives.particulars.trials import imo_overshoot_10_limit

    assert imo_overshoot_10_limit(5.0) == 10.0 and imo_overshoot_10_limit(9.99) == 10.0
    assert imo_overshoot_10_limit(10.0) == 10.0 and imo_overshoot_10_limit(20.0) == 15.0
    assert imo_overshoot_10_limit(29.9) == pytest.approx(19.95) and imo_overshoot_10_limit(30.0) == 20.0
    assert imo_overshoot_10_limit(60.0) == 20.0


def test_imo_10_10_second_overshoot_limit_follows_l_over_v():
    """MSC.137(76) 5.3.3.2: 25 deg below L/V 10 s, 40 deg from 30 s, 17.5 + 0.75 L/V between."""
    from primitives.particulars.trials import imo_second_overshoot_10_limit

    assert imo_second_overshoot_10_limit(9.99) == 25.0 and imo_second_overshoot_10_limit(10.0) == 25.0
    assert imo_second_overshoot_10_limit(20.0) == 32.5 and imo_second_overshoot_10_limit(30.0) == 40.0


def test_figures_inside_or_on_every_imo_limit_give_no_warning():
    from primitives.particulars.trials import imo_warnings

    assert imo_warnings(_figures(), 200.0, 10.0) == []  # inside every limit (L/V 20 s)
    on = _figures(td=5.0, adv=4.5, os10=15.0, os20=25.0, track=15.0, os10b=32.5, init=2.5)
    assert imo_warnings(on, 200.0, 10.0) == []  # "should not exceed": on the limit passes


@pytest.mark.parametrize(
    ("figures", "criterion", "ours", "limit", "count"),
    [
        (dict(td=5.2), "tactical diameter", "5.20 L", "5 L", 2),
        (dict(adv=4.6), "advance", "4.60 L", "4.5 L", 2),
        (dict(init=2.6), "initial turning", "2.60 L", "2.5 L", 2),
        (dict(os10=15.5), "10/10 zig-zag first overshoot", "15.50 deg", "15 deg", 2),  # L/V 20 s
        (dict(os10b=33.0), "10/10 zig-zag second overshoot", "33.00 deg", "32.5 deg", 2),
        (dict(os20=25.5), "20/20 zig-zag first overshoot", "25.50 deg", "25 deg", 2),
        (dict(track=16.0), "stopping track reach", "16.00 L", "15 L", 1),  # one stop
    ],
)
def test_each_imo_criterion_is_warned_with_ours_and_the_limit(figures, criterion, ours, limit, count):
    from primitives.particulars.trials import imo_warnings

    lines = imo_warnings(_figures(**figures), 200.0, 10.0)
    assert len(lines) == count, lines
    assert all(f"IMO criterion {criterion}" in w and f"ours {ours}, limit {limit}" in w for w in lines), lines
    assert not any("shown for reference" in w for w in lines)  # 200 m: the resolution applies


def test_imo_figures_not_reached_are_said_unchecked_and_short_ships_are_for_reference():
    """A course-unstable ship whose heading never falls back has no overshoot: it gets a line, not
    silence. MSC.137(76) applies from 100 m: a 60 m ship's lines say they are for reference."""
    from primitives.particulars.trials import imo_warnings

    lines = imo_warnings(_figures(os10=None, os10b=None), 200.0, 10.0)
    assert len(lines) == 4 and all("not reached, cannot be checked" in w for w in lines), lines
    short = imo_warnings(_figures(td=5.2), 60.0, 10.0)
    assert len(short) == 2 and all("applies to ships of 100 m and over; shown for reference" in w for w in short)


def test_imo_stopping_beyond_the_large_ship_allowance_and_a_coasting_stop():
    from primitives.particulars.trials import imo_warnings

    assert "up to 20 L" in imo_warnings(_figures(track=18.0), 200.0, 10.0)[0]
    assert "over the 20 L allowed" in imo_warnings(_figures(track=21.0), 200.0, 10.0)[0]
    assert imo_warnings(_figures(track=None), 200.0, 10.0) == []  # no astern: no crash stop to check


# The Mariner class cargo ship (issue 31's second published ship) and its planar-motion-mechanism
# model (Chislett & Strom-Tejsen 1965, benchmarks/mariner_pmm.py) sailing the same manoeuvres with
# the same steering gear, as measured by benchmarks/bench_profile_new.py: 35 deg tactical diameter
# 1029 / 1070 m (starboard / port), 10/10 first overshoot 6.4 / 4.7 deg.
MARINER = Particulars("mariner", 160.93, 23.17, 7.47, 0.6, 15.0)
PMM_TACTICAL_M = (1029.0, 1070.0)
PMM_OVERSHOOT_10 = (6.4, 4.7)


@cache
def mariner_built():
    return build_profile(MARINER, oe_nfev=0, draws=2, seed=1)


@cache
def mariner_figures():
    return standard_trials(mariner_built().profile)


def test_the_fine_hull_note_names_the_eps_regression_and_its_limits():
    """Below Kijima's eps maximum (Mariner 0.086 < 0.133) the header says eps is Lee & Shin's,
    second-hand, with Kijima's value beside it; KVLCC2 (0.147) gets Kijima's eps and no note."""
    text = mariner_built().text
    assert "eps 0.944: Lee & Shin (1998)" in text
    assert "Fine hull (Cb B/L 0.0864 < 0.1329" in text and "gives 0.666 here" in text and "second-hand" in text
    assert "Fine hull" not in kvlcc2_built().text
    assert "eps 0.974: Kijima et al. (1990)" in kvlcc2_built().text


def test_a_fine_hull_is_told_both_eps_regressions_and_the_clip():
    """An inland-vessel-like hull (L 110 m, B 11.45 m, T 3.5 m, Cb 0.85: Cb B/L 0.088, 2T/L 0.064):
    Lee & Shin's 2.457 is cut to Kijima's maximum 1.004, Kijima gives 0.696; the note says all
    three (the note), and the prior spread is the gap between the eps used and Kijima's (31 %)."""
    from primitives.particulars.build import coefficient_spreads, fine_hull_note

    barge = Particulars("barge", 110.0, 11.45, 3.5, 0.85, 10.0)
    assert rg.lee_shin_eps(barge.hull) == pytest.approx(2.457, abs=1e-3)
    note = fine_hull_note(barge)
    assert note.startswith("eps 1.004 (the rudder's inflow): Lee & Shin (1998)'s 2.457 cut to the maximum of Kijima")
    assert "Kijima et al. (1990)'s quadratic gives 0.696" in note
    assert coefficient_spreads(barge)["eps"] == pytest.approx((1.004 - 0.696) / 1.004, abs=1e-3)
    assert any(n.startswith("eps 0.944 (the rudder's inflow): Lee & Shin (1998);") for n in mariner_built().notes)
    assert kvlcc2_built().notes == []


def test_a_fine_hulls_eps_prior_spread_is_the_gap_to_kijimas():
    from primitives.particulars.build import coefficient_spreads

    assert coefficient_spreads(MARINER)["eps"] == pytest.approx((0.944 - 0.666) / 0.944, abs=2e-3)
    assert coefficient_spreads(KVLCC2)["eps"] == 0.2


def test_the_eps_spread_reaches_the_profiles_prior(monkeypatch):
    """The eps spread is carried into [prior] std (what `design`'s robust criteria draw from when no
    other prior is given): with every other spread 0, no eps spread gives no prior, and the Mariner's
    29 % gives a wider one than 20 % (same seed, the same normal draws scaled)."""
    from primitives.particulars import build as bd

    b, full = mariner_built(), bd.coefficient_spreads(MARINER)

    def std(eps_spread: float) -> np.ndarray:
        monkeypatch.setattr(bd, "coefficient_spreads", lambda p: dict.fromkeys(full, 0.0) | {"eps": eps_spread})
        return bd.prior_std(MARINER, b.mmg, b.approach_rps, bd.sample_time(MARINER), 1.15 * b.approach_rps, 4, 0)

    assert np.all(std(0.0) == 0.0)
    assert np.sum(std(full["eps"])) > 1.2 * np.sum(std(0.2)) > 0.0


def test_mariner_from_particulars_zigzags_like_its_pmm_model():
    """The part of the second ship's check that passes (10/10 first overshoot within 4 deg of each
    PMM run)."""
    fig = mariner_figures()
    for side in ("starboard", "port"):
        assert all(abs(fig.overshoot_10[side] - m) <= 4.0 for m in PMM_OVERSHOOT_10), fig.overshoot_10


def test_mariner_from_particulars_turns_like_its_pmm_model():
    """35 deg tactical diameter within 20 % of each PMM run. With Kijima's eps (0.67) this failed at
    +61 %; Lee & Shin's eps (0.944) for hulls finer than Kijima's maximum brings it in."""
    fig = mariner_figures()
    for side in ("starboard", "port"):
        td = fig.tactical_l[side] * MARINER.length
        assert all(abs(td - m) <= 0.20 * m for m in PMM_TACTICAL_M), td


def test_a_built_profile_has_no_astern_so_the_imo_stop_is_said_unchecked():
    """Profiles from particulars have no astern power (rps_limits from 0): the stop is a coast,
    no track reach is checked, and the printed line says so rather than passing it silently."""
    from primitives import helm as hm
    from primitives.particulars.trials import describe

    prof = kvlcc2_built().profile
    assert prof.engine.rps_limits[0] == 0.0 and not hm.has_astern(prof)
    fig = standard_trials(prof)
    assert fig.stop_track_l is None
    assert "stopping criterion (full-astern track reach) is not checked" in describe(fig, prof.length_m)[-1]


def test_a_full_astern_stop_gets_its_track_reach_measured_from_the_execute_point(monkeypatch):
    """The track reach of a crash stop is the path length sailed after the execute point. No
    profile from particulars goes astern yet, so the test declares KVLCC2's engine stop a
    full-astern one and checks the reach against the same primitive measured here from its
    execute point, which differs from the reach from the primitive's start by its approach."""
    from primitives import helm as hm
    from primitives.library import make_primitive
    from primitives.particulars.trials import imo_warnings

    prof = kvlcc2_built().profile
    monkeypatch.setattr(hm, "has_astern", lambda profile: True)
    fig = standard_trials(prof)
    gen, what = hm.stopping(prof)
    st = make_primitive(prof, "stop", what, gen)
    assert st.split_points, "the stop has an execute point"

    def path_l(xy):
        return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))) / prof.length_m

    from_execute, from_start = path_l(st.track[st.split_points[0] :, :2]), path_l(st.track[:, :2])
    assert from_start - from_execute > 0.5  # the approach before the execute point
    assert fig.stop_track_l == pytest.approx(from_execute, rel=1e-9)
    assert 15.0 < fig.stop_track_l < 40.0  # a coast to half speed runs long: over IMO's 15 L
    assert "not stopped: still" in fig.stopping  # it ends at half speed: a crash stop that did not stop says so
    assert any(
        w.startswith("IMO criterion stopping track reach") for w in imo_warnings(fig, prof.length_m, prof.cruise_speed_mps)
    )
