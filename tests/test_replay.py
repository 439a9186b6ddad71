"""gcs replay on recorded runs: same decisions, changed settings, damaged journals."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path

import pytest
from simulate_run import simulate_text

from groundstation.cli import main
from groundstation.runners.replay.journal import (
    JournalError,
    apply_overrides,
    core_config_of,
    load_journal,
)
from groundstation.runners.replay.run import replay_journal

SCENARIO = """\
name: replay-test
description: three UAVs with loiters, an override, a resume and a low battery
duration_s: 120
origin: {lat_deg: 78.93, lon_deg: 11.92}
fleet:
  count: 3
  loiter_s: 20
  loiter_radius_m: 120.0
  launch: {x_m: 0.0, y_m: 0.0}
targets:
  list:
    - {id: A, x_m: 800, y_m: 300, vx_m_s: 0.3, vy_m_s: -0.2}
    - {id: B, x_m: -600, y_m: 900, vx_m_s: -0.2, vy_m_s: 0.1}
    - {id: C, x_m: 1200, y_m: -700, vx_m_s: 0.1, vy_m_s: 0.3}
    - {id: D, x_m: -1000, y_m: -400, vx_m_s: 0.2, vy_m_s: 0.2}
    - {id: E, x_m: 300, y_m: 1400, vx_m_s: -0.3, vy_m_s: 0.0}
events:
  - {t_s: 40, kind: override, vehicle: "2"}
  - {t_s: 70, kind: resume, vehicle: "2"}
  - {t_s: 90, kind: battery_low, vehicle: "3"}
observer: {model: kalman, q_per_s: 0.01, iceberg_q_per_s: 0.0005}
planner: {objective: sequence, tau: 0.5}   # tau matters to it (the default, latency, has none)
policy: {replan: event, commit: true}
"""


@pytest.fixture(scope="module")
def event_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recorded 3-vehicle run with loiters, an override, a resume and a low battery."""
    return simulate_text(tmp_path_factory.mktemp("event-run"), SCENARIO)


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's scenario, 3 UAVs, replanning every 5 s without commitment."""
    out = tmp_path_factory.mktemp("paper-run") / "run"
    with contextlib.redirect_stdout(io.StringIO()):
        assert (
            main(
                [
                    "simulate",
                    "--scenario",
                    "paper-boat",
                    "--uavs",
                    "3",
                    "--duration",
                    "40",
                    "--out",
                    str(out),
                    "--quiet",
                    "--no-plots",
                ]
            )
            == 0
        )
    return out


def _copy(run: Path, tmp_path: Path) -> Path:
    dest = tmp_path / "copy"
    dest.mkdir()
    shutil.copy(run / "journal.jsonl", dest / "journal.jsonl")
    return dest


def _records(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "journal.jsonl").read_text().splitlines()]


def _write(run: Path, records: list[dict]) -> None:
    (run / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))


