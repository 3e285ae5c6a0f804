"""Design sweeps: ships x speeds x criteria x mean-subtraction modes, one tidy table.

A sweep is read from TOML::

    [sweep]
    ships = ["model-ship", "full-scale"]     # built-in names or profile files
    criteria = ["D", "A", "E"]
    mean_subtraction = ["batchwise", "complete"]
    library = "thesis"                        # or "standard": IMO/ITTC trials built at each speed
    speeds = [0.6, 1.0]                       # cruise speeds (m/s) for library = "standard"
    seed = 1

Every cell is an independent task (see ``expdesign.parallel``), so a sweep runs the same on
this machine and on a Dask cluster.
"""

from __future__ import annotations

import dataclasses
import json
import time
import tomllib
from pathlib import Path
from typing import Any

from expdesign.parallel import Engine, MapResult, get_engine, task_seeds
from primitives.errors import UserError
from primitives.validate import MAX_PRIMITIVE_SAMPLES, check_sweep_size, manoeuvre_samples, positive, unknown_key

CRITERIA = ("D", "A", "E")
MODES = ("none", "batchwise", "complete")
COLUMNS = [
    "ship",
    "library",
    "speed_mps",
    "criterion",
    "mean_subtraction",
    "logdet",
    "efficiency_vs_uniform",
    "efficiency_bound",
    "top_primitive",
    "top_share",
    "n_primitives_used",
    "weights",
    "solve_time_s",
    "error",
]


class SweepError(UserError):
    """A sweep configuration is malformed; the message names the file and field."""


@dataclasses.dataclass(frozen=True)
class Cell:
    ship: str
    library: str
    speed_mps: float | None
    criterion: str
    mean_subtraction: str
    seed: int


SWEEP_KEYS = ("ships", "criteria", "mean_subtraction", "library", "speeds", "seed")
TABLE_SUFFIXES = (".csv", ".parquet")


def check_outputs(out: str | Path, plot: str | Path | None = None, option: str = "--out", *, replace: bool = True) -> None:
    """Refuse, before any work, a table or plot path whose extension does not name its format
    (or that cannot be written); ``option`` names the table path in the message. ``replace=False``
    (no ``--force``): an existing file that is not a sweep's own table or plot (:func:`is_sweep_table`,
    :func:`is_sweep_plot`) is refused too. :func:`write_table` and :func:`plot_summary` check their
    own path again when they write (a notebook's call has no CLI to check first)."""
    _check_table(out, option, replace)
    if plot is not None:
        _check_plot(plot, "--plot", replace)


def _check_table(path: str | Path, option: str, replace: bool) -> None:
    from primitives.io import check_out_file

    try:
        check_out_file(path, TABLE_SUFFIXES, option, "table", replace=replace, ours=is_sweep_table, writer=WRITER)
    except UserError as exc:
        raise SweepError(str(exc)) from None


def _check_plot(path: str | Path, option: str, replace: bool) -> None:
    from primitives.io import check_figure_file

    try:
        check_figure_file(path, option, WRITER, force=replace)
    except UserError as exc:
        raise SweepError(str(exc)) from None


WRITER = "shiptrial sweep"  # the plot's Creator (PNG text chunk, PDF /Creator, SVG dc:creator): how its files are known


def is_sweep_table(path: Path) -> bool:
    """A table :func:`write_table` wrote: a CSV whose first line is the header row of :data:`COLUMNS`, or a Parquet
    file holding those columns (read with pyarrow; without it no Parquet table is written either)."""
    from primitives.io import file_head, first_lines

    if path.suffix.lower() != ".parquet":
        return first_lines(path, 1) == [",".join(COLUMNS)]
    if file_head(path, 4) != b"PAR1":
        return False
    try:
        import pyarrow.parquet as pq
    except ImportError:
        return False
    return set(COLUMNS) <= set(pq.read_schema(path).names)


def is_sweep_plot(path: Path) -> bool:
    """A figure :func:`plot_summary` wrote: its Creator metadata names :data:`WRITER` (a PDF keeps it at the end)."""
    from primitives.io import is_written_figure

    return is_written_figure(path, WRITER)


