"""The daemon's configuration (nested, frozen, typed; one pure parser; defaults resolved by
a pure function; config.yaml round-trips), ``gcs sitl``'s frozen options, and the one
fault-spec builder."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import yaml

from domain.errors import UsageError
from domain.geodesy import GeoOrigin
from groundstation.commands import sitl as sitl_command
from groundstation.commands.run import _parser, build_config
from groundstation.daemon.clock import MissionClock
from groundstation.daemon.config import (
    BatteryAction,
    ConfigError,
    DaemonConfig,
    Endpoint,
    Objective,
    OnExit,
    OperatingCenter,
    ReplanTrigger,
    StatusMode,
    resolve,
)
from groundstation.daemon.config_parse import ALIASES, FLAGS, parse_config
from groundstation.daemon.run_files import open_run_files
from sitl.faults import build_faults, fault_spec, fault_specs, parse_fault_spec
from sitl.sitl_setup import scenario_setup
from world.scenario import load_scenario

BUSY_ARGV = [
    "--vehicles", "sim:3", "--speedup", "20", "--duration", "123.5", "--origin", "70.25,19.125",
    "--lost-after", "7", "--on-exit", "rtl", "--status", "quiet", "--http", "off",
    "--detections", "127.0.0.1:0", "--http-allow-origin", "https://ops.example",
    "--replan", "both", "--period", "5", "--no-commit", "--objective", "arrival",
    "--sim-fault", "2:drop:at=60,for=30", "--sim-loss", "0.1", "--scenario", "none",
    "--loiter", "0", "--altitude", "120.5",
]  # fmt: skip
BUSY_YAML = """
fleet:
  battery: {low_pct: 30, action: release}
  settings:
    1: {name: alpha, altitude_m: 150}
    2: {name: bravo, loiter_radius_m: 90}
mission: {operating_center: boat, operating_radius_m: null, seed: 7}
planner: {num_workers: 2, time_limit_s: 1.5}
records: {journal: null}
"""


def _write(path: Path, text: str) -> str:
    path.write_text(text, encoding="utf-8")
    return str(path)


def test_nested_typed_and_frozen(tmp_path: Path) -> None:
    config = build_config(["--config", _write(tmp_path / "c.yaml", BUSY_YAML), *BUSY_ARGV])
    assert config.links.vehicles == ("sim:3",) and config.sim_count == 3
    assert config.mission.origin == GeoOrigin(70.25, 19.125)
    assert config.mission.duration_s == 123.5 and config.mission.operating_radius_m is None
    assert config.mission.operating_center is OperatingCenter.BOAT
    assert config.mission.scenario == "none" and config.mission.scenario_to_load is None
    assert config.fleet.lost_after_s == 7.0 and config.fleet.altitude_m == 120.5
    assert config.fleet.battery.action is BatteryAction.RELEASE
    assert config.fleet.battery.low_pct == 30.0
    assert config.planner.objective is Objective.ARRIVAL
    assert config.planner.replan is ReplanTrigger.BOTH and config.planner.commit is False
    assert config.on_exit is OnExit.RTL and config.status is StatusMode.QUIET
    assert config.http.bind is None and config.detections == Endpoint("127.0.0.1", 0)
    assert config.http.allow_origins == ("https://ops.example",)
    assert config.sim.faults == ("2:drop:at=60,for=30",) and config.sim.loss == 0.1
    assert config.settings_for(1).name == "alpha" and config.settings_for(3).name is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.fleet.lost_after_s = 1.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        config.fleet.settings[3] = config.settings_for(1)  # type: ignore[index]


def test_config_yaml_loads_back_to_the_same_config(tmp_path: Path) -> None:
    """What the run folder's config.yaml holds (written by the daemon's own writer) gives
    the same configuration with ``gcs run --config``; so does the start line's JSON."""
    config = build_config(
        ["--config", _write(tmp_path / "c.yaml", BUSY_YAML), *BUSY_ARGV,
         "--run-dir", str(tmp_path / "runs")]
    )  # fmt: skip
    files = open_run_files(config, MissionClock(1.0, source=lambda: 0.0))
    try:
        written = files.run_dir / "config.yaml"
        assert build_config(["--config", str(written)]) == config
        start_line = json.loads(json.dumps(files.effective))  # settings keys become strings
        assert resolve(parse_config(start_line, {})) == config
    finally:
        files.close()
    plain = build_config(["--vehicles", "tcp:127.0.0.1:5760"])
    assert build_config(["--config", _write(tmp_path / "p.yaml", yaml.safe_dump(
        plain.to_dict()))]) == plain


