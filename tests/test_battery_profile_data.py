"""The battery chooses its effects and noise from the profile's data (its manoeuvre library), not
from its name: a renamed copy of a bundled ship gets the same battery."""

from __future__ import annotations

import dataclasses

from diagnose.battery import EFFECTS, FULL_SCALE_EFFECTS, effects_for
from primitives.ship import load_profile


def test_renamed_profile_gets_the_battery_of_its_library():
    full = load_profile("full-scale")
    assert effects_for(dataclasses.replace(full, name="my-vessel")) is FULL_SCALE_EFFECTS
    assert effects_for(dataclasses.replace(load_profile("model-ship"), name="full-scale-copy")) is EFFECTS