def _read(path: Path) -> dict:
    from primitives.io import read_input_text

    text = read_input_text(path, SweepError, "a sweep TOML file")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SweepError(f"{path}: not valid TOML: {exc}") from None


def _check_keys(keys, allowed, where: str, path: Path) -> None:
    bad = unknown_key(keys, allowed)
    if bad:
        raise SweepError(f"{path}: unknown field '{where}{bad[0]}'{bad[1]}")


def _check_speeds(speeds: list, profiles: dict[str, Any], path: Path) -> None:
    """Speeds finite and > 0 m/s, and not so slow that a manoeuvre of 20 ship lengths never ends
    (``profiles``: the sweep's ships by name, loaded once)."""
    for s in speeds:
        if s is None:
            continue
        if isinstance(s, str):  # float() reads "0_6" as 6 and "1e1" as 10: a string is refused, as the profile loader does
            raise SweepError(
                f"{path}: field 'sweep.speeds' holds the string {s!r}: write each speed as a TOML number in m/s, "
                "without quotes (speeds = [0.6, 1.0])"
            )
        v = positive(s, f"{path}: field 'sweep.speeds'", "m/s", SweepError)
        for sh, prof in profiles.items():
            n = manoeuvre_samples(20 * prof.length_m, v, prof.sample_time)
            if n > MAX_PRIMITIVE_SAMPLES:
                v_min = 20 * prof.length_m / prof.sample_time / MAX_PRIMITIVE_SAMPLES
                raise SweepError(
                    f"{path}: field 'sweep.speeds': {s!r} m/s is too slow for {sh!r} (a manoeuvre of 20 ship lengths would take "
                    f"{n:.3g} samples); give speeds >= {v_min:.3g} m/s"
                )


def held_input(profile: Any, speed: float) -> tuple[str, float, float] | None:
    """The first input ``profile`` would need beyond its limit to hold ``speed`` m/s straight
    ahead (the steady surge force of primitives.steady_forces.steady_forces, allocated to its inputs)
    as (name, needed, limit), or None when the speed is within reach or the ship's actuators have
    no steady-force allocation (rudder and propeller: the cell says so itself)."""
    from primitives.steady_forces import STEADY_FORCE_ACTUATORS, steady_forces

    if profile.actuator not in STEADY_FORCE_ACTUATORS:
        return None
    need = profile.allocate(*steady_forces(profile, speed, 0.0, 0.0))[0]
    for name, a, b in zip(profile.inputs, need, profile.clip_inputs(need)):
        if abs(a - b) > 1e-6 * max(abs(a), 1.0):
            return name, float(a), float(b)
    return None


def top_speed(profile: Any, below: float) -> float:
    """The highest speed under ``below`` m/s that ``profile`` holds within its input limits
    (bisection on :func:`held_input`, 30 halvings: 1e-9 of ``below``)."""
    lo, hi = 0.0, below
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if held_input(profile, mid) else (mid, hi)
    return lo


def _check_top_speeds(speeds: list, profiles: dict[str, Any], path: Path) -> None:
    """Refuse a speed a ship cannot sail: its standard trials saturate an input in every step, so
    the cell either fails (with batchwise mean subtraction the saturated input is constant in every
    primitive: "cannot identify ['Xtau']", whose hint to add a manoeuvre misleads) or yields a
    design for trials the ship cannot make (model-ship at 3 m/s needs tau_x 19286 of 6000)."""
    for s in speeds:
        for sh, prof in profiles.items():
            over = None if s is None else held_input(prof, float(s))
            if over:
                v_max = top_speed(prof, float(s))
                raise SweepError(
                    f"{path}: field 'sweep.speeds': {s!r} m/s is too fast for {sh!r} (straight ahead it needs "
                    f"{over[0]} = {over[1]:.4g}, beyond its limit {over[2]:g}); give speeds <= {v_max:.3g} m/s, "
                    "or sweep the faster ships in a config of their own"
                )


