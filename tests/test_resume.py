"""Re-design mid-trial (issue 28): ``plan-trial --resume`` end to end on a small plan, its bad
input refused in one line with nothing written, and the library's bookkeeping of the information
already sailed (:mod:`expdesign.adaptive`, :mod:`maps.resume`).

The recordings are simulated on the profile's own model at parameters 20 % off its values
(:func:`maps.resume_example.example_recordings`): the tests check the plumbing and the bookkeeping,
not the estimator's accuracy on a real ship."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cli.app import _run
from diagnose.recording import write_csv
from expdesign import adaptive as ad
from maps.plan import Plan, content_digest
from maps.resume import simulated_recordings
from maps.resume_example import example_recordings
from maps.trialdesign import first_design, ship_library
from primitives.ship import load_profile


@pytest.fixture(scope="module")
def sailed(tmp_path_factory):
    """A 15-minute full-scale plan on the bundled map, the recordings of its first two
    manoeuvres (:func:`maps.resume_example.example_recordings`, as the README's resume example
    makes them) and the ship's position after them (--from)."""
    d = tmp_path_factory.mktemp("resume")
    assert _run(["plan", "--trial-length", "15min", "--no-export", "--json", "--out", str(d / "plan")]) == 0
    plan = Plan.load(d / "plan" / "plan.json")
    steps = [s for s in plan.steps if s.segment == "informative"][:2]
    pos = example_recordings(d / "plan" / "plan.json", d / "rec", 2)  # the README example's recordings
    return {"dir": d, "plan": plan, "steps": steps, "from": pos}


def _resume(s, out, *extra, recordings=None, start=None, left="10min"):
    args = ["plan", "--resume", str(s["dir"] / "plan" / "plan.json"), "--from", start or s["from"], "--time-left", left]
    for r in recordings or sorted((s["dir"] / "rec").glob("*.csv")):
        args += ["--recordings", str(r)]
    return _run([*args, "--out", str(out), *extra])


def test_resume_end_to_end_writes_the_rest_with_the_sailed_part(sailed, tmp_path, capsys):
    out = tmp_path / "rest"
    assert _resume(sailed, out, "--no-export", "--json") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["feasible"] and sum(summary["counts"].values()) > 0
    doc = json.loads((out / "plan.json").read_text())
    r = doc["stats"]["resume"]
    recorded = [s for s in r["sailed"]["steps"] if "recording" in s]
    assert [s["step"] for s in recorded] == [s.index + 1 for s in sailed["steps"]]
    assert r["sailed"]["steps"][-1]["step"] == sailed["steps"][-1].index + 1 and len(r["sailed"]["lonlat"]) > 10
    # the sailed information went into the design: its samples, the re-identified parameters
    by = {p.name: p for p in ship_library(load_profile("full-scale"))}
    assert doc["design"]["sailed_samples"] == sum(by[s.primitive].n_samples for s in sailed["steps"])
    assert set(doc["design"]["reidentified"]["parameters"]) == set(load_profile("full-scale").predictor_param_names)
    assert doc["design"]["planned_s"] <= 600.0
    assert any("re-designed after 2 sailed manoeuvre(s)" in n for n in doc["stats"]["notes"])
    # the plan starts where the ship is
    lat, lon, _ = (float(v) for v in sailed["from"].split(","))
    assert abs(doc["samples"]["lat"][0] - lat) < 1e-3 and abs(doc["samples"]["lon"][0] - lon) < 1e-3
    traj = json.loads((out / "trajectory.geojson").read_text())
    assert [f for f in traj["features"] if f["properties"]["kind"] == "sailed"]
    Plan.load(out / "plan.json")  # the resumed plan reads back (the exports read it)
    # the schedule of the rest starts when the last recording ended, on the first plan's clock
    from datetime import datetime, timedelta

    end = max(float(ln.split(",")[0]) for f in (sailed["dir"] / "rec").glob("*.csv") for ln in f.read_text().splitlines()[5:])
    first = datetime.fromisoformat(sailed["plan"].stats["start_utc"].replace("Z", "+00:00"))
    assert doc["stats"]["start_utc"] == (first + timedelta(seconds=end)).strftime("%Y-%m-%dT%H:%M:%SZ")
    # resumed again after the rest's first manoeuvre: the first part's recordings still count (7.58)
    rest = Plan.load(out / "plan.json")
    prof = load_profile(rest.ship)
    step = next(s for s in rest.steps if s.segment == "informative")
    for rec in simulated_recordings(rest, prof, [step], prof.params(), (0.02, 0.02, 0.0005), 1):
        write_csv(rec, tmp_path / "rec2" / rec.source)
    k = int(np.nonzero(rest.step_of_sample == step.index)[0][-1])
    pos = f"{rest.lonlat[k, 1]:.6f},{rest.lonlat[k, 0]:.6f},{np.degrees(rest.track[k, 2]) % 360:.1f}"
    args = ["plan", "--resume", str(out / "plan.json"), "--recordings", str(tmp_path / "rec2"), "--from", pos]
    assert _run([*args, "--time-left", "5min", "--no-export", "--out", str(tmp_path / "rest2")]) == 0
    again = json.loads((tmp_path / "rest2" / "plan.json").read_text())
    assert again["design"]["sailed_samples"] == doc["design"]["sailed_samples"] + by[step.primitive].n_samples
    assert again["stats"]["resume"]["earlier_runs"] == 2 and len(again["stats"]["resume"]["runs"]) == 3
    assert any("re-designed after 3 sailed manoeuvre(s)" in n for n in again["stats"]["notes"])
    assert len(again["stats"]["resume"]["sailed"]["lonlat"]) > len(r["sailed"]["lonlat"])


