"""What a diagnosis says of each finding beside its value: whether the --fit-on runs show it too
(a deficiency of the baseline's structure, :func:`structural`) and the evidence sentence of the
report (:func:`evidence`). Moved from :mod:`diagnose.api`, unchanged."""

from __future__ import annotations

import numpy as np

from diagnose.heldout import Parts, gram_sums, insample_rss
from diagnose.model import AugmentedModel, Prepared
from diagnose.perrun import fit_str, short_label
from diagnose.uncertainty import sensitivities
from primitives.ship import DOFS


def structural(model: AugmentedModel, calm: list[Prepared], w: np.ndarray, P: np.ndarray, findings: list[dict]) -> list[dict]:
    """Findings the --fit-on (reference) runs show too: refitting the baseline with the
    candidate on the reference runs (linearised, from the baseline as fitted there) lowers their
    residual by more than 1 % with a coefficient of the same sign and at least half the size.
    They are a deficiency of the baseline's structure, not a condition of the diagnosed runs
    (a current, a fault), and are reported apart; they stay in the model. The baseline's columns
    by forward sensitivities (P0 switches no candidate on: one pass a run, once for every finding,
    instead of a simulated member a coefficient a finding), the finding's by finite differences
    with the steps at P, as before."""
    if not calm or not findings:
        return []
    base = list(range(model.n_base))
    P0 = model.p0()
    fit_parts = list(range(len(calm)))
    parts = Parts(fit_parts, [np.ones(p.n, bool) for p in calm], [p.rec.source for p in calm], [], [])
    h = model.steps(calm, P)
    at_base = sensitivities(model, calm, P0, base, w, analytic=True, h=h)  # h: the steps as before where differenced
    out = []
    for f in findings:
        own = model.slot_of[f["key"]]
        fd = sensitivities(model, calm, P0, own, w, h=h)
        g = gram_sums([(R, np.concatenate([J, J_own])) for (R, J), (_R, J_own) in zip(at_base, fd)], calm, parts, base + own, w)
        zero = np.zeros(len(base) + len(own))
        rss0, _ = insample_rss(g, parts, list(range(len(base))), zero, zero, fit_parts)
        rss1, step = insample_rss(g, parts, list(range(len(base) + len(own))), zero, zero, fit_parts)
        est, val = step[len(base) :], P[own]
        same = float(est @ val) > 0 and np.linalg.norm(est) >= 0.5 * np.linalg.norm(val)
        if rss1 < 0.99 * rss0 and same:
            f["reference_fit_gain"] = float(1.0 - rss1 / max(rss0, 1e-300))
            out.append(f)
    return out


SHARE_SHOWN = 5.0  # fit points: another channel a finding moves this much is named with its own share
SIGNATURE = {
    "current": ["cos psi", "sin psi"],
    "wind": ["wind along", "wind across"],
    "actuator_delay": ["change of"],
    "input_offset": ["sign", ""],
    "thrust_loss": ["speed u"],
    "quadratic_damping": ["|v|", "|r|", "v|v|", "r|r|"],
    "missing_coupling": ["|r|", "speed u", "|v|"],
    "sensor_bias": [""],
    "inertia_change": ["change of"],
}


def evidence(f: dict, location: dict, fb: dict, fa: dict, where: str) -> str:
    dof = f["dof"]
    conds = location["conditions"].get(dof, [])
    keys = SIGNATURE.get(f["effect"], [])
    hit = next((c for c in conds if any(k and k in c["signal"] for k in keys)), None)
    parts = []
    if hit:
        parts.append(f"the {dof} residual follows {hit['signal']} (correlation {hit['correlation']:+.2f})")
    parts.append(
        f"adding it explains {100 * f['rss_drop']:.0f} % of the weighted residual (F = {f['f_statistic']:.1f}, "
        f"p = {f['p_value']:.2g}) and lowers the held-out residual by {100 * f['cv_gain']:.0f} %"
    )
    parts.append(
        own_share(f, dof, where)
        or f"{dof} fit on the {where} run(s) {fit_str(fb[dof])} -> {fit_str(fa[dof])} "
        "(the whole model's, the baseline refit included)"
    )
    return "; ".join(parts)


def own_share(f: dict, dof: str, where: str) -> str | None:
    """The finding's own share of the held-out fit, as the search recorded it when the finding
    was added: the model with the findings kept before it (and the baseline refit) against the
    same with it added (``Step.heldout``), per held-out run; another channel it moves by
    SHARE_SHOWN points or more is named too (a surge term can cost the sway fit)."""
    rows = f.get("heldout_per_run") or []
    if not rows:
        return None

    def moved(r: dict) -> str:
        return ", ".join(
            f"{k} {fit_str(r['before'][k])} -> {fit_str(r['after'][k])}"
            for k in DOFS
            if k != dof and abs(r["after"][k] - r["before"][k]) >= SHARE_SHOWN
        )

    cells = []
    for r in rows:
        other = moved(r)
        cell = f"{fit_str(r['before'][dof])} -> {fit_str(r['after'][dof])}"
        label = short_label(r["run"]) if len(rows) > 1 else ""
        inner = "; ".join(x for x in (label, other) if x)
        cells.append(cell + (f" ({inner})" if inner else ""))
    how = "simulated" if where == "validation" else "linearised refit without it"
    name = f" {short_label(rows[0]['run'])}" if len(rows) == 1 else "s"
    return (
        f"its own share: {dof} fit on the held-out run{name} ({how}) {', '.join(cells)} "
        "(with the findings before it, then with it added)"
    )
