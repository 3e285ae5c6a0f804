"""CSV schedule of a plan: one row per sample of the planned track.

Columns: time from start (s and h:mm:ss), UTC time, lat, lon (deg, 7 decimals), local x north
and y east (m), heading (deg, 0-360 from north), speed over ground (m/s and kn), the manoeuvre
(number, segment: run-in / informative / transit, primitive, its orders on the manoeuvre's
first row) and the commanded inputs: angles in degrees (column ``<input>_deg``), propeller speeds in
rpm as the card and the orders give them (column ``<input>_rpm``: the plan's rev/s x 60), forces as
the plan holds them (column ``<input>``).
"""

from __future__ import annotations

import csv
import io
import re
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from maps.export._common import KN_PER_MPS, check_plan, clock, resolve_start, sample_times_iso, sample_times_iso_at
from maps.export.wording import step_orders
from maps.plan import Plan
from primitives.io import atomic_write_text

_PROPELLER = re.compile(r"n\d*")  # n (single screw), n1, n2, ... (thrusters, pods): rev/s in the plan


def _input_columns(plan: Plan) -> list[tuple[str, str]]:
    """Each input's column name and kind: "deg" (an angle, the plan's rad), "rpm" (a propeller, the plan's
    rev/s: a crew reads rpm on the card and the orders, so the column says and holds rpm) or "" (as held)."""
    cols = []
    for n in plan.input_names:
        if n.startswith(("alpha", "delta")):
            cols.append((f"{n}_deg", "deg"))
        elif _PROPELLER.fullmatch(n):
            cols.append((f"{n}_rpm", "rpm"))
        else:
            cols.append((n, ""))
    return cols


def plan_csv(plan: Plan, *, start: datetime | str | None = None, every: int = 1) -> str:
    """The plan's schedule as CSV text (``every``: keep every n-th sample, always the last and
    every manoeuvre's first)."""
    check_plan(plan)
    t0 = resolve_start(plan, start)
    by_index = {st.index: st for st in plan.steps}
    cols = _input_columns(plan)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        [
            "time_s",
            "time_from_start",
            "utc",
            "lat",
            "lon",
            "x_north_m",
            "y_east_m",
            "heading_deg",
            "speed_mps",
            "speed_kn",
            "manoeuvre",
            "segment",
            "primitive",
            "orders",
        ]
        + [c for c, _ in cols]
    )
    k_total = len(plan.t)
    step_of = plan.step_of_sample.tolist()
    first_of = {}
    for k in range(k_total):
        first_of.setdefault(int(step_of[k]), k)
    starts = set(first_of.values())
    n_in = plan.inputs.shape[1] if plan.inputs.ndim == 2 else 0
    # every column's values as Python floats at once (the same elementwise arithmetic as sample by sample)
    t_rel = (plan.t - plan.t[0]).tolist()
    lat, lon = plan.lonlat[:, 1].tolist(), plan.lonlat[:, 0].tolist()
    x, y = plan.track[:, 0].tolist(), plan.track[:, 1].tolist()
    hdg = (np.degrees(plan.track[:, 2]) % 360.0).tolist()
    spd, kn = plan.speed.tolist(), (plan.speed * KN_PER_MPS).tolist()
    inputs = plan.inputs.tolist() if n_in else []
    step = max(every, 1)
    kept = [k for k in range(k_total) if not k % step or k in starts or k == k_total - 1]
    if step == 1:
        utc = sample_times_iso(plan, t0)  # the GPX track's times too: formatted once
    else:  # only the samples written: 1 in ``every`` of the times the GPX track formats for itself
        utc = dict(zip(kept, sample_times_iso_at(plan, t0, kept)))
    for k in kept:
        ts = t_rel[k]
        si = int(step_of[k])
        st = by_index.get(si)
        orders = " | ".join(step_orders(plan, st)) if (st is not None and k == first_of[si]) else ""
        row: list[Any] = [
            f"{ts:.3f}",
            clock(ts),
            utc[k],
            f"{lat[k]:.7f}",
            f"{lon[k]:.7f}",
            f"{x[k]:.2f}",
            f"{y[k]:.2f}",
            f"{hdg[k]:.1f}",
            f"{spd[k]:.3f}",
            f"{kn[k]:.2f}",
            si + 1,
            st.segment if st else "",
            st.primitive if st else "",
            orders,
        ]
        for j, (_, kind) in enumerate(cols):
            v = inputs[min(k, len(inputs) - 1)][j] if n_in else float("nan")
            row.append(f"{np.degrees(v):.2f}" if kind == "deg" else f"{60.0 * v:.1f}" if kind == "rpm" else f"{v:.4g}")
        w.writerow(row)
    return buf.getvalue()


def write_csv(plan: Plan, path: str | Path, **kw: Any) -> Path:
    """Write :func:`plan_csv` to ``path`` atomically."""
    return atomic_write_text(path, plan_csv(plan, **kw))
