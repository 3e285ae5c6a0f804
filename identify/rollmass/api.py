"""Library entry points of the mass / CoG estimator (the CLI is a thin layer over these).

Heights are body-frame ``z`` in metres, origin at the waterline amidships, **positive down**: a
load on deck 0.256 m above the waterline is ``z = -0.256``; the keel is at ``z = draft``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from identify.rollmass.estimate import DEFAULT_METHOD, METHODS, MassEstimate, estimate
from identify.rollmass.model import Load, RollProfile, load_profile
from identify.rollmass.output_error import start_values
from identify.rollmass.recording import read_roll_csv
from identify.rollmass.restoring import DEFAULT_HEEL_REFERENCE, HEEL_REFERENCES
from identify.rollmass.roles import loaded_message, measure_roles, role_message, role_verdict, unjudged_message
from identify.rollmass.signs import (
    check_signs,
    expected_signs,
    gain_signs,
    rudder_scale_message,
    steady_gains,
    yaw_scale_message,
)
from identify.rollmass.simulate import RollRecording
from identify.rollmass.speed import SPEED_LP_HZ, SPEED_NOISE_RATIO, SPEED_VAR_MIN, followed_speed, speed_variation
from primitives.errors import UserError
from primitives.profile_tables import names_ship, ship_name_words

ROLES = ("nominal", "calibration", "loaded")
SPEED_TOL = 0.25  # relative: recordings' speed vs the profile's, and between the three runs (turns slow a run)
IMU_TOL = 0.005  # m
LOAD_TOL = (0.001, 0.005)  # kg, m: --known-load vs the calibration file's header
KNOT = 1852.0 / 3600.0  # m/s
Z_WORDS = "z in metres, positive down from the waterline amidships (a load on deck is negative)"


def parse_known_load(text: str) -> Load:
    """``"KG@Z"`` (mass in kg at body-frame z in m, positive down) -> :class:`Load`."""
    if "@" not in text:
        raise UserError(f"--known-load {text!r}: unknown load position; write KG@Z, e.g. 0.2@-0.256 ({Z_WORDS})")
    kg, _, m = text.partition("@")
    try:
        load = Load(float(kg), float(m))
    except ValueError:
        raise UserError(f"--known-load {text!r}: not numbers; write KG@Z, e.g. 0.2@-0.256 ({Z_WORDS})") from None
    if not (0 < load.m < 1e6 and abs(load.zbar) < 1e3):
        raise UserError(f"--known-load {text!r}: give a finite mass > 0 kg and a z within the hull ({Z_WORDS}), e.g. 0.2@-0.256")
    return load


def hull_limits(prof: RollProfile) -> tuple[float, float]:
    """``(z_top, z_keel)``: where a load can sit (profile ``load_z_top``, draft)."""
    ship = prof.raw["ship"]
    return float(ship.get("load_z_top", -1.0)), float(ship["draft"])


def check_load_in_hull(load: Load, prof: RollProfile, what: str) -> None:
    """Refuse a load position below the keel or above the highest place a load can sit, and a load
    heavier than the ship can carry (``max_load_kg``: a mass in grams read as kg lands there)."""
    top, keel = hull_limits(prof)
    cap = float(prof.raw["ship"].get("max_load_kg", np.inf))
    if load.m > cap:
        raise UserError(
            f"{what}: {load.m:g} kg is more than the ship can carry (max_load_kg {cap:g} in the profile); "
            "give the load in kg (not g)"
        )
    if load.zbar > keel:
        raise UserError(
            f"{what}: z = {load.zbar:+g} m is {load.zbar - keel:.3f} m below the keel (draft {keel:g} m); "
            f"{Z_WORDS}: did you mean {load.m:g}@{-load.zbar:g}?"
        )
    if load.zbar < top:
        raise UserError(
            f"{what}: z = {load.zbar:+g} m is above the highest place a load can sit in the profile "
            f"(load_z_top = {top:g} m; {Z_WORDS})"
        )


def check_imu_in_hull(key: str, val: float, prof: RollProfile, paths: list[Path]) -> None:
    """Refuse an IMU position (header ``imu_z_m`` or ``imu_x_m``) no ship carries it at: z below the keel
    or higher above the waterline than the ship is long (an IMU may sit on a mast or the bridge, above any
    load), x beyond half the length between perpendiculars of midship (a position in mm, or a height given
    positive up, lands outside)."""
    keel, length = hull_limits(prof)[1], float(prof.raw["ship"].get("L_pp", np.inf))
    lo, hi, what = (
        (-length, keel, Z_WORDS)
        if key == "imu_z_m"
        else (-0.5 * length, 0.5 * length, "x in metres, positive forward of midship")
    )
    if not lo <= val <= hi:
        raise UserError(
            f"{', '.join(p.name for p in paths)}: header '# {key}: {val:g}' puts the IMU where the ship cannot carry it "
            f"({lo:+g} .. {hi:+g} m for this profile: below the keel, higher than L_pp above the waterline, or beyond "
            f"the perpendiculars; {what}); correct the header"
        )


def _meta_float(meta: dict[str, str], key: str, path: Path) -> float | None:
    if key not in meta:
        return None
    try:
        return float(meta[key])
    except ValueError:
        raise UserError(f"{path}: header '# {key}: {meta[key]}' is not a number; write e.g. '# {key}: 0.5'") from None


def _header_load(meta: dict[str, str], path: Path, need_z: bool) -> Load | None:
    """The load a header states (``load_kg``, ``load_z_m``); its z is required only where it is used
    (``need_z``: the calibration run's known load), elsewhere only the mass is read."""
    if "load_height_m" in meta:  # a height reads as positive up, our z is positive down: refuse the guess
        raise UserError(
            f"{path}: header key 'load_height_m' is ambiguous (a height is positive up); write '# load_z_m: Z' ({Z_WORDS})"
        )
    kg = _meta_float(meta, "load_kg", path)
    z = _meta_float(meta, "load_z_m", path)
    if kg is None:
        return None
    if kg > 0 and z is None and need_z:
        raise UserError(f"{path}: header has load_kg but no load_z_m; add '# load_z_m: Z' ({Z_WORDS})")
    return Load(kg, z or 0.0)


def check_roles(paths: list[Path], metas: list[dict[str, str]]) -> list[Load | None]:
    """Each file's header against the role its position gives it; returns the header loads (a z
    required only of the calibration run's, the one known load)."""
    loads = [_header_load(m, p, role == "calibration") for role, p, m in zip(ROLES, paths, metas)]
    for role, path, meta, load in zip(ROLES, paths, metas, loads):
        said = meta.get("role", "").strip().lower()
        if said and said not in ROLES:
            raise UserError(f"{path}: header role '{said}' is not one of {', '.join(ROLES)}")
        if said and said != role:
            raise UserError(
                f"{path}: its header says role '{said}' but it was given as the {role} run; "
                f"give the files in the order NOMINAL CALIBRATION LOADED"
            )
        if role == "nominal" and load is not None and load.m > 0:
            raise UserError(
                f"{path}: its header says load_kg {load.m:g} but it was given as the nominal run (no extra load); "
                f"give the files in the order NOMINAL CALIBRATION LOADED"
            )
        if role == "calibration" and load is not None and load.m <= 0:
            raise UserError(
                f"{path}: its header says load_kg {load.m:g} but it was given as the calibration run (a known load); "
                f"give the files in the order NOMINAL CALIBRATION LOADED"
            )
    return loads


def check_ship(prof: RollProfile, paths: list[Path], metas: list[dict[str, str]], explicit: bool) -> list[str]:
    """Refuse recordings whose '# ship:' headers differ between the runs, or name another ship than the
    default profile's (``[ship] name`` or ``vessel``), both compared as diagnose compares them, case and punctuation
    aside (:func:`primitives.profile_tables.names_ship`): the fit would take the profile's hull, inertia and
    hydrodynamics for another ship's (stop 52's sweep: '# ship: seed003_basin' with the default profile was read without a
    word). With a ``--profile`` the user chose, a header naming another ship is a warning: it may be a
    stale default (main's mass-sim wrote 'our_lass_ii' whatever the profile; stop 52's review, 4)."""
    said = [(p, m["ship"].strip()) for p, m in zip(paths, metas) if m.get("ship", "").strip()]
    if len({ship_name_words(s) for _, s in said}) > 1:
        raise UserError(
            f"the recordings' '# ship:' headers differ ({', '.join(f'{p.name} {s}' for p, s in said)}); "
            "the three runs must come from one ship"
        )
    if not said or names_ship(said[0][1], prof.name, prof.vessel):  # diagnose's rule, the profile's vessel too
        return []
    msg = f"{said[0][0]}: header '# ship: {said[0][1]}' but the profile is {prof.name}'s"
    if explicit:
        return [f"{msg} (--profile): the profile given is used; correct the header if the profile is right"]
    raise UserError(f"{msg} (the default profile); give that ship's roll profile with --profile")


def _calibration_load(opt: Load | None, header: Load | None, path: Path) -> Load:
    if opt is None and header is None:
        raise UserError(f"{path}: no known load; give --known-load KG@Z or the header lines '# load_kg:' and '# load_z_m:'")
    if (
        opt is not None
        and header is not None
        and (abs(opt.m - header.m) > LOAD_TOL[0] or abs(opt.zbar - header.zbar) > LOAD_TOL[1])
    ):
        raise UserError(
            f"--known-load {opt.m:g}@{opt.zbar:g} contradicts {path}'s header (load_kg {header.m:g}, load_z_m "
            f"{header.zbar:g}); correct one of them ({Z_WORDS})"
        )
    return opt if opt is not None else header


def known_from_recordings(
    prof: RollProfile, paths: list[Path], metas: list[dict[str, str]], explicit: bool
) -> tuple[RollProfile, list[str]]:
    """The profile with the recordings' speed and IMU z; a given profile that contradicts them is refused."""
    notes = []
    kn = prof.known
    for key, field, unit in (("speed_m_s", "U", "m/s"), ("imu_z_m", "zbar_s", "m"), ("imu_x_m", "xbar_s", "m")):
        vals = [(p, v) for p, m in zip(paths, metas) if (v := _meta_float(m, key, p)) is not None]
        if not vals:
            continue
        arr = np.array([v for _, v in vals])
        speed = key == "speed_m_s"
        lim = SPEED_TOL if speed else IMU_TOL
        if (np.ptp(arr) / np.mean(np.abs(arr)) if speed else np.ptp(arr)) > lim:
            raise UserError(
                f"{key} differs between the recordings ({', '.join(f'{p.name} {v:g}' for p, v in vals)}); "
                f"the three runs must be at one speed with the IMU in one place"
            )
        val, have = float(np.mean(arr)), getattr(kn, field)
        if not speed:
            check_imu_in_hull(key, val, prof, [p for p, _ in vals])
        if explicit and (abs(val - have) / abs(have) if speed else abs(val - have)) > lim:
            raise UserError(
                f"the profile's [known] {field} = {have:g} {unit} contradicts the recordings' {key} "
                f"{val:g}; correct the profile or the headers"
            )
        if abs(val - have) > 1e-9:
            notes.append(f"{field} = {val:g} {unit} from the recordings' {key} header (the profile has {have:g})")
        kn = replace(kn, **{field: val})
    return replace(prof, known=kn), notes


def speed_notes(recs: list[RollRecording], paths: list[Path]) -> list[str]:
    """Check each recording's measured speed ``u`` against its header speed; a recording without one, or
    whose speed's variation is within the positioning's error (:func:`speed.followed_speed`),
    gets a note that its speed is held through the run (``oe`` then neither follows a ship that slows
    in its turns, :func:`speed.speed_inputs`, nor takes the heel reference's centripetal
    ``u r`` at the speed of the moment, :func:`restoring.referenced_heel`)."""
    notes: list[str] = []
    no_u: dict[str, list[str]] = {}  # the files without u, by the speed held instead
    for rec, path in zip(recs, paths):
        if rec.u is not None and rec.U is not None and abs(np.mean(rec.u) / rec.U - 1) > SPEED_TOL:
            raise UserError(
                f"{path}: column 'u' has a mean of {np.mean(rec.u):g} m/s but the header says speed_m_s {rec.U:g}; "
                "give u in m/s (surge speed, positive ahead) or correct the header"
            )
        if rec.u is not None and followed_speed(rec) is None:
            slow, fast = speed_variation(rec)
            notes.append(
                f"{path.name}: column 'u' (surge speed) is held at the run's speed, not followed: its variation "
                f"below {SPEED_LP_HZ:g} Hz ({100 * slow:.1f} %) is not {SPEED_NOISE_RATIO:g} times the positioning's "
                f"error above it ({100 * fast:.1f} %) or not over {100 * SPEED_VAR_MIN:g} %"
                if np.isfinite(slow)
                else f"{path.name}: column 'u' (surge speed) is held at the run's speed, not followed: the recording is "
                f"shorter than two periods of its {SPEED_LP_HZ:g} Hz low-pass"
            )
        if rec.u is None:
            no_u.setdefault("speed_m_s" if rec.U is not None else "profile speed", []).append(path.name)
    # one note for every file without u (the bundled example's three files printed it three times)
    for held, names in no_u.items():
        notes.append(
            f"{', '.join(names)}: no column 'u' (surge speed): the speed is held at {'each' if len(names) > 1 else 'the'} "
            f"run's {held} throughout; a ship that slows in its turns is not followed (give u to follow it)"
        )
    return notes


def slowing_warning(recs: list[RollRecording], paths: list[Path], method: str) -> list[str]:
    """One warning when a recording's speed varies with its turns (:func:`speed.followed_speed`:
    above the positioning's error), with each such file's measured variation: the sd of its low-passed
    ``u / mean(u)`` and how far that falls below the mean. Why: on the independent basin truth's ships
    that slow in their turns (variants ``speed_loss`` and ``combined``) the oe fit, which follows the
    speed (:func:`speed.speed_inputs`), was off by tens of per cent, its intervals holding the truth
    in 10 of 12 fits at stop 50 (docs/mass-accuracy.md, stops 47-50); ``ls``, ``paper-iv`` and ``improved`` do not read
    ``u`` at all. The figures belong in the docs, the warning points there."""
    slowing = []
    for rec, path in zip(recs, paths):
        s = followed_speed(rec)
        if s is not None:
            slowing.append(f"{path.name} sd {100 * np.std(s):.1f} %, down to {100 * (1 - np.min(s)):.0f} % below its mean")
    if not slowing:
        return []
    how = (
        "oe follows it (identify/rollmass/speed.py)"
        if method == "oe"
        else f"method {method} holds the speed at the run's (it does not read u)"
    )
    return [
        f"the ship's speed varies with its turns ({'; '.join(slowing)}; column 'u' low-passed at {SPEED_LP_HZ:g} Hz): "
        f"{how}, but on the independent basin truth's ships that slow in their turns the estimate was off by tens "
        "of per cent: treat the mass and z as indicative, not measured (docs/mass-accuracy.md, variants speed_loss and "
        "combined)"
    ]


def heel_notes(recs: list[RollRecording], paths: list[Path]) -> tuple[list[RollRecording], list[str]]:
    """The wall-sided restoring (``output_error.heel_signal``) is a moment in the runs that carry ``phi``
    only: with ``phi`` in some files and not the others that moment would differ between the runs and
    be read as load, so ``phi`` is then dropped from all three and a note says so."""
    have = [p.name for r, p in zip(recs, paths) if r.phi is not None]
    if not have or len(have) == len(recs):
        return recs, []
    note = (
        f"column 'phi' (roll angle) is in {', '.join(have)} only: the wall-sided restoring is left out of "
        "all three runs (in some runs only it would read as load); give phi in every file to use it"
    )
    return [replace(r, phi=None) for r in recs], [note]


def one_rate(recs: list[RollRecording], paths: list[Path]) -> None:
    """Refuse recordings at different sample times (the model is discretised once, at one rate)."""
    if any(abs(r.T - recs[0].T) > 1e-9 * recs[0].T for r in recs):  # as estimate.estimate checks
        raise UserError(
            f"the recordings' sample times differ ({', '.join(f'{p.name} {r.T:g} s' for r, p in zip(recs, paths))}); "
            "resample all three to one rate"
        )


def check_recorded_signs(recs: list[RollRecording], prof: RollProfile, given: RollProfile) -> None:
    """Refuse a recording whose column signs contradict the profile's ship at the recordings' speed
    (:func:`signs.check_signs`). The expected signs of ``a_s`` against ``r`` and of ``r`` against the
    rudder are the model's steady gains, which change with the speed (7)-(8): when the columns fit the
    ``given`` profile's own speed but not the headers' ``speed_m_s``, the header is named, not a column
    (a speed in knots or a typo read as a flipped rudder in stop 50's sweep)."""
    nominal = (prof.known.z_f_prior, Load(0.0, 0.0))
    dc = steady_gains(start_values(prof), prof.known, *nominal)  # once: the signs and the turning gain
    expect, gain = gain_signs(dc), dc[2]
    U, U0 = prof.known.U, given.known.U
    own = expected_signs(start_values(given), given.known, *nominal) if abs(U - U0) > 1e-9 else None
    for rec in recs:
        msg = check_signs(rec, expect)
        if msg and own is not None and check_signs(rec, own) is None:
            raise UserError(
                f"{rec.name}: the recordings' header speed_m_s {U:g} m/s contradicts their motion: the signs of "
                f"a_s, r and delta fit the profile's ship at its U = {U0:g} m/s, not at {U:g} m/s; correct the "
                "header '# speed_m_s:' (the mean speed in m/s; knots read 1.94 times too high) or the profile"
            )
        if msg is None and (rudder := rudder_scale_message(rec, float(gain))):
            msg = yaw_scale_message(rec, dc) or rudder  # the turning gain fails for r in deg/s as for delta in degrees
        if msg:
            raise UserError(msg)


def usability_warnings(e: MassEstimate, prof: RollProfile) -> list[str]:
    """Warnings for an interval that cannot be used: zero or negative mass, more than the ship can
    carry, a load position outside the hull. None for a fit that did not converge: ``shiptrial mass``
    prints no number or interval for it (``cli.mass_cmd._no_estimate``), so a warning about "the 95 %
    interval" would speak of one the user was not shown."""
    out = []
    if not e.converged:
        return out
    if not (np.isfinite(e.m_sd) and np.isfinite(e.zbar_m_sd)):
        return ["no confidence interval could be computed: the estimate is unusable"]
    (mlo, mhi), (zlo, zhi) = e.ci()
    cap = float(prof.raw["ship"].get("max_load_kg", np.inf))
    top, keel = hull_limits(prof)
    if mlo <= 0:
        out.append(f"unusable interval: the 95 % mass interval {mlo:.4f} .. {mhi:.4f} kg includes zero or negative mass")
    if mhi > cap:
        out.append(
            f"unusable interval: the 95 % mass interval reaches {mhi:.4f} kg, more than the ship can carry "
            f"(max_load_kg {cap:g} in the profile)"
        )
    if zlo < top or zhi > keel:
        out.append(
            f"unusable interval: the 95 % z interval {zlo:+.3f} .. {zhi:+.3f} m reaches outside the hull "
            f"({top:+g} .. {keel:+g} m, z positive down)"
        )
    return out


def estimate_from_files(
    nominal: str | Path,
    calibration: str | Path,
    loaded: str | Path,
    known_load: str | Load | None = None,
    profile: str | Path | None = None,
    method: str | None = None,
    z_f: float | None = None,
    heel_reference: str = DEFAULT_HEEL_REFERENCE,
) -> MassEstimate:
    """Read three recordings and estimate the loaded run's mass change and the load's z with 95 % intervals.

    The headers' role, speed, IMU z and known load are checked against the file order, the
    profile and ``known_load`` (which may be omitted when the calibration file's header gives it).
    ``heel_reference`` (oe): how the roll angle is referenced, :func:`restoring.referenced_heel`.
    """
    method = DEFAULT_METHOD if method is None else method
    if method not in METHODS:
        raise UserError(f"--method {method!r}: choose one of {', '.join(METHODS)}")
    if heel_reference not in HEEL_REFERENCES:
        raise UserError(f"heel reference {heel_reference!r}: choose one of {', '.join(HEEL_REFERENCES)}")
    paths = [Path(p) for p in (nominal, calibration, loaded)]
    got = _checked_inputs(paths, known_load, profile, z_f)
    try:
        e = estimate(
            got.recs,
            got.prof.known,
            got.cal,
            method,
            with_ci=True,
            z_f=z_f,
            start=start_values(got.prof),
            heel_reference=heel_reference,
        )
    except (
        ValueError,
        FloatingPointError,
        np.linalg.LinAlgError,
    ) as exc:  # a fit that cannot start or diverges is said, never printed
        raise UserError(
            f"the {method} estimate failed on these recordings ({str(exc).splitlines()[0]}); "
            "check --z-f, --known-load and that the three runs come from one ship"
        ) from None
    e.notes = got.notes + [n for r in got.recs for n in r.notes]
    e.warnings += usability_warnings(e, got.prof) + slowing_warning(got.recs, paths, method) + got.warnings
    return e


@dataclass
class _Inputs:
    """What :func:`estimate_from_files` fits, after every check of the files, headers and profile."""

    recs: list[RollRecording]  # each at its header's speed, its heel referenced
    prof: RollProfile  # the headers' speed and IMU position in place of the profile's own
    cal: Load  # the calibration run's known load
    notes: list[str]
    warnings: list[str]  # said before the fit's own warnings


def _checked_inputs(paths: list[Path], known_load: str | Load | None, profile: str | Path | None, z_f: float | None) -> _Inputs:
    """The three recordings read and checked (roles, ship, rate, load in the hull, signs, order) against their
    headers, the profile and ``known_load``; a contradiction is a :class:`UserError` or a warning."""
    prof = load_profile(profile)
    given = prof  # before the headers' speed and IMU position replace its own
    read = [read_roll_csv(p) for p in paths]
    recs, metas = [r for r, _ in read], [m for _, m in read]
    loads = check_roles(paths, metas)
    ship = check_ship(prof, paths, metas, explicit=profile is not None)
    one_rate(recs, paths)
    if isinstance(known_load, str):
        known_load = parse_known_load(known_load)
    for load, what in ((known_load, "--known-load"), (loads[1], str(paths[1]))):
        if load is not None:
            check_load_in_hull(load, prof, what)
    cal = _calibration_load(known_load, loads[1], paths[1])
    prof, notes = known_from_recordings(prof, paths, metas, explicit=profile is not None)
    # each run at its own speed (the runs differ): the oe model's U r terms use the run's header speed,
    # else the profile's U; a u column (checked by speed_notes) gives the speed's variation within the run where
    # speed.followed_speed follows it (estimate drops a held one, the heel reference's u r included)
    recs = [replace(r, U=_meta_float(m, "speed_m_s", p)) for r, m, p in zip(recs, metas, paths)]
    notes += speed_notes(recs, paths)
    recs, heel = heel_notes(recs, paths)
    notes += heel
    warnings = ship + default_speed_warnings(given, prof, profile is None, paths, metas)
    check_recorded_signs(recs, prof, given)
    order, unchecked = order_check(recs, paths, metas, prof, cal, z_f)
    return _Inputs(recs, prof, cal, notes + unchecked, warnings + order)


def order_check(
    recs: list[RollRecording],
    paths: list[Path],
    metas: list[dict[str, str]],
    prof: RollProfile,
    cal: Load,
    z_f: float | None = None,
) -> tuple[list[str], list[str]]:
    """Before the fit: do the runs' roll frequencies fit the roles their order gives them
    (:mod:`identify.rollmass.roles`)? Returns ``(warnings, notes)``. Raises UserError for files without '# role:'
    headers whose nominal-to-calibration change has the opposite sign of the known load's, beyond its noise (given
    in the wrong order they fit to a negative load, or for minutes to no answer: stop 52); warns where the change is
    otherwise far from the prediction (:func:`roles.role_verdict`; with all three headers confirming the order it
    names the known load and the profile), or where the loaded run rolls clearly faster than the nominal. A note
    says when files without all three headers could not be judged (:func:`roles.unjudged_message`, stop 53): the
    answer stands, but its order was checked by nothing."""
    rc = measure_roles(recs, prof, cal, z_f)
    headed = all(m.get("role") for m in metas)
    msg = role_message(rc, paths, cal, headed)
    if msg and not headed and role_verdict(rc) == "refuse":
        raise UserError(msg)
    if msg:
        return [msg], []
    note = None if headed else unjudged_message(rc, recs, paths, cal)
    loaded = None if headed else loaded_message(rc, paths)
    return ([loaded] if loaded else []), ([note] if note else [])


def default_speed_warnings(
    given: RollProfile, prof: RollProfile, default: bool, paths: list[Path], metas: list[dict[str, str]]
) -> list[str]:
    """Before the fit, the recordings' header speed against the default profile's ship (a given profile
    that far off is refused by :func:`known_from_recordings`): refused when it is more than SPEED_TOL off
    in m/s but within it read as knots (1 kn = KNOT m/s: the unit slip, whose fit otherwise ran at twice the
    ship's speed and was warned only after it), warned when it is that far off otherwise (the profile's
    hydrodynamic start values are its ship's at its speed)."""
    U, U0 = prof.known.U, given.known.U
    if not default or abs(U / U0 - 1) <= SPEED_TOL:
        return []
    said = [(p, m["speed_m_s"]) for p, m in zip(paths, metas) if "speed_m_s" in m]
    if abs(U * KNOT / U0 - 1) <= SPEED_TOL:
        raise UserError(
            f"{said[0][0]}: header '# speed_m_s: {said[0][1]}' is {100 * (U / U0 - 1):+.0f} % off the default profile's "
            f"U = {U0:g} m/s and reads as knots ({U:g} kn = {U * KNOT:.3g} m/s): give the speed in m/s in the "
            "'# speed_m_s:' header of every file, or give the ship's --profile"
        )
    return [
        f"the recordings' speed_m_s {U:g} m/s is {100 * abs(U / U0 - 1):.0f} % off the default profile's U = {U0:g} m/s "
        "(Our Lass II at its basin speed): check the header '# speed_m_s:' (m/s, not knots) or give the ship's --profile"
    ]
