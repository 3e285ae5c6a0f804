"""Physical parameters of a kept candidate, with standard deviations (never NaN: None instead)."""

from __future__ import annotations

import numpy as np

from diagnose import windload
from diagnose.candidates import STEADY_WIND, Candidate, canonical_term, thrust_signal
from diagnose.interval95 import half_width_95
from diagnose.model import AugmentedModel
from primitives.ship import DOFS


def _sd(cov: np.ndarray, pos: list[int]) -> list[float | None]:
    if not len(cov):
        return [None] * len(pos)
    d = np.diag(cov)[pos]
    return [float(np.sqrt(x)) if np.isfinite(x) and x >= 0 else None for x in d]


def surge_base_index(model: AugmentedModel, term: str) -> int | None:
    """Position of the baseline surge term ``term`` in P (None when the model has none)."""
    return next((k for k, (i, t, *_r) in enumerate(model.base) if i == 0 and t == term), None)


def describe(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, free: list[int]) -> dict:
    """Physical parameters of candidate ``c`` at P (keys fixed by the issue)."""
    idx = model.slot_of[c.key]
    pos = [free.index(j) for j in idx]
    fn = _steady_wind if c.key == STEADY_WIND else _BY_EFFECT.get(c.effect)
    if fn is None:
        sd = _sd(cov, pos)
        return {s.name: float(v) for s, v in zip(c.slots, P[idx])} | {f"{s.name}_std": e for s, e in zip(c.slots, sd)}
    return fn(c, model, P, cov, pos)