def test_flat_keys_are_aliases_of_the_nested_ones() -> None:
    flat = parse_config({
        "vehicles": ["sim:2"], "lost_after_s": 9, "battery_low_pct": 40,
        "battery_low_action": "release", "http": "127.0.0.1:8080",
        "http_max_targets": 7, "sim_fault": "1:reboot:at=3", "duration": 50,
        "solver_time_limit_s": 0.5, "vehicle_settings": {1: {"name": "x"}},
        "signing_setup": False, "run_dir": "elsewhere",
    }, {})  # fmt: skip
    nested = parse_config({
        "links": {"vehicles": ["sim:2"]},
        "fleet": {"lost_after_s": 9, "battery": {"low_pct": 40, "action": "release"},
                  "settings": {1: {"name": "x"}}},
        "http": {"bind": "127.0.0.1:8080", "max_targets": 7},
        "sim": {"faults": ["1:reboot:at=3"]}, "mission": {"duration_s": 50},
        "planner": {"time_limit_s": 0.5}, "signing": {"setup": False},
        "records": {"run_dir": "elsewhere"},
    }, {})  # fmt: skip
    assert flat == nested
    assert flat.http.bind == Endpoint("127.0.0.1", 8080)
    assert all(_has(path) for path in [*ALIASES.values(), *FLAGS.values()])
    parser_flags = {
        a.option_strings[0] for a in _parser()._actions if a.option_strings
    } - {"-h", "--config", "--no-launch", "--no-commit"}
    assert parser_flags == set(FLAGS), "every gcs run flag sets exactly one field"


def _has(path: str) -> bool:
    node: object = DaemonConfig()
    for part in path.split("."):
        if not hasattr(node, part):
            return False
        node = getattr(node, part)
    return True


@pytest.mark.parametrize(
    ("data", "flags", "start"),
    [
        ({"vehicles": ["sim:1"], "fleet": {"battery": {"colour": 1}}}, {},
         "fleet.battery.colour: unknown key"),
        ({"vehicles": ["sim:1"], "lost_after_s": 3, "fleet": {"lost_after_s": 4}}, {},
         "fleet.lost_after_s: given twice (also as lost_after_s)"),
        ({"vehicles": ["sim:1"], "fleet": 3}, {}, "fleet: expected a mapping"),
        ({"vehicles": ["sim:1"], "fleet": {"battery": {"action": "land"}}}, {},
         "fleet.battery.action: expected one of rtl, release, got 'land'"),
        ({"vehicles": ["sim:1"], "battery_low_action": "land"}, {}, "battery_low_action:"),
        ({"vehicles": ["sim:1"], "mission": {"origin": "91,0"}}, {}, "mission.origin:"),
        ({"vehicles": ["sim:1"]}, {"--lost-after": -1.0}, "--lost-after: expected a number > 0"),
        ({"vehicles": ["sim:1"]}, {"--status": "loud"}, "--status: expected one of"),
        ({"links": {"vehicles": []}}, {}, "links.vehicles: at least one"),
        ({"vehicles": ["sim:1"], "planner": {"replan": "period"}}, {},
         "planner.period_s: required when replan is period or both"),
        ({"vehicles": ["sim:1"], "replan": "period"}, {}, "planner.period_s: required"),
        ({"vehicles": ["sim:1"], "http": {"max_targets": 0}}, {}, "http.max_targets:"),
        ({"vehicles": ["sim:1"], "sim": {"faults": ["3:reboot:at=1"]}}, {}, "sim.faults:"),
        ({"vehicles": ["sim:1"], "speedup": True}, {}, "speedup: expected a number"),
        # the geofence is the area: too small to leave a loiter's room inside, or beyond
        # ArduPlane's uint16 metres
        ({"vehicles": ["sim:1"]}, {"--operating-radius": 600.0},
         "--operating-radius: expected 1000..65535 m"),
        ({"vehicles": ["sim:1"], "operating_radius_m": 70000}, {},
         "operating_radius_m: expected 1000..65535 m"),
    ],
)
def test_errors_name_the_field_as_the_user_spelt_it(
    data: dict[str, object], flags: dict[str, object], start: str
) -> None:
    with pytest.raises(ConfigError) as info:
        parse_config(data, flags)
    assert str(info.value).startswith(start), str(info.value)
    assert "\n" not in str(info.value)


