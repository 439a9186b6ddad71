"""The daemon shows link trouble: ``link_drops`` journal lines (only when something grew),
``summary()["links"]``, the status table's link lines; re-bindings are journalled."""

from __future__ import annotations

import asyncio
from pathlib import Path

from daemon_run import status_text

from groundstation.core.config import CoreConfig
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config_parse import parse_config
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import Journal, read_journal
from groundstation.daemon.status import link_lines
from groundstation.link import open_link


def _daemon(tmp_path: Path, t: list[float]) -> Daemon:
    config = parse_config({"vehicles": ["udpin:127.0.0.1:0"], "rebind_after_s": 4.0}, {})
    journal = Journal(tmp_path / "journal.jsonl", lambda: t[0], lambda: 1.7e9)
    clock = MissionClock(1.0, source=lambda: t[0])
    return Daemon(config, CoreConfig(), clock, tmp_path, None, journal, None)


def test_link_drops_are_journalled_when_they_grow_and_shown(tmp_path: Path) -> None:
    async def main() -> None:
        t = [0.0]
        daemon = _daemon(tmp_path, t)
        fleet = open_link("udpin:127.0.0.1:0", link_id="vehicles0")
        quiet = open_link("udpin:127.0.0.1:0", link_id="vehicles1")
        daemon.router.add_vehicle_link(fleet)
        daemon.router.add_vehicle_link(quiet)
        daemon.report_links()  # nothing yet: no line
        fleet.counters.frames_in, fleet.counters.rx_dropped = 900, 120
        fleet.counters.foreign = 2
        daemon.report_links()
        daemon.report_links()  # nothing new: no second line
        fleet.counters.rx_dropped = 150
        t[0] = 10.0
        daemon.report_links()
        # The router reports a re-binding through the daemon's journal.
        assert daemon.router.on_notice is not None
        daemon.router.on_notice(
            "link_rebound", {"system_id": 1, "link": "vehicles1", "previous": "vehicles0"}
        )
        daemon.journal_file.close()
        lines = read_journal(tmp_path / "journal.jsonl")
        drops = [e for e in lines if e["event"] == "link_drops"]
        assert [(e["link"], e["dropped"], e["foreign"]) for e in drops] == [
            ("vehicles0", 120, 2),
            ("vehicles0", 30, 0),
        ]
        assert drops[1]["totals"]["dropped"] == 150 and drops[1]["t"] == 10.0
        assert [e["event"] for e in lines if e["event"] != "link_drops"] == ["link_rebound"]
        assert daemon.router.binder.rules.rebind_after_s == 4.0
        stats = daemon.summary()["links"]
        assert stats["vehicles0"]["received"] == 900 and stats["vehicles1"]["dropped"] == 0
        assert link_lines(stats, only_trouble=True) == [
            "link vehicles0: received 900, dropped 150, bad 0, foreign 2"
        ]
        assert len(link_lines(stats)) == 2
        table = status_text(daemon)
        assert "link vehicles0: received 900, dropped 150, bad 0, foreign 2" in table
        assert "link vehicles1: received 0, dropped 0" in table

    asyncio.run(main())