def _current(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    cn, ce = P[model.slot_of[c.key]]
    spd = float(np.hypot(cn, ce))
    out = {
        "speed_mps": spd,
        "toward_deg": float(np.degrees(np.arctan2(ce, cn)) % 360.0),
        "north_mps": float(cn),
        "east_mps": float(ce),
    }
    if len(cov):
        sub = cov[np.ix_(pos, pos)]
        g_s = np.array([cn, ce]) / max(spd, 1e-12)
        g_d = np.array([-ce, cn]) / max(spd**2, 1e-12)
        if np.all(np.isfinite(sub)):
            out["speed_std"] = float(np.sqrt(max(g_s @ sub @ g_s, 0)))
            out["toward_std_deg"] = float(np.degrees(np.sqrt(max(g_d @ sub @ g_d, 0))))
    return out


def _steady_wind(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    """A wind not recorded: its speed and the direction it comes from (clockwise from north, as a
    recorded ``wind_dir``), from the fitted air velocity toward north/east, with delta-method stds,
    the yaw arm of its lateral load (s_L / L, forward of midship) and the scale of its surge load."""
    wn, we, arm, surge = P[model.slot_of[c.key]]
    spd = float(np.hypot(wn, we))
    out = {
        "speed_mps": spd,
        "from_deg": float(np.degrees(np.arctan2(-we, -wn)) % 360.0),
        "north_mps": float(wn),
        "east_mps": float(we),
        "yaw_arm_over_length": float(arm),
        "yaw_arm_over_length_std": _sd(cov, pos[2:3])[0],
        "surge_scale": 1.0 + float(surge),
        "surge_scale_std": _sd(cov, pos[3:])[0],
    }
    sub = cov[np.ix_(pos[:2], pos[:2])] if len(cov) else np.full((2, 2), np.nan)
    g_s = np.array([wn, we]) / max(spd, 1e-12)
    g_d = np.array([-we, wn]) / max(spd**2, 1e-12)
    ok = bool(np.all(np.isfinite(sub)))
    out["speed_std"] = float(np.sqrt(max(g_s @ sub @ g_s, 0))) if ok else None
    out["from_std_deg"] = float(np.degrees(np.sqrt(max(g_d @ sub @ g_d, 0)))) if ok else None
    return out


def _delay(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    shift = float(P[model.slot_of[c.key][0]])
    d = shift + model.half_sample
    return {
        "delay_s": d,
        "delay_std": _sd(cov, pos)[0],
        "samples": d / model.profile.sample_time,
        "model_shift_s": shift,
        "half_sample_s": model.half_sample,
    }


def _offset(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    name = model.profile.inputs[c.slots[0].index]
    val = float(P[model.slot_of[c.key][0]])
    out = {"input": name, "offset": val, "offset_std": _sd(cov, pos)[0]}
    if name in ("delta",) or name.startswith("alpha"):
        out["offset_deg"] = float(np.degrees(val))
    return out


def _bias(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    return {"signal": "uvr"[c.slots[0].index], "bias": float(P[model.slot_of[c.key][0]]), "bias_std": _sd(cov, pos)[0]}


def _term(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    """An added hull term; a change of a term the model has is also stated relative to it."""
    val = float(P[model.slot_of[c.key][0]])
    out = {"term": c.slots[0].term, "value": val, "value_std": _sd(cov, pos)[0], "dof": DOFS[c.dof]}
    key = canonical_term(c.slots[0].term)
    j = next((k for k, (i, t, *_r) in enumerate(model.base) if i == c.dof and canonical_term(t) == key), None)
    if j is not None and P[j] != 0:
        out["change_percent"] = 100.0 * float(val / P[j])
    return out


def _thrust_fraction(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    """A constant fraction of the thrust lost (every thrust term; the rudder by its slipstream share)."""
    j0 = model.slot_of[c.key][0]
    f = float(P[j0])
    sd = _sd(cov, pos)[0]
    share = float(model.thrust_share(P, j0)[0])
    return {
        "loss_percent": 100.0 * f,
        "loss_percent_std": None if sd is None else 100.0 * sd,
        "loss_fraction": f,
        "terms": [model.base[k][1] for k in model.thrust_terms],
        "rudder_terms": [f"{DOFS[model.base[k][0]]}:{model.base[k][1]}" for k in model.rudder_terms],
        "rudder_thrust_share": share,
        "rudder_force_change_percent": -100.0 * share * f,
    }


def _surge_term(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    """A change of a surge term the model has (resistance), relative to it."""
    val = float(P[model.slot_of[c.key][0]])
    term = c.slots[0].term
    j = surge_base_index(model, term)
    base = float(P[j]) if j is not None else 0.0
    frac = float(val / base) if base else None
    sd = _sd(cov, pos)[0]
    out = {"term": term, "coefficient": val, "coefficient_std": sd}
    pct_sd = None if frac is None or sd is None else 100.0 * sd / abs(base)
    if c.effect == "thrust_loss":
        out["loss_percent"] = None if frac is None else -100.0 * frac
        out["loss_percent_std"] = pct_sd
    else:
        out["resistance_change_pct"] = None if frac is None else 100.0 * frac
        out["resistance_change_pct_std"] = pct_sd
    return out


def _thrust(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    if c.slots[0].kind == "thrust":
        return _thrust_fraction(c, model, P, cov, pos)
    if c.key != "thrust_loss":
        return _surge_term(c, model, P, cov, pos)
    val = float(P[model.slot_of[c.key][0]])  # thrust falling with speed (u_r * thrust signal)
    prof = model.profile
    tsig = thrust_signal(prof)
    j = surge_base_index(model, tsig)
    out = {"coefficient": val, "coefficient_std": _sd(cov, pos)[0], "term": c.slots[0].term}
    if j is not None and P[j] != 0 and tsig == "tau_x":
        out["thrust_loss_per_mps"] = float(-val / P[j])
        out["thrust_change_at_cruise"] = float(val * prof.cruise_speed_mps / P[j])
    return out


def _inertia(c: Candidate, model: AugmentedModel, P: np.ndarray, cov: np.ndarray, pos: list[int]) -> dict:
    s = float(P[model.slot_of[c.key][0]])
    sd = _sd(cov, pos)[0]
    ok = s > -1
    # delta method: d(1 / (1 + s)) / ds = -1 / (1 + s)^2
    return {
        "scale": s,
        "scale_std": sd,
        "inertia_ratio": float(1.0 / (1.0 + s)) if ok else None,
        "inertia_ratio_std": float(sd / (1.0 + s) ** 2) if ok and sd is not None else None,
        "dof": DOFS[c.dof],
    }


_BY_EFFECT = {
    "current": _current,
    "actuator_delay": _delay,
    "input_offset": _offset,
    "sensor_bias": _bias,
    "quadratic_damping": _term,
    "missing_coupling": _term,
    "resistance_change": _surge_term,
    "thrust_loss": _thrust,
    "inertia_change": _inertia,
}


STD_SUFFIXES = ("_std", "_std_deg")


def _beyond_runs(cov) -> bool:
    """Whether ``cov``'s total holds a part beyond noise and run-to-run misfit (the --fit-on runs',
    the within-run or the held-out runs' misfit), so that its noise and run-to-run part is worth its own column."""
    return any(getattr(cov, part, None) is not None for part in ("reference", "within", "heldout"))


# the parts of a FindingCov whose stds set the 95 % interval's degrees of freedom (uncertainty.half_width_95)
_T_PARTS = ("noise", "model", "within", "reference", "heldout")


def _part_covs(cov) -> dict[str, np.ndarray]:
    """The parts of ``cov`` by name (a part not measured: zero)."""
    return {part: C if (C := getattr(cov, part, None)) is not None else np.zeros_like(cov.noise) for part in _T_PARTS}


def args_95(by_part: dict[str, dict], k: str, cov) -> dict | None:
    """The arguments of :func:`diagnose.uncertainty.half_width_95` for the std ``k``: its std in each
    part (``by_part``) and the runs they were measured over; None when a part is not a finite number."""
    sds = {part: by_part[part].get(k) for part in _T_PARTS}
    if not all(isinstance(v, float) and np.isfinite(v) for v in sds.values()):
        return None
    return sds | {"n_runs": cov.n_runs, "n_heldout": getattr(cov, "heldout_runs", 0)}


def _add_95(out: dict, by_part: dict[str, dict], cov) -> None:
    """``<name>_95`` beside each std ``<name>`` of ``out``: the half-width of its 95 % interval
    (:func:`diagnose.uncertainty.half_width_95`) from the same std of each part (``by_part``); and
    ``<name>_95_runs``: the same of its noise and run-to-run parts alone (the in-sample test of
    :func:`indistinct`)."""
    for k in [k for k in out if k.endswith(STD_SUFFIXES) and isinstance(out[k], float)]:
        if (a := args_95(by_part, k, cov)) is not None:
            out[f"{k}_95"] = half_width_95(**a)
            out[f"{k}_95_runs"] = half_width_95(a["noise"], a["model"], n_runs=a["n_runs"])


def with_interval(c: Candidate, model: AugmentedModel, P: np.ndarray, cov, free: list[int]) -> dict:
    """:func:`describe` with each std the total of ``cov`` (a :class:`diagnose.uncertainty.FindingCov`:
    noise, run-to-run model misfit, the --fit-on runs' and the within-run misfit), its noise part kept as
    ``<name>_noise``, when a part beyond them was measured, noise and run-to-run part as ``<name>_runs``,
    and the half-width of its 95 % interval as ``<name>_95`` (Student-t at the parts' degrees of freedom)."""
    out = describe(c, model, P, cov.total, free)
    parts = {"noise": cov.noise} | ({"runs": cov.runs} if _beyond_runs(cov) else {})
    for part, C in parts.items():
        d = describe(c, model, P, C, free)
        for k in [k for k in out if k.endswith(STD_SUFFIXES)]:
            out[f"{k}_{part}"] = d.get(k)
    _add_95(out, {part: describe(c, model, P, C, free) for part, C in _part_covs(cov).items()}, cov)
    return out


def add_wind_means(findings: list[dict], model: AugmentedModel, preps: list, P: np.ndarray, cov, free: list[int]) -> None:
    """Each wind finding's mean acceleration of the ship per DOF over the diagnosed runs ``preps``
    (:func:`diagnose.windload.mean_acceleration`), with its interval from ``cov`` (a
    :class:`diagnose.uncertainty.FindingCov`), added to its parameters in place."""
    for f in findings:
        if f["effect"] != "wind" or not len(cov.noise):
            continue
        idx = model.slot_of[f["key"]]
        pos = [free.index(j) for j in idx]
        ix = np.ix_(pos, pos)
        parts = {"": cov.total, "_noise": cov.noise} | ({"_runs": cov.runs} if _beyond_runs(cov) else {})
        parts |= {f"_part_{part}": C for part, C in _part_covs(cov).items()}
        sub = {k: C[ix] for k, C in parts.items()}
        if f["key"] == STEADY_WIND:
            means = windload.steady_mean_acceleration(model.profile, preps, P[idx], sub)
        else:
            means = windload.mean_acceleration(preps, P[idx], sub)
        by_part = {
            part: {k.removesuffix(f"_part_{part}"): means.pop(k) for k in list(means) if k.endswith(f"_part_{part}")}
            for part in _T_PARTS
        }
        _add_95(means, by_part, cov)
        f["parameters"].update(means)


# What a thrust loss's interval cannot hold (interval_note). The loss is a fraction of the thrust the
# baseline holds; at one propeller speed n^2 is a constant, so --fit-on runs pin the net surge force
# and its slope with speed but not how much of it is thrust and how much resistance, and every run at
# that speed, held-out ones too, sees only the product of the fraction and that thrust. On the MMG
# battery the calm fit's thrust terms are 13-18 % above the truth's propeller thrust at the lossy
# run's speed (model scale, seeds 1, 3; their net force within 0.00032 m/s per second of the truth's), and a
# 20 % loss reads 17.3-18.4 % on every seed at both scales. Runs at a second propeller speed separate n^2 from u^2 (not measured).
THRUST_SPLIT = (
    "the baseline's split of the surge force between thrust and resistance when every run is at one propeller "
    "speed (the loss is a fraction of the thrust the baseline holds, which such runs do not pin: on the MMG "
    "battery a 20 % loss reads 17.3-18.4 %); calm runs at a second propeller speed separate the two"
)


def interval_note(cov, key: str | None = None) -> dict:
    """What a finding's +- std covers (JSON ``interval``; the text report prints ``covers``), in
    words a trials engineer can act on; ``key``: the finding's candidate key (whether the --fit-on
    runs' misfit was measured for it; a thrust loss's also names :data:`THRUST_SPLIT`). ``diagnosed_runs``: the diagnosed recordings given;
    ``between_run_runs``: the runs the run-to-run misfit was measured over (0: none)."""
    runs, ref = cov.n_runs, getattr(cov, "reference_runs", 0)
    given = max(getattr(cov, "runs_given", 0) or runs, 1)
    noise = "measurement noise (of the --fit-on runs too)" if cov.fit_on else "measurement noise"
    what = noise
    if runs >= 2:
        over = f"the {runs} runs ({runs - ref} diagnosed, {ref} --fit-on fitted jointly)" if ref else f"the {runs} diagnosed runs"
        what = f"{noise} and the model's run-to-run misfit over {over}"
        if runs == 2:
            what += (
                " (rough with two runs: a spread with one degree of freedom, it can be several times too "
                "large or too small; diagnose a third run to firm it up)"
            )
    if getattr(cov, "within", None) is not None:
        what += " and its misfit within the runs (the spread over eighths of each run)"
    tried = getattr(cov, "reference", None) is not None
    measured = tried and (key is None or key in getattr(cov, "reference_keys", frozenset()))
    n_heldout = getattr(cov, "heldout_runs", 0)
    if measured:
        what += " and the misfit the --fit-on runs (which hold no such effect) put on the finding"
        missing = (
            "a model error common to every run that the --fit-on runs "
            + ("and the held-out runs " if n_heldout else "")
            + "do not show"
        )
    elif tried:
        missing = (
            "a model error common to every run (the --fit-on runs do not move this finding's parameters, "
            "e.g. they recorded no wind, or its refit there was not finite: their misfit on it was not measured)"
        )
    else:
        missing = "a model error common to every run (give --fit-on runs to measure it)"
    if n_heldout:
        n = n_heldout
        what += f" and the misfit the {n} held-out (--validate) run{'s' if n > 1 else ''} show{'' if n > 1 else 's'} on it"
    if key is not None and key.startswith("thrust_loss"):
        missing += "; " + THRUST_SPLIT
    if getattr(cov, "misfit_failed", False):
        missing = (
            "the model's run-to-run misfit (its leave-one-run-out spread was not finite: a run's fit diverges "
            "when the others are left out, so no between-run check was made) and " + missing
        )
    elif runs < 2:
        missing = (
            "the model's misfit on this recording (one diagnosed recording gives no between-run check: "
            "diagnose two or more runs to measure it) and " + missing
        )
    return {
        "covers": f"1 std of {what}. Not covered: {missing}",
        "diagnosed_runs": given - ref,
        "between_run_runs": runs,
        "between_runs": runs >= 2,
    }


# the estimate whose interval says whether the effect is there at all (its "no effect" value is 0)
_MAIN = {
    "current": [("speed_mps", "speed_std")],
    "actuator_delay": [("delay_s", "delay_std")],
    "input_offset": [("offset", "offset_std")],
    "sensor_bias": [("bias", "bias_std")],
    "quadratic_damping": [("value", "value_std")],
    "missing_coupling": [("value", "value_std")],
    "thrust_loss": [("loss_percent", "loss_percent_std"), ("coefficient", "coefficient_std")],
    "resistance_change": [("coefficient", "coefficient_std")],
    "inertia_change": [("scale", "scale_std")],
}


def _finite(x) -> bool:
    return isinstance(x, int | float) and bool(np.isfinite(x))


def _main_keys(f: dict) -> list[tuple[str, str]]:
    p = f["parameters"]
    pairs = _MAIN.get(f["effect"]) or [(k, f"{k}_std") for k in p if f"{k}_std" in p]
    return [(k, s) for k, s in pairs if _finite(p.get(k)) and _finite(p.get(s))]


def _main_pairs(f: dict) -> list[tuple[float, float]]:
    p = f["parameters"]
    return [(p[k], p[s]) for k, s in _main_keys(f)]


#: A held-out run confirms a finding when, the finding added (its share in ``heldout_per_run``),
#: the residual of one of its channels falls by more than this many noise stds (RMS): the term
#: predicts, on a run its fit never saw, more than the measurement noise. A fit point is worth
#: ``noise_spread / 100`` noise stds on a channel spread over ``noise_spread`` of them
#: (:func:`diagnose.perrun.channel_slack`).
CONFIRM_NOISE = 1.0


def confirmed_by_heldout(f: dict, spread: dict[str, dict[str, float]]) -> bool:
    """Whether a held-out run confirms the finding ``f`` (:data:`CONFIRM_NOISE`); ``spread``: each
    held-out run's noise spread per channel (:func:`diagnose.perrun.noise_spread`)."""
    for row in f.get("heldout_per_run") or []:
        s = spread.get(str(row.get("run"))) or {}
        for k, b in (row.get("before") or {}).items():
            a = (row.get("after") or {}).get(k)
            if _finite(a) and _finite(b) and _finite(s.get(k)) and (a - b) * s[k] / 100.0 > CONFIRM_NOISE:
                return True
    return False


def z_score(f: dict) -> float:
    """The finding's largest |estimate / std| over its main estimates (inf without an interval)."""
    pairs = _main_pairs(f)
    return max((abs(v) / sd if sd > 0 else float("inf") for v, sd in pairs), default=float("inf"))


def _within(f: dict, suffix: str) -> bool:
    """Every main estimate of ``f`` lies inside the half-width ``<std><suffix>`` of no effect (1.96
    std without one): that 95 % interval includes zero."""
    p, keys = f["parameters"], _main_keys(f)

    def half(s: str) -> float:
        v = p.get(s + suffix)
        return float(v) if _finite(v) else 1.96 * float(p[s])

    return bool(keys) and all(abs(p[k]) < half(s) for k, s in keys)


def includes_no_effect(f: dict) -> bool:
    """The finding's 95 % interval, the reported one (noise, run-to-run misfit and the model-error
    parts; Student-t at their degrees of freedom, ``<std>_95``), includes no effect on every main estimate."""
    return _within(f, "_95")


def indistinct(f: dict) -> bool:
    """Whether the finding is not told apart from no effect, and so not named (issue 26): the 95 %
    interval of its noise and run-to-run misfit includes zero (``<std>_95_runs``: the estimate is
    not resolved even in-sample), or its whole reported interval does (:func:`includes_no_effect`)
    and no held-out run confirms it (``heldout_confirmed``, :func:`confirmed_by_heldout`). The
    model-error parts (the --fit-on runs', within-run and held-out misfit) guard against a term
    that only trades the model's misfit on the diagnosed runs; a term that predicts runs its fit
    never saw by more than their noise is not such a term. Its size can stay unresolved: the
    report says so (:func:`diagnose.report.sentence`). On the MARIN KVLCC2 runs (two zig-zags
    diagnosed, the turning circles held out) every finding's held-out part was wide and the
    turning circles confirm them; on the MMG battery's yaw-damping seed 3 a sway damping term at
    1.54 std beside the true yaw term raised no held-out channel by a noise std."""
    return _within(f, "_95_runs") or (includes_no_effect(f) and not f.get("heldout_confirmed"))