def test_flags_win_and_parse_config_is_pure() -> None:
    data = {"fleet": {"lost_after_s": 4, "settings": {1: {"name": "a"}}}, "vehicles": ["sim:1"]}
    before = json.dumps(data, sort_keys=True)
    config = parse_config(data, {"--lost-after": 6.0, "--vehicles": ["sim:2"]})
    assert config.fleet.lost_after_s == 6.0 and config.links.vehicles == ("sim:2",)
    assert json.dumps(data, sort_keys=True) == before  # its input is not touched
    assert parse_config(data, {"--lost-after": 6.0, "--vehicles": ["sim:2"]}) == config


def test_defaults_resolved_by_a_pure_idempotent_function() -> None:
    raw = parse_config({"vehicles": ["sim:2"]}, {})
    assert raw.speedup is None and raw.fleet.launch is None and raw.mission.scenario is None
    done = resolve(raw)
    assert raw.speedup is None  # untouched
    assert done.speedup == 50.0 and done.fleet.launch is True
    assert done.mission.scenario == "default" and resolve(done) == done
    none = resolve(parse_config({"vehicles": ["sim:2"], "scenario": "none"}, {}))
    assert none.mission.scenario_to_load is None and resolve(none) == none
    airborne = resolve(parse_config({"vehicles": ["sim:2"], "sim_airborne": True}, {}))
    assert airborne.fleet.launch is False
    real = resolve(parse_config({"vehicles": ["udpin:127.0.0.1:0"]}, {}))
    assert real.speedup == 1.0 and real.fleet.launch is False
    assert real.mission.scenario_to_load is None


# ------------------------------------------------------------------ fault specs
def test_one_fault_spec_builder() -> None:
    spec = fault_spec(2, "drop", {"at": 60.0, "for": 30.5})
    assert spec == "2:drop:at=60.0,for=30.5"
    assert parse_fault_spec(spec, 3) == [(2, "drop", {"at": "60.0", "for": "30.5"})]
    assert fault_spec("all", "reboot") == "all:reboot"
    specs = fault_specs(["1:loss:p=0.5"], loss=0.25, dup=0.1, delay_s=0.2,
                        scripted=["3:reboot:at=9"])  # fmt: skip
    assert specs == ["1:loss:p=0.5", "all:loss:p=0.25", "all:dup:p=0.1", "all:delay:s=0.2",
                     "3:reboot:at=9"]  # fmt: skip
    faults = build_faults(specs, [1, 2, 3], seed=4)
    assert faults[1].down.loss == 0.25  # the later spec wins, as before
    assert faults[2].up.delay_s == 0.2 and [e.kind for e in faults[3].events] == ["reboot"]
    assert faults[1].rng.random() == build_faults(specs, [1, 2, 3], seed=4)[1].rng.random()
    with pytest.raises(ValueError, match="no vehicle with system id 3"):
        build_faults(["3:reboot:at=1"], [1, 2], seed=0)


