"""Scenario files: bundled ones load; every invalid field is named in the error."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from domain.yaml_fields import FieldError
from world.scenario import ScenarioError, bundled_scenarios, load_scenario, parse_scenario


def test_bundled_scenarios_load_with_the_papers_parameters() -> None:
    assert {"default", "paper-boat", "svalbard-2015"} <= set(bundled_scenarios())
    paper = load_scenario("paper-boat")
    assert paper.boat is not None
    assert paper.boat.heading_rad == pytest.approx(2.0246)
    assert paper.random_targets is not None and paper.random_targets.count == 10
    assert paper.policy.period_s == 5.0 and paper.policy.commit is False
    assert paper.fleet.launch_headings_rad(3) == pytest.approx([0, math.pi / 2, math.pi])
    assert paper.launch_point() == (1500.0, 0.0)
    field = load_scenario("svalbard-2015")
    assert field.observer.model == "linear"
    assert field.fleet.loiter_s == 30
    assert [t.sigma0 for t in field.targets] == [1, 5, 8, 2]
    assert field.events[0].kind == "target_added" and field.events[0].t_s == 100


@pytest.mark.parametrize(
    ("data", "path"),
    [
        ({"fleet": {"count": 0}}, "fleet.count"),
        ({"fleet": {"cont": 2}}, "fleet.cont"),
        ({"fleet": {"speed_m_s": -1}}, "fleet.speed_m_s"),
        ({"fleet": {"turn_radius_m": float("nan")}}, "fleet.turn_radius_m"),
        ({"boat": {"x_m": 0}}, "boat.y_m"),
        ({"targets": {"list": [{"id": "A", "x_m": 0}]}}, "targets.list[0].y_m"),
        ({"targets": {"list": [{"id": "A", "x_m": 0, "y_m": 0, "speed": 1}]}},
         "targets.list[0].speed"),
        ({"targets": {"random": {"count": 3, "x_m": [5, 1]}}}, "targets.random.x_m"),
        ({"observer": {"model": "magic"}}, "observer.model"),
        ({"planner": {"tau": 2}}, "planner.tau"),
        ({"policy": {"replan": "period"}}, "policy.period_s"),
        ({"events": [{"t_s": 1, "kind": "explode", "vehicle": "1"}]}, "events[0].kind"),
        ({"events": [{"t_s": 1, "kind": "override"}]}, "events[0].vehicle"),
        ({"duration_s": 0}, "duration_s"),
        ({"colour": "red"}, "colour"),
        ({"faults": ["1:explode"]}, "faults[0]"),
        ({"faults": ["2:drop:at=5", 3]}, "faults[0]"),
        ({"faults": ["2:drop:at=5,for=3", 3]}, "faults[1]"),
    ],
)
def test_invalid_fields_are_named(data: dict, path: str) -> None:
    with pytest.raises(FieldError) as info:
        parse_scenario(data)
    assert info.value.path == path
    assert str(info.value).startswith(path + ":")


def test_duplicate_target_ids_are_rejected() -> None:
    data = {"targets": {"list": [{"id": "A", "x_m": 0, "y_m": 0},
                                 {"id": "A", "x_m": 1, "y_m": 1}]}}
    with pytest.raises(FieldError, match="duplicate target id 'A'"):
        parse_scenario(data)


def test_files_errors_name_the_file(tmp_path: Path) -> None:
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("fleet: [1, 2\n")
    with pytest.raises(ScenarioError, match="not valid YAML"):
        load_scenario(str(bad_yaml))
    bad_field = tmp_path / "field.yaml"
    bad_field.write_text(yaml.safe_dump({"fleet": {"count": "three"}}))
    with pytest.raises(ScenarioError, match=r"field\.yaml: fleet\.count: must be an integer"):
        load_scenario(str(bad_field))
    with pytest.raises(ScenarioError, match="no such file or bundled scenario"):
        load_scenario(str(tmp_path / "missing.yaml"))


def test_a_copied_bundled_scenario_loads_from_a_file(tmp_path: Path) -> None:
    original = load_scenario("svalbard-2015")
    from importlib import resources

    text = (resources.files("world") / "scenarios" / "svalbard-2015.yaml").read_text()
    copy = tmp_path / "mine.yaml"
    copy.write_text(text.replace("duration_s: 800", "duration_s: 100"))
    mine = load_scenario(str(copy))
    assert mine.duration_s == 100
    assert mine.targets == original.targets


def test_fault_specs_are_kept_for_the_mavlink_simulator() -> None:
    scenario = parse_scenario({"faults": ["all:loss:p=0.2", "2:drop:at=60,for=30"]})
    assert scenario.faults == ("all:loss:p=0.2", "2:drop:at=60,for=30")


def test_malformed_yaml_keeps_pyyaml_line_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The error said only "while parsing a block mapping": no line, no column."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: t\nfleet:\n  count: 3\n   speed_m_s: 18\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(str(bad))
    message = str(info.value)
    assert "bad.yaml" in message and "\n" not in message
    assert "line 4, column 13: mapping values are not allowed here" in message
    flow = tmp_path / "flow.yaml"
    flow.write_text("fleet: [1, 2\nname: t\n")
    with pytest.raises(ScenarioError, match=r"line 2, column 5: .*flow sequence that started "
                       r"at line 1, column 8"):
        load_scenario(str(flow))
    # the same through gcs run --config: one line, line and column kept, exit 2
    from groundstation.commands import run as run_cmd

    assert run_cmd.run(["--config", str(bad), "--vehicles", "sim:1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gcs run: error: --config ") and "\n" not in err
    assert "line 4, column 13" in err
