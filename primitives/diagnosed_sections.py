"""The sections a diagnosed ``model.json`` (``diagnose.model_file``) adds beside its ship profile, checked when the
file is read as a ship (``--ship model.json``, :func:`primitives.profile_document.profile_from_dict`): the
``augmentations`` list, the ``diagnosed_model`` table, and that the profile part is the scored ship."""

from __future__ import annotations

from typing import Any

from primitives.errors import UserError
from primitives.ship import ROLL_DOFS, ProfileError
from primitives.validate import check_table_keys


def diagnosed_current(d: dict) -> bool:
    """Whether ``d`` is a diagnosed model.json whose findings include a current (in the summary,
    ``augmentations``, or in the exact model, ``diagnosed_model.candidates``)."""
    dm = d.get("diagnosed_model")
    if not isinstance(dm, dict):
        return False
    listed = [a for a in (d.get("augmentations"), dm.get("candidates")) if isinstance(a, list)]
    return any(isinstance(a, dict) and a.get("effect") == "current" for lst in listed for a in lst)


# The sections a diagnosed model.json (diagnose.model_file) adds beside the profile. A profile
# read from such a file reads neither, but refuses a malformed one; diagnose.model_file.load_model
# checks the rest of what it reads (the baseline profile, the candidates and their values).
AUGMENTATION_KEYS = ("effect", "dof", "parameters")
DIAGNOSED_MODEL_KEYS = ("format", "note", "baseline_profile", "half_sample_s", "candidates")
MODEL_JSON_FIX = "write the model.json again with `shiptrial diagnose --out DIR`, or remove the field"


def check_diagnosed_sections(d: dict[str, Any], src: str, error: type[UserError] = ProfileError) -> None:
    """Refuse a malformed ``augmentations`` list or ``diagnosed_model`` table of a diagnosed
    model.json in one line naming the file, the field and the fix."""
    aug = d.get("augmentations")
    if aug is not None:
        if not isinstance(aug, list) or not all(isinstance(a, dict) for a in aug):
            raise error(
                f"{src}: field 'augmentations' must be a list of tables with {', '.join(AUGMENTATION_KEYS)}: {MODEL_JSON_FIX}"
            )
        for i, a in enumerate(aug):
            check_table_keys(a, AUGMENTATION_KEYS, src, f"[[augmentations]] number {i + 1}", error)
            if not isinstance(a.get("effect"), str) or not a["effect"]:
                raise error(
                    f"{src}: field 'augmentations.{i}.effect' must name the effect (e.g. 'current'), got {a.get('effect')!r}: "
                    f"{MODEL_JSON_FIX}"
                )
            if a.get("dof") not in (None, *ROLL_DOFS):
                raise error(
                    f"{src}: field 'augmentations.{i}.dof' must be one of {list(ROLL_DOFS)} or null, got {a.get('dof')!r}: "
                    f"{MODEL_JSON_FIX}"
                )
            if not isinstance(a.get("parameters", {}), dict):
                raise error(
                    f"{src}: field 'augmentations.{i}.parameters' must be a table of the effect's values, got "
                    f"{a['parameters']!r}: {MODEL_JSON_FIX}"
                )
    dm = d.get("diagnosed_model")
    if dm is not None:
        if not isinstance(dm, dict):
            raise error(
                f"{src}: field 'diagnosed_model' must be a table with {', '.join(DIAGNOSED_MODEL_KEYS)}: {MODEL_JSON_FIX}"
            )
        check_table_keys(dm, DIAGNOSED_MODEL_KEYS, src, "[diagnosed_model]", error)


# diagnose.model_file.FORMAT (the library layer does not import the diagnosis; a test keeps them equal)
DIAGNOSED_FORMAT = "shiptrial-diagnosed-model/1"


def check_model_json_as_ship(d: dict[str, Any], src: str, actuator: str, inputs: tuple[str, ...], sample_time: float) -> None:
    """A diagnosed model.json given as a ship (``--ship model.json``): the profile part is what
    the commands read, so what would make it another model than the one scored is refused in one
    line naming the file, the field and the fix: a format of another version, a
    ``diagnosed_model`` whose baseline is another ship (actuator, inputs, sample time) or whose
    half-sample shift or candidate list is malformed, and a current among the findings that the
    profile part has lost (``disturbances.current_mean_ne``)."""
    dm = d.get("diagnosed_model")
    if dm is None:
        return
    if dm.get("format") != DIAGNOSED_FORMAT:
        raise ProfileError(
            f"{src}: field 'diagnosed_model.format' must be {DIAGNOSED_FORMAT!r}, got {dm.get('format')!r}: {MODEL_JSON_FIX}"
        )
    base = dm.get("baseline_profile")
    if not isinstance(base, dict):
        raise ProfileError(
            f"{src}: field 'diagnosed_model.baseline_profile' must be the scored ship profile (a table): {MODEL_JSON_FIX}"
        )
    ours = {"actuator": actuator, "inputs": list(inputs), "sample_time": sample_time}
    theirs = {
        "actuator": base.get("actuator", "generalized"),
        "inputs": base.get("inputs"),
        "sample_time": base.get("sample_time"),
    }
    for k, v in ours.items():
        if theirs[k] != v:
            raise ProfileError(
                f"{src}: field 'diagnosed_model.baseline_profile.{k}' is {theirs[k]!r} and the profile's '{k}' is "
                f"{v!r}: the two parts are different ships; {MODEL_JSON_FIX}"
            )
    half = dm.get("half_sample_s", 0.0)
    if isinstance(half, bool) or not isinstance(half, int | float) or not 0.0 <= half <= sample_time:
        raise ProfileError(
            f"{src}: field 'diagnosed_model.half_sample_s' must be a number of seconds in 0..{sample_time:g} "
            f"(the model's half-sample shift), got {half!r}: {MODEL_JSON_FIX}"
        )
    cands = dm.get("candidates", [])
    if not isinstance(cands, list) or not all(isinstance(c, dict) for c in cands):
        raise ProfileError(f"{src}: field 'diagnosed_model.candidates' must be a list of tables: {MODEL_JSON_FIX}")
    if diagnosed_current(d) and "current_mean_ne" not in (d.get("disturbances") or {}):
        raise ProfileError(
            f"{src}: field 'disturbances.current_mean_ne' is missing, and the findings ('augmentations') include "
            f"a current: {MODEL_JSON_FIX}"
        )
