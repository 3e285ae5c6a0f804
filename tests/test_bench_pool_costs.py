"""benchmarks/pool_costs.py's ``--terms`` (the which-term table of docs/kernel-speed.md, stop 56): the figures
from the first reading's printed terms, and one-line errors for bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.pool_costs import parse_terms, which_term

ROOT = Path(__file__).resolve().parent.parent
# the terms `bench_design.py --scaling` printed in stop 56's first reading (docs/kernel-speed.md, Stop 56)
READING_1 = {
    "fixed": {"optimized": 0.023, "random": 0.036},
    "per_run": {"optimized": 0.00103, "random": 0.00132},
    "first": [0.058, 0.051],
    "fork": 0.0181,
    "child": 0.0233,
    "serial": 0.040,
    "infl": 1.07,
}


def _figures(capsys, t: dict) -> dict[str, float]:
    which_term(t)
    out = {}
    for line in capsys.readouterr().out.splitlines():
        name, _, value = line.rpartition(":")
        if name.strip().startswith(("16 workers", "without")):
            out[name.strip()] = float(value)
    return out


def test_the_first_readings_terms_give_the_documented_figures(capsys):
    f = _figures(capsys, READING_1)
    assert f["16 workers, all terms"] == pytest.approx(0.432, abs=5e-4)
    assert f["without the forks' delay"] == pytest.approx(0.649, abs=5e-4)
    assert f["without the forks' delay"] > f["16 workers, all terms"] + 0.2  # the term that costs most


def test_each_term_is_used(capsys):
    """A term the prediction ignored would leave the efficiency unchanged when it is taken out or scaled."""
    base = _figures(capsys, READING_1)["16 workers, all terms"]
    for key, scale in (("fork", 2.0), ("child", 2.0), ("serial", 2.0), ("infl", 1.2), ("first", 2.0)):
        t = json.loads(json.dumps(READING_1))
        t[key] = [v * scale for v in t[key]] if isinstance(t[key], list) else t[key] * scale
        assert _figures(capsys, t)["16 workers, all terms"] < base - 0.005, key


@pytest.mark.parametrize(
    "text, says",
    [
        ("nojson", "not JSON"),
        ('{"fixed": 1}', "'fixed'"),
        (json.dumps({**READING_1, "fork": "8 ms"}), "'fork' must be a number"),
        (json.dumps({**READING_1, "first": [0.05]}), "'first' must be"),
    ],
)
def test_bad_terms_are_named(text, says):
    with pytest.raises(ValueError, match=says):
        parse_terms(text)


@pytest.mark.parametrize(
    "args, says",
    [(["--terms", "nojson"], "--terms: not JSON"), (["--fork-ratios", "0.5", "0.5", "0.1"], "give --terms too")],
)
def test_the_command_gives_one_line_and_no_traceback(args, says):
    r = subprocess.run(
        [sys.executable, "benchmarks/pool_costs.py", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert r.returncode != 0 and r.stdout == ""
    assert says in r.stderr and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("pool_costs.py: error:")
