"""The ground station's wind from the vehicles' own WIND messages: parsing and evidence in
the telemetry reducer, forwarding by the vehicle controller, the core's robust estimate,
and journal + replay of a run with wind reports."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from test_vehicle_controller import Rig, active_rig

from domain.geodesy import GeoOrigin
from domain.wind_triangle import wind_from_vector, wind_vector_m_s
from groundstation.cli import main
from groundstation.core import events as ev
from groundstation.core.commands import Note, SolveRequest, WindEstimate
from groundstation.core.config import CoreConfig, ReplanPolicy, config_from_dict, config_to_dict
from groundstation.core.decision import DecisionCore
from groundstation.core.records import command_to_record, event_to_record, record_to_event
from groundstation.mavlink.codec import MavlinkDecoder, MavlinkEncoder, MAVLinkMessage, mavlink2
from groundstation.mavlink.evidence import WindEvidence
from groundstation.mavlink.telemetry import (
    InvalidTelemetry,
    VehicleTelemetry,
    WindReported,
)
from groundstation.vehicle import controller_io as vio
from planner import solve_plan

M = mavlink2
ORIGIN = GeoOrigin(78.9, 11.9, 0.0)


def wire(msg: MAVLinkMessage) -> MAVLinkMessage:
    out = MavlinkDecoder().feed(MavlinkEncoder(1, 1).encode(msg))
    assert len(out) == 1
    return out[0]


def wind_msg(direction: float, speed: float, speed_z: float = 0.0) -> MAVLinkMessage:
    return wire(M.MAVLink_wind_message(direction, speed, speed_z))


def reported(events: list[Any]) -> list[WindReported]:
    return [e for e in events if isinstance(e, WindReported)]


# ------------------------------------------------------------------ the reducer
def test_arduplane_wind_is_parsed_after_evidence_as_the_enu_towards_vector() -> None:
    """ArduPlane's direction is atan2 in [-180, 180] (-90: from the west) and its speed the
    3-D length; 10 m/s from the west blows towards +x (east)."""
    tel = VehicleTelemetry(1, ORIGIN)
    speed_3d = math.hypot(10.0, 1.0)  # 10 m/s horizontal, 1 m/s vertical
    first = tel.receive(wind_msg(-90.0, speed_3d, 1.0), 0.0)
    second = tel.receive(wind_msg(-90.0, speed_3d, 1.0), 1.0)
    assert reported(first + second) == [] and tel.snapshot().wind_xy_m_s is None
    third = reported(tel.receive(wind_msg(-90.0, speed_3d, 1.0), 2.0))
    assert len(third) == 1
    assert third[0].wx_m_s == pytest.approx(10.0, abs=1e-4)
    assert third[0].wy_m_s == pytest.approx(0.0, abs=1e-4)
    assert third[0].speed_z_m_s == pytest.approx(1.0)
    assert tel.snapshot().wind_xy_m_s == (third[0].wx_m_s, third[0].wy_m_s)
    # a wind vane's wrap_360 spelling of the same direction reads the same
    vane = VehicleTelemetry(1, ORIGIN)
    out = [e for t in range(3) for e in vane.receive(wind_msg(270.0, 10.0), float(t))]
    assert reported(out)[0].wx_m_s == pytest.approx(10.0, abs=1e-4)
    # 8 m/s from the north-east (45): the air moves south-west
    ne = VehicleTelemetry(1, ORIGIN)
    last = [e for t in range(3) for e in ne.receive(wind_msg(45.0, 8.0), float(t))][-1]
    assert isinstance(last, WindReported)
    assert wind_from_vector(last.wx_m_s, last.wy_m_s) == pytest.approx((8.0, 45.0), abs=1e-4)


@pytest.mark.parametrize(
    ("direction", "speed", "speed_z", "field"),
    [
        (math.nan, 10.0, 0.0, "direction"),
        (90.0, math.inf, 0.0, "speed"),
        (90.0, 61.0, 0.0, "speed"),
        (90.0, -1.0, 0.0, "speed"),
        (400.0, 10.0, 0.0, "direction"),
        (-181.0, 10.0, 0.0, "direction"),
        (90.0, 10.0, math.nan, "speed_z"),
    ],
)
def test_bad_wind_is_counted_and_dropped(
    direction: float, speed: float, speed_z: float, field: str
) -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    for t in range(3):
        tel.receive(wind_msg(270.0, 5.0), float(t))
    before = tel.snapshot().wind_xy_m_s
    events = tel.receive(wind_msg(direction, speed, speed_z), 3.0)
    assert [(e.message, e.field) for e in events if isinstance(e, InvalidTelemetry)] == [
        ("WIND", field)
    ]
    assert reported(events) == [] and tel.bad_wind == 1
    assert tel.snapshot().wind_xy_m_s == before


def test_one_stray_frame_never_moves_the_vehicles_wind() -> None:
    tel = VehicleTelemetry(1, ORIGIN)
    accepted = []
    for t, (direction, speed) in enumerate([(270, 10)] * 4 + [(90, 40)] + [(270, 10)] * 3):
        accepted += reported(tel.receive(wind_msg(direction, speed), float(t)))
    assert accepted and all(e.wx_m_s == pytest.approx(10.0, abs=1e-4) for e in accepted)


def test_wind_evidence_starts_again_after_a_silence_and_a_reboot() -> None:
    evidence = WindEvidence()
    assert [evidence.observe(1.0, 0.0, t) for t in (0.0, 1.0)] == [None, None]
    assert evidence.observe(1.0, 0.0, 2.0) == (1.0, 0.0)
    assert evidence.observe(2.0, 0.0, 9.0) is None  # 7 s of silence: evidence again
    tel = VehicleTelemetry(1, ORIGIN)
    for t in range(3):
        tel.receive(wind_msg(270.0, 5.0), float(t))
    assert tel.snapshot().wind_xy_m_s is not None
    tel._rebooted(0, 3.0)  # the autopilot's wind estimate starts again, and so do we
    assert tel.snapshot().wind_xy_m_s is None
    assert reported(tel.receive(wind_msg(270.0, 5.0), 4.0)) == []


# ------------------------------------------------------------------ the controller
def _wind_frame(rig: Rig, wx: float, wy: float) -> list[vio.Output]:
    return rig.frame("WIND", WindReported(rig.t, wx, wy, 0.0), wind_xy_m_s=(wx, wy))


def test_an_active_vehicle_reports_its_wind_after_settling_at_most_1_hz() -> None:
    rig = active_rig(wind_settle_s=3.0)
    start = rig.t
    sent = []
    for _ in range(20):  # 4 Hz of accepted winds over 5 s
        rig.t = round(rig.t + 0.25, 6)
        sent += [o.event for o in _wind_frame(rig, 7.0, -1.0) if isinstance(o, vio.CoreEvent)]
    assert all(isinstance(e, ev.WindReport) and e.vehicle == "v1" for e in sent)
    assert sent[0].t_s == start + 0.25 + 3.0  # reporting (and active) for 3 s first
    assert len(sent) == 2 and sent[1].t_s - sent[0].t_s >= 0.8
    assert (sent[0].wx_m_s, sent[0].wy_m_s) == (7.0, -1.0)


def test_a_vehicle_not_in_the_plan_reports_no_wind() -> None:
    rig = Rig()  # still connecting: never assessed
    rig.t = 1.0
    assert not [o for o in _wind_frame(rig, 7.0, 0.0) if isinstance(o, vio.CoreEvent)]


# ------------------------------------------------------------------ the core
def _core(fallback: tuple[float, float] = (0.0, -3.0), vehicles: str = "123",
          **config: Any) -> DecisionCore:
    core = DecisionCore(CoreConfig(wind_xy_m_s=fallback, **config))
    for v in vehicles:
        core.handle(ev.VehicleJoined(0.0, v, 0.0, 0.0, 0.0, 22.0))
    return core


def _second(core: DecisionCore, t: float, reports: dict[str, tuple[float, float]]) -> list[Any]:
    out: list[Any] = []
    for vehicle, (wx, wy) in reports.items():
        out += core.handle(ev.WindReport(t, vehicle, wx, wy))
    out += core.handle(ev.Tick(t + 0.5))
    return out


@pytest.mark.parametrize("bad", [(40.0, 0.0), (-25.0, 31.0), (math.nan, 1.0), (1e6, 0.0)])
def test_one_bad_vehicle_does_not_move_the_fleets_estimate(bad: tuple[float, float]) -> None:
    core = _core()
    true = wind_vector_m_s(10.0, 270.0)
    notes = []
    for t in range(40):
        wobble = 0.3 * math.sin(t)
        out = _second(core, float(t), {"1": (true[0] + wobble, true[1]),
                                       "2": (true[0], true[1] - wobble), "3": bad})
        notes += [c for c in out if isinstance(c, Note) and c.kind == "wind_outlier"]
        # inside the box the good reports span (the median's breakdown point)
        wx, wy = core.planning_wind_m_s()
        assert abs(wx - true[0]) <= 0.3 and abs(wy - true[1]) <= 0.3
    assert core.wind_state.source == "vehicles"
    if all(math.isfinite(v) and abs(v) < 60 for v in bad):
        assert [(n.vehicle, n.t_s) for n in notes] == [("3", 10.0)]  # flagged once, after 10 s
        assert core.wind.flagged == {"3"}
    else:
        assert notes == [] and core.wind.rejected == 40  # garbage never even counts


def test_silence_falls_back_to_the_configured_wind_after_the_age_limit() -> None:
    core = _core(fallback=(0.0, -3.0))
    assert core.planning_wind_m_s() == (0.0, -3.0)
    lines = []
    for t in range(5):
        lines += [c for c in _second(core, float(t), {"1": (10.0, 0.0), "2": (10.4, 0.2)})
                  if isinstance(c, WindEstimate)]
    assert [(c.source, c.vehicles) for c in lines] == [("vehicles", ("1",))]
    assert core.planning_wind_m_s() == pytest.approx((10.2, 0.1))
    for k in range(1, 40):  # the reports stop
        t = 4.5 + k
        lines += [c for c in core.handle(ev.Tick(t)) if isinstance(c, WindEstimate)]
        assert core.wind_state.source == ("vehicles" if t - 4.0 <= 30.0 else "fallback")
    assert [(c.t_s, c.source) for c in lines[1:]] == [(34.5, "fallback")]
    assert core.planning_wind_m_s() == (0.0, -3.0)


def test_two_disagreeing_vehicles_keep_the_estimate_they_agreed_on() -> None:
    core = _core(vehicles="12")
    for t in range(5):
        _second(core, float(t), {"1": (10.0, 0.0), "2": (10.5, 0.0)})
    assert core.planning_wind_m_s() == pytest.approx((10.25, 0.0))
    for t in range(5, 30):  # vehicle 2's estimate runs away
        _second(core, float(t), {"1": (10.0, 0.0), "2": (30.0, 0.0)})
        if t >= 6:  # its 20 s mean is now > 5 m/s off: vehicle 1 agrees with the anchor
            assert core.planning_wind_m_s() == (10.0, 0.0)
            assert core.wind_state.vehicles == ("1",)
    # before any agreement the fallback (the operator's wind) decides which one to trust,
    # also when one of them reported alone first
    fresh = _core(fallback=(0.0, 12.0), vehicles="12")
    _second(fresh, 0.0, {"1": (0.0, 0.0)})
    assert fresh.planning_wind_m_s() == (0.0, 0.0)
    _second(fresh, 1.0, {"1": (0.0, 0.0), "2": (0.0, 11.0)})
    assert fresh.planning_wind_m_s() == (0.0, 11.0)


def test_only_active_vehicles_count_and_small_changes_are_not_journalled() -> None:
    core = _core()
    _second(core, 0.0, {"1": (10.0, 0.0), "2": (10.0, 0.0), "3": (10.0, 0.0)})
    core.handle(ev.VehicleLost(1.0, "3"))
    out = _second(core, 1.0, {"3": (-20.0, 0.0)})  # a lost vehicle's report
    assert core.planning_wind_m_s() == (10.0, 0.0) and core.wind_state.vehicles == ("1", "2")
    assert not [c for c in out if isinstance(c, WindEstimate)]
    out = _second(core, 2.0, {"1": (10.6, 0.5), "2": (10.6, 0.5)})  # 0.6 m/s, 2.7 deg
    assert not [c for c in out if isinstance(c, WindEstimate)]
    lines = []
    for t in range(3, 30):  # the wind veers 28 deg: the 20 s means follow
        lines += [(t, c) for c in _second(core, float(t), {"1": (8.7, -4.6), "2": (8.7, -4.6)})
                  if isinstance(c, WindEstimate)]
    assert [(c.vehicles, c.source) for _t, c in lines][:1] == [(("1", "2"), "vehicles")]
    assert 3 < lines[0][0] < 23 and core.planning_wind_m_s() == pytest.approx((8.7, -4.6))


def test_wind_blind_core_plans_in_still_air_but_still_estimates() -> None:
    core = _core(fallback=(0.0, -3.0), wind_aware=False)
    _second(core, 0.0, {"1": (10.0, 0.0)})
    assert core.planning_wind_m_s() == (0.0, 0.0)
    assert core.wind_state.xy_m_s == (10.0, 0.0)


def test_records_round_trip_exactly_and_old_configs_still_load() -> None:
    report = ev.WindReport(12.3, "2", 0.1 + 0.2, -7.123456789012345)
    assert record_to_event(json.loads(json.dumps(event_to_record(report)))) == report
    line = command_to_record(WindEstimate(5.0, -10.0, 0.0, "vehicles", ("1", "2")))
    assert line == {"event": "wind", "t": 5.0, "speed_m_s": 10.0, "from_deg": 90.0,
                    "wx_m_s": -10.0, "wy_m_s": 0.0, "source": "vehicles",
                    "vehicles": ["1", "2"]}
    data = json.loads(json.dumps(config_to_dict(CoreConfig(wind_xy_m_s=(1.5, -2.0)))))
    assert config_from_dict(data).wind_xy_m_s == (1.5, -2.0)
    old = {k: v for k, v in data.items() if k not in ("wind_xy_m_s", "wind_aware")}
    assert config_from_dict(old) == CoreConfig()
    for bad in ([1.0, math.nan], "ab", [1.0]):
        with pytest.raises(ValueError, match="wind_xy_m_s must be two finite numbers"):
            config_from_dict({**data, "wind_xy_m_s": bad})


# ------------------------------------------------------------------ journal and replay
def _record_run(run: Path, config: CoreConfig, wind: bool) -> list[dict[str, Any]]:
    """A small frontend: three vehicles circling, three targets, 1 Hz wind reports (vehicle
    3 a steady outlier), 10 Hz ticks, plans solved inline; journalled as gcs simulate does."""
    records: list[dict[str, Any]] = [{"event": "start", "t": 0.0, "frontend": "test",
                                      "core_config": config_to_dict(config)}]
    core = DecisionCore(config)
    core.on_input = lambda event: records.append(event_to_record(event))

    def feed(event: ev.Event) -> None:
        pending = core.handle(event)
        while pending:
            command = pending.pop(0)
            records.append(command_to_record(command))
            if isinstance(command, SolveRequest):
                result = solve_plan(command.problem, command.hint, num_workers=1,
                                    random_seed=0, deterministic=True)
                pending += core.handle(ev.PlanSolved(command.t_s, command.request_id, result))

    for k, (x, y) in enumerate([(800.0, 300.0), (-600.0, 900.0), (1200.0, -700.0)]):
        feed(ev.TargetAdded(0.0, "ABC"[k], x, y, 0.2, -0.1))
    for v in "123":
        feed(ev.VehicleJoined(0.0, v, 0.0, 0.0, 0.0, 22.0))
    for step in range(600):
        t = step / 10.0
        for n, v in enumerate("123"):
            a = 0.05 * t + n * 2.0
            feed(ev.Telemetry(t, v, 300.0 * math.cos(a), 300.0 * math.sin(a), a + 1.57, 22.0))
        if wind and step % 10 == 3:
            gust = 0.7 * math.sin(0.3 * t)
            reports = {"1": (9.0 + gust, 1.0), "2": (9.5, 1.0 - gust), "3": (35.0, 0.0)}
            if t > 25.0:  # the wind veers: vehicles 1 and 2 agree on 12 m/s from the north
                reports.update({"1": (0.0, -12.0), "2": (0.3, -12.2)})
            for v, w in reports.items():
                feed(ev.WindReport(t, v, *w))
        if step == 450:
            feed(ev.LoiterEnded(t, "1"))
        feed(ev.Tick(t))
    run.mkdir()
    (run / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return records


def _replay(run: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, dict[str, Any]]:
    code = main(["replay", str(run), "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_a_run_with_wind_reports_replays_identical_and_a_changed_report_shows(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = CoreConfig(policy=ReplanPolicy(on_events=True, period_s=5.0, commit=False),
                        wind_xy_m_s=(0.0, -4.0), time_limit_s=1.0)
    run = tmp_path / "windy"
    records = _record_run(run, config, wind=True)
    winds = [r for r in records if r["event"] == "wind"]
    assert [w["source"] for w in winds][:1] == ["vehicles"] and len(winds) >= 2
    turn = (winds[-1]["from_deg"] + 180.0) % 360.0 - 180.0  # from the north: near 0 or 360
    assert abs(turn) < 2.0 and winds[-1]["t"] > 30
    assert [r["vehicle"] for r in records if r["event"] == "wind_outlier"] == ["3"]
    code, report = _replay(run, capsys)
    assert code == 0 and report["identical"] is True and report["differences"] == []
    assert report["inputs"] == sum(r["event"] == "input" for r in records)
    assert report["solves"] >= 10 and report["problems_equal"] == report["solves"]
    # one vehicle's report changed in the journal: replay names the wind decision
    edited = [dict(r) for r in records]
    first = next(r for r in edited if r.get("kind") == "WindReport" and r["vehicle"] == "1")
    first["wx_m_s"] = -20.0
    (run / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in edited))
    code, report = _replay(run, capsys)
    assert code == 1 and report["identical"] is False
    assert "wind" in {d["kind"] for d in report["differences"]}


def test_a_calm_journal_without_the_wind_settings_replays_identical(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A journal written before wind existed: no wind keys in its core config, no
    WindReport inputs, no wind lines."""
    run = tmp_path / "calm"
    records = _record_run(run, CoreConfig(time_limit_s=1.0), wind=False)
    assert not [r for r in records if r["event"] in ("wind", "wind_outlier")]
    del records[0]["core_config"]["wind_xy_m_s"], records[0]["core_config"]["wind_aware"]
    (run / "journal.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    code, report = _replay(run, capsys)
    assert code == 0 and report["identical"] is True and report["solves"] >= 1
