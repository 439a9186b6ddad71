"""``gcs run`` over lossy simulated SiK radios, end to end on 127.0.0.1 (ephemeral ports):
the GCS heartbeat keeps 1 Hz of mission time however slowly the simulator runs, the link
budgets hear the radios and measure each link's round trip, and uploads verify within
a few seconds of mission time with few repeated requests (docs/links.md, "Over a
telemetry radio")."""

from __future__ import annotations

import statistics
from collections import Counter
from pathlib import Path

from daemon_run import events, run_gcs

from groundstation.link.tlog import TlogReader


def test_gcs_run_keeps_its_budget_over_lossy_radios(tmp_path: Path) -> None:
    # 10x: the host's own delays count ten-fold in mission time, not fifty-fold (at 50x
    # with two busy loops beside the suite the median upload took 4.96 s of mission time)
    daemon, journal = run_gcs(
        tmp_path, "--vehicles", "sim:2", "--sim-radio", "sik,loss=0.05", "--scenario",
        "default", "--speedup", "10", "--duration", "60", timeout_s=120,
    )  # fmt: skip
    assert daemon.stop_reason == "duration", daemon.stop_reason
    assert not events(journal, "task_error") and not events(journal, "core_error")
    mission_s = journal[-1]["t"]
    frames = [r.message for r in TlogReader(daemon.run_dir / "flight.tlog")]
    sent = Counter(m.get_type() for m in frames if m.get_srcSystem() == 245)
    # the heartbeat (and so the radios' RADIO_STATUS) at 1 Hz of mission time
    assert 0.85 <= sent["HEARTBEAT"] / mission_s <= 1.1, sent["HEARTBEAT"] / mission_s
    # every upload verified, in a few mission seconds, with few repeated requests
    uploads = events(journal, "upload")
    assert len(uploads) >= 3 and all(u["ok"] for u in uploads), uploads
    took = [u["took_s"] for u in uploads]
    assert statistics.median(took) <= 4.5, took
    # each transfer (the missions and the fences) is verified by one download's
    # MISSION_REQUEST_LIST; lost answers add a probe or a resend each, a few per transfer
    fences = events(journal, "fence")
    assert fences and all(f["ok"] for f in fences), fences
    transfers = len(uploads) + len(fences)
    assert transfers <= sent["MISSION_REQUEST_LIST"] <= 2 * transfers, (transfers, sent)
    # the budgets heard both radios and timed both links' round trips
    budgets = daemon.budgets.summary()
    assert len(budgets) == 2
    for link in budgets.values():
        assert link["txbuf_pct"] is not None and link["capacity_bps"] is not None
        assert link["rtt_samples"] >= 3 and 0.05 <= link["srtt_s"] <= 2.0, link
