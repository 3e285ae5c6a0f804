"""One model (issue 13): the diagnosis simulates with the primitives' kernel, and the exported
model.json is exactly the scored model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from diagnose.api import run
from diagnose.battery import scenario
from diagnose.candidates import Candidate, Slot, build_library
from diagnose.model import AugmentedModel, fit_percent, prepare
from diagnose.model_file import load_model
from diagnose.recording import Recording
from diagnose.report import write_all
from primitives.profile_document import profile_from_dict
from primitives.ship import DOFS, load_profile
from primitives.simulate import WIND_EXCESS, Disturbances, simulate
from primitives.terms import TermSet

CURRENT = (0.035, -0.035)
WIND = (-6.0, 4.0)
WIND_COEF = (-4e-4, -8e-4, -2e-4)


@pytest.fixture(scope="module")
def ship():
    return load_profile("model-ship")


def test_augmented_model_is_the_kernel_with_a_current_and_wind(ship):
    """A noise-free run of primitives.simulate in a current and a wind (the wind as the kernel's
    wind-load terms, primitives.simulate.WIND_EXCESS; the current turned into the velocity over
    ground as the ship turns) is reproduced by the diagnosis's model with its current and wind
    slots set to the truth: the same step, so the same numbers to rounding."""
    x = scenario((), 3, n_prims=4).diagnose[0].inputs_for(ship.inputs)
    terms = [list(t) for t in ship.model_terms]
    theta = [list(ship.params()[ship.model.dof_slice(i)]) for i in range(3)]
    for i, (tw, c) in enumerate(zip(WIND_EXCESS, WIND_COEF)):
        terms[i] += [tw]
        theta[i] += [c]
    nu0 = np.array([0.6, 0.0, 0.0])
    sim = simulate(
        ship,
        x[:-1],
        np.concatenate(theta),
        terms=TermSet(terms),
        nu0=nu0,
        disturbances=Disturbances(current_ne=CURRENT, wind_ne=WIND),
        current_turning=True,
    )
    chans = {n: x[:, j] for j, n in enumerate(ship.inputs)}
    n = len(sim.t)
    chans["wind_speed"] = np.full(n, float(np.hypot(*WIND)))
    chans["wind_dir"] = np.full(n, float(np.arctan2(-WIND[1], -WIND[0])))  # where it comes from
    rec = Recording("kernel", sim.t, sim.nu[0], sim.eta[0, :, 2], sim.eta[0, :, :2], chans)
    cands, _ = build_library(ship, [rec])
    # the library's wind candidate is the recorded wind's Blendermann loads (diagnose.windload);
    # the kernel's wind-load terms enter the same model as term slots
    kernel_wind = Candidate(
        "wind", "wind", tuple(Slot("term", f"wind_{DOFS[i]}", dof=i, term=t) for i, t in enumerate(WIND_EXCESS))
    )
    cands = [c for c in cands if c.effect != "wind"] + [kernel_wind]
    model = AugmentedModel(ship, ship.params(), cands)
    P = model.p0()
    P[model.slot_of["current"]] = CURRENT
    P[model.slot_of["wind"]] = WIND_COEF
    prep = dataclasses.replace(prepare(ship, rec), y0=nu0)
    yhat = model.simulate(prep, P)[0]
    assert np.max(np.abs(sim.nu[0])) > 0.5  # the run moves
    np.testing.assert_allclose(yhat, sim.nu[0], rtol=1e-9, atol=1e-12)
    # and the current and the wind matter: without them the model is far off
    assert np.max(np.abs(model.simulate(prep, model.p0())[0] - sim.nu[0])) > 0.05
    # and the turning of the current matters (the ship turns through it)
    flat = simulate(
        ship,
        x[:-1],
        np.concatenate(theta),
        terms=TermSet(terms),
        nu0=nu0,
        disturbances=Disturbances(current_ne=CURRENT, wind_ne=WIND),
    )
    assert np.max(np.abs(flat.nu[0] - sim.nu[0])) > 0.01


def test_exported_model_with_refit_baseline_and_delay_current_reproduces_per_run_fit(ship, tmp_path):
    """A diagnosis whose baseline is refitted (--fit-on) and which finds a delay and a current:
    model.json holds the refitted baseline and the findings; reloaded and simulated on the
    validation runs, it gives the reported per-run fit."""
    sc = scenario(("current", "actuator_delay"), 7, n_prims=6)
    calm = scenario((), 8, n_prims=6).diagnose
    d = run(sc.diagnose, ship, fit_on=calm, validate=sc.validate)
    effects = {f["effect"] for f in d.findings + d.structure}
    assert {"current", "actuator_delay"} <= effects, effects
    assert not np.allclose(d.theta, ship.params())  # the baseline was refitted
    paths = write_all(d, tmp_path)
    model, P = load_model(paths["model"])
    np.testing.assert_array_equal(P[: model.n_base], d.P[: d.model.n_base])  # the scored baseline, refit included
    assert d.per_run and all(row["role"] == "validation" for row in d.per_run)
    for row, p in zip(d.per_run, d.val_preps):
        fit = fit_percent(p.y, model.simulate(prepare(model.profile, p.rec), P)[0])
        np.testing.assert_allclose(fit, [row["after"][k] for k in DOFS], atol=1e-6)


def test_closed_loop_generators_step_with_the_kernel(ship):
    """A heading-switched zig-zag generated in closed loop (maneuvers.model_step) is the same
    trajectory, bit for bit, as primitives.simulate driven by the forces it produced."""
    from primitives.maneuvers import closed_loop, excitation_zigzag

    gen = excitation_zigzag(ship, 300, 0.8, 0.1, 0.2, np.radians(10))
    forces, psi = closed_loop(ship, lambda k, nu, psi, memo: tuple(gen.forces[k]) if k < len(gen.forces) else None, 1000, gen.nu0)
    sim = simulate(ship, ship.allocate(*forces.T), nu0=gen.nu0)
    assert len(gen.split_points) >= 2
    np.testing.assert_array_equal(psi, sim.eta[0, :, 2])


def test_closed_loop_reads_the_speed_through_the_water(ship):
    """A model term in the speed through the water U (the kernel's signal) works in the closed-loop
    generators too: before they stepped with their own signals and failed with KeyError 'U'."""
    from primitives.maneuvers import zigzag

    d = ship.to_dict()
    d["model"]["yaw"][0] = "r*U"  # N_r r U: the same damping at 1 m/s, hull-force scaling elsewhere
    prof = profile_from_dict(d, "<test>")
    gen = zigzag(prof, 20, 20, n_switches=2)
    sim = simulate(prof, prof.allocate(*gen.forces.T), nu0=gen.nu0)
    assert len(gen.split_points) == 2
    # the helm reversed at the first sample where the kernel's heading had passed 20 deg
    psi = np.degrees(sim.eta[0, :, 2])
    k = gen.split_points[0]
    assert psi[k - 1] < 20 <= psi[k]


@pytest.mark.parametrize("name", ["full-scale", "model-ship", "kvlcc2", "kvlcc2-linear"])
def test_one_ship_float_step_is_the_batch_step(name):
    """The closed-loop generators step one ship on Python floats (VelocityStep.next_one): the
    bits of the kernel's batch step with the inputs as arrays, as primitives.simulate gives them
    (squares of states and of inputs alike, e.g. kvlcc2's delta*n^2)."""
    from primitives.simulate import VelocityStep

    prof = load_profile(name)
    step = VelocityStep(prof.model, prof.params(), prof.rigid_body, prof.sample_time)
    assert step.scalar
    rng = np.random.default_rng(3)
    names = ("tau_x", "tau_y", "tau_n") if prof.actuator != "rudder_propeller" else prof.inputs
    n = 20000  # enough that pow() on a float would differ from a product somewhere (about 1 in 1000 squares)
    nu = rng.normal(size=(n, 3)) * (5.0, 1.0, 0.01)
    ins = rng.normal(size=(n, len(names))) * 3.0
    batch = step(nu, dict(zip(names, ins.T.copy())) | {"psi": np.full(n, 0.2)})
    one = [step.next_one(nu[i], dict(zip(names, ins[i].tolist())) | {"psi": 0.2}) for i in range(n)]
    np.testing.assert_array_equal(np.array(one), batch)


@pytest.mark.parametrize("name", ["full-scale", "kvlcc2"])
@pytest.mark.parametrize("positions", [True, False])
def test_one_ship_simulation_is_the_batch_simulation(name, positions):
    """simulate() of one ship in calm water runs on floats (primitives.onestep.one_ship_loop): the same
    velocities and pose, bit for bit, as the same ship in a batch of two (the array loop)."""
    prof = load_profile(name)
    rng = np.random.default_rng(4)
    lim = [prof.input_limits.get(k, (-1.0, 1.0)) for k in prof.inputs]
    x = rng.uniform([lo for lo, _ in lim], [hi for _, hi in lim], (400, len(prof.inputs))) * 0.3
    kw = {"nu0": (prof.cruise_speed_mps, 0.1, 0.001), "eta0": (10.0, -5.0, 0.3), "positions": positions}
    one, two = simulate(prof, x, **kw), simulate(prof, x, batch=2, **kw)
    assert np.max(np.abs(one.nu[0, :, 2])) > 1e-3  # it turns
    np.testing.assert_array_equal(one.nu[0], two.nu[0])
    np.testing.assert_array_equal(one.eta[0], two.eta[0])
