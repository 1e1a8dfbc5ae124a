"""Several independently trained self-play populations from one plan entry, every test partner, and declared seeds."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from rllib_conv import partners
from rllib_conv.common.seeds import population_seed
from rllib_conv.pipelines import reproduce as reproduce_module
from rllib_conv.pipelines.plans import expand_adapt_to, expand_selfplay, narrow, plan_for, read_plan_file, shipped_plan
from rllib_conv.pipelines.reproduce import Reproduction


def _write(tmp_path: Path, plan: dict) -> Path:
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(plan))
    return path


def test_an_entry_with_three_populations_becomes_three_equal_but_for_their_seeds() -> None:
    entries = [{"name": "sp", "env_config": {"symmetric": 3}, "seed": 5, "populations": 3}, {"name": "one"}]
    expanded, groups = expand_selfplay(entries, "bandit")
    assert [e["name"] for e in expanded] == ["sp-p0", "sp-p1", "sp-p2", "one"]
    assert [e.get("seed") for e in expanded] == [5, 10_005, 20_005, None]  # `one` keeps its config's seed
    assert all(e["env_config"] == {"symmetric": 3} and "populations" not in e for e in expanded[:3])
    assert groups == {"sp": ["sp-p0", "sp-p1", "sp-p2"]}
    # Pair k of population p is seeded seed + 10 000 p + k: no two populations share a pair seed.
    pairs = [{population_seed(5, p) + k for k in range(20)} for p in range(3)]
    assert not (pairs[0] & pairs[1]) and not (pairs[1] & pairs[2])


def test_an_entry_without_a_seed_counts_from_the_games_self_play_config() -> None:
    shipped = yaml.safe_load((Path(shipped_plan("bandit")).parent / "selfplay_bandit.yaml").read_text())["seed"]
    expanded, _ = expand_selfplay([{"name": "sp", "populations": 2}], "bandit")
    assert [e["seed"] for e in expanded] == [shipped, shipped + 10_000]


def test_the_full_plans_train_three_self_play_populations_and_adapt_to_every_test_partner() -> None:
    for game in ("bandit", "blocks", "hanabi"):
        full, quick = plan_for(game), plan_for(game, quick=True)
        assert full.population_groups and all(len(m) >= 3 for m in full.population_groups.values())
        assert full.adapt_partners is None  # every held-out partner of each population
        assert not quick.population_groups and quick.adapt_partners == 1  # the quick plans stay small
    # Every self-play entry of the full bandit plan is pooled from three populations.
    assert sorted(plan_for("bandit").population_groups) == ["bandit-s2-selfplay", "bandit-s3-selfplay", "bandit-s4-selfplay"]


def test_a_one_population_entry_keeps_its_name_so_earlier_run_folders_are_read() -> None:
    overcooked = plan_for("overcooked")
    assert [sp["name"] for sp in overcooked.selfplay] == ["overcooked-cramped_room-selfplay"]
    assert overcooked.population_groups == {}


def test_the_egos_of_each_population_train_and_adapt_as_experiments_of_their_own() -> None:
    repro = Reproduction(narrow(plan_for("hanabi", seeds=2), None, ["agg"]), Path("/runs"))
    trained = repro.stage_experiments("train")
    assert trained == [f"hanabi-selfplay-p{p}__{m}" for p in range(3) for m in ("modular-lam0.5", "agg")]
    assert repro.stage_experiments("selfplay") == [f"hanabi-selfplay-p{p}" for p in range(3)]


@pytest.mark.parametrize(("value", "match"), [(0, "positive integer, got 0"), ("3", "positive integer, got '3'")])
def test_a_bad_population_count_is_refused_naming_the_entry(tmp_path, value, match) -> None:
    plan = yaml.safe_load(shipped_plan("bandit").read_text())
    plan["full"]["selfplay"][1]["populations"] = value
    with pytest.raises(ValueError, match=rf"plan\.yaml.*selfplay\[1\] \(bandit-s3-selfplay\): `populations` must be a {match}"):
        read_plan_file(_write(tmp_path, plan))


def test_a_held_out_agent_naming_an_entry_of_several_populations_is_refused(tmp_path) -> None:
    plan = yaml.safe_load(shipped_plan("overcooked").read_text())
    plan["full"]["selfplay"][0]["populations"] = 2
    with pytest.raises(ValueError, match="full.heldout.agents.PPO_SP: 'overcooked-cramped_room-selfplay' trains 2 populations"):
        read_plan_file(_write(tmp_path, plan))


def test_adapt_to_names_every_population_of_an_entry_as_source_and_as_target() -> None:
    groups = {"sp": ["sp-p0", "sp-p1"]}
    assert expand_adapt_to({"sp": ["hproxy"], "cooks": ["sp"]}, groups) == {
        "sp-p0": ["hproxy"],
        "sp-p1": ["hproxy"],
        "cooks": ["sp-p0", "sp-p1"],
    }


def test_seeds_default_to_the_plans_declaration_and_the_run_writes_it_with_the_groups(tmp_path, monkeypatch) -> None:
    assert plan_for("bandit").declared_seeds == 10 and plan_for("bandit").seeds == list(range(10))
    assert plan_for("bandit", seeds=3).seeds == [0, 1, 2] and plan_for("bandit", seeds=3).declared_seeds == 10
    assert plan_for("blocks").declared_seeds is None and plan_for("blocks").seeds == [0, 1, 2]
    assert plan_for("bandit", quick=True).declared_seeds is None
    monkeypatch.setattr(Reproduction, "stages", lambda self: [])  # plan.json is written before any stage
    Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-selfplay"], ["agg"]), tmp_path, log=lambda _: None).run()
    written = json.loads((tmp_path / "plan.json").read_text())
    assert written["declared_seeds"] == 10 and written["seeds"] == [0, 1, 2]
    assert written["population_groups"] == {"bandit-s2-selfplay": [f"bandit-s2-selfplay-p{p}" for p in range(3)]}
    # A plan without either writes neither key: plan.json of earlier runs is unchanged.
    Reproduction(plan_for("blocks", quick=True), tmp_path / "quick", log=lambda _: None).run()
    assert not {"declared_seeds", "population_groups"} & set(json.loads((tmp_path / "quick" / "plan.json").read_text()))


def test_seeds_declared_on_the_quick_scale_are_refused(tmp_path) -> None:
    plan = yaml.safe_load(shipped_plan("bandit").read_text())
    plan["quick"]["seeds"] = 4
    with pytest.raises(ValueError, match="quick.seeds: the quick plan runs seed 0 alone"):
        read_plan_file(_write(tmp_path, plan))


def test_the_full_plan_adapts_to_every_test_partner_of_a_population(tmp_path, monkeypatch) -> None:
    captured: list[dict] = []
    monkeypatch.setattr(Reproduction, "egos", lambda self, experiment: [f"/runs/{experiment}/seed=0"])
    monkeypatch.setattr(reproduce_module.config_files, "checked", lambda raw, schema, blame: raw)
    monkeypatch.setattr(reproduce_module, "run_adaptations", lambda configs, **kwargs: captured.extend(configs))
    Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-user-study"], ["agg"]), tmp_path).stage_adapt()
    every = [e.name for e in partners.get("bandit-user-study").entries("test")]
    assert len(every) > 4 and captured and all(c["partners"] == every for c in captured)


def test_a_plan_may_name_the_teams_a_population_adapts_to_and_a_bad_team_is_refused_by_the_file(tmp_path) -> None:
    raw = yaml.safe_load(shipped_plan("lbf").read_text())
    raw["full"].update(adapt_variants=["modular-lam0.5-seat-known"], adapt_teams={"lbf-heuristics": ["H1+H3", "H4+H2", "H2"]})
    plan = plan_for("lbf", path=_write(tmp_path, raw))
    assert plan.adapt_teams == {"lbf-heuristics": ["H1+H3", "H4+H2", "H2+H2"]}  # one name: it sits in every seat
    assert Reproduction(plan, Path("/runs")).adapt_partners("lbf-heuristics") == ["H1+H3", "H4+H2", "H2+H2"]
    # Without them: every team of the test members.
    default = Reproduction(plan_for("lbf"), Path("/runs")).adapt_partners("lbf-heuristics")
    assert default == ["H3+H3", "H3+H4", "H4+H3", "H4+H4"]
    for teams, error in (
        (
            {"lbf-heuristics": ["H1+H9"]},
            r"adapt_teams.lbf-heuristics: partners: population 'lbf-heuristics' has no partner\(s\) \['H9'\]",
        ),
        ({"lbf-heuristics": ["H1+H2+H3"]}, r"adapt_teams.lbf-heuristics: partners: 'H1\+H2\+H3' names 3 partners"),
        ({"lbf-other": ["H1+H3"]}, r"full.adapt_teams: \['lbf-other'\] not defined"),
    ):
        raw["full"]["adapt_teams"] = teams
        with pytest.raises(ValueError, match=error):
            plan_for("lbf", path=_write(tmp_path, raw))
    two = yaml.safe_load(shipped_plan("blocks").read_text())
    two["full"]["adapt_teams"] = {"blocks-perm": ["p0"]}
    with pytest.raises(ValueError, match="adapt_teams.blocks-perm: a team needs several partner seats; it has one"):
        plan_for("blocks", path=_write(tmp_path, two))
