"""Stop 62 (outputs3): detect-prior --out, detect --plot and primitives --plot replace an existing file only if that
command wrote it (a prior by its own fields, a figure by its Creator mark), else refuse before any work naming the
file and --force (export's wording), the user's file kept byte for byte, exit 2. On s62-int all three replaced it."""

from __future__ import annotations

from pathlib import Path

import pytest

from cli.app import _run

USERS = b"\x89PNG\r\n\x1a\n my own figure, drawn by hand"  # a real PNG header: the content, not the name, decides


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> tuple[Path, Path]:
    from diagnose.recording import write_csv
    from identify.detect.api import simulated_recording
    from identify.detect.vessel import Vessel

    d = tmp_path_factory.mktemp("owned")
    nominal, run = d / "nominal.csv", d / "run.csv"
    write_csv(simulated_recording(Vessel(), 200, seed=21, measured_moment=True), nominal)
    write_csv(simulated_recording(Vessel(), 150, seed=51, measured_moment=True), run)
    return nominal, run


def _refused(capsys, args: list[str], path: Path, option: str, writer: str) -> None:
    before = path.read_bytes()
    assert _run(args) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        f"error: {option} {path}: exists and was not written by {writer}; move it, choose another {option}, "
        "or pass --force to replace it"
    ), err
    assert path.read_bytes() == before


def test_detect_prior_replaces_only_a_prior(recordings, tmp_path, capsys):
    nominal, _ = recordings
    mine = tmp_path / "settings.json"
    mine.write_text('{"format": "my-tool/1", "kind": "full", "values": {}, "sigma": 1}\n')  # a prior's keys, not its format
    args = ["detect-prior", str(nominal), "--bootstrap", "0", "--out"]
    _refused(capsys, [*args, str(mine)], mine, "--out", "shiptrial detect-prior")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["settings.json"]  # nothing else written
    prior = tmp_path / "prior.json"
    assert _run([*args, str(prior)]) in (0, None)
    prior.write_text(prior.read_text() + "\n")  # its own file, touched: still known by its fields
    assert _run([*args, str(prior)]) in (0, None)  # replaced without --force
    assert not prior.read_text().endswith("\n\n")
    assert _run([*args, str(mine), "--force"]) in (0, None)
    assert '"shiptrial-yaw-prior/' in mine.read_text()


def test_detect_plot_replaces_only_a_figure_detect_drew(recordings, tmp_path, capsys):
    from identify.detect.api import fit_prior, save_prior

    nominal, run = recordings
    prior = save_prior(fit_prior([nominal], "full", bootstrap=0), tmp_path / "prior.json")
    mine = tmp_path / "figure.png"
    mine.write_bytes(USERS)
    args = ["detect", str(run), "--prior", str(prior), "--plot"]
    _refused(capsys, [*args, str(mine)], mine, "--plot", "shiptrial detect")
    ours = tmp_path / "detect.png"
    assert _run([*args, str(ours)]) in (0, None)
    first = ours.stat().st_mtime_ns
    ours.write_bytes(ours.read_bytes() + b"\0")  # its own figure, touched: still known by its Creator mark
    assert _run([*args, str(ours)]) in (0, None)
    assert not ours.read_bytes().endswith(b"\0") and ours.stat().st_mtime_ns >= first
    assert _run([*args, str(mine), "--force"]) in (0, None)
    assert mine.read_bytes() != USERS


def test_detect_plot_library_refuses_a_users_file_among_the_per_recording_figures(tmp_path):
    """Beyond 4 recordings one file each: every one is checked before any is drawn (a notebook's fix: force=True)."""
    from identify.detect.api import check_plot_out
    from primitives.errors import UserError

    sources = [f"run{k}.csv" for k in range(5)]
    (tmp_path / "s-003-run2.png").write_bytes(USERS)
    with pytest.raises(UserError, match=r"^path .*s-003-run2\.png: exists and was not written by shiptrial detect; .*force=True"):
        check_plot_out(sources, tmp_path / "s.png")
    assert len(check_plot_out(sources, tmp_path / "s.png", force=True)) == 5


def test_primitives_plot_replaces_only_a_figure_primitives_drew(tmp_path, capsys):
    mine = tmp_path / "tracks.png"
    mine.write_bytes(USERS)
    _refused(capsys, ["primitives", "--plot", str(mine)], mine, "--plot", "shiptrial primitives")
    ours = tmp_path / "library.png"
    assert _run(["primitives", "--plot", str(ours)]) in (0, None)
    ours.write_bytes(ours.read_bytes() + b"\0")
    assert _run(["primitives", "--plot", str(ours)]) in (0, None)
    assert not ours.read_bytes().endswith(b"\0")
    assert _run(["primitives", "--plot", str(mine), "--force"]) in (0, None)
    assert mine.read_bytes()[:8] == USERS[:8] and mine.read_bytes() != USERS


def test_detect_prior_refuses_a_deeply_nested_json_in_one_line(tmp_path):
    """A user's JSON nested deeper than the parser recurses is not a prior: refused in one line, not a RecursionError
    traceback (review of stop 62)."""
    from identify.detect.yawmodel import check_prior_out
    from primitives.errors import UserError

    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000)
    with pytest.raises(UserError, match=r"deep\.json: exists and was not written by shiptrial detect-prior"):
        check_prior_out(deep)
    assert deep.read_text() == "[" * 100_000


def test_detect_plot_beyond_four_recordings_leaves_a_users_file_of_the_stem_alone(recordings, tmp_path, capsys):
    """Beyond 4 recordings ``--plot m.png`` names only the stem of the per-recording files: a user's m.png, never
    written, is not refused (review of stop 62: it was, exit 2); a second run replaces its own files."""
    from identify.detect.api import fit_prior, save_prior

    nominal, run = recordings
    prior = save_prior(fit_prior([nominal], "full", bootstrap=0), tmp_path / "prior.json")
    runs = []
    for k in range(5):
        runs.append(tmp_path / f"r{k}.csv")
        runs[-1].write_bytes(run.read_bytes())
    mine = tmp_path / "m.png"
    mine.write_bytes(USERS)
    args = ["detect", *map(str, runs), "--prior", str(prior), "--plot", str(mine)]
    for _ in range(2):
        assert _run(args) in (0, None), capsys.readouterr().err
        assert mine.read_bytes() == USERS
        assert len(list(tmp_path.glob("m-00?-r?.png"))) == 5