def test_scenario_events_are_spelt_by_the_builder(tmp_path: Path) -> None:
    path = _write(tmp_path / "s.yaml", (
        "name: t\ndescription: t\nduration_s: 100\norigin: {lat_deg: 70.0, lon_deg: 20.0}\n"
        "fleet: {count: 2}\ntargets:\n  list:\n    - {id: A, x_m: 800, y_m: 300}\n"
        "events:\n  - {t_s: 30, kind: vehicle_lost, vehicle: '2'}\n"
        "  - {t_s: 50.5, kind: vehicle_returned, vehicle: '2'}\n"
        "  - {t_s: 60, kind: override, vehicle: '1'}\n"
        "  - {t_s: 70, kind: battery_low, vehicle: '1'}\n"))
    setup = scenario_setup(load_scenario(path), 2, (78.93, 11.92), False)
    assert setup.fault_specs == [  # the spelling the journal's sim_faults always had
        "2:drop:at=30.0,for=20.5", "1:mode:at=60.0,mode=FBWA", "1:battery:at=70.0,pct=10",
    ]


# ------------------------------------------------------------------ gcs sitl options
def test_gcs_sitl_options_are_checked_once_and_frozen() -> None:
    options = sitl_command.parse_options(
        ["--count", "2", "--delay-ms", "250", "--detections", "none", "--home", "70,20",
         "--out", "udp:127.0.0.1:14550", "--fault", "1:reboot:at=5", "--loss", "0"]
    )  # fmt: skip
    assert options.delay_s == 0.25 and options.detections is None
    assert options.home == (70.0, 20.0) and options.out == ("127.0.0.1", 14550)
    assert options.faults == ("1:reboot:at=5",) and options.loss == 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.count = 3  # type: ignore[misc]
    _, faults, feed, server = sitl_command.build(options)
    assert feed is None and server.feed_address is None
    assert faults[2].up.delay_s == 0.25 and [e.kind for e in faults[1].events] == ["reboot"]
    for argv, name in (
        (["--home", "x"], "--home"), (["--out", "nowhere"], "--out"),
        (["--camera-of", "a:b"], "--camera-of"), (["--loss", "2"], "--loss"),
        (["--ardupilot", "/x", "--signing-key", "k"], "--signing-*"),
    ):
        with pytest.raises(UsageError) as info:
            sitl_command.parse_options(argv)
        assert str(info.value).startswith(name)


# ------------------------------------------------------------------ enums below the daemon
def test_core_and_planner_closed_sets_are_enums_spelt_as_before() -> None:
    from groundstation.core.config import BatteryAction as CoreBattery
    from groundstation.core.config import CoreConfig, config_from_dict, config_to_dict
    from groundstation.core.records import RecordError, result_from_record
    from planner import Objective as PlannerObjective
    from planner import PlanStatus, problem_from_dict, problem_to_dict

    assert BatteryAction is CoreBattery and Objective is PlannerObjective  # one definition
    core = config_from_dict({"objective": "arrival", "battery_low_action": "release"})
    assert core.objective is Objective.ARRIVAL and core.battery_low_action is BatteryAction.RELEASE
    plain = config_to_dict(core)
    assert type(plain["objective"]) is str and plain["battery_low_action"] == "release"
    assert config_from_dict(json.loads(json.dumps(plain))) == core
    with pytest.raises(ValueError, match="objective"):
        CoreConfig(objective="fastest")  # type: ignore[arg-type]
    problem = problem_from_dict({"uavs": [{"id": "u", "x": 0, "y": 0, "heading": 0}],
                                 "targets": [], "turn_radius": 100, "objective": "arrival"})
    assert problem.objective is Objective.ARRIVAL
    assert type(problem_to_dict(problem)["objective"]) is str
    record = {"status": "feasible", "solver": "dp", "objective": 1.0, "f1": 1.0, "f2": 0.0,
              "mu": 1.0, "routes": {}, "solve_time_s": 0.1}  # fmt: skip
    assert result_from_record(record).status is PlanStatus.FEASIBLE
    with pytest.raises(RecordError):
        result_from_record({**record, "status": "great"})


