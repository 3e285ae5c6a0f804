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


def test_a_speed_the_ship_cannot_sail_is_refused_naming_ship_and_top_speed(tmp_path: Path) -> None:
    """The example's former 3 m/s (the full-scale ship's cruise speed) needs tau_x = 19286 of the
    model ship's 6000: its cells failed with 'cannot identify Xtau ... add a manoeuvre that varies
    that actuator' (batchwise) or gave a design for trials it cannot sail (complete). Refused at
    load now, before any cell runs; the full-scale ship alone at 3 m/s is accepted."""
    import pytest

    from expdesign.sweep import SweepError

    cfg = tmp_path / "s.toml"
    cfg.write_text('[sweep]\nships = ["model-ship", "full-scale"]\nlibrary = "standard"\nspeeds = [1.0, 3.0]\n')
    with pytest.raises(SweepError) as err:
        load_sweep(cfg)
    msg = str(err.value)
    assert "field 'sweep.speeds': 3.0 m/s is too fast for 'model-ship'" in msg and "tau_x = 1.929e+04" in msg
    assert "limit 6000" in msg and "give speeds <= 1.17 m/s" in msg  # eq. 9.1: 0.06 u + 0.01 u^2 = 1.4e-5 * 6000
    cfg.write_text('[sweep]\nships = ["full-scale"]\nlibrary = "standard"\nspeeds = [3.0]\n')
    assert len(load_sweep(cfg)) == 1