def load_sweep(path: str | Path) -> list[Cell]:
    """Parse and validate a sweep file into its cells (grid order)."""
    path = Path(path)
    doc = _read(path)
    _check_keys(doc, ("sweep",), "", path)
    sw = doc.get("sweep")
    if not isinstance(sw, dict):
        raise SweepError(f"{path}: missing table [sweep]")
    _check_keys(sw, SWEEP_KEYS, "sweep.", path)

    def listed(key: str, default: list, allowed: tuple | None = None, kind: type | None = None) -> list:
        val = sw.get(key, default)
        if not isinstance(val, list) or not val:
            raise SweepError(f"{path}: field 'sweep.{key}' must be a non-empty list")
        if kind is not None and not all(isinstance(v, kind) for v in val):
            raise SweepError(f"{path}: field 'sweep.{key}' must hold only {kind.__name__} values, got {val!r}")
        if allowed:
            bad = [v for v in val if v not in allowed]
            if bad:
                raise SweepError(f"{path}: field 'sweep.{key}' has {bad}; allowed: {list(allowed)}")
        return val

    ships = listed("ships", ["model-ship"], kind=str)
    criteria = listed("criteria", ["D"], CRITERIA, kind=str)
    modes = listed("mean_subtraction", ["complete"], MODES, kind=str)
    library = sw.get("library", "thesis")
    if library not in ("thesis", "standard"):
        raise SweepError(f"{path}: field 'sweep.library' must be 'thesis' or 'standard', got {library!r}")
    seed = sw.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2**63:
        raise SweepError(f"{path}: field 'sweep.seed' must be a whole number >= 0, got {seed!r}")
    from primitives.ship import load_profile

    profiles = {}
    for s in ships:
        profiles[s] = load_profile(s)
        profiles[s].require_planar(f"a sweep ({path}: field 'sweep.ships')")  # fail early with the profile's own message
    speeds: list[float | None] = [None]
    if library == "standard":
        speeds = listed("speeds", [None])
        _check_speeds(speeds, profiles, path)
    elif "speeds" in sw:
        raise SweepError(f"{path}: field 'sweep.speeds' applies to library = \"standard\" only; remove it or set the library")
    cells = [(sh, library, sp, c, m) for sh in ships for sp in speeds for c in criteria for m in modes]
    check_sweep_size(len(cells), str(path), SweepError)
    _check_top_speeds(speeds, profiles, path)
    seeds = task_seeds(seed, len(cells))
    return [Cell(sh, lib, None if sp is None else float(sp), c, m, sd) for (sh, lib, sp, c, m), sd in zip(cells, seeds)]


def ship_warnings(cells: list[Cell]) -> list[str]:
    """Each swept ship's load warnings (a diagnosed model.json's findings its profile cannot hold:
    the designs are made without them), once per ship, prefixed with the ship."""
    from primitives.ship import load_profile

    ships = list(dict.fromkeys(c.ship for c in cells))
    return [f"{s}: {w}" for s in ships for w in load_profile(s).load_warnings]


def failed_cells(rows: list[dict[str, Any]]) -> list[str]:
    """One line per failed cell: which cell and its error."""
    return [
        f"{r['ship']}{'' if r.get('speed_mps') is None else ' @ ' + format(r['speed_mps'], 'g') + ' m/s'} "
        f"{r['criterion']}/{r['mean_subtraction']}: {r['error']}"
        for r in rows
        if r.get("error")
    ]


def _library(cell: Cell):
    """The cell's dictionary: the thesis primitives, or the standard trials at the cell's speed
    plus sway moves at that speed (rudder-type trials alone never excite the sway force)."""
    from primitives import maneuvers as mv
    from primitives.library import make_primitive, standard_trials, thesis_primitives
    from primitives.ship import load_profile

    profile = load_profile(cell.ship)
    if cell.library == "thesis":
        return profile, thesis_primitives(profile)
    if cell.speed_mps is not None:
        profile = dataclasses.replace(profile, cruise_speed_mps=cell.speed_mps)
    u = profile.cruise_speed_mps
    n = int(20 * profile.length_m / u / profile.sample_time)
    sway = make_primitive(
        profile,
        "sway_moves",
        f"sway steps +-{0.15 * u:.2f} m/s at {u:.2f} m/s",
        mv.sway_steps(profile, [(0.15 * u, n), (-0.15 * u, n)], u=u),
    )
    return profile, [p for p in standard_trials(profile) if p.name != "stopping"] + [sway]


