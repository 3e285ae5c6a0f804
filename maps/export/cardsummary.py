"""The trial card's summary and experiment-design table (split from :mod:`maps.export.card`, which
re-exports them): page 1's facts in words, and the design's rows named as the steps table names the
manoeuvres (the name a master knows, measured on the planned track, with the design's code after it).
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from maps.export._common import M_PER_NM
from maps.export.chart import plan_chart
from maps.export.wording import manoeuvre_name, phase, standard_name
from maps.plan import Plan
from maps.sizing import row_text

DESIGN_COLS = ["manoeuvre (design code)", "weight", "rounded count", "planned"]


def duration_text(t_s: float) -> str:
    """A duration in words a master reads at once: "59 min 53 s", "3 h 37 min 31 s" (the card's
    "59:53 (h:)min:s" left the reader to work out which fields were there)."""
    s = int(round(t_s))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h} h {m} min {sec} s" if h else f"{m} min {sec} s"


def design_name(plan: Plan, code: str) -> str:
    """A design row's manoeuvre as the steps table names it: the name of the code's first planned
    manoeuvre step (:func:`maps.export.wording.manoeuvre_name`, from the planned track) or the
    standard manoeuvre's name, with the code in brackets; the code alone when the plan sails none."""
    st = next((s for s in plan.steps if s.primitive == code and s.segment not in ("run-in", "transit")), None)
    name = manoeuvre_name(plan, st) if st is not None else standard_name(code)
    return f"{name} [{code}]" if name and name != code else code


def _design_head(d: dict) -> list[str]:
    """The design's summary lines: criterion and mean subtraction, D-efficiency, what was dropped and why,
    the parameters held at the profile's values."""
    head = []
    crit = d.get("criterion")
    if crit:
        ms = d.get("mean_subtraction")
        head.append(
            f"Design: {crit}-optimal"
            + (
                ""
                if ms is None
                else (
                    ", with mean subtraction"
                    if ms is True
                    else ", without mean subtraction"
                    if ms is False
                    else f", mean subtraction {ms}"
                )
            )
        )
    eff = d.get("d_efficiency")
    if isinstance(eff, (int, float)):
        head.append(f"D-efficiency of the rounded design against the continuous optimum: {100.0 * eff:.1f} %")
    for dr in d.get("dropped") or []:
        if isinstance(dr, dict):
            need = dr.get("needs_m")
            loss = dr.get("efficiency_loss")
            pair = isinstance(need, (list, tuple)) and len(need) == 2 and all(isinstance(x, (int, float)) for x in need)
            name = str(dr.get("primitive"))
            head.append(
                (
                    f"Dropped ({'not sailable with the rest of the mix' if dr.get('apart') else 'fits nowhere on the map'}): "
                    f"{row_text(dr | {'primitive': name})}"
                    if pair
                    else f"Dropped {name}: fits nowhere on the map"
                )
                + (f", efficiency loss {100.0 * loss:.1f} %" if isinstance(loss, (int, float)) else "")
            )
    held = [h for h in d.get("held_parameters") or [] if isinstance(h, dict) and "parameter" in h]
    if held:
        from maps.searoom import held_text

        head.append(f"Held at the profile's values (the manoeuvres that fit cannot identify them): {held_text(held)}")
    return head


def design_rows(plan: Plan) -> tuple[list[str], list[list[str]]]:
    """The experiment design behind the counts (``plan.design``): summary lines and one row
    per primitive (its name with the code, weight, rounded count, planned count). Empty without a design."""
    d = getattr(plan, "design", None) or {}
    if not d:
        return [], []
    head = _design_head(d)
    weights = d.get("weights") or {}
    counts = d.get("counts") or {}
    # rows for the primitives the design uses; those it gives no weight (maps.trialdesign.UNUSED_WEIGHT) are named
    # once, not listed with count 0
    unused = [*(d.get("not_used") or []), *(n for n, x in weights.items() if float(x) <= 1e-4 and not counts.get(n))]
    names = [n for n in dict.fromkeys([*weights, *counts]) if n not in unused]
    rows = [
        [
            design_name(plan, n),
            f"{float(weights[n]):.3f}" if n in weights else "",
            str(counts.get(n, 0)),
            str(plan.counts.get(n, 0)),
        ]
        for n in names
    ]
    if unused:
        head.append(f"Not used (no weight in the optimal design): {', '.join(dict.fromkeys(unused))}")
    return head, rows


def _resumed(plan: Plan) -> list[str]:
    """A resumed plan's first line: what was sailed before it (``stats['resume']``)."""
    r = plan.stats.get("resume")
    if not r:
        return []
    steps = r["sailed"]["steps"]
    rec = [s for s in steps if "recording" in s]
    before = f", {r['earlier_runs']} recorded under the plans before" if r.get("earlier_runs") else ""
    return [
        f"RESUMED TRIAL: steps 1-{steps[-1]['step']} sailed ({duration_text(r['sailed']['sailed_s'])}, {len(rec)} manoeuvre(s) "
        f"recorded: {', '.join(s['primitive'] for s in rec)}{before}); this plan is the rest, from {r['position'][0]:.5f}, "
        f"{r['position'][1]:.5f}, heading {r['position'][2]:03.0f}"
    ]


def summary_lines(plan: Plan, t0: datetime, vessel: str, sea_map: Any = None) -> list[str]:
    """Page 1's facts: what was sailed before (a resumed plan), ship, area and start; steps, duration and
    length; feasibility, hull and margin; how the cross-track limits were set."""
    phases = [phase(plan, st) for st in plan.steps]
    n_man = sum(1 for p in phases if p in ("EXECUTE", "manoeuvre"))
    kinds = [f"{n_man} manoeuvre{'s' if n_man != 1 else ''}"] + [
        f"{n} {w}{'s' if n != 1 else ''}" for w in ("run-in", "stop", "transit") if (n := phases.count(w))
    ]
    chart = plan_chart(plan, sea_map)
    return [
        *_resumed(plan),
        # "; " between the facts: the HTML collapses the spaces that set them apart ("Ship x   Area y" read "Ship x Area y")
        f"Ship {vessel}"
        + (f" ({plan.ship})" if vessel != plan.ship else "")
        + (f"; area {plan.map_name}" if plan.map_name else "")
        + f"; start {t0.strftime('%Y-%m-%d %H:%M')} UTC",
        f"{len(plan.steps)} steps: {', '.join(kinds)}; "
        f"duration {duration_text(plan.duration_s)}, {plan.length_m:.0f} m ({plan.length_m / M_PER_NM:.2f} NM)",
        "Plan "
        + ("feasible" if plan.feasible else "NOT FEASIBLE")
        + (", optimal" if plan.optimal else "")
        + f"; hull {plan.hull[0]:g} m x {plan.hull[1]:g} m; safety margin {plan.margin_m:.0f} m",
        "Cross-track limits of the route: "
        + (
            "NOT checked against a chart (export with --map)"
            if chart is None
            else "the chart shows no land or no-go water near the track"
            if chart.is_empty()
            else "cut to the land-free water of the chart"
        ),
    ]
