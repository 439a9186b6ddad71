"""Scenario fields of discovery (world/discovery_spec.py): camera, targets.known, area,
prior, tracker, search; errors naming the field; the generated prior list."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from domain.yaml_fields import FieldError
from world.discovery_spec import (
    AreaSpec,
    CameraSpec,
    PriorEntry,
    SearchSpec,
    resolve_prior,
    scenario_camera,
)
from world.scenario import (
    ScenarioError,
    load_scenario,
    load_scenario_data,
    parse_scenario,
    resolve_targets,
)

BASE: dict[str, Any] = {
    "name": "t",
    "duration_s": 100,
    "area": {"x_m": [0, 3000], "y_m": [0, 2000]},
    "targets": {"random": {"count": 12, "x_m": [0, 3000], "y_m": [0, 2000],
                           "vx_m_s": [-0.5, 0.5], "vy_m_s": [-0.5, 0.5]}},
}


def scenario(**sections: Any) -> Any:
    data = copy.deepcopy(BASE)
    for key, value in sections.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    return parse_scenario(data, source="test")


def test_defaults_keep_todays_fields_and_an_unlabelled_camera() -> None:
    s = scenario(area=None)
    assert s.camera == CameraSpec(1.0, 0.0, False) and not s.camera.classic
    assert s.targets_known and s.area is None and s.prior is None
    assert s.tracker == {} and s.search is None


@pytest.mark.parametrize("name", ["paper-boat", "svalbard-2015", "default"])
def test_the_papers_scenarios_keep_the_papers_camera(name: str) -> None:
    s = load_scenario(name)
    assert s.camera.classic and s.targets_known and s.prior is None and s.search is None


def test_discovery_and_paper_boat_clutter() -> None:
    d = load_scenario("discovery")
    assert d.camera == CameraSpec(0.85, 0.1, False) and not d.targets_known
    assert d.area == AreaSpec(0.0, 3000.0, 0.0, 3000.0)
    assert d.prior is not None and (d.prior.listed, d.prior.max_age_s, d.prior.phantoms) == (
        8, 600.0, 1)
    assert d.search == SearchSpec(300.0, 25.0, 4, 0.0) and d.duration_s == 1800.0
    assert d.fleet.count == 3 and d.tracker["association"] == "gnn"
    assert d.tracker["lost_sigma_m"] == 300.0
    targets = resolve_targets(d, np.random.default_rng(5))
    assert len(targets) == 12
    outside = [t for t in targets if not d.area.contains(t.x_m, t.y_m)]
    assert outside and all(  # they drift in before the end
        d.area.contains(t.x_m + t.vx_m_s * d.duration_s, t.y_m + t.vy_m_s * d.duration_s)
        for t in outside)
    pb, clutter = load_scenario("paper-boat"), load_scenario("paper-boat-clutter")
    assert clutter.camera == CameraSpec(1.0, 0.1, False)
    same = ("fleet", "boat", "targets", "random_targets", "observer", "planner", "policy",
            "duration_s", "origin")
    assert all(getattr(pb, key) == getattr(clutter, key) for key in same)


def test_fields_parse() -> None:
    s = scenario(
        camera={"pd": 0.5, "clutter_per_frame": 2, "labelled": True},
        targets={"known": False, "list": [{"id": "A", "x_m": 1, "y_m": 2}]},
        prior={"list": [{"id": "P1", "x_m": 3, "y_m": 4, "age_s": 60, "truth": "A"},
                        {"id": "P2", "x_m": 5, "y_m": 6, "sigma_m": 10}], "sigma_m": 20},
        tracker={"association": "jpda", "confirm_hits": 2, "confirm_window": 4,
                 "existence_delete": 0.1, "existence_confirm_min": 0.6,
                 "new_track_vel_var_m2_s2": 1.5, "gate_probability": 0.99, "lost_sigma_m": 450},
        search={"cell_m": 250, "max_cells": 6},
    )
    assert s.camera == CameraSpec(0.5, 2.0, True) and not s.targets_known
    assert s.prior is not None and s.prior.entries == (
        PriorEntry("P1", 3.0, 4.0, 60.0, 20.0, "A"), PriorEntry("P2", 5.0, 6.0, 0.0, 10.0, None))
    assert s.tracker == {"association": "jpda", "confirm_hits": 2, "confirm_window": 4,
                         "existence_delete": 0.1, "existence_confirm_min": 0.6,
                         "new_track_vel_var_m2_s2": 1.5, "gate_probability": 0.99,
                         "lost_sigma_m": 450.0}
    assert s.search == SearchSpec(250.0, 50.0, 6, 1.0)
    assert s.area is not None and s.area.contains(0, 2000) and not s.area.contains(-1, 5)
    camera = scenario_camera(s)
    assert (camera.pd, camera.clutter_per_frame, camera.labelled) == (0.5, 2.0, True)
    assert resolve_prior(s, resolve_targets(s, np.random.default_rng(0)), 0) == list(
        s.prior.entries)


@pytest.mark.parametrize(("sections", "message"), [
    ({"camera": {"pd": 0}}, "camera.pd: must be in (0, 1], got 0"),
    ({"camera": {"pd": 1.5}}, "camera.pd: must be in (0, 1], got 1.5"),
    ({"camera": {"pd": float("nan")}}, "camera.pd: must be finite"),
    ({"camera": {"pd": "high"}}, "camera.pd: must be a number"),
    ({"camera": {"clutter_per_frame": -1}}, "camera.clutter_per_frame: must be >= 0"),
    ({"camera": {"clutter_per_frame": 1e9}}, "camera.clutter_per_frame: must be <= 1000"),
    ({"camera": {"labelled": "yes"}}, "camera.labelled: must be true or false"),
    ({"camera": {"fps": 3}}, "camera.fps: unknown field"),
    ({"camera": [1]}, "camera: must be a mapping"),
    ({"targets": {"known": 1}}, "targets.known: must be true or false"),
    ({"area": {"x_m": [0, 10]}}, "area.y_m: is required"),
    ({"area": {"x_m": [5, 5], "y_m": [0, 1]}}, "area.x_m: must have high > low"),
    ({"area": {"x_m": [0, 1], "y_m": [0, 1], "z_m": [0, 1]}}, "area.z_m: unknown field"),
    ({"prior": {"listed": 13}}, "prior.listed: lists 13 icebergs but the scenario has 12"),
    ({"prior": {"listed": -1}}, "prior.listed: must be an integer >= 0"),
    ({"prior": {"max_age_s": -5}}, "prior.max_age_s: must be >= 0"),
    ({"prior": {"sigma_m": 0}}, "prior.sigma_m: must be > 0"),
    ({"prior": {"phantoms": 1}, "area": None}, "prior.phantoms: needs an area"),
    ({"prior": {"list": [{"id": "P", "x_m": 0, "y_m": 0}], "listed": 2}},
     "prior.listed: cannot be given with prior.list"),
    ({"prior": {"list": [{"id": "P", "x_m": 0, "y_m": 0}, {"id": "P", "x_m": 1, "y_m": 0}]}},
     "prior.list: duplicate id 'P'"),
    ({"prior": {"list": [{"id": "P", "x_m": 0}]}}, "prior.list[0].y_m: is required"),
    ({"prior": {"list": [{"id": "P", "x_m": 0, "y_m": 0, "colour": 1}]}},
     "prior.list[0].colour: unknown field"),
    ({"prior": {"seen": 3}}, "prior.seen: unknown field"),
    ({"tracker": {"association": "nearest"}}, "tracker.association: must be one of gnn, jpda"),
    ({"tracker": {"confirm_hits": 0}}, "tracker.confirm_hits: must be an integer >= 1"),
    ({"tracker": {"confirm_hits": 6, "confirm_window": 5}},
     "tracker.confirm_hits: must be <= confirm_window (5), got 6"),
    ({"tracker": {"existence_delete": 1}}, "tracker.existence_delete: must be in (0, 1), got 1"),
    ({"tracker": {"lost_sigma_m": 0}}, "tracker.lost_sigma_m: must be > 0"),
    ({"tracker": {"existence_delete": 0.6, "existence_confirm_min": 0.5}},
     "tracker.existence_delete: must be below existence_confirm_min"),
    ({"tracker": {"gate_probability": 0}}, "tracker.gate_probability: must be in (0, 1)"),
    ({"tracker": {"new_track_vel_var_m2_s2": -1}}, "tracker.new_track_vel_var_m2_s2: must be >"),
    ({"tracker": {"id_prefix": "X"}}, "tracker.id_prefix: unknown field"),
    ({"search": {"cell_m": 0}}, "search.cell_m: must be > 0"),
    ({"search": {"cell_m": 10}}, "search.cell_m: gives 60000 cells over the area"),
    ({"search": {"max_cells": 0}}, "search.max_cells: must be an integer >= 1"),
    ({"search": {"growth_m2_per_s": float("inf")}}, "search.growth_m2_per_s: must be finite"),
    ({"search": {"cell_m": 300}, "area": None}, "search: needs an area"),
])
def test_bad_values_name_the_field(sections: dict[str, Any], message: str) -> None:
    with pytest.raises(FieldError) as info:
        scenario(**sections)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_unknown_truth_in_a_prior_list_names_the_field() -> None:
    s = scenario(prior={"list": [{"id": "P", "x_m": 0, "y_m": 0, "truth": "nobody"}]})
    with pytest.raises(FieldError, match=r"prior.list\[0\].truth: names no iceberg"):
        resolve_prior(s, resolve_targets(s, np.random.default_rng(0)), 0)


def test_generated_prior() -> None:
    s = scenario(prior={"listed": 8, "max_age_s": 600, "phantoms": 2, "sigma_m": 1e-6})
    assert s.area is not None
    targets = resolve_targets(s, np.random.default_rng(11))
    by_id = {t.id: t for t in targets}
    entries = resolve_prior(s, targets, 11)
    assert [e.id for e in entries] == [f"P{k}" for k in range(1, 11)]
    listed = [e for e in entries if e.truth_id is not None]
    phantoms = [e for e in entries if e.truth_id is None]
    assert len(listed) == 8 and len({e.truth_id for e in listed}) == 8 and len(phantoms) == 2
    for e in listed:
        t = by_id[str(e.truth_id)]
        assert 0.0 <= e.age_s <= 600.0 and e.sigma_m == 1e-6
        # where the iceberg was age_s before the start (noise 1e-6 m)
        assert e.x_m == pytest.approx(t.x_m - t.vx_m_s * e.age_s, abs=1e-4)
        assert e.y_m == pytest.approx(t.y_m - t.vy_m_s * e.age_s, abs=1e-4)
    assert all(s.area.contains(e.x_m, e.y_m) and 0.0 <= e.age_s <= 600.0 for e in phantoms)
    ages = sorted(e.age_s for e in listed)
    assert ages[-1] - ages[0] > 60.0  # drawn, not constant
    # ids say nothing about the truth: over seeds, the phantom is not always the last id
    last_ids = {next(e.id for e in resolve_prior(s, targets, seed) if e.truth_id is None)
                for seed in range(20)}
    assert len(last_ids) > 2


def test_generated_prior_is_deterministic_per_seed_and_leaves_the_run_alone() -> None:
    s = scenario(prior={"listed": 5, "max_age_s": 300, "phantoms": 1})
    rng = np.random.default_rng(4)
    targets = resolve_targets(s, rng)
    state = copy.deepcopy(rng.bit_generator.state)
    first = resolve_prior(s, targets, 4)
    assert rng.bit_generator.state == state  # the run's generator is not touched
    assert resolve_prior(s, targets, 4) == first
    assert resolve_prior(s, targets, 5) != first
    # the same draw whatever the run's generator did before
    again = resolve_targets(s, np.random.default_rng(4))
    np.random.default_rng(4).random(100)
    assert resolve_prior(s, again, 4) == first
    assert resolve_prior(scenario(), targets, 4) == []


def test_prior_lists_only_icebergs_present_at_the_start() -> None:
    s = scenario(
        targets={"list": [{"id": "A", "x_m": 0, "y_m": 0},
                          {"id": "B", "x_m": 5, "y_m": 5, "appear_s": 50}]},
        prior={"listed": 2},
    )
    entries = resolve_prior(s, resolve_targets(s, np.random.default_rng(0)), 0)
    assert [e.truth_id for e in entries] == ["A"]


def test_campaign_overrides_reach_the_new_fields() -> None:
    from pathlib import Path

    from groundstation.runners.campaign.grid import parse_campaign

    spec = parse_campaign({"grid": {"scenario": ["discovery"], "camera.pd": [0.7, 1.0],
                                    "camera.clutter_per_frame": [0.0, 0.5], "seed": [0]}},
                          base_dir=Path("."))
    assert spec.run_count() == 4
    with pytest.raises(FieldError, match=r"camera.pd: must be in \(0, 1\], got 2"):
        parse_campaign({"grid": {"scenario": ["discovery"], "camera.pd": [2.0], "seed": [0]}},
                       base_dir=Path("."))
    data, source = load_scenario_data("discovery")
    data["camera"]["pd"] = 0.0
    with pytest.raises(FieldError, match=r"camera\.pd"):
        parse_scenario(data, source=source)
    with pytest.raises(ScenarioError):
        load_scenario("/nonexistent/discovery.yaml")


def test_prior_variance_grows_with_the_listings_age() -> None:
    """``drift_m_s``: a listing ``age_s`` old is announced with variance
    ``sigma_m^2 + (drift_m_s age_s)^2`` per axis; without it, ``sigma_m^2``."""
    plain = scenario(prior={"listed": 4, "max_age_s": 600, "sigma_m": 30})
    aged = scenario(prior={"listed": 4, "max_age_s": 600, "sigma_m": 30, "drift_m_s": 0.3})
    targets = resolve_targets(aged, np.random.default_rng(2))
    for p, a in zip(resolve_prior(plain, targets, 2), resolve_prior(aged, targets, 2),
                    strict=True):
        assert (p.x_m, p.y_m, p.age_s) == (a.x_m, a.y_m, a.age_s)  # same draws
        assert p.variance_m2 == pytest.approx(900.0)
        assert a.variance_m2 == pytest.approx(900.0 + (0.3 * a.age_s) ** 2)
    with pytest.raises(FieldError, match=r"prior\.drift_m_s"):
        scenario(prior={"listed": 1, "drift_m_s": -1})


def test_planner_tentative_weight_reaches_the_core() -> None:
    from groundstation.core.scenario_config import core_config_for

    assert core_config_for(scenario()).tentative_weight == 0.0
    assert core_config_for(scenario(planner={"tentative_weight": 0.5})).tentative_weight == 0.5
    with pytest.raises(FieldError, match=r"planner\.tentative_weight: must be >= 0"):
        scenario(planner={"tentative_weight": -1})
