"""Issue 25, "Distrust a failed airspeed sensor", done-when: ``gcs run`` with the built-in
simulator (127.0.0.1, ephemeral ports) and a simulated airspeed failure on the only plane:
its wind is dropped and planning falls back to the configured wind with a warning; the
run replays identical."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from daemon_run import Journal, after, events, run_gcs

from domain.wind_triangle import wind_vector_m_s
from groundstation.cli import main

CONFIGURED = wind_vector_m_s(15.0, 270.0)


def _planned_after_failure(journal: Journal) -> bool:
    """The sensor failed and a plan was made after it (the loiter's end, ~196 s)."""
    failed = events(journal, "airspeed_failed", vehicle="1")
    return bool(failed) and bool(after(events(journal, "plan"), failed[0]["t"]))


@pytest.mark.timeout(120)
def test_a_failed_airspeed_sensor_on_the_only_plane_falls_back_to_the_configured_wind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:1", "--scenario", "default", "--wind", "15,270",
        "--sim-fault", "1:airspeed:at=120", "--speedup", "50", "--duration", "300",
        until=_planned_after_failure, timeout_s=100.0,
    )  # fmt: skip
    assert daemon.stop_reason == "test: awaited events seen", daemon.stop_reason
    assert not events(journal, "task_error") and not events(journal, "core_error")
    # before the failure the fleet's wind is the plane's own (~15 m/s, not exactly 15)
    winds = events(journal, "wind")
    before = [w for w in winds if w["t"] < 120.0]
    assert before and before[0]["source"] == "vehicles" and before[0]["vehicles"] == ["1"]
    assert before[-1]["speed_m_s"] == pytest.approx(15.0, abs=1.0)
    reports = [e for e in events(journal, "input", kind="WindReport") if e["t"] < 120.0]
    assert len(reports) > 30 and all(math.hypot(r["wx_m_s"], r["wy_m_s"]) > 14.0
                                     for r in reports[-10:])
    # ArduPlane's health check disables the sensor 4.4 s after the fault (22 checks at 5 Hz)
    [text] = [e for e in events(journal, "statustext", vehicle="1") if "Airspeed" in e["text"]]
    assert text["text"] == "Airspeed sensor 1 failure. Disabling" and text["severity"] == 3
    [failed] = events(journal, "airspeed_failed", vehicle="1")
    # (journalled on the daemon's mission clock, which runs a fraction of a second off the
    # simulator's: 124.35 s was seen for the simulator's 124.4 s)
    assert failed["how"] == "statustext" and 123.9 <= failed["t"] <= 126.0
    t_failed = failed["t"]
    # at once: the withdrawal, the fallback wind line and the warning, at the same instant
    [withdrawn] = events(journal, "input", kind="WindWithdrawn", vehicle="1")
    assert withdrawn["t"] == pytest.approx(t_failed, abs=0.01)
    later = after(winds, t_failed - 0.01)
    assert later and later[0]["t"] == pytest.approx(t_failed, abs=0.01)
    assert all(w["source"] == "fallback" for w in later)
    assert (later[0]["wx_m_s"], later[0]["wy_m_s"]) == CONFIGURED
    [warning] = events(journal, "wind_fallback", vehicle="1")
    assert warning["t"] == pytest.approx(t_failed, abs=0.01)
    assert "falls back to the configured wind, 15.0 m/s from 270 deg" in warning["detail"]
    # never the degraded estimate: the plane's WIND keeps coming but is not sent to the core.
    # Compared with the withdrawal's own time (the frame's, at full precision): the journal
    # line's ``t`` is rounded to the millisecond, and a WIND frame handled just before the
    # STATUSTEXT, within that millisecond, can carry a later unrounded time.
    reports = events(journal, "input", kind="WindReport")
    assert not after(reports, withdrawn["t"])
    assert journal.index(withdrawn) > max(journal.index(r) for r in reports)
    plans = after(events(journal, "plan"), t_failed)
    assert plans and all(p["problem"]["wind_m_s"] == list(CONFIGURED) for p in plans)
    [session] = daemon.sessions.values()
    own = session.snapshot.wind_xy_m_s
    assert own is not None and math.hypot(*own) == pytest.approx(6.75, abs=0.5)
    assert not events(journal, "wind_outlier")
    # gcs replay re-feeds the journalled inputs, WindWithdrawn included: identical
    capsys.readouterr()
    assert main(["replay", str(daemon.run_dir), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["identical"] is True and report["differences"] == []
