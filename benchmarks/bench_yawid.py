"""Seed 000 chapter 4: yaw-dynamics identification Monte Carlo, ours beside the thesis's.

The multipurpose naval vessel (primitives/profiles/naval-vessel.toml) in the shared 4-DOF kernel,
10 min at 10 Hz of our forward-only manoeuvring (identify.yawid.experiment.identification_run:
pod-angle pulses up to 20 deg, propeller steps 55-80 rev/s, u >= 0 throughout so the lumped A u r
of (2.17) holds), Table 4.1 white noise on r, v_dot, u, v, phi and the measured pod yaw moment,
output-error fits of the full (2.17) and simplified (2.18) models from the true values. Seed 000
gives its Monte Carlo results only as figures (Fig. 4.3-4.4, no numbers in the text): its column
here is the qualitative finding it states.

    python benchmarks/bench_yawid.py --runs 50                 # Table 4.1 noise
    python benchmarks/bench_yawid.py --runs 50 --noise 0.5     # half the noise
    python benchmarks/bench_yawid.py --runs 50 --json out.json # with every run's estimates

Also printed: section 2.4.2's identifiability on the noise-free run (singular values), and the
thesis's harbour exit with the pods at 90 deg, which goes astern and breaks A u r.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from identify.yawid.estimate import fit_yaw  # noqa: E402
from identify.yawid.experiment import Noise, harbour_exit, true_signals  # noqa: E402
from identify.yawid.identifiability import yaw_identifiability  # noqa: E402
from identify.yawid.model import FULL, LABELS, forward_only, true_parameters  # noqa: E402
from identify.yawid.montecarlo import clean_recording, run_monte_carlo  # noqa: E402
from primitives.io import atomic_write_text  # noqa: E402
from primitives.ship import load_profile  # noqa: E402


def _identifiability(profile) -> None:
    clean = clean_recording(profile)
    print("Section 2.4.2 identifiability, noise-free 10 min run (normalised singular values of the yaw-row regressors):")
    for par in ("physical", "lumped"):
        ident = yaw_identifiability(clean, par)
        print(
            f"  {par:9s} {len(ident.names)} parameters, smallest singular values "
            + ", ".join(f"{x:.2e}" for x in ident.singular_values[-3:])
            + f"; zero: {ident.rank_deficiency}"
        )
    harb = true_signals(profile, harbour_exit(profile.sample_time))
    frac = forward_only(harb.signals["u"], tol=0.0)
    truth = true_parameters(profile)
    fit = fit_yaw(harb, FULL, truth)
    print(
        f"  harbour exit (pods 90 deg, n = 80 on 10-50 s): u min {harb.signals['u'].min():+.2f} m/s, astern in "
        f"{100 * frac:.0f} % of samples; the full model fitted to it (noise-free) reaches {fit.fit_percent[0]:.1f} % fit "
        f"with A = {fit.theta[0, 2]:.3g} (true ahead {truth['A']:.3g}; astern the data lump -N_|u|r - m x_g = "
        f"{-(truth['A'] + 2 * profile.rigid_body.mass * profile.rigid_body.x_g):.3g})"
    )


def _table(mc) -> list[str]:
    f = mc.fits
    lines = [
        f"{mc.model} model: {int(f.ok.sum())}/{len(f.ok)} runs converged ({int((~f.finite).sum())} non-finite), "
        f"fit to the noisy r {np.median(f.fit_percent[f.ok]):.1f} % median (run range {f.fit_percent[f.ok].min():.1f}"
        f"..{f.fit_percent[f.ok].max():.1f} %), residual RMS {1e3 * np.median(f.rms[f.ok]):.2f} mrad/s",
        f"  {'param':10s} {'true':>11s} {'mean':>11s} {'std':>10s} {'bias %':>8s} {'std %':>7s} {'no-noise %':>10s}  thesis (Fig. 4.3/4.4)",
    ]
    for r in mc.rows():
        lines.append(
            f"  {LABELS[r['param']]:10s} {r['true']:11.4g} {r['mean']:11.4g} {r['std']:10.3g} {100 * r['rel_bias']:8.1f} "
            f"{100 * r['rel_std']:7.1f} {100 * r['noise_free_rel']:10.1f}  {r['thesis']}"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50, help="noise realisations (thesis: 500)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noise", type=float, default=1.0, help="scale of Table 4.1's noise")
    ap.add_argument(
        "--prefilter",
        type=float,
        default=None,
        metavar="HZ",
        help="ours: zero-phase low-pass of the measured inputs at HZ before the fit (default: none, the thesis's method)",
    )
    ap.add_argument("--json", type=Path, default=None, help="write every run's estimates here")
    args = ap.parse_args(argv)
    if args.runs < 2 or args.noise < 0 or (args.prefilter is not None and not 0 < args.prefilter < 5):
        print("error: --runs must be >= 2, --noise >= 0 and --prefilter between 0 and 5 Hz (Nyquist)", file=sys.stderr)
        return 2
    profile = load_profile("naval-vessel")
    _identifiability(profile)
    noise = Noise().scaled(args.noise)
    t0, c0 = time.perf_counter(), time.process_time()
    res = run_monte_carlo(profile, runs=args.runs, seed=args.seed, noise=noise, prefilter_hz=args.prefilter)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(
        f"\nMonte Carlo: {args.runs} runs, seed {args.seed}, noise {args.noise:g} x Table 4.1 "
        f"(r {noise.r:g} rad/s, v_dot {noise.v_dot:g} m/s2, u, v {noise.u:g} m/s, phi {noise.phi:g} rad, "
        f"tau_r {noise.tau_r:g} N m; white, no anti-alias filter); inputs "
        + (f"low-passed at {args.prefilter:g} Hz (ours)" if args.prefilter else "used as measured (thesis)")
        + "; thesis: 500 runs"
    )
    for mc in res.values():
        print("\n".join(_table(mc)))
    print(f"time: {wall:.1f} s wall, {cpu:.1f} s CPU (both models, {args.runs} runs)")
    if args.json:
        doc = {
            "runs": args.runs,
            "seed": args.seed,
            "noise_scale": args.noise,
            "models": {
                k: {
                    "params": list(mc.fits.model.params),
                    "truth": mc.truth,
                    "rows": mc.rows(),
                    "per_run": {
                        "theta": mc.fits.theta.tolist(),
                        "ok": mc.fits.ok.tolist(),
                        "fit_percent": mc.fits.fit_percent.tolist(),
                    },
                }
                for k, mc in res.items()
            },
        }
        atomic_write_text(args.json, json.dumps(doc, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
