"""The bundled sweep example (examples/sweep.toml, the README's `shiptrial sweep` example) runs
without a failed cell: every cell's library identifies every parameter of its ship."""

from __future__ import annotations

from pathlib import Path

from expdesign import api
from expdesign.api import InfoSet, check_identifiable
from expdesign.sweep import _library, load_sweep

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sweep.toml"


def test_every_cell_of_the_bundled_sweep_example_is_identifiable() -> None:
    """Stop 62's walk: `shiptrial sweep examples/sweep.toml --out sweep.csv` exited 1 with
    'model-ship @ 3 m/s D/batchwise: DesignError: ... cannot identify ['Xtau']' (and A/batchwise):
    a new user's first sweep failed. The identifiability check is run_design's own, before any
    solve (1.6 s CPU for the example's four ship-speed libraries)."""
    cells = load_sweep(EXAMPLE)
    infos: dict[tuple[str, float | None], tuple] = {}
    failed = []
    for c in cells:
        key = (c.ship, c.speed_mps)
        if key not in infos:
            profile, prims = _library(c)
            infos[key] = (profile, InfoSet.from_infos(api._moments(profile, prims, 0, c.seed), None, 0.0))
        profile, info = infos[key]
        try:
            check_identifiable(profile, info, c.mean_subtraction)
        except api.DesignError as exc:
            failed.append(f"{c.ship} @ {c.speed_mps} m/s {c.mean_subtraction}: {str(exc)[:120]}")
    assert not failed, "\n".join(failed)
