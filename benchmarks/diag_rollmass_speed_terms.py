"""Which part of the ``oe`` model's speed following biases the load on a slowing ship (stop 62, issue 25).

The basin truth's ``speed_loss`` (or ``combined``) ships of the ``--runs 30`` family (seed 2015 and the variant's
offset, as ``bench_rollmass_truth``), with or without sea and sensor noise (``--quiet``), fitted by ``oe`` as the
bench fits it (``bench_rollmass_truth._one``: the three CSVs read by ``estimate_from_files``), under one estimator
switch at a time (the truth is never changed):

``main``     the estimator as it is;
``held``     the recordings without ``u``: one speed per run, nothing followed;
``lp0``      the speed followed without its 0.2 Hz low-pass (``speed.SPEED_LP_HZ = 0``: on a quiet run ``u`` is exact);
``nosway``   no sway-velocity share ``(u/U - 1) (Y_v, K_v, n_v) v`` (``oe_fit.SWAY_TERM = False``);
``bias0``    the turn input's gyro bias taken as zero, the quiet truth's own (in place of the fit's estimate);
``nokappa``  the wall-sided heel gain held at the hull's (``output_error.FIT_KAPPA = False``);
``align``    the followed speed delayed by the IMU channels' post-processing FIR (0.1 s, :data:`FIR_DELAY`);
``truev``   (quiet only) the sway term's velocity the truth's own (:func:`with_sway_velocity`), not the model's;
``surge``    the speed followed from the surge equation (benchmarks/rollmass_surge_speed.py) in place of the low-pass.

Switches combine with ``+`` (``lp0+bias0``: both).

    PYTHONPATH=$PWD nice -n 10 python benchmarks/diag_rollmass_speed_terms.py --quiet --last 3 --switches main,lp0 --dump D

``--twin``: the same ships at a constant speed (the truth's ``base`` drawn from the variant's seed: same draws, rudder,
sea and noise, no surge state), the reference a speed loss is measured against.

Each fit's row (the bench's ``--dump`` format, its family naming the switch) is appended to ``--dump`` as it ends,
and a table of signed mass % / z mm per switch, run and case is printed at the end.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from unittest import mock

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one BLAS thread, as the bench

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_rollmass_truth as bench  # noqa: E402
import numpy as np  # noqa: E402
import rollmass_surge_speed as surge  # noqa: E402

from identify.rollmass import oe_fit, output_error, speed  # noqa: E402
from tests.physics import basin_truth as bt  # noqa: E402

SWITCHES = ("main", "held", "lp0", "nosway", "bias0", "nokappa", "surge", "align", "truev")
# the fit's datasets' true sway velocity (``truev``: set before each fit from the quiet truth's own measurement chain)
TRUE_V: list[np.ndarray] = []
# the group delay of the truth's order-20 FIR at 100 Hz (section 5's post-processing of the IMU channels and the
# rudder, not of the positioning's speed), in samples of the 50 Hz recording
FIR_DELAY = 5
FAMILY_RUNS, FAMILY_SEED = 30, 2015
# the switches that are one module setting: (module, name, value)
SETTINGS = {
    "lp0": (speed, "SPEED_LP_HZ", 0.0),
    "nosway": (oe_fit, "SWAY_TERM", False),
    "nokappa": (output_error, "FIT_KAPPA", False),
}


@contextmanager
def switched(name: str) -> Iterator[None]:
    """The estimator with switch ``name`` (module docstring; ``a+b``: both) on inside the block."""
    if "+" in name:
        first, rest = name.split("+", 1)
        with switched(first), switched(rest):
            yield
    elif name in SETTINGS:
        with mock.patch.object(*SETTINGS[name]):
            yield
    elif name == "truev":
        terms = oe_fit.speed_terms

        def true_sway(*args, **kw):
            r_bias, sway = terms(*args, **kw)
            # how far the model's own sway velocity is from the truth's: corr and sd ratio, per dataset
            print(
                "  model v against true v: "
                + ", ".join(
                    f"corr {np.corrcoef(w, v)[0, 1]:.3f} sd {np.std(w) / np.std(v):.3f}"
                    for w, v in zip(sway, TRUE_V)
                    if w is not None
                ),
                flush=True,
            )
            return r_bias, [None if w is None else v for w, v in zip(sway, TRUE_V)]

        with mock.patch.object(oe_fit, "speed_terms", true_sway):
            yield
    elif name == "bias0":
        terms = oe_fit.speed_terms

        def zero_bias(*args, **kw):
            r_bias, sway = terms(*args, **kw)
            return [None if b is None else 0.0 for b in r_bias], sway

        with mock.patch.object(oe_fit, "speed_terms", zero_bias):
            yield
    elif name == "align":
        held = speed.followed_speed

        def delayed(rec):
            s = held(rec)
            return None if s is None else np.concatenate([np.full(FIR_DELAY, s[0]), s[:-FIR_DELAY]])

        with mock.patch.object(speed, "followed_speed", delayed), mock.patch.object(output_error, "followed_speed", delayed):
            yield
    elif name == "surge":
        # the value is read in output_error.model_inputs and speed.speed_inputs; every other caller asks only None or not
        with (
            mock.patch.object(speed, "followed_speed", surge.followed),
            mock.patch.object(output_error, "followed_speed", surge.followed),
        ):
            yield
    else:
        yield


@contextmanager
def with_sway_velocity() -> Iterator[None]:
    """Every quiet dataset the truth simulates in the block also holds ``v``: the true sway velocity through the truth's
    own roll-gyro chain (its ``_measure`` called again with ``v`` in the roll rate's place: with no noise and no
    misalignment, the sensor's low-pass, the FIR and the decimation the IMU channels have, so it is the sway velocity
    as the oe model's states see it)."""
    measure = bt._measure

    def both(ship, rng, delta, v, p, *rest, **kw):
        out = measure(ship, rng, delta, v, p, *rest, **kw)
        out["v"] = measure(ship, np.random.default_rng(0), delta, v, v, *rest, **kw)["p"]
        return out

    with mock.patch.object(bt, "_measure", both):
        yield


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default="speed_loss", choices=("speed_loss", "combined"))
    ap.add_argument("--quiet", action="store_true", help="no sea, no sensor noise")
    ap.add_argument(
        "--twin",
        action="store_true",
        help="the variant's ships, rudder, sea and noise without the speed loss (basin_truth's base drawn from the variant's seed)",
    )
    ap.add_argument("--first", type=int, default=0, help="runs FIRST..LAST of the 30-run family")
    ap.add_argument("--last", type=int, default=3, help="runs FIRST..LAST of the 30-run family")
    ap.add_argument("--cases", default="case1,case2,case3")
    ap.add_argument("--switches", default="main")
    ap.add_argument("--dump", required=True, help="rows appended here")
    a = ap.parse_args()
    switches = a.switches.split(",")
    bad = [s for s in switches if any(p not in SWITCHES for p in s.split("+"))]
    if not a.quiet and any("truev" in sw.split("+") for sw in switches):
        ap.exit(2, f"{ap.prog}: error: --switches {a.switches}: truev needs --quiet; fix: add --quiet or drop truev\n")
    if bad:
        ap.exit(2, f"{ap.prog}: error: --switches {a.switches}: unknown {', '.join(bad)}; fix: some of {', '.join(SWITCHES)}\n")
    try:  # before the simulation: an unwritable dump must not cost the run
        Path(a.dump).touch()
    except OSError as e:
        ap.exit(2, f"{ap.prog}: error: --dump {a.dump}: {e.strerror}; fix: give a writable file in an existing folder\n")
    # every parameter is drawn from one stream in every variant, and the effects then switched on: base drawn from the
    # variant's seed is the same ships with the same rudder, sea and noise, at a constant speed (Xdd = 0, no surge state)
    truth = "base" if a.twin else a.variant
    with with_sway_velocity() if a.quiet else contextlib.nullcontext():
        ship, data = bt.simulate_runs(truth, FAMILY_RUNS, bt.variant_seed(FAMILY_SEED, a.variant), quiet=a.quiet)
    heel = bench.rm_restoring.DEFAULT_HEEL_REFERENCE
    table = {}
    for sw in switches:
        family = {"diag": "s62 speed terms", "switch": sw, "quiet": a.quiet, "twin": a.twin}
        for run in range(a.first, a.last + 1):
            for case in a.cases.split(","):
                recs = bt.case_recordings(ship, data, case, run)
                TRUE_V[:] = [data[name]["v"][run] for name in bt.CASES[case]] if a.quiet else []
                with switched(sw):
                    rows = bench._one((a.variant, run, case, recs, ["oe"], "held" not in sw.split("+"), heel, family))
                for r in rows:
                    with open(a.dump, "a") as fh:
                        fh.write(json.dumps(r, default=bool) + "\n")
                    res = "failed" if r[4] is None else f"{r[4][0]:+.1f} / {r[4][1]:+.0f}"
                    kappa = r[7].get("kappa", float("nan"))
                    table[(sw, run, case)] = res
                    print(
                        f"{sw:8s} run {run} {case}: {res}  kappa {kappa:.2f}  X_v {r[7].get('X_v', float('nan')):.0f}  "
                        f"{r[6]:.1f} s",
                        flush=True,
                    )
    runs = range(a.first, a.last + 1)
    print("\nswitch   " + "  ".join(f"run {r} {c}" for r in runs for c in a.cases.split(",")))
    for sw in switches:
        print(f"{sw:8s} " + "  ".join(table[(sw, r, c)] for r in runs for c in a.cases.split(",")))


if __name__ == "__main__":
    main()
