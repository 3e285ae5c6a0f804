"""Fit the nonlinear ``kvlcc2`` profile on the MARIN free-running runs and print per-run fits.

    python benchmarks/fit_kvlcc2.py [--write]

Training runs: zz_10, zz_-10, zz_20, tc_35. Held out: zz_-20, tc_-35. Steps:

1. the neutral rudder angle (mean rudder over the first 10 s of the approaches) is taken out of
   the recorded rudder: the profile's delta is measured from neutral, so "midships" steers
   straight;
2. one-step least squares (equation error) gives starting values;
3. output error (open-loop simulation residuals, each run scaled by its own spread) fits
   every parameter;
4. the propeller term is then set so the model holds 7.97 m/s at the MARIN approach rpm (the
   runs hold the rpm near constant, so the data do not separate thrust from resistance).

Prints the per-run NRMSE fit % (surge, sway, yaw) of the linear baseline (``kvlcc2-linear``)
and of the new model; ``--write`` rewrites the [parameters.fitted] table of kvlcc2.toml.
"""

from __future__ import annotations

import argparse
import re
import sys
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from diagnose.model import AugmentedModel, fit_percent, prepare  # noqa: E402
from diagnose.recording import Recording, read_marin_dat  # noqa: E402
from primitives.io import atomic_write_text  # noqa: E402
from primitives.particulars.fit import balance_thrust as hold_speed  # noqa: E402
from primitives.particulars.fit import relative_least_squares  # noqa: E402
from primitives.profile_document import profile_from_dict  # noqa: E402
from primitives.regressors import predictor_regressors  # noqa: E402
from primitives.ship import load_profile  # noqa: E402

DATA = ROOT / "diagnose" / "data"
PROFILE = ROOT / "primitives" / "profiles" / "kvlcc2.toml"
TRAIN = ("zz_10", "zz_-10", "zz_20", "tc_35")
HELD_OUT = ("zz_-20", "tc_-35")
APPROACH_S = 10


def load_runs(names: tuple[str, ...]) -> list[Recording]:
    return [read_marin_dat(DATA / f"MARIN_FREE_KVLCC2_{n}_m.dat") for n in names]


def neutral_rudder(recs: list[Recording]) -> float:
    """Mean rudder angle [rad] over the approach (before the first order) of every run."""
    return float(np.mean([r.channels["delta"][:APPROACH_S].mean() for r in recs]))


def from_neutral(rec: Recording, delta0: float) -> Recording:
    ch = dict(rec.channels)
    ch["delta"] = ch["delta"] - delta0
    return Recording(rec.source, rec.t, rec.y, rec.psi, rec.pos, ch, rec.segments, rec.meta, rec.notes)


def one_step_ls(profile, recs: list[Recording]) -> np.ndarray:
    """Equation-error start: per DOF least squares of y(k+1) - y(k) on the regressors."""
    phis, dys = zip(*(predictor_regressors(profile, r.y, r.inputs_for(profile.inputs)[:-1], terms=profile.model) for r in recs))
    phi, dy = np.concatenate(phis), np.concatenate(dys)
    th = np.zeros(profile.model.n_params)
    for i in range(3):
        s = profile.model.dof_slice(i)
        th[s] = np.linalg.lstsq(phi[:, s], dy[:, i], rcond=None)[0]
    return th


def balance_thrust(profile, theta: np.ndarray) -> np.ndarray:
    """Set the n^2 coefficient so the surge increment is zero at cruise speed and approach rpm."""
    return hold_speed(profile, theta, profile.cruise_speed_mps, profile.engine.approach_rpm / 60.0)


