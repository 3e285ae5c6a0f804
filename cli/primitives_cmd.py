"""``shiptrial primitives``: the primitive library as a table, JSON and plots."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from primitives.io import atomic_savefig, dumps

if TYPE_CHECKING:
    from rich.table import Table

    from primitives.ship import ShipProfile


def library_rows(library) -> list[dict]:
    rows = []
    for p in library:
        r = p.ranges()
        minx, miny, maxx, maxy = p.footprint.bounds
        rows.append(
            {
                "name": p.name,
                "kind": p.kind,
                "description": p.description,
                "duration_s": p.duration_s,
                "u_range": list(r["u"]),
                "v_range": list(r["v"]),
                "r_range": list(r["r"]),
                "end_pose": p.end_pose.tolist(),
                "footprint_m": [maxx - minx, maxy - miny],
                "footprint_area_m2": p.footprint.area,
                "split_points": len(p.split_points),
                "orders": [o.to_dict() for o in p.orders],
                "expectations": p.expectations(),
                "abort_criteria": p.abort_criteria(),
            }
        )
    return rows


PLOT_WRITER = "shiptrial primitives"  # the --plot figure's Creator mark (primitives.io.is_written_figure)


def plot_library(library, path: Path, *, force: bool = False) -> None:
    """Each primitive's track and states; a figure primitives did not draw is refused unless ``force``."""
    from primitives.io import check_figure_file

    check_figure_file(path, "--plot", PLOT_WRITER, force=force)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    n = len(library)
    cols = 4
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols * 2, figsize=(4 * cols * 1.6, 2.4 * rows), squeeze=False)
    for i, p in enumerate(library):
        ax_tr, ax_st = axes[i // cols, 2 * (i % cols)], axes[i // cols, 2 * (i % cols) + 1]
        fp = p.footprint
        geoms = getattr(fp, "geoms", [fp])
        for g in geoms:
            ys, xs = g.exterior.xy  # (x north, y east): plot east right, north up
            ax_tr.fill(xs, ys, color="0.85")
        ax_tr.plot(p.track[:, 1], p.track[:, 0], lw=1)
        ax_tr.set_aspect("equal", adjustable="datalim")
        ax_tr.set_title(p.name, fontsize=8)
        ax_tr.tick_params(labelsize=6)
        t = np.arange(p.nu.shape[0]) * p.profile.sample_time
        for j, lab in enumerate("uvr"):
            ax_st.plot(t, p.nu[:, j], lw=1, label=lab)
        ax_st.tick_params(labelsize=6)
        if i == 0:
            ax_st.legend(fontsize=6)
    for j in range(n, rows * cols):
        axes[j // cols, 2 * (j % cols)].axis("off")
        axes[j // cols, 2 * (j % cols) + 1].axis("off")
    fig.suptitle("Primitive tracks (east right, north up; swept hull shaded) and states u, v, r over time", fontsize=9)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110, metadata={"Creator": PLOT_WRITER})  # how a second run knows its own plot
    plt.close(fig)


def register(app: typer.Typer) -> None:
    @app.command("primitives")
    def primitives(
        ship: str = typer.Option("model-ship", "--ship", help="built-in profile name or a .toml/.json profile file"),
        json_out: bool = typer.Option(False, "--json", help="print the library as JSON"),
        plot: Path | None = typer.Option(None, "--plot", help="draw each primitive's track and states to this PNG"),
        orders: bool = typer.Option(False, "--orders", help="also list each primitive's helm/engine orders and abort criteria"),
        force: bool = typer.Option(
            False, "--force", help="replace a --plot file that primitives did not draw (default: refuse, naming the file)"
        ),
    ) -> None:
        """List the manoeuvre primitive library of a ship."""
        from cli.errors import warn_ship
        from cli.options import validate_primitives_options
        from primitives.library import build_library
        from primitives.ship import load_profile

        validate_primitives_options(plot, force)
        profile = load_profile(ship)
        profile.require_planar("shiptrial primitives")
        warn_ship(profile)
        library = build_library(profile)
        rows = library_rows(library)
        if plot:
            plot_library(library, plot, force=force)
        if json_out:
            typer.echo(dumps(rows))
            return
        from rich.console import Console

        Console().print(library_table(profile, rows))
        from primitives.library import library_notes

        for note in library_notes(profile):
            typer.echo(f"note: {note}")
        if profile.actuator == "rudder_propeller":
            from primitives.helm import steady_rps

            rpm = 60 * steady_rps(profile)
            src = profile.engine.approach_rpm
            import textwrap

            typer.echo(
                textwrap.fill(
                    f"approach: the model holds {profile.cruise_speed_mps:.2f} m/s at {rpm:.1f} rpm"
                    + (f" (the source's trials ran {src:g} rpm)" if src else "")
                    + f"; rudder {profile.helm.max_rudder_deg:g}° max at {profile.helm.rudder_rate_deg_s:g}°/s",
                    80,
                    subsequent_indent="  ",
                )
            )
        if orders:
            for p in library:
                typer.echo(f"\n{p.name} ({p.description}, {p.duration_s:.0f} s)")
                for line in p.commands:
                    typer.echo(f"  {line}")
                typer.echo(f"  {p.abort_criteria()}")
        if plot:
            typer.echo(f"wrote {plot}")


def _num(x: float, decimals: int) -> str:
    """``x`` to ``decimals`` places, without the sign of a value that rounds to zero ("-0.00")."""
    text = f"{x:.{decimals}f}"
    return text.lstrip("-") if float(text) == 0.0 else text


def library_table(profile: ShipProfile, rows: list[dict]) -> Table:
    """The library as a rich table that fits 80 columns: the name whole (its last letter says
    starboard or port), speeds and rates as their largest magnitude (--json has the ranges), no
    cell borders; a range reads "lo..hi" so that a negative bound stays readable."""
    from rich.table import Table

    table = Table(
        title=f"primitives of {profile.name} (Ts = {profile.sample_time} s)",
        box=None,
        pad_edge=False,
        caption="k: i informative, b basic; s: duration; u: surge speed range (m/s); |v|, |r|: largest sway "
        "speed (m/s) and yaw rate (°/s); end: x ahead, y to starboard (m), heading change (°); room: "
        "swept footprint along x across (m)",
        caption_justify="left",
    )
    table.add_column("name", no_wrap=True, min_width=max(len(r["name"]) for r in rows))
    table.add_column("k", no_wrap=True)
    for col in ("s", "u", "|v|", "|r|", "end", "room"):
        table.add_column(col, justify="right", no_wrap=True)
    for r in rows:
        table.add_row(
            r["name"],
            r["kind"][:1],
            f"{r['duration_s']:.0f}",
            "..".join(_num(x, 2) for x in r["u_range"]),
            f"{max(abs(x) for x in r['v_range']):.2f}",
            f"{math.degrees(max(abs(x) for x in r['r_range'])):.2f}",
            ",".join(_num(x, 0) for x in (r["end_pose"][0], r["end_pose"][1], math.degrees(r["end_pose"][2]))),
            "{:.0f}x{:.0f}".format(*r["footprint_m"]),
        )
    return table
