"""Eq. 18's mu three ways (issue 31): the rules, the problem file, scenarios, the core's
journal and replay, and metrics.json's mu_ratio."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from simulate_run import simulate_text

from domain.yaml_fields import FieldError
from groundstation.cli import main
from groundstation.commands.plan import run as plan_command
from groundstation.core.config import CoreConfig, config_from_dict, config_to_dict
from groundstation.core.metrics import MetricsRecorder, ensemble_growth, third_means
from groundstation.runners.replay.journal import apply_overrides
from planner import (
    MU_RULES,
    MuRule,
    ProblemError,
    problem_from_dict,
    problem_to_dict,
    solve_plan,
)
from planner.instance import build_instance, f1_max
from world.scenario import MU_RULE_NAMES, load_scenario_data, parse_scenario

PROBLEM: dict[str, Any] = {
    "uavs": [
        {"id": "a", "x": 0, "y": 0, "heading": 0.0},
        {"id": "b", "x": 500.0, "y": 0, "heading": 1.5},
    ],
    "targets": [
        {"id": "t1", "x": 300, "y": 200, "sigma": 5},
        {"id": "t2", "x": 900, "y": 100, "sigma": 1.5},
        {"id": "t3", "x": 100, "y": 800, "sigma": 3},
        {"id": "t4", "x": -400, "y": 300, "sigma": 4},
    ],
    "turn_radius": 105,
    "tau": 0.5,
    "objective": "sequence",
}


def test_f1_max_by_rule() -> None:
    sigmas = [1.0, 3.0, 5.0, 2.0]
    # N = 6 (2 UAVs): floe's round robin t = 2, 2, 3, 3; paper t = 2; unconstrained t = 1
    assert f1_max(sigmas, 2, 6) == pytest.approx(5 * 4 + 3 * 4 + 2 * 3 + 1 * 3)
    assert f1_max(sigmas, 2, 6, MuRule.PAPER) == pytest.approx(4 * 11)
    assert f1_max(sigmas, 2, 6, MuRule.UNCONSTRAINED) == pytest.approx(5 * 11)


@pytest.mark.parametrize("rule", MU_RULES)
def test_each_rule_is_eq_18_with_its_f1max(rule: str) -> None:
    problem = problem_from_dict({**PROBLEM, "mu": rule})
    inst = build_instance(problem)
    n_nodes, sigma = inst.n_nodes, inst.sigma.tolist()
    f2avg = inst.d_avg * (n_nodes - inst.m)
    assert inst.mu == pytest.approx(f1_max(sigma, inst.m, n_nodes, MuRule(rule)) / f2avg)
    result = solve_plan(problem)
    assert result.mu == pytest.approx(inst.mu)
    # the problem file keeps the rule (floe, the default, reads as before: no key)
    assert problem_to_dict(problem).get("mu") == (None if rule == "floe" else rule)
    assert problem_from_dict(problem_to_dict(problem)) == problem


def test_the_paper_rule_weighs_distance_more_than_floes() -> None:
    mus = {rule: build_instance(problem_from_dict({**PROBLEM, "mu": rule})).mu
           for rule in MU_RULES}
    assert mus["floe"] < mus["paper"] < mus["unconstrained"]
    assert build_instance(problem_from_dict({**PROBLEM, "mu": 2.5})).mu == 2.5


@pytest.mark.parametrize("bad", ["Paper", "", True, -1, [1], {"rule": "paper"}])
def test_bad_mu_in_a_problem_file_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: Any
) -> None:
    with pytest.raises(ProblemError, match=r"^mu: "):
        problem_from_dict({**PROBLEM, "mu": bad})
    path = tmp_path / "problem.json"
    path.write_text(json.dumps({**PROBLEM, "mu": bad}))
    assert plan_command([str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gcs plan: error: mu: ") and len(err.strip().splitlines()) == 1


def test_gcs_plan_reports_the_rules_mu(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "problem.json"
    path.write_text(json.dumps({**PROBLEM, "mu": "paper"}))
    assert plan_command([str(path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["mu"] == pytest.approx(build_instance(problem_from_dict(
        {**PROBLEM, "mu": "paper"})).mu)


def test_world_and_planner_agree_on_the_rule_names() -> None:
    assert MU_RULE_NAMES == MU_RULES


def _scenario(planner: str) -> Any:
    data, _ = load_scenario_data("paper-boat")
    return parse_scenario({**data, "planner": json.loads(planner)}, source="test")


def test_scenario_planner_mu() -> None:
    assert _scenario('{"mu": "paper"}').planner.mu == "paper"
    assert _scenario('{"mu": 3}').planner.mu == 3.0
    assert _scenario("{}").planner.mu == "floe"
    for bad in ('{"mu": "literal"}', '{"mu": -1}', '{"mu": true}'):
        with pytest.raises(FieldError, match=r"planner\.mu"):
            _scenario(bad)


def test_core_config_journals_mu_and_old_journals_read_as_floe() -> None:
    for value in ("paper", "unconstrained", 2.5):
        config = CoreConfig(mu=value)  # type: ignore[arg-type]
        data = json.loads(json.dumps(config_to_dict(config)))
        assert data["mu"] == value
        assert config_from_dict(data) == config
    old = config_to_dict(CoreConfig())
    del old["mu"]
    assert config_from_dict(old).mu == MuRule.FLOE
    with pytest.raises(ValueError, match="mu"):
        CoreConfig(mu="Paper")  # type: ignore[arg-type]
    assert apply_overrides(CoreConfig(), ["mu=paper"]).mu == MuRule.PAPER
    assert apply_overrides(CoreConfig(mu=MuRule.PAPER), ["planner.mu=0.5"]).mu == 0.5
    with pytest.raises(ValueError, match="mu"):
        apply_overrides(CoreConfig(), ["mu=literal"])


def test_mu_ratio_leaves_out_plans_without_f1_or_mu() -> None:
    rec = MetricsRecorder()
    assert rec.mu_ratio() == {"mean": None, "sd": None, "n": 0}
    rec.plan(0.01, mu=2.0, f1=100.0, f2=50.0)
    rec.plan(0.01, mu=2.0, f1=0.0, f2=50.0)  # F1 = 0: left out
    rec.plan(0.01, mu=0.0, f1=100.0, f2=0.0)  # no distance term (latency): left out
    assert rec.mu_ratio() == {"mean": 0.5, "sd": None, "n": 1}
    rec.plan(0.01, mu=2.0, f1=100.0, f2=100.0)
    assert rec.mu_ratio() == pytest.approx({"mean": 0.75, "sd": 0.5**0.5 / 2, "n": 2})
    assert rec.plans == 4


SCENARIO = """\
name: mu-paper
duration_s: 40
origin: {lat_deg: 78.93, lon_deg: 11.92}
fleet: {count: 2, loiter_s: 0, launch: {x_m: 0.0, y_m: 0.0}}
targets:
  list:
    - {id: A, x_m: 800, y_m: 300, vx_m_s: 0.3, vy_m_s: -0.2}
    - {id: B, x_m: -600, y_m: 900, vx_m_s: -0.2, vy_m_s: 0.1}
    - {id: C, x_m: 1200, y_m: -700, vx_m_s: 0.1, vy_m_s: 0.3}
    - {id: D, x_m: -1000, y_m: -400, vx_m_s: 0.2, vy_m_s: 0.2}