def test_detections_default_is_resolved_by_config_resolve() -> None:
    """Unset: 127.0.0.1:14600 for real links, a free port with sim:N; given: as given."""
    from groundstation.daemon.config import DETECTIONS_UNSET, Endpoint

    unset = parse_config({"vehicles": ["sim:2"]}, {})
    assert unset.detections == DETECTIONS_UNSET and "detections" not in unset.to_dict()
    assert resolve(unset).detections == Endpoint("127.0.0.1", 0)
    assert resolve(resolve(unset)) == resolve(unset)
    real = resolve(parse_config({"vehicles": ["tcp:127.0.0.1:5760"]}, {}))
    assert real.detections == Endpoint("127.0.0.1", 14600)
    given = build_config(["--vehicles", "sim:1", "--detections", "127.0.0.1:14600"])
    assert given.detections == Endpoint("127.0.0.1", 14600)
    assert build_config(["--vehicles", "sim:1", "--detections", "off"]).detections is None


def test_the_wind_replan_settings_reach_the_core() -> None:
    """docs/wind.md, "The first leg": on by default (2 m/s, 5 s), tunable, or off."""
    from groundstation.daemon.startup import core_config

    def core(planner: dict[str, object]) -> tuple[float | None, float]:
        config = resolve(parse_config({"vehicles": ["sim:1"], "planner": planner}, {}))
        cc = core_config(config, None, 1.0)
        return cc.wind_replan_m_s, cc.wind_replan_margin_s

    assert core({}) == (2.0, 5.0)
    assert core({"wind_replan_m_s": 3, "wind_replan_margin_s": 8}) == (3.0, 8.0)
    assert core({"wind_replan": False}) == (None, 5.0)
    with pytest.raises(ConfigError, match=r"planner\.wind_replan_margin_s"):
        parse_config({"vehicles": ["sim:1"], "planner": {"wind_replan_margin_s": 0}}, {})


def test_ship_beacon_is_a_system_id_or_off_and_round_trips(tmp_path: Path) -> None:
    assert build_config(["--vehicles", "sim:1"]).links.ship_beacon == 17
    off = build_config(["--vehicles", "sim:1", "--ship-beacon", "off"])
    assert off.links.ship_beacon is None and off.to_dict()["links"]["ship_beacon"] == "off"
    assert build_config(["--config", _write(tmp_path / "b.yaml", yaml.safe_dump(
        off.to_dict()))]) == off  # fmt: skip
    assert build_config(["--vehicles", "sim:1", "--ship-beacon", "42"]).links.ship_beacon == 42
    data = {"links": {"vehicles": ["sim:1"], "ship_beacon": "off"}}
    assert parse_config(data, {}).links.ship_beacon is None
    with pytest.raises(UsageError, match=r"--ship-beacon: expected 1\.\.254 or off"):
        build_config(["--vehicles", "sim:1", "--ship-beacon", "300"])
    with pytest.raises(UsageError, match="must not be floe's own"):
        build_config(["--vehicles", "sim:1", "--ship-beacon", "245"])
    with pytest.raises(UsageError, match=r"links\.ship_beacon: expected an integer"):
        parse_config({"links": {"vehicles": ["sim:1"], "ship_beacon": "on"}}, {})


def test_a_link_rate_must_name_a_vehicle_link() -> None:
    """--link-rate for a link floe does not open would be ignored: one line instead; sim:N's
    links are the simulator's; the same URL spelt another way is the same link."""
    from groundstation.daemon.config_parse import check_config

    ok = build_config(["--vehicles", "tcp:localhost:5760", "/dev/ttyUSB0,57600",
                       "--link-rate", "tcp://localhost:5760=64k"])
    check_config(ok)
    assert dict(ok.links.link_rates()) == {"tcp:localhost:5760": 64000.0}
    with pytest.raises(ConfigError, match=r"names no vehicle link \(the links are: "):
        check_config(build_config(["--vehicles", "tcp:localhost:5760",
                                   "--link-rate", "tcp:localhost:5770=64k"]))
    with pytest.raises(ConfigError, match="give them a radio with --sim-radio"):
        check_config(build_config(["--vehicles", "sim:2", "--link-rate",
                                   "tcp:localhost:5760=64k"]))
