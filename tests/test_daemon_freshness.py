"""End-to-end (issue 28, "fresh telemetry only"): ``gcs run`` against ``gcs sitl`` vehicles
on loopback TCP, ephemeral ports.

* A 5 s flood of valid frames (``sitl.flood_proxy --mix flood``, from the autopilot's own
  ids: they count as heard but carry no position) on vehicle 1's link holds its real
  telemetry back behind the flood (5 s of wall time hold it back by 37-47 mission s at
  5x; 10 s, as before, by 46-47, for 7-9 CPU-s more). floe must warn
  (``telemetry_lagging``), give the core a prediction instead of a stale fix, and plan from
  fresh fixes once the flood has passed.
  The truth of each fix's age is measured by the test itself from the tlog: its receive
  time against the vehicle's ``time_boot_ms``, relative to the least lateness before the
  flood.
* A vehicle whose autopilot dies while its link stays up (a radio bridge: the link keeps
  delivering the radio's unsigned RADIO_STATUS, with the vehicle's system id and with the
  SiK radio's 51/68) is declared lost on time.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import sys
from pathlib import Path
from typing import Any

import pytest
from daemon_run import events, start_helper, status_text, stop_when

from groundstation.commands.run import build_config, run_daemon
from groundstation.daemon.daemon import Daemon
from groundstation.daemon.journal import read_journal
from groundstation.link.tlog import TlogReader
from groundstation.mavlink.codec import MavlinkEncoder, mavlink2

M = mavlink2
SPEEDUP = 5.0
LAG_S = 2.0




def _sitl(count: int) -> tuple[Any, list[int]]:
    gcs = str(Path(sys.executable).parent / "gcs")
    sim, lines = start_helper(
        [gcs, "sitl", "--count", str(count), "--base-port", "0", "--scenario", "default",
         "--airborne", "--speedup", f"{SPEEDUP:g}", "--detections", "none",
         "--duration", "5000"],
        "system id", count, 30.0,
    )  # fmt: skip
    ports = [int(x.rsplit(":", 1)[1]) for x in lines if "system id" in x]
    assert len(ports) == count, lines
    return sim, ports


def _stop(proc: Any, wait_s: float = 20.0) -> str:
    """End a helper: close its stdin (the flood proxy then prints its count and exits),
    kill it if it has not ended after ``wait_s`` (``gcs sitl`` runs to its duration)."""
    out = ""
    with contextlib.suppress(Exception):
        out, _ = proc.communicate(input="", timeout=wait_s)
    if proc.poll() is None:
        proc.kill()
        proc.wait(timeout=10)
    return out or ""


def _config(tmp_path: Path, vehicles: list[str], *extra: str) -> Any:
    return build_config(
        ["--vehicles", *vehicles, "--scenario", "default", "--speedup", f"{SPEEDUP:g}",
         "--run-dir", str(tmp_path), "--http", "off", "--detections", "off",
         "--status", "quiet", *extra]
    )  # fmt: skip


def _fix_lateness(
    run_dir: Path, origin: Any, flood_start_unix: float
) -> dict[tuple[float, float], float]:
    """Per fix of vehicle 1 (local x, y rounded to mm): how late it reached floe, in
    mission s: its tlog receive time against its ``time_boot_ms``, less the least lateness
    of its fixes before the flood."""
    rows = []
    for rec in TlogReader(run_dir / "flight.tlog"):
        m = rec.message
        if (m.get_type() == "GLOBAL_POSITION_INT" and m.get_srcSystem() == 1
                and m.get_srcComponent() == 1 and (m.lat or m.lon)):
            x, y, _ = origin.to_local(m.lat * 1e-7, m.lon * 1e-7)
            rows.append((rec.t_unix_s - m.time_boot_ms / 1000.0 / SPEEDUP, x, y, rec.t_unix_s))
    base = min(late for late, _, _, t in rows if t < flood_start_unix)
    out: dict[tuple[float, float], float] = {}
    for late, x, y, _ in rows:
        key = (round(x, 3), round(y, 3))
        out[key] = max(out.get(key, 0.0), (late - base) * SPEEDUP)
    return out


@pytest.mark.timeout(180)
def test_flood_backlog_is_drained_without_being_believed(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    sim, ports = _sitl(2)
    proxy, plines = start_helper(
        [sys.executable, "-m", "sitl.flood_proxy", "--upstream", str(ports[0]),
         "--rate", "100000", "--at", "6", "--for", "5", "--sysid", "1", "--compid", "1",
         "--mix", "flood"],
        "listening", 1, 30.0,
    )  # fmt: skip
    flood_rx: list[float] = []  # mission times floe received flood frames at
    shown: list[Any] = []  # while it lagged: the status table, the API's prediction

    def watch(daemon: Daemon) -> None:
        deliver = daemon.router.on_vehicle_frame
        assert deliver is not None

        def recording(rx: Any) -> None:
            if rx.message.get_type() == "DEBUG_VECT":  # first and last
                flood_rx[min(len(flood_rx), 1):] = [daemon.clock.now_s()]
            deliver(rx)

        daemon.router.on_vehicle_frame = recording

        def done(journal: list[dict[str, Any]]) -> bool:  # fresh again, then 20 s more
            session = daemon.sessions.get(1)
            if not shown and session is not None and session.lagging:
                # the first look while it lags that has its prediction (the flag and the
                # prediction are set on the same step, which can fall between two looks)
                prediction = session.prediction()
                if prediction is not None:
                    shown.extend([status_text(daemon), prediction])
            fresh = [e for e in journal if e["event"] == "telemetry_fresh"]
            return bool(fresh) and len(flood_rx) == 2 and daemon.clock.now_s() > max(
                fresh[-1]["t"], flood_rx[-1]) + 20.0

        asyncio.get_running_loop().create_task(stop_when(daemon, done))

    try:
        config = _config(tmp_path, [f"tcp:127.0.0.1:{plines[-1].split()[1]}",
                                    f"tcp:127.0.0.1:{ports[1]}"], "--duration", "600")
        with caplog.at_level(logging.WARNING):
            daemon = asyncio.run(asyncio.wait_for(
                run_daemon(config, print_fn=lambda _: None, install_signals=False,
                           on_started=watch), 150.0))
    finally:
        out = _stop(proxy)
        _stop(sim, 0.5)
    flood = [x for x in out.splitlines() if x.startswith("flood")]
    assert flood, out
    start_unix = float(flood[-1].split()[3])
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    assert not events(journal, "task_error")
    assert len(flood_rx) == 2, "the flood never reached floe"
    first_flood_s, last_flood_s = flood_rx
    # the warning while it lasts: journal and console, one line when it starts, one at the end
    lagging = events(journal, "telemetry_lagging", vehicle="1")
    fresh = events(journal, "telemetry_fresh", vehicle="1")
    assert lagging and first_flood_s < lagging[0]["t"] < last_flood_s, (lagging, flood_rx)
    assert fresh and fresh[-1]["t"] > lagging[-1]["t"]
    assert fresh[-1]["worst_age_s"] > 10.0  # the flood really held its telemetry back
    console = [r.getMessage() for r in caplog.records]
    assert len([x for x in console if "vehicle 1: telemetry lagging" in x]) == len(lagging)
    assert len([x for x in console if "vehicle 1: telemetry fresh again" in x]) == len(fresh)
    assert not events(journal, "telemetry_lagging", vehicle="2")
    assert shown, "no look at the lagging vehicle found its prediction"
    table, prediction = shown
    assert [line for line in table.splitlines() if " lag " in line], table  # its link column
    assert prediction is not None and prediction["sigma_m"] > 0
    # what the core planned vehicle 1 from: never a stale fix; a prediction while it lagged
    poses = [e for e in journal if e["event"] == "input" and e["kind"] == "Telemetry"
             and e["vehicle"] == "1"]  # fmt: skip
    lateness = _fix_lateness(daemon.run_dir, daemon.origin, start_unix)
    fixes = [(e["t"], lateness.get((round(e["x_m"], 3), round(e["y_m"], 3))))
             for e in poses if "fix_age_s" not in e]  # fmt: skip
    assert fixes and all(late is not None for _, late in fixes)
    stale = [(t, late) for t, late in fixes if late is not None and late > LAG_S + 0.5]
    assert not stale, f"stale fixes given to the core as current: {stale[:5]}"
    predicted = [e for e in poses if "fix_age_s" in e]
    assert predicted and max(e["fix_age_s"] for e in predicted) > 10.0
    assert all(e["sigma_m"] > 0 for e in predicted)
    assert all(lagging[0]["t"] - 1.0 <= e["t"] <= fresh[-1]["t"] + 1.0 for e in predicted)
    # once the flood has passed (its last frame, then the vehicle's own frames held back
    # behind it, reached floe): planned from fresh fixes again
    assert fresh[-1]["t"] > last_flood_s, (fresh, flood_rx)
    after = [e for e in poses if e["t"] > fresh[-1]["t"]]
    assert after and all("fix_age_s" not in e for e in after)
    print(f"flood reached floe {first_flood_s:.1f}-{last_flood_s:.1f} mission s; lagging "
          f"{lagging[0]['t']:.1f}-{fresh[-1]['t']:.1f} (worst {fresh[-1]['worst_age_s']} s); "
          f"{len(predicted)} predicted poses; {len(fixes)} fixes, worst "
          f"{max(late for _, late in fixes if late is not None):.2f} s late")


# ------------------------------------------------------------------ radio keeps-alive
def _radio_status(encoder: MavlinkEncoder) -> bytes:
    return encoder.encode(M.MAVLink_radio_status_message(180, 170, 90, 40, 35, 0, 0))


def _radio(encoder: MavlinkEncoder) -> bytes:
    return encoder.encode(M.MAVLink_radio_message(180, 170, 90, 40, 35, 0, 0))


class _RadioBridge:
    """A TCP bridge in front of one vehicle, as a radio is: it relays the vehicle's bytes
    to floe and floe's to the vehicle; when the vehicle's side closes (the autopilot died)
    it keeps floe's connection and goes on sending the radio's unsigned reports, with the
    vehicle's ids and with the SiK radio's (51/68), every 0.2 s."""

    def __init__(self, upstream: int, clock: Any) -> None:
        self.upstream = upstream
        self.clock = clock  # the daemon's, once it runs (the mission time the vehicle died)
        self.died_s: float | None = None
        self.reports = 0
        self.port = 0

    async def start(self) -> asyncio.Server:
        server = await asyncio.start_server(self._client, "127.0.0.1", 0)
        self.port = server.sockets[0].getsockname()[1]
        return server

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        up_r, up_w = await asyncio.open_connection("127.0.0.1", self.upstream)

        async def down() -> None:
            with contextlib.suppress(OSError, ConnectionError):
                while data := await up_r.read(65536):
                    writer.write(data)
            self.died_s = self.clock() if self.clock is not None else None
            own, sik = MavlinkEncoder(1, 1), MavlinkEncoder(51, 68)
            while not writer.is_closing():
                writer.write(_radio_status(own) + _radio(own) + _radio_status(sik))
                self.reports += 3
                await asyncio.sleep(0.2)

        async def up() -> None:
            with contextlib.suppress(OSError, ConnectionError):
                while data := await reader.read(65536):
                    if not up_w.is_closing():
                        up_w.write(data)

        await asyncio.gather(down(), up())


@pytest.mark.timeout(120)
@pytest.mark.parametrize("signed", [False, True], ids=["unsigned", "signing"])
def test_radio_reports_keep_no_dead_vehicle_alive(tmp_path: Path, signed: bool) -> None:
    """With signing on too: the unsigned radio reports are let through (a SiK radio cannot
    sign), and still keep nothing alive."""
    t_kill = 40.0
    gcs = str(Path(sys.executable).parent / "gcs")
    phrase = tmp_path / "phrase"
    phrase.write_text("radio test passphrase\n")
    signing = ["--signing-passphrase-file", str(phrase)] if signed else []
    sim, lines = start_helper(
        [gcs, "sitl", "--count", "2", "--base-port", "0", "--scenario", "default",
         "--airborne", "--speedup", f"{SPEEDUP:g}", "--detections", "none",
         "--duration", "5000", "--fault", f"1:kill:at={t_kill:g},for=1000", *signing],
        "system id", 2, 30.0,
    )  # fmt: skip
    ports = [int(x.rsplit(":", 1)[1]) for x in lines if "system id" in x]
    assert len(ports) == 2, lines

    async def main() -> tuple[Daemon, _RadioBridge]:
        bridge = _RadioBridge(ports[0], None)
        server = await bridge.start()
        config = _config(tmp_path, [f"tcp:127.0.0.1:{bridge.port}",
                                    f"tcp:127.0.0.1:{ports[1]}"], "--duration", "400", *signing)

        def started(daemon: Daemon) -> None:
            bridge.clock = daemon.clock.now_s

            def done(journal: list[dict[str, Any]]) -> bool:
                died = bridge.died_s
                return died is not None and daemon.clock.now_s() > died + 20.0

            asyncio.get_running_loop().create_task(stop_when(daemon, done))

        try:
            daemon = await run_daemon(config, print_fn=lambda _: None, install_signals=False,
                                      on_started=started)
        finally:
            server.close()
        return daemon, bridge

    try:
        daemon, bridge = asyncio.run(asyncio.wait_for(main(), 100.0))
    finally:
        _stop(sim, 0.5)
    journal = read_journal(daemon.run_dir / "journal.jsonl")
    assert not events(journal, "task_error")
    assert bridge.died_s is not None and bridge.reports >= 30
    lost = events(journal, "link_lost", vehicle="1")
    # the usual bound: silent lost_after_s (5), checked on the daemon's ticks
    assert lost and 0.0 < lost[0]["t"] - bridge.died_s <= 5.0 + 1.5, (lost, bridge.died_s)
    print(f"link_lost {lost[0]['t'] - bridge.died_s:.2f} mission s after the autopilot died "
          f"({bridge.reports} radio reports since; signing {'on' if signed else 'off'})")
    assert not events(journal, "link_restored", vehicle="1")
    assert not events(journal, "link_lost", vehicle="2")
    # the radio's reports are the link's, never a vehicle's: kept, bound to nothing
    link = daemon.router.vehicle_links[0]
    assert link.counters.radio_frames >= bridge.reports - 10
    assert link.radio is not None and link.radio.rssi == 180
    assert 51 not in daemon.router.routes and 51 not in daemon.sessions
    if signed:  # the vehicles really spoke signed, and the radio's reports passed unsigned
        assert daemon.signing is not None
        assert events(journal, "vehicle_seen", system_id=1)