planner: {objective: sequence, tau: 0.5, mu: paper}
policy: {replan: period, period_s: 5.0, commit: false}
"""


@pytest.fixture(scope="module")
def paper_mu_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate_text(tmp_path_factory.mktemp("mu-paper"), SCENARIO)


def test_simulate_with_the_paper_rule_writes_mu_ratio(paper_mu_run: Path) -> None:
    metrics = json.loads((paper_mu_run / "metrics.json").read_text())
    records = [json.loads(line) for line in (paper_mu_run / "journal.jsonl").open()]
    start = next(r for r in records if r["event"] == "start")
    assert start["core_config"]["mu"] == "paper"
    problems = [r["problem"] for r in records if "problem" in r]
    assert problems and all(p["mu"] == "paper" for p in problems)
    plans = [r["result"] for r in records if r["event"] == "plan"]
    ratios = [p["f2"] / p["f1"] for p in plans if p["f1"] != 0]
    assert len(plans) == metrics["plans"] > len(ratios) > 3  # the first plan: every sigma 0
    ratio = metrics["mu_ratio"]
    assert ratio["n"] == len(ratios)
    assert ratio["mean"] == pytest.approx(sum(ratios) / len(ratios), rel=1e-12)


def test_replay_resolves_with_the_recorded_rule(
    paper_mu_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(paper_mu_run), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["identical"] is True
    assert report["objectives_equal"] == report["objectives_compared"] > 3
    # floe's rule re-solves differently: every problem differs in its mu setting
    assert main(["replay", str(paper_mu_run), "--set", "mu=floe"]) == 1
    out = capsys.readouterr().out
    assert "setting changed: mu 'paper' -> 'floe'" in out


def test_ensemble_growth_is_the_mean_curves_last_over_middle_third() -> None:
    t = [float(s) for s in range(0, 301)]
    level = third_means(t, [100.0] * len(t))
    assert level == (100.0, 100.0)
    rising = third_means(t, [5000.0 + 25.0 * s for s in t])
    # middle third t in (100, 200], mean t 150.5; last (200, 300], mean 250.5
    assert rising == pytest.approx((5000.0 + 25.0 * 150.5, 5000.0 + 25.0 * 250.5))
    growth = ensemble_growth([(100.0, 100.0), (100.0, 300.0), (100.0, 200.0)])
    assert growth.value == pytest.approx(2.0)
    assert growth.low is not None and growth.high is not None
    assert 1.0 <= growth.low < 2.0 < growth.high <= 3.0
    assert ensemble_growth([(100.0, 150.0)]).text() == "1.50 (1 run: no interval)"


def test_a_scenario_with_a_bad_mu_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "bad.yaml"
    scenario.write_text(SCENARIO.replace("mu: paper", "mu: literal"))
    assert main(["simulate", "--scenario", str(scenario), "--out", str(tmp_path / "o"),
                 "--quiet", "--no-plots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "planner.mu: must be a number >= 0 or one of floe, paper, " \
        "unconstrained, got 'literal'" in err[0]


def test_campaign_end_of_run_table_gives_the_growth_not_a_bounded_count() -> None:
    import io

    from groundstation.commands.campaign_progress import print_summary
    from groundstation.runners.campaign.summary import summarise

    t = [float(s) for s in range(31)]
    rows = [
        {"uavs": u, "seed": s, "mean_uncertainty": 1.0, "bounded_trend": True,
         "series_t_s": t, "series_mean_sigma": [100.0 * (1 + (x > 20) * (s + u)) for x in t]}
        for u in (1, 3) for s in range(4)
    ]
    keys, cells = summarise(rows, {"uavs": [1, 3], "seed": [0, 1, 2, 3]})
    for cell in cells:
        u = cell.cell["uavs"]
        want = ensemble_growth([(100.0, 100.0 * (1 + s + u)) for s in range(4)])
        assert cell.growth == want and want.value == pytest.approx(1 + 1.5 + u)
    out = io.StringIO()
    print_summary(keys, cells, out)
    text = out.getvalue()
    assert "growth 2nd half [95 % CI]" in text and "trend <= 0.5" in text
    assert "bounded" not in text
    assert cells[1].growth is not None and cells[1].growth.text() in text
