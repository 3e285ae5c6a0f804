"""`shiptrial sweep` given a diagnosed model.json as a ship says, as every command given the file
does (README), which findings the designs leave out (before: never shown by sweep)."""

from __future__ import annotations

import json

from cli.app import _run
from expdesign.sweep import load_sweep, ship_warnings
from tests.test_model_json_ship import _model_json


def test_sweep_warns_about_the_findings_a_model_json_ship_leaves_out(tmp_path, capsys):
    path = _model_json(tmp_path)
    cfg = tmp_path / "sweep.toml"
    cfg.write_text(f'[sweep]\nships = ["{path}"]\ncriteria = ["D"]\n')
    (w,) = ship_warnings(load_sweep(cfg))
    assert w.startswith(f"{path}: ") and "actuator_delay (delay_s 0.5)" in w
    rc = _run(["sweep", str(cfg), "--out", str(tmp_path / "s.csv"), "--json", "--scheduler", "inline"])
    cap = capsys.readouterr()
    warned = [ln for ln in cap.err.splitlines() if ln.startswith("warning: ")]
    assert rc == 0 and warned == [f"warning: {w}"], cap.err
    assert json.loads(cap.out)["warnings"] == [w]