@pytest.mark.parametrize("fixture", ["event_run", "paper_run"])
def test_recorded_run_replays_to_the_same_decisions(
    fixture: str, request: pytest.FixtureRequest, capsys: pytest.CaptureFixture[str]
) -> None:
    run = request.getfixturevalue(fixture)
    assert main(["replay", str(run), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["identical"] is True
    assert report["differences"] == []
    recorded = _records(run)
    flies = sum(1 for r in recorded if r["event"] == "fly")
    plans = sum(1 for r in recorded if r["event"] == "plan")
    assert flies > 3 and plans > 2
    assert report["solves"] == plans
    assert report["problems_equal"] == plans
    assert report["objectives_equal"] == report["objectives_compared"] == plans
    assert report["inputs"] == sum(1 for r in recorded if r["event"] == "input")
    tracks = sum(1 for r in recorded if r["event"] == "track")
    assert report["track_samples_compared"] == tracks > 10
    assert report["track_samples_differing"] == 0


def test_event_run_holds_releases_and_send_home(event_run: Path) -> None:
    events = {r["event"] for r in _records(event_run)}
    assert {"release", "send_home", "loiter_end", "fly"} <= events
    journal = load_journal(event_run)
    report = replay_journal(journal, core_config_of(journal), resolve=False)
    assert report.identical
    assert report.decisions_replayed >= report.decisions_recorded > 5


def test_changed_planner_setting_shows_differences(
    event_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(event_run), "--set", "planner.tau=0.9"]) == 1
    out = capsys.readouterr().out
    assert "setting changed: tau 0.5 -> 0.9" in out
    problem_lines = [line for line in out.splitlines() if " problem " in line]
    assert problem_lines and "tau 0.5" in problem_lines[0] and "tau 0.9" in problem_lines[0]
    assert any(" objective " in line for line in out.splitlines())
    assert "DIFFERENCE" in out.splitlines()[-1]


def test_set_summarises_how_many_routes_changed(
    event_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 29: a what-if replay says whether any route changed: "routes changed: N of
    M" (M re-solved plans, N with another route than recorded); JSON: ``routes_changed``."""
    assert main(["replay", str(event_run), "--set", "planner.tau=0.9"]) == 1
    last = capsys.readouterr().out.splitlines()[-1]
    found = re.search(r"routes changed: (\d+) of (\d+) re-solved plans", last)
    assert found is not None, last
    changed, compared = int(found.group(1)), int(found.group(2))
    assert compared > 0 and 0 <= changed <= compared
    assert main(["replay", str(event_run), "--set", "planner.tau=0.9", "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["routes_changed"] == changed and report["objectives_compared"] == compared
    assert main(["replay", str(event_run)]) == 0  # no setting changed: not in the line
    assert "routes changed" not in capsys.readouterr().out


def test_override_alias_and_observer_setting(
    paper_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert (
        main(
            [
                "replay",
                str(paper_run),
                "--override",
                "observer.q_per_s=0.5",
                "--json",
                "--no-resolve",
            ]
        )
        == 1
    )
    report = json.loads(capsys.readouterr().out)
    kinds = {d["kind"] for d in report["differences"]}
    assert {"problem", "track"} <= kinds
    assert report["track_samples_differing"] > 0
    assert any("sigma" in d["now"] for d in report["differences"])


def test_edited_journal_config_shows_differences(event_run: Path, tmp_path: Path) -> None:
    run = _copy(event_run, tmp_path)
    records = _records(run)
    records[0]["core_config"]["tau"] = 0.9
    _write(run, records)
    assert main(["replay", str(run), "--no-resolve"]) == 1


def test_changed_decision_is_reported_event_by_event(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(event_run, tmp_path)
    records = _records(run)
    fly = next(r for r in records if r["event"] == "fly")
    original = fly["target"]
    fly["target"] = "Z"
    _write(run, records)
    assert main(["replay", str(run), "--json", "--no-resolve"]) == 1
    report = json.loads(capsys.readouterr().out)
    [diff] = report["differences"]
    assert diff["kind"] == "fly"
    assert diff["recorded"].startswith("fly Z") and diff["now"].startswith(f"fly {original}")
    assert diff["t"] == pytest.approx(fly["t"])


def test_recorded_solve_that_hit_its_deadline_is_not_comparable(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(event_run, tmp_path)
    records = _records(run)
    solved = next(r for r in records if r["event"] == "input" and r["kind"] == "PlanSolved")
    solved["result"]["hit_time_limit"] = True
    solved["result"]["objective"] += 1000.0  # a worse plan, found before the deadline
    _write(run, records)
    assert main(["replay", str(run), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert len(report["not_comparable"]) == 1
    assert "deadline" in report["not_comparable"][0]
    assert report["objectives_compared"] == report["solves"] - 1


def test_truncated_last_line_is_reported_not_fatal(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(event_run, tmp_path)
    data = (run / "journal.jsonl").read_bytes()
    last_start = data.rstrip(b"\n").rfind(b"\n") + 1
    (run / "journal.jsonl").write_bytes(data[: last_start + 25])  # cut the last line
    status = main(["replay", str(run), "--no-resolve"])
    out = capsys.readouterr().out
    assert "truncated last line" in out
    assert status == 0  # the last line is a sample, not a decision: nothing else changes
    journal = load_journal(run)
    assert journal.truncated_last_line
    assert len(journal.records) == data.count(b"\n") - 1


def test_damaged_line_in_the_middle_is_reported(event_run: Path, tmp_path: Path) -> None:
    run = _copy(event_run, tmp_path)
    lines = (run / "journal.jsonl").read_bytes().split(b"\n")
    lines[5] = b"\x00\xff garbage"
    (run / "journal.jsonl").write_bytes(b"\n".join(lines))
    journal = load_journal(run)
    assert [n for n, _ in journal.damaged] == [6]
    assert not journal.truncated_last_line


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "no journal.jsonl"),
        (b"", "empty"),
        (b"\x00\x01\x02garbage\n", "no readable"),
        (b'{"event": "stop", "t": 1.0}\n', "no 'start' record"),
    ],
)
def test_bad_journal_is_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes | None, message: str
) -> None:
    if content is not None:
        (tmp_path / "journal.jsonl").write_bytes(content)
    assert main(["replay", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err


def test_journal_without_inputs_says_what_is_missing(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(event_run, tmp_path)
    _write(run, [r for r in _records(event_run) if r["event"] != "input"])
    assert main(["replay", str(run)]) == 2
    assert "no core inputs" in capsys.readouterr().err


def test_bad_settings_are_errors(event_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(event_run), "--set", "nonsense=1"]) == 2
    assert "unknown key 'nonsense'" in capsys.readouterr().err
    assert main(["replay", str(event_run), "--set", "tau"]) == 2
    config = core_config_of(load_journal(event_run))
    with pytest.raises(ValueError, match="takes a bool"):
        apply_overrides(config, ["policy.commit=maybe"])
    assert apply_overrides(config, ["policy.commit=false"]).policy.commit is False
    with pytest.raises(JournalError):
        load_journal(Path("/nonexistent/run"))


def test_speed_paces_with_a_real_clock(event_run: Path, tmp_path: Path) -> None:
    """--speed K: mission time passes K times faster than the wall clock."""
    import time

    run = _copy(event_run, tmp_path)
    records = _records(run)
    keep = [r for r in records if r["event"] != "input" or r["t"] <= 1.0]
    _write(run, keep)
    start = time.monotonic()
    main(["replay", str(run), "--speed", "10", "--no-resolve", "--quiet"])
    assert 0.08 <= time.monotonic() - start < 5.0  # 1 mission s at 10x: >= 0.1 s wall


def test_daemon_style_journal_replays(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The spelling of ``gcs run``'s journal: None values left out, ``core`` in the start
    record, ``request`` for the plan id, no ``solve_request`` lines, aim points to 0.1 m,
    a send-home journalled as a release with ``home``."""
    out = []
    for r in _records(event_run):
        if r["event"] == "solve_request":
            continue
        r = {k: v for k, v in r.items() if v is not None}
        if r["event"] == "start":
            r["core"] = r.pop("core_config")
        elif r["event"] == "plan":
            r["request"] = r.pop("request_id")
        elif r["event"] == "fly":
            r["x_m"], r["y_m"] = round(r["x_m"], 1), round(r["y_m"], 1)
        elif r["event"] == "track":
            r = {
                "event": "track",
                "t": r["t"],
                "target": r["target"],
                "sigma": round(r["sigma"], 3),
                "x_m": round(r["x_m"], 1),
                "y_m": round(r["y_m"], 1),
            }
        elif r["event"] == "send_home":
            r = {**r, "event": "release", "home": True}
        out.append(r)
    assert any(
        r["event"] == "input" and r["kind"] == "TargetAdded" and "sigma0" not in r for r in out
    )
    run = tmp_path / "daemon-style"
    run.mkdir()
    _write(run, out)
    assert main(["replay", str(run), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["identical"] and report["problems_equal"] == report["solves"] > 2
    assert report["track_samples_compared"] > 10
    # and a changed setting still shows
    assert main(["replay", str(run), "--set", "tau=0.7", "--no-resolve"]) == 1


def test_skipped_lines_are_counted_with_their_first_line_numbers(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(event_run, tmp_path)
    lines = (run / "journal.jsonl").read_bytes().split(b"\n")
    damaged = list(range(30, 100, 7))  # ten damaged lines (0-based)
    for k in damaged:
        lines[k] = b"\x00\xff" + lines[k][:12]
    (run / "journal.jsonl").write_bytes(b"\n".join(lines))
    main(["replay", str(run), "--no-resolve"])
    out = capsys.readouterr().out
    first = ", ".join(str(k + 1) for k in damaged[:5])
    total = len(lines) - 1 if lines[-1] == b"" else len(lines)
    assert f"skipped 10 of {total} journal lines: {first} and 5 more" in out
    assert out.count("(skipped)") == 5  # the first few, then only the count
    with contextlib.redirect_stdout(io.StringIO()) as buf:
        main(["replay", str(run), "--no-resolve", "--json"])
    report = json.loads(buf.getvalue())
    assert report["skipped_lines"] == [k + 1 for k in damaged]
    assert report["lines_total"] == total


def test_nothing_replayable_is_an_error_saying_where(
    event_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _copy(event_run, tmp_path)
    records = _records(event_run)
    for r in records:
        if r["event"] == "input":
            r["kind"] = "NoSuchEvent"
    _write(run, records)
    assert main(["replay", str(run)]) == 2
    err = capsys.readouterr().err.strip()
    bad = [n for n, r in enumerate(records, 1) if r["event"] == "input"]
    assert err.startswith("gcs replay: error: ") and "nothing replayable" in err
    assert f"skipped {len(bad)} of {len(records)} journal lines: {bad[0]}, {bad[1]}" in err
    assert "\n" not in err and "Traceback" not in err


@pytest.mark.parametrize(
    "content",
    [bytes(range(256)) * 40, b'{"event": "start", "t": 0.0, "core": {"tau', b"\n \n"],
)
def test_binary_or_truncated_journal_is_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes
) -> None:
    (tmp_path / "journal.jsonl").write_bytes(content)
    assert main(["replay", str(tmp_path / "journal.jsonl")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gcs replay: error: ") and "\n" not in err and "Traceback" not in err
