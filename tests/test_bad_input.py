"""Bad input to every option of every command: one clear line, a non-zero exit, no traceback, no
hang and nothing written (issue 15).

Each case runs in-process (``cli.app._run``) in an empty working directory, under a 30 s alarm.
A case passes when the exit code is non-zero, stderr holds no traceback and starts with
``error:`` (or click's usage error for a value of the wrong type), and no file appeared
anywhere in the working directory or the scratch area.
"""

from __future__ import annotations

import dataclasses
import json
import signal
from pathlib import Path

import numpy as np
import pytest

from cli.app import _run

NAN, INF, HUGE = "nan", "inf", "1e400"
FLOATS_BAD = [NAN, INF, "-inf", HUGE, "-1", "abc"]  # every float option gets these (plus its own zero/limits)
# empty, blank, a pasted escape, two lines, longer than an RTZ route holds (32)
VESSEL_NAMES_BAD = ["", "   ", "MT Example\x1b[0m", "MT\nExample", "MT Example of a Very Long Name Indeed"]


def _profile(tmp: Path, **changes) -> str:
    import tomllib

    from primitives.ship import PROFILE_DIR

    doc = tomllib.loads((PROFILE_DIR / "model-ship.toml").read_text())
    for k, v in changes.items():
        if v is None:
            doc.pop(k, None)
        else:
            doc[k] = v
    p = tmp / f"ship-{len(list(tmp.iterdir()))}.json"
    p.write_text(json.dumps(doc, allow_nan=True))
    return str(p)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Inputs of every kind: good ones (to isolate the bad option) and bad ones."""
    from diagnose.battery import scenario
    from diagnose.recording import write_csv
    from maps.export._testing import synthetic_plan

    tmp = tmp_path_factory.mktemp("inputs")
    f = {"tmp": tmp}
    f["dir"] = tmp / "a-directory"
    f["dir"].mkdir()
    (f["dir"] / "keep.txt").write_text("the user's file")
    f["missing"] = tmp / "no-such-file.json"
    f["binary"] = tmp / "binary.json"
    f["binary"].write_bytes(bytes(range(256)))
    f["latin1"] = tmp / "latin1.csv"
    f["latin1"].write_bytes("t,x,y,psi\n0,1,2,caf\xe9\n".encode("latin-1"))
    f["notjson"] = tmp / "notjson.json"
    f["notjson"].write_text("{this is not json")
    f["file"] = tmp / "a-file.txt"
    f["file"].write_text("x")
    f["plan"] = tmp / "plan.json"
    f["plan"].write_text(synthetic_plan("model-ship").to_json())
    run = scenario((), 17, n_prims=2).diagnose[0]
    f["rec"] = write_csv(run, tmp / "run.csv")
    f["rec_scaled"] = write_csv(
        dataclasses.replace(run, channels={k: v * 1e6 for k, v in run.channels.items()}), tmp / "scaled.csv"
    )
    huge = run.y.copy()
    huge[5, 0] = 1e308
    f["rec_huge"] = write_csv(dataclasses.replace(run, y=huge), tmp / "huge.csv")
    f["rec_coarse"] = write_csv(dataclasses.replace(run, t=run.t * 2, pos=run.pos * 2, meta={}), tmp / "coarse.csv")
    f["zeros"] = tmp / "zeros.csv"
    f["zeros"].write_text("t,x,y,psi,u,v,r,tau_x,tau_y,tau_n\n" + "\n".join(f"{i * 0.125},0,0,0,0,0,0,0,0,0" for i in range(80)))
    f["cfg"] = tmp / "sweep.toml"
    f["cfg"].write_text('[sweep]\nships = ["model-ship"]\ncriteria = ["D"]\n')
    for name, body in {
        "cfg_unknown": '[sweep]\nships = ["model-ship"]\nshipz = ["x"]\n',
        "cfg_slow": '[sweep]\nlibrary = "standard"\nspeeds = [0.001]\n',
        "cfg_nan": '[sweep]\nlibrary = "standard"\nspeeds = [nan]\n',
        "cfg_neg": '[sweep]\nlibrary = "standard"\nspeeds = [-1.0]\n',
        "cfg_strspeed": '[sweep]\nlibrary = "standard"\nspeeds = ["0_6"]\n',  # stop 61: read as 6 m/s
        "cfg_badtoml": "[sweep\nships = 1\n",
        "cfg_seed": "[sweep]\nseed = -3\n",
        "cfg_podded": '[sweep]\nships = ["naval-vessel"]\n',
        "cfg_huge": '[sweep]\nlibrary = "standard"\nspeeds = [' + ", ".join(str(0.5 + i / 100) for i in range(700)) + "]\n"
        'criteria = ["D", "A", "E"]\n',
    }.items():
        f[name] = tmp / f"{name}.toml"
        f[name].write_text(body)
    for name, change in {
        "ship_neg_length": {"length_m": -1.0},
        "ship_neg_beam": {"beam_m": -0.3},
        "ship_nan_draught": {"draught_m": float("nan")},
        "ship_zero_speed": {"cruise_speed_mps": 0.0},
        "ship_zero_ts": {"sample_time": 0.0},
        "ship_no_draught": {"draught_m": None},
        "ship_typo": {"draught": 0.1},
        "ship_str_length": {"length_m": "long"},
        "ship_tiny_ts": {"sample_time": 1e-9},
    }.items():
        f[name] = _profile(tmp, **change)
    from identify.rollmass.model import load_profile as roll_profile
    from identify.rollmass.recording import write_roll_csv
    from identify.rollmass.simulate import Noise, simulate_case

    roll = roll_profile(None)
    for role, rec in zip(
        ("nominal", "calibration", "loaded"), simulate_case(roll, "case1", Noise.from_profile(roll), 0, length_factor=0.2)
    ):
        f[f"roll_{role}"] = write_roll_csv(rec, tmp / f"roll-{role}.csv")
    f.update(_yaw_files(tmp))
    f["roll_bad_profile"] = tmp / "roll-bad.toml"
    f["roll_bad_profile"].write_text("this is = not [a roll profile\n")
    _detect_inputs(tmp, f)
    f.update(_steering_files(tmp))
    return f


def _steering_files(tmp: Path) -> dict[str, Path]:
    """A good steering record (first-order Nomoto response to a square-wave rudder, 2 s sampling) and the
    same with each defect the command refuses: a missing column, time not increasing, a rudder in degrees,
    a yaw rate in deg/s, a yaw rate without heading, a lone heading in degrees."""
    from tests.physics.nomoto_square import square_wave_record, write_record

    cols = square_wave_record()
    t, delta, r, psi = cols["t"], cols["delta"], cols["r"], cols["psi"]

    def write(name, c):
        return write_record(tmp / f"{name}.csv", c)

    t_back = t.copy()
    t_back[100] = t_back[99]
    return {
        "steer": write("steer", cols),
        "steer_nodelta": write("steer-nodelta", {k: v for k, v in cols.items() if k != "delta"}),
        "steer_noheading": write("steer-noheading", {k: v for k, v in cols.items() if k not in ("r", "psi")}),
        "steer_tback": write("steer-tback", {**cols, "t": t_back}),
        "steer_deg": write("steer-deg", {**cols, "delta": np.degrees(delta)}),
        "steer_rdeg": write("steer-rdeg", {**cols, "r": np.degrees(r)}),
        "steer_ronly": write("steer-ronly", {k: v for k, v in cols.items() if k != "psi"}),
        "steer_psideg_only": write("steer-psideg-only", {"t": t, "delta": delta, "psi": np.degrees(psi)}),
    }


def _yaw_files(tmp: Path) -> dict[str, Path]:
    """A short good yaw recording, and the same without roll, without pod moment, going astern."""
    from identify.yawid.experiment import YawData, harbour_exit, true_signals, turn_pulse
    from identify.yawid.recording import write_yaw_csv
    from primitives.ship import load_profile

    nv = load_profile("naval-vessel")
    good = true_signals(nv, turn_pulse(nv.sample_time, duration_s=120.0))
    astern = true_signals(nv, harbour_exit(nv.sample_time, duration_s=60.0))
    out = {"yaw": write_yaw_csv(good, tmp / "yaw.csv"), "yaw_astern": write_yaw_csv(astern, tmp / "yaw-astern.csv")}
    for name, drop in (("yaw_noroll", "phi"), ("yaw_nopod", "tau_r")):
        out[name] = write_yaw_csv(YawData(good.t, {k: v for k, v in good.signals.items() if k != drop}), tmp / f"{name}.csv")
    return out


def _detect_inputs(tmp: Path, f: dict) -> None:
    """Podded-ship recordings (good, without pods, without r, another sample time) and priors."""
    from diagnose.recording import write_csv
    from identify.detect.api import save_prior, simulated_recording
    from identify.detect.vessel import Vessel
    from identify.detect.yawmodel import NOMINAL, PARAMS, YawPrior

    rec = simulated_recording(Vessel(), 60, seed=1)
    f["det_rec"] = write_csv(rec, tmp / "podded.csv")
    f["det_dt2"] = write_csv(simulated_recording(Vessel(), 60, dt=0.2, seed=2), tmp / "podded-dt02.csv")
    lines = f["det_rec"].read_text().splitlines()
    header = lines[1].split(",")
    for name, drop in (("det_nopods", {"alpha1", "alpha2"}), ("det_nor", {"r"})):
        keep = [i for i, h in enumerate(header) if h not in drop]
        f[name] = tmp / f"{name}.csv"
        f[name].write_text("\n".join([lines[0]] + [",".join(row.split(",")[i] for i in keep) for row in lines[1:]]) + "\n")
    names = PARAMS["full"]
    prior = YawPrior("full", {k: NOMINAL[k] for k in names}, 0.0025, 1e-6 * np.eye(len(names)), np.zeros(2), 0.001, 10, 0.1)
    f["det_prior"] = save_prior(prior, tmp / "prior.json")
    f["det_prior_bad"] = tmp / "prior-bad.json"
    f["det_prior_bad"].write_text(json.dumps({"format": "shiptrial-yaw-prior/1", "kind": "full", "values": {}}))
    # a noise reader this version does not know (a newer shiptrial's, or a hand edit) may mean another noise model
    # under the same fields: refuse rather than draw it as a first-order low-pass
    pink = dataclasses.replace(prior, noise_tau={"r": 0.3}, noise_model="pink").to_dict()
    f["det_prior_pink"] = tmp / "prior-pink.json"
    f["det_prior_pink"].write_text(json.dumps(pink))


def _cases() -> list[tuple[str, list[str]]]:
    """(case id, argv) with {placeholders} filled from ``files``."""
    ship_bad = [
        "no-such-ship",
        "{missing}",
        "{dir}",
        "{binary}",
        "{notjson}",
        "{ship_neg_length}",
        "{ship_neg_beam}",
        "{ship_nan_draught}",
        "{ship_zero_speed}",
        "{ship_zero_ts}",
        "{ship_no_draught}",
        "{ship_typo}",
        "{ship_str_length}",
        "{ship_tiny_ts}",
        "{file}",
    ]
    out_dir_bad = ["{file}", "/proc/shiptrial-out", "{dir}"]
    cases: list[tuple[str, list[str]]] = []

    def add(cmd: list[str], option: str, values: list[str], base: list[str] | None = None, named: bool = False):
        for v in values:
            cases.append((f"{cmd[0]} {option} {v}", [*cmd, *(base or []), option, v]))
            if named:
                NAMED[cases[-1][0]] = option

    # primitives
    add(["primitives"], "--ship", ship_bad)
    add(["primitives"], "--plot", ["{tmp}/x.txt", "/proc/x.png", "{dir}"])
    # design (monte carlo off where the option is not about it: refusals must come before any work)
    d = ["design", "--monte-carlo", "0"]
    add(d, "--ship", ship_bad)
    add(d, "--criterion", ["X", "", "d-optimal"])
    add(d, "--mean-subtraction", ["sometimes", ""])
    add(d, "--trial-length", [*FLOATS_BAD, "0", "1e12"])
    add(["design"], "--monte-carlo", ["-1", "1000000000", "1.5", "abc"])
    add(["design"], "--mc-samples", ["0", "5", "-10", "100000000", "abc"])
    add(["design", "--monte-carlo", "1000000"], "--mc-samples", ["1000"])
    add(d, "--seed", ["-1", "abc"])
    add(d, "--out", out_dir_bad)
    add(d, "--psi-switch", [*FLOATS_BAD, "0", "100"])
    add(d, "--min-frac", [*FLOATS_BAD, "2"])
    add(d, "--max-frac", [*FLOATS_BAD, "2"])
    add(d, "--noisy-moments", ["-1", "1000000000", "abc"])
    cases.append(("design --min-frac > --max-frac", [*d, "--min-frac", "0.5", "--max-frac", "0.1"]))
    # Monte Carlo options: refused before the design step (here with the Monte Carlo off, so a late check would pass them)
    add(d, "--mc-protocol", ["restart", "", "Continuous"])
    add(d, "--mc-order", ["shuffled", "", "1"])
    add(d, "--mc-estimator", ["ml", "", "OE"])
    add(d, "--mc-settle", ["-1", "abc"])
    add(d, "--mc-min-block", ["1", "-5", "201", "abc"])
    # robust design's prior (issue 28): refused before the draws are simulated
    rb = [*d, "--criterion", "bayes-D"]
    add(rb, "--prior-spread", [*FLOATS_BAD, "0", "1.5"])
    add(rb, "--prior-file", ["{missing}", "{dir}", "{binary}", "{notjson}", "{plan}"])
    add([*rb, "--prior-spread", "0.3"], "--prior-draws", ["1", "0", "-5", "1000000", "abc"])
    add([*rb, "--prior-spread", "0.3"], "--prior-truths", ["0", "-1", "1000000", "abc"])
    add(d, "--prior-spread", ["0.3"])  # a prior without a robust criterion
    # plan
    p = ["plan", "--counts", "tau12=1"]  # a plan of the default ship (full-scale): only the bad option can fail it
    add(p, "--map", ["{missing}", "{dir}", "{binary}", "{notjson}", "{plan}"])
    add(p, "--ship", ship_bad)
    add(
        p,
        "--start",
        ["60.1,24.9,nan", "nan,24.9", "60.1,inf", "1e400,24.9", "abc", "60.1", "95,24.9,0", "60.1,24.9,1e9", "1,2,3,4"],
    )
    add(p, "--goal", ["nan,24.9", "60.1,-inf", "x,y", "60.1,200"])
    add(
        ["plan"],
        "--counts",
        ["tau1=1", "tau1=1000000", "tau1=-1", "tau1=abc", "=3", "tau1", ",", "tau1=50,tau2=50,tau3=50,tau4=50"],
    )
    add(p, "--resolution", [*FLOATS_BAD, "0", "1e9"])
    add(p, "--headings", ["5", "0", "-4", "1000000", "abc"])
    add(p, "--heuristic", ["greedy", ""])
    add(p, "--margin", [*FLOATS_BAD, "1e9"])
    add(p, "--size", ["0x0", "axb", "1000000000x1", "35", "-5x44", "1x1"])
    add(p, "--out", ["{file}", "/proc/shiptrial-out"])
    add(["plan"], "--start-time", ["yesterday", "2026-13-45T99:00Z", "9999-12-31T23:59Z", "0226-06-01T08:00Z"], named=True)
    add(p, "--seed", ["-1", "abc"])
    # plan's design options, run-in, memory limit and vessel name: with a base that would plan
    # (the design runs when neither --counts nor --scenario is given), so only the refusal fails fast
    add(["plan"], "--scenario", ["thesis-9.5", "", "9.4"], named=True)
    add(["plan"], "--criterion", ["X", "", "d-optimal"], named=True)
    add(["plan", "--criterion", "maximin-D"], "--prior-spread", [*FLOATS_BAD, "0", "1.5"])
    add(["plan", "--criterion", "maximin-D"], "--prior-file", ["{missing}", "{dir}", "{notjson}"])
    add(["plan", "--criterion", "maximin-D", "--prior-spread", "0.3"], "--prior-draws", ["1", "1000000", "abc"])
    add(["plan"], "--mean-subtraction", ["sometimes", ""], named=True)
    add(["plan"], "--trial-length", [*FLOATS_BAD, "0", "1e12"], named=True)
    add(["plan"], "--run-in", [*FLOATS_BAD, "1e9"], named=True)
    add(["plan"], "--max-memory", [*FLOATS_BAD, "0", "1e9"], named=True)
    add(["plan"], "--vessel-name", VESSEL_NAMES_BAD, named=True)
    # design options beside --counts or --scenario (which plan without a design): refused, not ignored
    add(["plan", "--counts", "tau12=1"], "--criterion", ["A"], named=True)
    add(["plan", "--counts", "tau12=1"], "--mean-subtraction", ["none"], named=True)
    add(["plan", "--scenario", "thesis-9.4"], "--trial-length", ["3600"], named=True)
    add(["plan", "--scenario", "thesis-9.4"], "--criterion", ["D"], named=True)
    # resuming a trial (issue 28): each option refused before any work, the others given
    at = "60.165,24.955,90"  # open water of the bundled map
    add(
        ["plan", "--recordings", "{rec}", "--from", at, "--time-left", "600"],
        "--resume",
        ["{missing}", "{dir}", "{notjson}", "{rec}"],
    )
    rr = ["plan", "--resume", "{plan}", "--from", at, "--time-left", "600"]
    add(rr, "--recordings", ["{missing}", "{dir}", "{binary}", "{notjson}", "{rec}"])
    add(
        ["plan", "--resume", "{plan}", "--recordings", "{rec}", "--time-left", "600"],
        "--from",
        ["abc", "60.1,24.9", "nan,24.9,0", "95,24.9,0", "1,2,3,4"],
        named=True,
    )
    add(["plan", "--resume", "{plan}", "--recordings", "{rec}", "--from", at], "--time-left", ["abc", "0", "-1", ""], named=True)
    add(["plan"], "--time-left", ["600"], named=True)  # without --resume
    # export
    for plan in ["{missing}", "{dir}", "{binary}", "{notjson}", "{rec}", "{cfg}"]:
        cases.append((f"export PLAN {plan}", ["export", plan, "--format", "gpx", "--out", "{tmp}/o.gpx"]))
    add(["export", "{plan}"], "--format", ["pdf", "", "kml"])
    add(["export", "{plan}", "--format", "gpx"], "--out", ["{tmp}/x.rtz", "{plan}", "/proc/x.gpx", "{tmp}/x.gpx.txt"])
    add(["export", "{plan}", "--format", "rtz"], "--out", ["{tmp}/x.gpx", "{tmp}/x.rtz.json"])
    add(["export", "{plan}", "--format", "all"], "--out", ["{file}", "/proc/shiptrial-out"])
    add(["export", "{plan}", "--format", "gpx", "--out", "{tmp}/o.gpx"], "--map", ["{missing}", "{dir}", "{binary}", "{notjson}"])
    add(
        ["export", "{plan}", "--format", "gpx", "--out", "{tmp}/o.gpx"],
        "--start",
        ["yesterday", "2026-99-01T00:00Z", "9999-12-31T23:59Z", "0226-06-01T08:00Z"],
        named=True,
    )
    add(["export", "{plan}", "--format", "rtz", "--out", "{tmp}/o.rtz"], "--vessel-name", VESSEL_NAMES_BAD, named=True)
    add(
        ["export", "{plan}", "--format", "all", "--out", "{tmp}/all-out"],
        "--vessel-name",
        ["MT Example\x01", "x" * 40],
        named=True,
    )
    # diagnose
    for rec in [
        "{missing}",
        "{dir}",
        "{latin1}",
        "{binary}",
        "{zeros}",
        "{cfg}",
        "{plan}",
        "{rec_scaled}",
        "{rec_huge}",
        "{rec_coarse}",
    ]:
        cases.append((f"diagnose RECORDING {rec}", ["diagnose", rec, "--ship", "model-ship"]))
    add(["diagnose", "{rec}"], "--ship", ship_bad)
    add(
        ["diagnose", "{rec}", "--ship", "model-ship"],
        "--params",
        ["{missing}", "{dir}", "{binary}", "{notjson}", "{ship_neg_length}"],
    )
    add(["diagnose", "{rec}", "--ship", "model-ship"], "--fit-on", ["{missing}", "{dir}", "{latin1}", "{zeros}"])
    add(["diagnose", "{rec}", "--ship", "model-ship"], "--validate", ["{missing}", "{dir}", "{latin1}", "{zeros}"])
    add(["diagnose", "{rec}", "--ship", "model-ship"], "--out", ["{file}", "/proc/shiptrial-out"])
    add(["diagnose", "{rec}", "--ship", "model-ship"], "--environment", ["lake", "Basin"], named=True)
    add(["diagnose", "{rec}", "--ship", "model-ship"], "--rudder-sign", ["port", "+1"], named=True)
    add(["diagnose", "{rec}", "--ship", "model-ship"], "--yaw-rate-sign", ["clockwise", "-1"], named=True)
    # sweep
    for cfg in [
        "{missing}",
        "{dir}",
        "{binary}",
        "{cfg_badtoml}",
        "{cfg_unknown}",
        "{cfg_slow}",
        "{cfg_nan}",
        "{cfg_neg}",
        "{cfg_strspeed}",
        "{cfg_seed}",
        "{cfg_huge}",
        "{plan}",
        "{cfg_podded}",
    ]:
        cases.append((f"sweep CONFIG {cfg}", ["sweep", cfg, "--out", "{tmp}/s.csv"]))
    add(["sweep", "{cfg}"], "--out", ["{tmp}/t.xlsx", "{tmp}/t", "/proc/s.csv", "{dir}"])
    add(["sweep", "{cfg}", "--out", "{tmp}/s.csv"], "--plot", ["{tmp}/p.txt", "/proc/p.png", "{dir}"])
    # mass (seed 003) and its example generator
    m = ["mass", "{roll_nominal}", "{roll_calibration}", "{roll_loaded}"]
    for i, rec in enumerate(["{missing}", "{dir}", "{latin1}", "{binary}", "{rec}", "{plan}"]):
        argv = [*m[1:]]
        argv[i % 3] = rec
        cases.append((f"mass RECORDING {rec}", ["mass", *argv, "--known-load", "0.2@-0.256"]))
    add(m, "--known-load", ["", "0.2", "abc@def", "nan@-0.2", "0.2@inf", "-0.2@-0.256", "0@-0.256", "1e400@0", "0.2@1e9"])
    add([*m, "--known-load", "0.2@-0.256"], "--profile", ["{missing}", "{dir}", "{binary}", "{roll_bad_profile}", "{plan}"])
    add([*m, "--known-load", "0.2@-0.256"], "--method", ["best", ""])
    add([*m, "--known-load", "0.2@-0.256"], "--z-f", [*FLOATS_BAD[:4], "1e9", "abc"])
    add(["mass-sim", "{tmp}/roll-out"], "--case", ["case9", ""])
    add(["mass-sim", "{tmp}/roll-out"], "--seed", ["-1", "abc"])
    add(["mass-sim", "{tmp}/roll-out"], "--profile", ["{missing}", "{dir}", "{roll_bad_profile}"])
    for out in ["{file}", "/proc/roll-out", "{dir}"]:
        cases.append((f"mass-sim OUT {out}", ["mass-sim", out]))
    # yawid (seed 000 chapter 4) and its example generator
    for rec in ["{missing}", "{dir}", "{latin1}", "{binary}", "{rec}", "{plan}", "{yaw_noroll}", "{yaw_nopod}", "{yaw_astern}"]:
        cases.append((f"yawid RECORDING {rec}", ["yawid", rec]))
    add(["yawid", "{yaw}"], "--model", ["best", ""])
    add(["yawid", "{yaw}"], "--ship", [*ship_bad, "model-ship"])
    add(["yawid", "{yaw}"], "--prefilter", [*FLOATS_BAD, "0", "6"])
    add(["yawid-sim", "{tmp}/y.csv"], "--seed", ["-1", "abc"])
    add(["yawid-sim", "{tmp}/y.csv"], "--noise", [*FLOATS_BAD, "1e9"])
    for out in ["{file}", "/proc/y.csv", "{dir}"]:
        cases.append((f"yawid-sim OUT {out}", ["yawid-sim", out]))
    # detect (seed 000 ch. 5): recordings without pod inputs or yaw rate, mixed sample times, bad priors
    det = ["detect", "{det_rec}"]
    for rec in ["{missing}", "{dir}", "{latin1}", "{binary}", "{det_nopods}", "{det_nor}", "{plan}"]:
        cases.append((f"detect RECORDING {rec}", ["detect", rec, "--prior", "{det_prior}"]))
    cases.append(("detect RECORDINGS of different sample times", ["detect", "{det_rec}", "{det_dt2}", "--prior", "{det_prior}"]))
    add(
        det,
        "--prior",
        ["{missing}", "{dir}", "{binary}", "{notjson}", "{det_prior_bad}", "{det_prior_pink}", "{det_rec}", "{plan}"],
    )
    add([*det, "--prior", "{det_prior}"], "--plot", ["{tmp}/x.txt", "/proc/x.png", "{dir}"])
    add([*det, "--prior", "{det_prior}"], "--false-alarm", [*FLOATS_BAD, "0", "0.9"], named=True)
    add([*det, "--prior", "{det_prior}"], "--min-change", [*FLOATS_BAD, "0", "5"], named=True)
    add([*det, "--prior", "{det_prior}"], "--seed", ["-1", "abc"], named=True)
    add([*det, "--prior", "{det_prior}"], "--n-rdot", ["abc", "nan", "inf", "", "0", "28.7e6", "-1e13"], named=True)
    add([*det, "--prior", "{det_prior}"], "--i-z", ["abc", "nan", "inf", "", "0", "-33.7e6", "1e14"], named=True)
    add([*det, "--prior", "{det_prior}"], "--profile", ship_bad)
    add([*det, "--prior", "{det_prior}"], "--n-rdot", ["-28.7e6"], named=True)  # without --i-z or --profile
    for rec in ["{missing}", "{dir}", "{binary}", "{det_nopods}", "{det_nor}"]:
        cases.append((f"detect-prior RECORDING {rec}", ["detect-prior", rec, "--out", "{tmp}/p.json"]))
    cases.append(
        ("detect-prior RECORDINGS of different sample times", ["detect-prior", "{det_rec}", "{det_dt2}", "--out", "{tmp}/p.json"])
    )
    add(["detect-prior", "{det_rec}"], "--out", ["{tmp}/p.txt", "{dir}", "/proc/p.json"])
    add(["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"], "--model", ["fancy", ""])
    add(
        ["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"],
        "--noise-model",
        ["pink", "", "LOWPASS", "Spectral", "lowpass"],
        named=True,
    )
    add(["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"], "--bootstrap", ["-1", "1001", "1.5", "abc"], named=True)
    add(["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"], "--seed", ["-1", "abc", "1.5"], named=True)
    add(["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"], "--n-rdot", ["abc", "nan", "0", "28.7e6"], named=True)
    add(["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"], "--i-z", ["abc", "inf", "0", "-33.7e6"], named=True)
    add(["detect-prior", "{det_rec}", "--out", "{tmp}/p.json"], "--profile", ship_bad)
    # steering (Källström 1977): records without rudder or heading, time not increasing, degrees for radians
    for rec in ["{missing}", "{dir}", "{binary}", "{latin1}", "{plan}", "{steer_nodelta}", "{steer_noheading}", "{steer_tback}"]:
        cases.append((f"steering RECORDING {rec}", ["steering", rec, "--ship", "kvlcc2"]))
    for rec in ["{steer_deg}", "{steer_rdeg}", "{steer_ronly}", "{steer_psideg_only}"]:
        cases.append((f"steering RECORDING {rec}", ["steering", rec, "--ship", "kvlcc2", "--out", "{tmp}/steer-out"]))
    add(["steering", "{steer}"], "--ship", [*ship_bad])
    add(["steering", "{steer}", "--ship", "kvlcc2"], "--model", ["fancy", "", "nomoto3"], named=True)
    add(["steering", "{steer}", "--ship", "kvlcc2"], "--estimator", ["pem", ""], named=True)
    add(["steering", "{steer}", "--ship", "kvlcc2"], "--out", out_dir_bad)
    add(["steering", "{steer}", "--ship", "kvlcc2"], "--split", ["abc", "-5", "300:100", "nan", "1e9", "5"], named=True)
    cases.append(("steering --split two recordings", ["steering", "{steer}", "{steer}", "--ship", "kvlcc2", "--split", "300"]))
    cases.append(("steering state-space without v", ["steering", "{steer}", "--ship", "kvlcc2", "--model", "state-space"]))
    add(["steering", "{steer}", "--ship", "kvlcc2"], "--log-x", ["nan", "400", "-1e9"], named=True)
    add(["steering", "{steer}", "--ship", "kvlcc2"], "--save-profile", ["{tmp}/ship.txt", "/proc/ship.toml", "{dir}"])
    cases.append(
        (
            "steering --save-profile into a non-rudder ship",
            ["steering", "{steer}", "--ship", "full-scale", "--save-profile", "{tmp}/s.toml"],
        )
    )
    return cases


NAMED: dict[str, str] = {}  # case id -> the option its message must name
CASES = _cases()


def _snapshot(*dirs: Path) -> set[str]:
    return {str(p) for d in dirs for p in d.rglob("*")}


@pytest.fixture
def alarm():
    def boom(*_):
        raise TimeoutError("a bad input hung for 30 s")

    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(30)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("case,argv", CASES, ids=[c for c, _ in CASES])
def test_bad_input_is_one_line_nonzero_and_writes_nothing(case, argv, files, tmp_path, monkeypatch, capsys, alarm):
    monkeypatch.chdir(tmp_path)
    args = [a.format(**files) for a in argv]
    before = _snapshot(files["tmp"], tmp_path)
    rc = _run(args)
    err = capsys.readouterr().err
    assert rc not in (0, None), f"{case}: exit 0 on invalid input"
    assert "Traceback" not in err
    first = err.strip().splitlines()[0] if err.strip() else ""
    assert first.startswith("error:") or "Usage:" in err or "Invalid value" in err, f"{case}: unclear message {err!r}"
    if first.startswith("error:"):
        assert len(err.strip().splitlines()) == 1 or case.startswith("sweep"), f"{case}: more than one line {err!r}"
    if case in NAMED:
        assert f"'{NAMED[case]}'" in err if "Usage:" in err else first.startswith(f"error: {NAMED[case]}"), (
            f"{case}: the message does not name {NAMED[case]}: {err!r}"
        )
    assert _snapshot(files["tmp"], tmp_path) == before, f"{case}: wrote files on invalid input"


@pytest.mark.parametrize("speed", ['"0_6"', '"1.0"', '"1e1"'])
def test_a_sweep_speed_given_as_a_string_is_refused(tmp_path, speed):
    """Stop 61: float() read the string "0_6" as 6 m/s (a design at ten times the speed meant); every string is
    refused in one line, as the profile loader refuses a string length."""
    from expdesign.sweep import SweepError, load_sweep

    cfg = tmp_path / "s.toml"
    cfg.write_text(f'[sweep]\nships = ["model-ship"]\nlibrary = "standard"\nspeeds = [0.6, {speed}]\n')
    with pytest.raises(SweepError, match=r"s.toml: field 'sweep.speeds' holds the string .*: write each speed as a TOML number"):
        load_sweep(cfg)


def test_the_suite_covers_every_option_of_every_command():
    """Each command's options (from its typer signature) appear in at least one bad-input case, and
    each command with arguments has a case aimed at an argument (its id names it in capitals).

    ``plan-trial`` (``cli.app.plan_main``) is ``shiptrial plan`` on the same typer app, so the
    ``plan`` command's parameters are its parameters. Options are told by ``param_type_name``:
    typer builds its own ``TyperOption`` on its vendored click, which is not a ``click.Option``.
    """
    import typer.main

    from cli.app import app

    group = typer.main.get_command(app)
    covered = {(argv[0], a) for _, argv in CASES for a in argv if a.startswith("--")}
    covered |= {(case.split()[0], "ARG") for case, _ in CASES if case.split()[1].isupper()}
    missing = []
    for name, cmd in group.commands.items():
        for prm in cmd.params:
            if prm.param_type_name == "option":
                flag = max(prm.opts, key=len)
                if prm.is_flag or flag in ("--scheduler", "--help"):
                    continue  # flags take no value; an unreachable --scheduler is the Monte Carlo work's
                if (name, flag) not in covered:
                    missing.append(f"{name} {flag}")
            elif prm.param_type_name != "argument":
                missing.append(f"{name} {prm.name}: a parameter of unknown kind {prm.param_type_name!r}")
            elif (name, "ARG") not in covered:
                missing.append(f"{name} {prm.name}")
    assert not missing, f"options without a bad-input case: {missing}"


def test_plan_trial_is_the_plan_command(monkeypatch, capsys, tmp_path):
    """``plan-trial`` (the second entry point) is ``shiptrial plan``: the same options, so the plan
    cases above cover it, and the same one-line refusal with nothing written."""
    import sys

    from cli.app import plan_main

    monkeypatch.chdir(tmp_path)
    assert _run(["plan", "--help"]) == 0
    plan_help = capsys.readouterr().out
    monkeypatch.setattr(sys, "argv", ["plan-trial", "--help"])
    with pytest.raises(SystemExit) as exc:
        plan_main()
    assert exc.value.code == 0 and capsys.readouterr().out == plan_help
    monkeypatch.setattr(sys, "argv", ["plan-trial", "--run-in", "nan"])
    with pytest.raises(SystemExit) as exc:
        plan_main()
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.startswith("error: --run-in") and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.iterdir())


# Stop 60's sweep (docs/bad-input-sweep.md): inputs the option-by-option cases above did not reach


def test_export_never_writes_outside_out_whatever_the_plans_ship_name(tmp_path, monkeypatch, capsys):
    """A plan's ``ship`` names the exported files (``<ship>-trial.gpx``): a plan.json whose ship is a path (a hand
    edit, or a plan of a profile named so) wrote every file beside that path, outside --out (stop 60: exit 0, the
    eight files next to the profile). Refused in one line; nothing written anywhere."""
    from maps.export._testing import synthetic_plan

    monkeypatch.chdir(tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    doc = json.loads(synthetic_plan("model-ship").to_json())
    for ship in (str(elsewhere / "ship.toml"), "../up", "..", "a\\b"):
        doc["ship"] = ship
        (tmp_path / "plan.json").write_text(json.dumps(doc))
        before = _snapshot(tmp_path)
        assert _run(["export", "plan.json", "--format", "all", "--out", "exp"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: plan.json: field 'ship'"), err
        assert _snapshot(tmp_path) == before


def test_a_profile_named_as_a_path_is_refused(tmp_path):
    """The profile's name names the plan's files: refused on loading, as profile new refuses it."""
    import tomllib

    from primitives.ship import PROFILE_DIR, ProfileError, load_profile

    doc = tomllib.loads((PROFILE_DIR / "model-ship.toml").read_text())
    for name in ("../evil", "a/b", " ", "."):
        doc["name"] = name
        path = tmp_path / "ship.json"
        path.write_text(json.dumps(doc))
        with pytest.raises(ProfileError, match="field 'name'.*plain name"):
            load_profile(path)


def test_export_map_by_bundled_name_and_only_the_plans_own(tmp_path, monkeypatch, capsys):
    """``export --map`` takes a bundled map's name as --help says (stop 60: 'no such map file' for helsinki), and
    refuses a map the plan's track is not on (a Helsinki plan was drawn on the open-sea chart, exit 0)."""
    from maps.export._testing import synthetic_plan
    from maps.geo import bundled_map_path

    monkeypatch.chdir(tmp_path)
    (tmp_path / "plan.json").write_text(synthetic_plan("model-ship").to_json())
    assert _run(["export", "plan.json", "--format", "gpx", "--out", "a.gpx", "--map", "helsinki"]) == 0
    assert (tmp_path / "a.gpx").is_file()
    capsys.readouterr()
    for other in ("open-sea", str(bundled_map_path("open-sea"))):
        assert _run(["export", "plan.json", "--format", "gpx", "--out", "b.gpx", "--map", other]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "the plan's track" in err[0] and "is nowhere on this map" in err[0], err
        assert not (tmp_path / "b.gpx").exists()


def test_export_map_whose_features_cover_part_of_the_track_is_the_plans_own(tmp_path, monkeypatch, capsys):
    """A map without a trial area: its extent is the box of its features, and the plan made on it leaves that box
    (review of stop 60: a plan made on a one-island map was refused with that very map, 'not on this map'). A
    track that reaches the map is exported on it."""
    from maps.export._testing import synthetic_plan

    monkeypatch.chdir(tmp_path)
    plan = synthetic_plan("model-ship")
    (tmp_path / "plan.json").write_text(plan.to_json())
    lon0, lat0 = (float(x) for x in plan.lonlat[0])
    ring = [
        [lon0 - 0.002, lat0 - 0.001],
        [lon0 + 0.0001, lat0 - 0.001],
        [lon0 + 0.0001, lat0 - 0.0005],
        [lon0 - 0.002, lat0 - 0.001],
    ]
    start = [lon0, lat0]  # the features' box reaches the track's first point only
    island = {
        "type": "FeatureCollection",
        "features": [
            {"type": "Feature", "properties": {"kind": "land"}, "geometry": {"type": "Polygon", "coordinates": [ring]}},
            {"type": "Feature", "properties": {"kind": "start"}, "geometry": {"type": "Point", "coordinates": start}},
        ],
    }
    (tmp_path / "island.geojson").write_text(json.dumps(island))
    assert not (plan.lonlat[:, 0].max() <= lon0 + 0.0001 and plan.lonlat[:, 1].max() <= lat0)  # the track leaves the box
    assert _run(["export", "plan.json", "--format", "gpx", "--out", "a.gpx", "--map", "island.geojson"]) == 0, (
        capsys.readouterr().err
    )
    assert (tmp_path / "a.gpx").is_file()


@pytest.mark.parametrize(
    "edit,field",
    [
        ({"feasible": False}, "'feasible'"),  # the synthetic plan is feasible: its card would say NOT FEASIBLE
        ({"ship": "kvlcc2"}, "'ship'"),
        ({"map_name": "open-sea"}, "'map_name'"),
        ({"extra": 1}, "'extra'"),
    ],
    ids=["feasible", "ship", "map_name", "unknown-key"],
)
def test_export_refuses_a_plan_edited_after_planning_and_reads_an_old_one_with_a_note(tmp_path, monkeypatch, capsys, edit, field):
    """Stop 60's sweep exported plans whose labels were edited by hand (a 'feasible' flipped puts an infeasible plan
    on the crew's card as feasible; another 'ship' gives export another ship's draught). plan.json now carries a
    digest of each field: such an edit is refused in one line naming the field, nothing written. A plan without the
    digest (written before stop 60) is exported with a note."""
    from maps.export._testing import synthetic_plan

    monkeypatch.chdir(tmp_path)
    doc = json.loads(synthetic_plan("model-ship").to_json())
    (tmp_path / "plan.json").write_text(json.dumps(doc))
    assert _run(["export", "plan.json", "--format", "gpx", "--out", "a.gpx"]) == 0
    assert "note:" not in capsys.readouterr().out
    (tmp_path / "plan.json").write_text(json.dumps(doc | edit))
    before = _snapshot(tmp_path)
    assert _run(["export", "plan.json", "--format", "gpx", "--out", "b.gpx"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: plan.json: field(s) {field} changed after plan-trial"), err
    assert _snapshot(tmp_path) == before
    old = {k: v for k, v in doc.items() if k != "digest"} | edit
    (tmp_path / "plan.json").write_text(json.dumps(old))
    assert _run(["export", "plan.json", "--format", "gpx", "--out", "c.gpx"]) == 0
    assert "note: plan.json: the plan carries no digest" in capsys.readouterr().out
    assert (tmp_path / "c.gpx").is_file()


# Stop 61's sweep (docs/bad-input-sweep.md, "Stop 61")


def test_export_never_replaces_a_file_it_did_not_write_without_force(tmp_path, monkeypatch, capsys):
    """``export --format all --out DIR`` replaced a hand-written ``<ship>-trial.gpx`` in DIR without a word (stop 61,
    exit 0). Now refused in one line naming the file and --force, nothing touched; with --force replaced, and the
    user's other files (notes.txt) never touched either way; a re-export replaces its own files, but not one
    changed since; a single format's --out FILE obeys the same rule."""
    from maps.export._testing import synthetic_plan

    monkeypatch.chdir(tmp_path)
    (tmp_path / "plan.json").write_text(synthetic_plan("model-ship").to_json())
    exp = tmp_path / "exp"
    exp.mkdir()
    (exp / "notes.txt").write_text("my notes")
    (exp / "model-ship-trial.gpx").write_text("<gpx>my own route</gpx>")
    before = _snapshot(tmp_path)
    assert _run(["export", "plan.json", "--format", "all", "--out", "exp"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: exp/model-ship-trial.gpx: exists and was not written by an export"), err
    assert "--force" in err[0] and _snapshot(tmp_path) == before
    assert (exp / "model-ship-trial.gpx").read_text() == "<gpx>my own route</gpx>"

    assert _run(["export", "plan.json", "--format", "all", "--out", "exp", "--force"]) == 0
    assert (exp / "notes.txt").read_text() == "my notes" and "topografix" in (exp / "model-ship-trial.gpx").read_text()
    assert _run(["export", "plan.json", "--format", "all", "--out", "exp"]) == 0  # its own files: replaced
    capsys.readouterr()
    (exp / "model-ship-trial.csv").write_text("edited by hand")
    assert _run(["export", "plan.json", "--format", "csv", "--out", "exp"]) == 2
    assert "was changed after an export wrote it" in capsys.readouterr().err
    assert (exp / "model-ship-trial.csv").read_text() == "edited by hand" and (exp / "notes.txt").read_text() == "my notes"
    (tmp_path / "mine.gpx").write_text("<gpx>mine</gpx>")
    assert _run(["export", "plan.json", "--format", "gpx", "--out", "mine.gpx"]) == 2
    assert (tmp_path / "mine.gpx").read_text() == "<gpx>mine</gpx>"


# Stop 62: output files replaced without a word (docs/bad-input-sweep.md, "Stop 62")


def test_sweep_replaces_only_its_own_table_and_plot_without_force(tmp_path, monkeypatch, capsys):
    """``sweep --out results.csv`` replaced the user's results.csv and the results.png beside it (the default
    --plot) without a word (stop 62, exit 0). Now refused before any work, one line naming the file and --force,
    nothing touched; with --force replaced; a sweep's own table and plot (its header row, the plot's Creator) are
    replaced without it."""
    monkeypatch.chdir(tmp_path)
    Path("small.toml").write_text(
        '[sweep]\nships = ["model-ship"]\nlibrary = "standard"\nspeeds = [0.6]\ncriteria = ["D"]\n'
        'mean_subtraction = ["batchwise"]\nseed = 1\n'
    )
    Path("results.csv").write_text("name,score\nalice,3\n")
    Path("results.png").write_bytes(b"my own figure")
    before = {p: p.read_bytes() for p in tmp_path.iterdir()}
    assert _run(["sweep", "small.toml", "--out", "results.csv"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "error: --out results.csv: exists and was not written by shiptrial sweep; move it, choose another --out, "
        "or pass --force to replace it"
    ]
    Path("results.csv").unlink()  # the plot beside the table is the user's too
    assert _run(["sweep", "small.toml", "--out", "results.csv"]) == 2
    assert "error: --plot results.png: exists and was not written by shiptrial sweep" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == {k: v for k, v in before.items() if k.name != "results.csv"}
    assert _run(["sweep", "small.toml", "--out", "results.csv", "--force"]) == 0
    assert Path("results.png").read_bytes()[:4] == b"\x89PNG"
    for plot in ("results.png", "fig.svg", "fig.pdf"):  # its own files, each format of the plot
        assert _run(["sweep", "small.toml", "--out", "results.csv", "--plot", plot]) == 0, capsys.readouterr().err
        assert _run(["sweep", "small.toml", "--out", "results.csv", "--plot", plot]) == 0, capsys.readouterr().err


def test_sweep_keep_partial_refuses_a_users_partial_table_before_the_sweep(tmp_path, monkeypatch, capsys):
    """With ``--keep-partial`` a Ctrl-C writes NAME.partial.csv: a user's file of that name is refused before the
    sweep, in one line naming it and the fix (another --out names another partial table), untouched; nothing was
    checked for it before stop 62 (the sweep ran; an interrupt replaced the file)."""
    monkeypatch.chdir(tmp_path)
    Path("small.toml").write_text(
        '[sweep]\nships = ["model-ship"]\nlibrary = "standard"\nspeeds = [0.6]\ncriteria = ["D"]\nseed = 1\n'
    )
    Path("results.partial.csv").write_text("name,score\nalice,3\n")
    assert _run(["sweep", "small.toml", "--out", "results.csv", "--keep-partial"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "error: --out results.partial.csv: exists and was not written by shiptrial sweep; move it, choose another "
        "--out, or pass --force to replace it"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.partial.csv", "small.toml"]
    assert Path("results.partial.csv").read_text() == "name,score\nalice,3\n"


def test_sweep_knows_its_plot_by_the_creator_field_not_by_the_words_anywhere(tmp_path, monkeypatch, capsys):
    """A user's workflow diagram (SVG text) that says "shiptrial sweep" is not a sweep's plot: the mark is the Creator
    field as matplotlib writes it (the review found any file holding the words replaced without --force)."""
    monkeypatch.chdir(tmp_path)
    Path("small.toml").write_text(
        '[sweep]\nships = ["model-ship"]\nlibrary = "standard"\nspeeds = [0.6]\ncriteria = ["D"]\nseed = 1\n'
    )
    mine = '<svg xmlns="http://www.w3.org/2000/svg"><text>plan-trial, then shiptrial sweep</text></svg>\n'
    Path("workflow.svg").write_text(mine)
    assert _run(["sweep", "small.toml", "--out", "results.csv", "--plot", "workflow.svg"]) == 2
    assert "error: --plot workflow.svg: exists and was not written by shiptrial sweep" in capsys.readouterr().err
    assert Path("workflow.svg").read_text() == mine and not Path("results.csv").exists()


def test_yawid_sim_never_replaces_a_recording_it_did_not_write_without_force(tmp_path, monkeypatch, capsys):
    """``yawid-sim trial_run.csv`` over a real recording destroyed it (stop 62, exit 0). Now refused, one line,
    untouched; its own simulation ('# source: shiptrial yawid-sim') is replaced; --force replaces any."""
    monkeypatch.chdir(tmp_path)
    real = "# ship: naval-vessel\n# source: sea trial, bridge logger\nt,r,u,v,delta\n0,0.001,7.9,0.01,0\n"
    Path("trial_run.csv").write_text(real)
    assert _run(["yawid-sim", "trial_run.csv"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "error: OUT trial_run.csv: exists and was not written by shiptrial yawid-sim; move it, choose another OUT, "
        "or pass --force to replace it"
    ]
    assert Path("trial_run.csv").read_text() == real
    assert _run(["yawid-sim", "sim.csv"]) == 0 and _run(["yawid-sim", "sim.csv", "--seed", "2"]) == 0
    assert "# seed: 2" in Path("sim.csv").read_text()
    assert _run(["yawid-sim", "trial_run.csv", "--force"]) == 0 and "yawid-sim" in Path("trial_run.csv").read_text()
