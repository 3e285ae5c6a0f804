"""Recordings for trying ``plan-trial --resume`` without a ship: the first manoeuvres of a plan
as a ship whose parameters differ from its profile's would sail them (docs/commands/plan-trial.md:
'Resuming a trial: re-design from the first recordings').
Simulated on the profile's own model structure at drawn parameters: an example, not evidence."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diagnose.recording import write_csv
from maps.plan import Plan
from maps.resume import simulated_recordings
from primitives.ship import load_profile

NOISE = (0.02, 0.02, 0.0005)  # u, v (m/s), r (rad/s): a full-scale ship's GNSS/gyro-derived velocities


def example_recordings(plan_path: str | Path, out_dir: str | Path, manoeuvres: int, spread: float = 0.2, seed: int = 0) -> str:
    """Write the recordings of the plan's first ``manoeuvres`` informative steps into ``out_dir``
    (parameters drawn within +-``spread`` of the profile's, seeded) and return the ship's position
    after the last, ``LAT,LON,HEADING_DEG`` as ``--from`` takes it."""
    plan = Plan.load(plan_path)
    prof = load_profile(plan.ship)
    steps = [s for s in plan.steps if s.segment == "informative"][:manoeuvres]
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(28, 8)))
    theta = prof.params() * (1 + spread * rng.uniform(-1, 1, prof.params().shape))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for rec in simulated_recordings(plan, prof, steps, theta, NOISE, seed):
        write_csv(rec, out / rec.source)
    k = int(np.nonzero(plan.step_of_sample == steps[-1].index)[0][-1])
    return f"{plan.lonlat[k, 1]:.6f},{plan.lonlat[k, 0]:.6f},{np.degrees(plan.track[k, 2]) % 360:.1f}"