def output_error(profile, theta: np.ndarray, recs: list[Recording], max_nfev: int = 60) -> np.ndarray:
    """Output-error least squares of every parameter, each run's residual scaled by that run's
    own spread per DOF so a 10/10 zig-zag weighs as much as a turning circle (the OE method of
    seed 004; batched finite-difference Jacobian through ``AugmentedModel.simulate``)."""
    model = AugmentedModel(profile, theta, [])
    preps = [prepare(profile, r) for r in recs]
    scale = [np.std(p.y, axis=0) * np.sqrt(p.n) for p in preps]

    def parts(P: np.ndarray) -> list[np.ndarray]:
        return [((p.y[None] - model.simulate(p, P))[:, 1:] / s).reshape(len(P), -1) for p, s in zip(preps, scale)]

    return relative_least_squares(parts, theta, max_nfev)


def run_fits(profile, theta: np.ndarray, recs: list[Recording]) -> list[tuple[str, np.ndarray]]:
    """Open-loop fit % per run (initial state from the first samples, nothing else fitted)."""
    model = AugmentedModel(profile, theta, [])
    out = []
    for r in recs:
        p = prepare(profile, r)
        yh = model.simulate(p, theta)[0]
        if not np.all(np.isfinite(yh)):
            out.append((Path(r.source).name, np.full(3, np.nan)))
        else:
            out.append((Path(r.source).name, fit_percent(p.y, yh)))
    return out


def fit(write: bool = False) -> tuple[np.ndarray, dict]:
    doc = tomllib.loads(PROFILE.read_text(encoding="utf-8"))
    profile = profile_from_dict(doc, str(PROFILE))
    train, held = load_runs(TRAIN), load_runs(HELD_OUT)
    delta0 = neutral_rudder(train + held)
    train_n = [from_neutral(r, delta0) for r in train]
    held_n = [from_neutral(r, delta0) for r in held]
    theta = one_step_ls(profile, train_n)
    theta = balance_thrust(profile, theta)
    theta = output_error(profile, theta, train_n)
    theta = balance_thrust(profile, theta)
    linear = load_profile("kvlcc2-linear")
    table = {
        "linear": run_fits(linear, linear.params(), train + held),
        "nonlinear": run_fits(profile, theta, train_n + held_n),
    }
    return theta, {"table": table, "delta0_deg": float(np.degrees(delta0)), "profile": profile}


def write_params(profile, theta: np.ndarray) -> None:
    text = PROFILE.read_text(encoding="utf-8")
    parts = []
    for i, dof in enumerate(("surge", "sway", "yaw")):
        vals = ", ".join(repr(float(x)) for x in theta[profile.model.dof_slice(i)])
        parts.append(f"{dof} = [{vals}]")
    block = "[parameters.fitted]\n" + "\n".join(parts) + "\n"
    text = re.sub(r"\[parameters\.fitted\]\n(?:[a-z]+ = \[.*\]\n)+", block, text)
    atomic_write_text(PROFILE, text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write the fitted parameters into kvlcc2.toml")
    args = ap.parse_args()
    theta, res = fit()
    if not np.all(np.isfinite(theta)):
        sys.exit("error: the output-error fit diverged (non-finite parameters)")
    print(f"neutral rudder angle: {res['delta0_deg']:+.2f} deg (taken out of the recorded rudder)")
    print(f"{'run':34s} {'set':9s} {'linear: surge sway yaw':>24s}   {'nonlinear: surge sway yaw':>27s}")
    for (name, lin), (_n, nl) in zip(res["table"]["linear"], res["table"]["nonlinear"]):
        tag = "train" if any(f"_{t}_m" in name for t in TRAIN) else "held-out"
        print(f"{name:34s} {tag:9s} {lin[0]:8.1f} {lin[1]:6.1f} {lin[2]:6.1f}   {nl[0]:11.1f} {nl[1]:6.1f} {nl[2]:6.1f}")
    prof = res["profile"]
    for name, val in zip(prof.param_names, theta):
        print(f"  {name:8s} {val:+.6e}")
    if args.write:
        write_params(prof, theta)
        print(f"wrote {PROFILE}")


if __name__ == "__main__":
    main()
