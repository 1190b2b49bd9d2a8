"""``btcap run`` as a log sees it: plain progress lines, an unusable ``--out`` refused
before the run, ``--compare`` saying what it runs and drawing the comparison."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import msgspec
import pytest

import btcap.cli
from btcap.cli import main
from btcap.sim.running.metrics import MissionResult

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
LINE = re.compile(r"^small t=(\d+) s: found \d+/4, identified \d+, decontaminated \d+, explored")


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() would configure logging onto this test's captured stderr (see test_cli_run)."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def refused(capsys: pytest.CaptureFixture[str], argv: list[str], *fragments: str) -> None:
    """Exit 2 with a one-line error naming ``fragments``, before any mission started."""
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert "running" not in out
    assert err.startswith("btcap: error: ")
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in err, err


def test_a_redirected_run_prints_progress_lines(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["run", str(SMALL), "--fast", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "\x1b[" not in out
    times = [int(m[1]) for m in map(LINE.match, out.splitlines()) if m]
    # One line per 100 s of mission time from the start, and one at the end.
    final = msgspec.json.decode((tmp_path / "o" / "result.json").read_bytes(), type=MissionResult)
    assert times[0] == 0
    assert times[1:-1] == list(range(100, int(final.mission_time_s), 100))
    assert times[-1] == round(final.mission_time_s)
    assert re.search(r"^small t=0 s: .*; husky1 idle, spot1 idle, bebop1 idle$", out, re.M)


def test_quiet_means_no_progress_lines(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(SMALL), "--fast", "--quiet", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert not any(LINE.match(line) for line in out.splitlines())
    assert "mission summary" in out


def test_an_out_that_is_a_file_is_refused_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    taken = tmp_path / "taken"
    taken.write_text("not a folder")
    refused(capsys, ["run", str(SMALL), "--fast", "--out", str(taken)], str(taken), "not a folder")
    assert taken.read_text() == "not a folder"


def test_an_out_that_cannot_be_made_is_refused_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "file").write_text("")
    out = tmp_path / "file" / "results"
    refused(capsys, ["run", str(SMALL), "--fast", "--out", str(out)], str(out), "Not a directory")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_an_out_without_write_permission_is_refused_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        argv = ["run", str(SMALL), "--fast", "--out", str(locked)]
        refused(capsys, argv, str(locked), "Permission denied")
    finally:
        locked.chmod(0o700)


def test_compare_says_what_it_runs_and_draws_the_comparison(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = tmp_path / "other.yaml"
    other.write_text(SMALL.read_text().replace("name: small", "name: other-seed"))
    other.write_text(other.read_text().replace("seed: 4", "seed: 5"))
    out = tmp_path / "cmp"
    argv = ["run", "--compare", str(SMALL), str(other), "--fast", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "comparing 2 scenarios: small, other-seed" in printed
    for name in ("small", "other-seed"):
        assert (out / name / "result.json").exists()
        assert (out / name / "timeline.png").read_bytes().startswith(PNG_MAGIC)
    png = (out / "compare.png").read_bytes()
    assert png.startswith(PNG_MAGIC)
    assert len(png) > 10_000
    assert set(json.loads((out / "compare.json").read_text())) == {"small", "other-seed"}
    assert "compare.png" in printed.replace("\n", "")


def test_compare_refuses_two_scenarios_of_one_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["run", "--compare", str(SMALL), str(SMALL), "--fast", "--out", str(tmp_path / "o")]
    refused(capsys, argv, "--compare", "small")
    assert not (tmp_path / "o").exists()


def test_several_scenarios_need_compare(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", str(SMALL), "single-husky", "--fast", "--out", str(tmp_path / "o")]
    refused(capsys, argv, "--compare")
    assert not (tmp_path / "o").exists()


def test_help_explains_distributed_and_compare(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "own OS process" in text
    assert "ZeroMQ" in text
    assert "compare.png" in text