def _edit(src, dst, header=None, shift=0.0, drop=None):
    """A copy of recording ``src`` with one header line replaced or dropped, or its time column shifted."""
    lines = [ln for ln in src.read_text().splitlines() if not (drop and ln.startswith(drop))]
    if header:
        key = header.split(":")[0]
        lines = [header if ln.startswith(key + ":") else ln for ln in lines]
    if shift:
        i = next(i for i, ln in enumerate(lines) if ln.startswith("t,"))
        lines[i + 1 :] = [",".join([f"{float(ln.split(',')[0]) + shift:g}", *ln.split(",")[1:]]) for ln in lines[i + 1 :]]
    dst.write_text("\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize(
    "ship, match",
    [("naval-vessel", "supports 3-DOF ships only"), ("coaster", "give its profile file with --ship")],
)
def test_resume_of_a_plan_for_a_ship_it_cannot_load_or_plan(sailed, tmp_path, capsys, ship, match):
    """A 4-DOF profile is refused as plan-trial refuses it; a ship from particulars (not built in)
    is asked for its profile file."""
    doc = json.loads((sailed["dir"] / "plan" / "plan.json").read_text())
    (tmp_path / "p").mkdir()
    other = {**doc, "ship": ship}
    other["digest"] = content_digest(other)  # as plan-trial would write it for that ship (an edit by hand is refused)
    (tmp_path / "p" / "plan.json").write_text(json.dumps(other))
    args = ["plan", "--resume", str(tmp_path / "p" / "plan.json"), "--from", sailed["from"], "--time-left", "10min"]
    capsys.readouterr()
    assert _run([*args, "--recordings", str(sailed["dir"] / "rec"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and match in err[0], err
    assert not (tmp_path / "o").exists()


def test_resume_refuses_a_plan_edited_by_hand_and_notes_one_without_a_digest(sailed, tmp_path, capsys):
    """plan-trial --resume reads the plan as export does: a field edited after plan-trial wrote it is refused in one
    line naming it, nothing written; a plan without a digest (written before stop 60) is read with a note on stderr
    (here its ship is then refused, so the check stays cheap)."""
    doc = json.loads((sailed["dir"] / "plan" / "plan.json").read_text())
    (tmp_path / "p").mkdir()
    args = ["plan", "--resume", str(tmp_path / "p" / "plan.json"), "--from", sailed["from"], "--time-left", "10min"]
    args += ["--recordings", str(sailed["dir"] / "rec"), "--out", str(tmp_path / "o")]
    (tmp_path / "p" / "plan.json").write_text(json.dumps({**doc, "margin_m": doc["margin_m"] + 5}))
    capsys.readouterr()
    assert _run(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "field(s) 'margin_m' changed after plan-trial" in err[0], err
    old = {k: v for k, v in doc.items() if k != "digest"} | {"ship": "coaster"}
    (tmp_path / "p" / "plan.json").write_text(json.dumps(old))
    assert _run(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith("note: ") and "carries no digest" in err[0] and "give its profile file" in err[-1], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "case, match",
    [
        ("ship", "header '# ship: kvlcc2' but the plan is for full-scale"),
        ("manoeuvre", "header '# manoeuvre: tau99' but step"),
        ("time", "was planned at"),
        ("order", "which the plan sails before step"),
        ("land", "is on land"),
        ("off-map", "is outside the map"),
        ("no-time", "holds no manoeuvre"),
        ("twice", "has a recording already"),
        ("too-long", "trim the recording to the manoeuvre"),
    ],
)
def test_bad_resume_input_one_line_exit_2_nothing_written(sailed, tmp_path, capsys, case, match):
    recs = sorted((sailed["dir"] / "rec").glob("*.csv"))
    kw = {}
    if case == "ship":
        kw["recordings"] = [_edit(recs[0], tmp_path / "a.csv", header="# ship: kvlcc2"), recs[1]]
    elif case == "manoeuvre":
        kw["recordings"] = [_edit(recs[0], tmp_path / "a.csv", header="# manoeuvre: tau99")]
    elif case == "time":  # without '# step:' the time names the step: 2000 s late on the first is no step of it
        kw["recordings"] = [_edit(recs[0], tmp_path / "a.csv", shift=2000.0, drop="# step:")]
    elif case == "order":  # '# step:' names the step; the first then overlaps the second
        kw["recordings"] = [_edit(recs[0], tmp_path / "a.csv", shift=2000.0), recs[1]]
    elif case == "land":
        kw["start"] = "60.17,24.94,90"
    elif case == "off-map":
        kw["start"] = "59.0,24.9,90"
    elif case == "no-time":
        kw["left"] = "10"
    elif case == "twice":
        kw["recordings"] = [recs[0], recs[0]]
    elif case == "too-long":  # the manoeuvre and as long again after it
        lines = recs[0].read_text().splitlines()
        i = next(i for i, ln in enumerate(lines) if ln.startswith("t,"))
        rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[i + 1 :]])
        more = rows.copy()  # the same run again, its time and track (t, x, y) carried on from the end
        more[:, :3] += 2 * rows[-1, :3] - rows[0, :3] - rows[-2, :3]
        more = [",".join(f"{v:.9g}" for v in row) for row in more]
        (tmp_path / "long.csv").write_text("\n".join(lines + more) + "\n")
        kw["recordings"] = [tmp_path / "long.csv"]
    out = tmp_path / "out"
    capsys.readouterr()
    assert _resume(sailed, out, "--no-export", **kw) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and match in err[0], err
    assert not out.exists()


def test_default_out_holding_the_plan_and_recordings_is_refused(sailed, tmp_path, monkeypatch, capsys):
    """The default --out is trial-out, where the first plan was written; the output directory is
    replaced whole, so resuming trial-out/plan.json with its recordings inside it must refuse
    (one line, exit 2) and leave the plan and the recordings untouched."""
    import shutil

    shutil.copytree(sailed["dir"] / "plan", tmp_path / "trial-out")
    shutil.copytree(sailed["dir"] / "rec", tmp_path / "trial-out" / "rec")
    before = sorted(p.relative_to(tmp_path) for p in (tmp_path / "trial-out").rglob("*"))
    monkeypatch.chdir(tmp_path)
    base = ["plan", "--resume", "trial-out/plan.json", "--from", sailed["from"], "--time-left", "10min", "--no-export"]
    capsys.readouterr()
    for extra in ([], ["--out", "trial-out/rec"]):
        assert _run([*base, "--recordings", "trial-out/rec", *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: --out ") and "would replace" in err[0], err
    assert sorted(p.relative_to(tmp_path) for p in (tmp_path / "trial-out").rglob("*")) == before


def test_plan_options_given_with_resume_override_the_plans_others_are_restored(sailed, tmp_path):
    """The lattice options a plan was made with come back on resume (heuristic, run-in, split,
    size from plan.json); those given on the command line override them, none is ignored."""
    import copy

    from maps.resume import plan_options

    plan = copy.deepcopy(sailed["plan"])
    assert plan_options(plan).size == (35, 44) and plan.stats["options"]["split"] is False
    plan.stats["heuristic"] = "thesis"
    assert plan_options(plan).settle == "lattice"  # large water: the lattice's own settling
    plan.stats["options"] |= {"run_in_s": 120.0, "split": True, "size": [40, 50], "settle": "ship"}
    o = plan_options(plan)
    assert (o.heuristic, o.run_in_s, o.split, o.size, o.settle) == ("thesis", 120.0, True, (40, 50), "ship")
    doc = json.loads((sailed["dir"] / "plan" / "plan.json").read_text())
    doc["stats"]["heuristic"], doc["margin_m"] = "thesis", 25.0  # as if planned with --heuristic thesis --margin 25
    doc["digest"] = content_digest(doc)  # as plan-trial writes it (an edit by hand is refused)
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "plan.json").write_text(json.dumps(doc))
    out = tmp_path / "rest"
    args = ["plan", "--resume", str(tmp_path / "p" / "plan.json"), "--from", sailed["from"], "--time-left", "10min"]
    args += ["--recordings", str(sailed["dir"] / "rec"), "--margin", "30", "--vessel-name", "Aurora", "--no-export"]
    assert _run([*args, "--out", str(out)]) == 0
    doc = json.loads((out / "plan.json").read_text())
    assert doc["margin_m"] == 30.0 and doc["stats"]["heuristic"] == "thesis" and doc["vessel_name"] == "Aurora"


def _matched(plan, files):
    from diagnose.recording import load_recording
    from maps.resume import match_recordings

    prof = load_profile(plan.ship)
    return [(r.step + 1, r.source) for r in match_recordings(plan, [load_recording(f)[0] for f in files], prof)]


def test_a_ship_header_is_matched_by_the_one_ship_name_rule(sailed, tmp_path):
    """'# ship: Full_Scale' names the plan's full-scale ship as diagnose and mass read it (case and punctuation
    aside: primitives.profile_tables.names_ship); resume refused it as another ship before the re-read of stop 62.
    'fullscale' is still another name."""
    from maps.resume import ResumeError

    recs = sorted((sailed["dir"] / "rec").glob("*.csv"))
    spelt = [_edit(recs[0], tmp_path / "a.csv", header="# ship: Full_Scale"), recs[1]]
    assert [n for n, _ in _matched(sailed["plan"], spelt)] == [s.index + 1 for s in sailed["steps"]]
    other = [_edit(recs[0], tmp_path / "b.csv", header="# ship: fullscale"), recs[1]]
    with pytest.raises(ResumeError, match="header '# ship: fullscale' but the plan is for full-scale"):
        _matched(sailed["plan"], other)


def test_a_late_schedule_matches_by_step_number_or_in_sailing_order(sailed, tmp_path):
    """A trial running behind: '# step: N' decides the step whatever the delay (only the order is
    checked); without it the recordings go in time order to the next step of their manoeuvre, the
    schedule's slip carried from one to the next, so a repeated manoeuvre sailed late is not taken
    for its later repetition."""
    import copy

    recs = sorted((sailed["dir"] / "rec").glob("*.csv"))
    steps = [s.index + 1 for s in sailed["steps"]]
    late = [_edit(r, tmp_path / f"late{i}.csv", shift=1000.0) for i, r in enumerate(recs)]
    assert [n for n, _ in _matched(sailed["plan"], late)] == steps  # 1000 s behind: refused before (900 s window)
    bare = [_edit(r, tmp_path / f"bare{i}.csv", shift=500.0 + 400 * i, drop="# step:") for i, r in enumerate(recs)]
    assert [n for n, _ in _matched(sailed["plan"], bare)] == steps
    # the plan sails the first manoeuvre again as its second; the crew is 500 s behind: the first
    # recording (nearer the second's planned start) is the first step, the next one the second
    plan = copy.deepcopy(sailed["plan"])
    first, second = sailed["steps"]
    plan.steps[second.index].primitive = first.primitive
    dt = second.start_time_s - first.start_time_s
    again = [bare[0], _edit(recs[0], tmp_path / "again.csv", shift=500.0 + dt, drop="# step:")]
    assert _matched(plan, again) == [(first.index + 1, str(again[0])), (second.index + 1, str(again[1]))]


def test_resume_options_need_each_other(sailed, tmp_path, capsys):
    assert _run(["plan", "--time-left", "10min", "--out", str(tmp_path / "o")]) == 2
    assert "--time-left: resumes a trial" in capsys.readouterr().err
    args = ["plan", "--resume", str(sailed["dir"] / "plan" / "plan.json"), "--time-left", "10min", "--out", str(tmp_path / "o")]
    assert _run(args) == 2
    assert "also give --recordings and --from" in capsys.readouterr().err
    args += ["--recordings", str(sailed["dir"] / "rec"), "--from", sailed["from"]]
    assert _run([*args, "--criterion", "A"]) == 2
    assert "--criterion: chooses a first design" in capsys.readouterr().err
    assert _run([*args, "--start", sailed["from"]]) == 2
    assert "--start: a resumed trial starts at --from" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# -- the library: information sailed counted in the rest (7.58) -------------------------------------


@pytest.fixture(scope="module")
def model_ship():
    prof = load_profile("model-ship")
    lib = ship_library(prof)
    return prof, lib, {p.name: p for p in lib}


def test_reidentify_recovers_the_ship_sailed_and_the_rest_complements_it(model_ship, monkeypatch):
    """Noise-free runs of a ship 20 % off the profile: the IV estimate recovers it; and the rest of
    a trial whose first part sailed only some manoeuvres is designed towards the others (without
    the sailed term the rest would be the first design's mix)."""
    prof, lib, by = model_ship
    truth = prof.params() * (1 + 0.2 * np.random.default_rng(3).uniform(-1, 1, prof.params().shape))
    fresh = first_design(prof, lib).design.counts
    top = max(fresh, key=fresh.get)
    seq = [by[n] for n in fresh for _ in range(fresh[n])]
    runs = ad.sail(prof, seq, truth, (0.0, 0.0, 0.0), np.random.default_rng(0))
    reid = ad.reidentify(prof, runs, ad.profile_predictor(prof, lib))
    assert np.allclose(reid.theta, truth, rtol=1e-3, atol=1e-9) and not reid.disagrees
    # sailed: the most used manoeuvre of the design, as often as the whole design uses it, and one of each other
    part = [by[top]] * fresh[top] + [by[n] for n in fresh if n != top]
    part_runs = ad.sail(prof, part, truth, (0.0, 0.0, 0.0), np.random.default_rng(0))
    rd = ad.redesign(prof, lib, part_runs, 300.0)
    assert rd.planned_s <= 300.0 and np.isfinite(rd.logdet_total) and rd.logdet_total > rd.logdet_sailed
    # the same re-design with the sailed term dropped (the same re-identification and M_rest) sails top more
    real_design, real_from = ad.run_design, ad.InfoSet.from_infos
    monkeypatch.setattr(ad, "run_design", lambda *a, **k: real_design(*a, **{**k, "prior": None, "prior_samples": 0}))
    monkeypatch.setattr(ad.InfoSet, "from_infos", lambda infos, prior=None, a=0.0: real_from(infos))
    blind = ad.redesign(prof, lib, part_runs, 300.0, reid=rd.reid)
    assert rd.counts.get(top, 0) < blind.counts.get(top, 0), (rd.counts, blind.counts)


def test_a_recording_the_model_cannot_reproduce_points_to_diagnose(model_ship):
    """A ship with a structure the model lacks (here a slow sway oscillation no term carries)
    is said to disagree, naming `shiptrial diagnose`."""
    prof, lib, by = model_ship
    seq = [by[n] for n in ("tau1", "tau6", "tau8", "tau11")]
    runs = ad.sail(prof, seq, prof.params(), (0.0, 0.0, 0.0), np.random.default_rng(0))
    for r in runs:
        t = np.arange(len(r.y)) * prof.sample_time
        r.y[:, 1] += 0.5 * np.abs(r.y[:, 1]).max() * np.sin(2 * np.pi * t / 20.0) + 0.05
    reid = ad.reidentify(prof, runs, ad.profile_predictor(prof, lib))
    assert reid.disagrees and all("shiptrial diagnose" in d for d in reid.disagrees)


def test_no_time_for_a_manoeuvre_is_refused(model_ship):
    prof, lib, by = model_ship
    runs = ad.sail(prof, [by["tau1"]], prof.params(), (0.0, 0.0, 0.0), np.random.default_rng(0))
    with pytest.raises(ad.DesignError, match="holds no manoeuvre"):
        ad.redesign(prof, lib, runs, 10.0)


def test_batchwise_sailed_information_removes_each_runs_own_mean(model_ship):
    """Under 'batchwise' (7.53) each sailed run is its own sub-experiment: M_sailed is
    sum_r n_r (X_r - Y_r Z_r^T) / N, not the pooled runs with one mean removed (which counts the
    spread between the runs' means as information); under 'complete' (7.57) the pooled moments."""
    from expdesign.estimators import data_information

    prof, lib, by = model_ship
    runs = ad.sail(prof, [by[n] for n in ("tau1", "tau6", "tau8", "tau11")], prof.params(), (0.0,) * 3, np.random.default_rng(0))
    rd = ad.redesign(prof, lib, runs, 300.0, mean_subtraction="batchwise")
    inst = rd.reid.theta[None]
    per_run = [data_information(prof, [r.segment()], inst) for r in runs]
    n = sum(i.n_samples for i in per_run)
    want = sum(i.n_samples * i.gamma("batchwise") for i in per_run) / n
    pooled = data_information(prof, [r.segment() for r in runs], inst).gamma("batchwise")
    a = n * prof.sample_time / 300.0
    assert rd.logdet_sailed == pytest.approx(np.linalg.slogdet(a * want)[1], abs=1e-6)
    assert np.linalg.slogdet(a * pooled)[1] > rd.logdet_sailed + 1.0  # the runs' means differ: pooling inflates it
    got = ad.sailed_information(prof, runs, inst[0], "batchwise")
    assert got.n_samples == n and np.allclose(got.gamma("batchwise"), want, rtol=1e-12, atol=1e-15)
    complete = ad.sailed_information(prof, runs, inst[0], "complete")
    assert np.allclose(complete.X, data_information(prof, [r.segment() for r in runs], inst).X)


def test_a_held_dof_does_not_silence_the_others_disagreement(model_ship):
    """Runs that cannot identify surge yet (tau6, tau8: surge held at the profile's values): a
    structurally wrong sway is still reported, while clean runs of a ship 20 % off the profile are
    not (the held surge misses by construction and is not judged)."""
    prof, lib, by = model_ship
    truth = prof.params() * (1 + 0.2 * np.random.default_rng(3).uniform(-1, 1, prof.params().shape))
    seq = [by["tau6"], by["tau8"]]
    clean = ad.sail(prof, seq, truth, (0.0, 0.0, 0.0), np.random.default_rng(0))
    reid = ad.reidentify(prof, clean, ad.profile_predictor(prof, lib))
    assert any("cannot identify Xu" in n for n in reid.notes) and not reid.disagrees
    wrong = ad.sail(prof, seq, truth, (0.0, 0.0, 0.0), np.random.default_rng(0))
    for r in wrong:
        t = np.arange(len(r.y)) * prof.sample_time
        r.y[:, 1] += 0.5 * np.abs(r.y[:, 1]).max() * np.sin(2 * np.pi * t / 20.0) + 0.05
    reid = ad.reidentify(prof, wrong, ad.profile_predictor(prof, lib))
    assert any("cannot identify Xu" in n for n in reid.notes)
    assert len(reid.disagrees) == 2 and all("shiptrial diagnose" in d for d in reid.disagrees)


def test_the_rest_leaves_out_what_the_first_plan_dropped_for_sea_room(sailed, monkeypatch):
    """A manoeuvre the first plan dropped because it fits nowhere on the map is not offered to the
    re-design of the rest (it would make the rest's plan infeasible)."""
    import copy

    import maps.resume as mr
    from diagnose.recording import load_recording
    from maps.geo import load_map

    plan = copy.deepcopy(sailed["plan"])
    prof = load_profile(plan.ship)
    plan.design = {**(plan.design or {}), "dropped": [{"primitive": "tau12", "needs_m": [9000.0, 300.0]}]}
    runs = mr.match_recordings(plan, [load_recording(f)[0] for f in sorted((sailed["dir"] / "rec").glob("*.csv"))], prof)
    seen = {}

    def capture(profile, library, *a, **k):
        seen["names"] = [p.name for p in library]
        raise RuntimeError("captured")

    monkeypatch.setattr(mr, "redesign", capture)
    lat, lon, hdg = (float(v) for v in sailed["from"].split(","))
    with pytest.raises(RuntimeError, match="captured"):
        mr.resume_plan(plan, runs, mr.Position(lat, lon, hdg), 600.0, load_map("helsinki", draught_m=prof.draught_m), prof)
    assert "tau12" not in seen["names"] and "tau16" in seen["names"]


def test_a_robust_plan_resumed_says_the_rest_is_designed_d_optimal(sailed):
    """Before, a plan designed bayes-D was resumed with D without a word (the record's criterion "D")."""
    import copy

    import maps.resume as mr
    from diagnose.recording import load_recording
    from maps.geo import load_map

    plan = copy.deepcopy(sailed["plan"])
    prof = load_profile(plan.ship)
    plan.design = {**(plan.design or {}), "criterion": "bayes-D"}
    runs = mr.match_recordings(plan, [load_recording(f)[0] for f in sorted((sailed["dir"] / "rec").glob("*.csv"))], prof)
    lat, lon, hdg = (float(v) for v in sailed["from"].split(","))
    new, rd = mr.resume_plan(plan, runs, mr.Position(lat, lon, hdg), 600.0, load_map("helsinki", draught_m=prof.draught_m), prof)
    assert rd.record["criterion"] == "D" and rd.record["first_criterion"] == "bayes-D"
    said = [n for n in new.stats["notes"] if "designed bayes-D" in n]
    assert len(said) == 1 and "re-designed D-optimal" in said[0]


def test_rest_efficiency_bounds_what_a_redesign_can_gain(model_ship):
    """The D-efficiency at the true parameters of a rest of the trial against the best rest there
    (both counting the sailed runs, (7.58)): the re-design at the truth scores its own rounding
    loss only (consistent with its log-dets, <= 1), a rest of one manoeuvre repeated scores far
    lower, and the first design's rest lies between (what the benchmark prints as the ceiling)."""
    prof, lib, by = model_ship
    truth = prof.params() * (1 + 0.3 * np.random.default_rng(5).uniform(-1, 1, prof.params().shape))
    runs = ad.sail(prof, [by[n] for n in ("tau1", "tau6", "tau8")], truth, (0.0,) * 3, np.random.default_rng(0))
    reid = ad.Reidentification(truth, prof.predictor_param_names, {})
    oracle = ad.redesign(prof, lib, runs, 300.0, mean_subtraction="batchwise", reid=reid)
    p = len(truth)

    def eff(counts):
        return ad.rest_efficiency(prof, lib, runs, truth, counts, 300.0, oracle.logdet_continuous, "batchwise")

    # the bound is the continuous optimum's log det (not the rounded one's) on the efficiency's own
    # normalisation: the design's weights give it back through rest_problem's (7.58) sum
    lib_i = [q for q in lib if q.kind == "informative"]
    _, _, info, _ = ad.rest_problem(prof, lib_i, runs, truth, 300.0, "batchwise")
    w = np.array([oracle.weights.get(q.name, 0.0) for q in lib_i])
    assert info.logdet(w / w.sum(), "batchwise") == pytest.approx(oracle.logdet_continuous, abs=1e-3)
    own = eff(oracle.counts)
    assert own == pytest.approx(np.exp((oracle.logdet_total - oracle.logdet_continuous) / p), rel=1e-9)
    assert 0.9 < own <= 1.0 + 1e-9
    n_one = int(300.0 // by["tau1"].duration_s)
    one = eff({"tau1": n_one})
    assert eff({"tau1": n_one // 2}) < one  # half the time left unsailed: less information, not the same mix
    fresh = first_design(prof, lib, trial_length_s=300.0, mean_subtraction="batchwise").design.counts
    assert one < 0.8 and one < eff(fresh) <= own + 1e-9
    with pytest.raises(ad.DesignError, match="tau99"):
        eff({"tau99": 1})


def test_the_first_design_and_the_redesign_share_one_information_model(model_ship):
    """The first design's moments of every primitive are the re-design's at the profile's values:
    the converged IV's instruments (the predictor simulated at the design's parameters, (7.12)),
    not the profile's crude instrument set, which only starts the estimator's iteration (before,
    tau1's X differed by 9 % and tau2's batchwise X|u|u moment by 2.5x)."""
    from primitives.information import primitive_information

    prof, lib, _ = model_ship
    assert prof.instrument_set != prof.simulation_set  # the case where the two models differed
    at_profile = ad.information_at(prof, lib, prof.params())
    for p, b in zip(lib, at_profile):
        a = primitive_information(prof, p)
        for ms in ("none", "batchwise"):
            assert np.allclose(a.gamma(ms), b.gamma(ms), rtol=1e-9, atol=1e-12), (p.name, ms)
        assert np.allclose(a.Z, b.Z, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("ms", ["batchwise", "complete"])
def test_a_resume_that_learnt_nothing_leaves_the_rest_as_planned(model_ship, ms):
    """The first third of a plan sailed by the profile's own ship (noise-free) and re-designed at
    the profile's values: the rest is the plan's own rest, manoeuvre for manoeuvre (before, under
    batchwise the re-design swapped tau1 for tau2 and moved tau8: the fixed rest was 0.925
    D-efficient in the re-design's own model)."""
    from benchmarks.bench_adaptive import first_third, interleave, rest_seconds

    prof, lib, _ = model_ship
    th = prof.params()
    plan = first_design(prof, lib, trial_length_s=2 * sum(p.duration_s for p in lib), mean_subtraction=ms).design.counts
    seq = interleave(plan, lib)
    n = first_third(seq)
    runs = ad.sail(prof, seq[:n], th, (0.0, 0.0, 0.0), np.random.default_rng(0))
    nothing_learnt = ad.Reidentification(th, prof.predictor_param_names, {})
    rd = ad.redesign(prof, lib, runs, rest_seconds(seq, n), mean_subtraction=ms, reid=nothing_learnt)
    rest: dict[str, int] = {}
    for p in seq[n:]:
        rest[p.name] = rest.get(p.name, 0) + 1
    assert rd.counts == rest