def run_cell(cell: Cell) -> dict[str, Any]:
    """One sweep cell: build the library, solve the design, summarise it as one table row."""
    from expdesign.api import run_design

    row: dict[str, Any] = {k: None for k in COLUMNS}
    row.update(
        ship=cell.ship,
        library=cell.library,
        speed_mps=cell.speed_mps,
        criterion=cell.criterion,
        mean_subtraction=cell.mean_subtraction,
    )
    t0 = time.perf_counter()
    try:
        profile, prims = _library(cell)
        d = run_design(profile, prims, criterion=cell.criterion, mean_subtraction=cell.mean_subtraction, seed=cell.seed)
    except Exception as exc:  # a failing cell is a row with its error, not a lost sweep
        row["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0]
        return row
    w = {k: float(v) for k, v in d.weights.items() if v > 1e-4}
    top = max(w, key=w.get) if w else None
    row.update(
        logdet=float(d.logdet),
        efficiency_vs_uniform=_f(getattr(d, "efficiency_vs_uniform", None)),
        efficiency_bound=_f(getattr(d, "efficiency_bound", None)),
        top_primitive=top,
        top_share=w.get(top) if top else None,
        n_primitives_used=len(w),
        weights=json.dumps({k: round(v, 4) for k, v in sorted(w.items(), key=lambda kv: -kv[1])}),
        solve_time_s=time.perf_counter() - t0,
    )
    return row


def _f(x: Any) -> float | None:
    return None if x is None else float(x)


def run_sweep(cells: list[Cell], engine: Engine | str | None = None, progress: bool = True) -> MapResult:
    eng = get_engine(engine)
    try:
        return eng.map(run_cell, cells, desc="sweep", progress=progress)
    finally:
        if not isinstance(engine, Engine):
            eng.close()


def write_table(rows: list[dict[str, Any]], path: str | Path, *, force: bool = False, option: str = "table") -> Path:
    """Write rows as CSV (or Parquet for a .parquet path when pyarrow is installed), atomically.
    An existing file is replaced only if a sweep wrote it (:func:`is_sweep_table`) or ``force``
    (the CLI's ``--force``): otherwise SweepError, in the CLI's words (``option`` names the path)."""
    import csv
    import io

    from primitives.io import atomic_write_bytes, atomic_write_text

    path = Path(path)
    _check_table(path, option, force)
    if path.suffix.lower() == ".parquet":
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise SweepError(f"{path}: writing Parquet needs pyarrow (pip install pyarrow), or use a .csv path") from None
        buf = io.BytesIO()
        pq.write_table(pa.Table.from_pylist(rows), buf)
        return atomic_write_bytes(path, buf.getvalue())
    out = io.StringIO()
    w = csv.DictWriter(out, fieldnames=COLUMNS, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in COLUMNS})
    return atomic_write_text(path, out.getvalue())


def plot_summary(rows: list[dict[str, Any]], path: str | Path, *, force: bool = False, option: str = "plot") -> Path:
    """Bar chart of each cell's efficiency against the uniform mix. An existing file is replaced only if
    a sweep drew it (:func:`is_sweep_plot`) or ``force``; otherwise SweepError, before any drawing
    (``option`` names the path: the CLI's "--plot")."""
    _check_plot(path, option, force)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from primitives.io import atomic_savefig

    ok = [r for r in rows if r.get("efficiency_vs_uniform") is not None]
    labels = [
        f"{r['ship']}{'' if r['speed_mps'] is None else ' @' + format(r['speed_mps'], 'g')} {r['criterion']}/{r['mean_subtraction']}"
        for r in ok
    ]
    fig, ax = plt.subplots(figsize=(max(6, 0.45 * len(ok) + 2), 4))
    ax.bar(range(len(ok)), [r["efficiency_vs_uniform"] for r in ok], color="tab:blue")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xticks(range(len(ok)), labels, rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("efficiency vs uniform mix")
    ax.set_title("Design sweep: gain of the optimized mix over equal shares")
    fig.tight_layout()
    p = atomic_savefig(fig, path, dpi=110, metadata={"Creator": WRITER})  # how a sweep knows its own plot (check_outputs)
    plt.close(fig)
    return p
