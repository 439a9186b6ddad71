"""Progress on stderr: rich bars on a terminal (one task per fleet size), plain lines with
no escape codes in a pipe, nothing with --quiet; stdout keeps only the result."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from groundstation.cli import main
from groundstation.commands.progress_bars import ProgressBars


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_terminal_gets_one_bar_per_task() -> None:
    stream = _Terminal()
    with ProgressBars(stream=stream) as bars:
        updates = [bars.task(f"paper-boat uavs={k}", 200.0, " s") for k in (1, 3, 5)]
        for update in updates:
            for t in range(0, 201, 50):
                update(float(t))
    text = stream.getvalue()
    assert "\x1b[" in text  # a terminal: rich draws
    for k in (1, 3, 5):
        assert f"paper-boat uavs={k}" in text
    assert "200/200 s" in text and "100%" in text


def test_a_pipe_gets_plain_quarter_lines_and_no_escape_codes() -> None:
    stream = io.StringIO()
    with ProgressBars(stream=stream) as bars:
        update = bars.task("replay", 100.0, " inputs")
        for done in range(101):
            update(float(done))
    lines = stream.getvalue().splitlines()
    assert "\x1b" not in stream.getvalue()
    assert lines == [f"replay: {n} / 100 inputs" for n in (25, 50, 75, 100)]


def test_replay_style_shows_nothing_in_a_pipe_and_bars_on_a_terminal() -> None:
    pipe = io.StringIO()
    with ProgressBars(stream=pipe, plain_lines=False) as bars:
        bars.task("gcs replay --serve", 10.0, " frames")(10.0)
    assert pipe.getvalue() == ""
    terminal = _Terminal()
    with ProgressBars(stream=terminal, plain_lines=False) as bars:
        bars.task("gcs replay --serve", 10.0, " frames")(10.0)
    assert "gcs replay --serve" in terminal.getvalue() and "10/10 frames" in terminal.getvalue()


def test_quiet_shows_nothing() -> None:
    stream = _Terminal()
    with ProgressBars(quiet=True, stream=stream) as bars:
        bars.task("x", 10.0)(10.0)
    assert stream.getvalue() == ""


@pytest.mark.timeout(120)
def test_simulate_list_of_fleet_sizes_reports_each_size_on_stderr_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    status = main(["simulate", "--scenario", "paper-boat", "--uavs", "1,2", "--duration", "20",
                   "--out", str(tmp_path), "--no-plots", "--no-journal"])
    assert status == 0
    captured = capsys.readouterr()
    assert "\x1b" not in captured.err  # captured stderr is not a terminal
    for k in (1, 2):
        assert f"paper-boat uavs={k} seed=0: 20 / 20 s" in captured.err
        assert f"uavs={k}" not in captured.out
    assert captured.out.splitlines()[0].split()[:2] == ["uavs", "mean"]
