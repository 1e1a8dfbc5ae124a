"""The adapters' one vocabulary (`rllib_conv.common.adapters`, bound to code by `rllib_conv.adaptation.registry`)."""

from __future__ import annotations

import inspect
import re
import typing
from pathlib import Path

import pytest
import yaml

from rllib_conv.adaptation import registry
from rllib_conv.common import adapters
from rllib_conv.common.methods import method
from rllib_conv.common.resources import config_file
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.play import conditions
from rllib_conv.play.conditions import build_settings

ROOT = Path(__file__).resolve().parents[2]


def test_every_adapter_names_files_that_exist_and_the_code_bound_to_it_lives_there() -> None:
    for record in adapters.ADAPTERS.values():
        paths = re.findall(r"rllib_conv/[\w/]+\.py", record.module)
        assert paths and all((ROOT / p).is_file() for p in paths), record
    for name, code in registry.IMPLEMENTED_BY.items():
        assert Path(inspect.getsourcefile(code)).resolve() == (ROOT / adapters.adapter(name).module).resolve(), name


def test_adapt_and_play_offer_the_vocabularys_starts() -> None:
    assert list(typing.get_args(adapters.StartName)) == adapters.names(role="start")
    assert adapters.names(role="start") == [
        "fresh",
        "pick",
        "posterior",
        "lookup",
        "counts-planner",
        "prior-planner",
        "plastic",
        "known-seats",
    ]
    assert AdaptConfig.model_fields["head_init"].default == adapters.FRESH
    for start in adapters.names(role="start"):
        assert AdaptConfig(runs=["r"], head_init=start).head_init == start
    assert list(conditions.ADAPTERS) == adapters.names(surface="play") == ["fresh", "posterior"]


def test_the_guard_combines_only_with_the_starts_it_names() -> None:
    guard = adapters.adapter(adapters.GUARD)
    for start in adapters.names(role="start"):
        if start in guard.guards:
            assert AdaptConfig(runs=["r"], head_init=start, guard=True).guard
        else:
            with pytest.raises(ValueError, match="guard: true"):
                AdaptConfig(runs=["r"], head_init=start, guard=True)


def test_the_old_spelling_table_is_the_fresh_adapter_in_the_server() -> None:
    assert adapters.canonical("table") == adapters.FRESH and adapters.adapter("table") is adapters.adapter("fresh")
    old = build_settings(agents=["pilot=oracle"], adapter="table").condition("pilot")
    new = build_settings(agents=["pilot=oracle"], adapter="fresh").condition("pilot")
    assert old.description == new.description and old.agent.description == new.agent.description
    assert old.agent.conventions is None and new.agent.conventions is None  # the paper's agent, no posterior around it
    with pytest.raises(
        ValueError, match=r"--adapter must be one of \['fresh', 'posterior'\] \(or the old spelling 'table'\), got 'pick'"
    ):
        build_settings(agents=["pilot=oracle"], adapter="pick")  # an adapter of `adapt` only
    with pytest.raises(
        ValueError,
        match="unknown adapter 'bayes'; adapters: fresh, pick, posterior, guard, lookup, counts-planner, prior-planner, plastic, known-seats",
    ):
        adapters.adapter("bayes")


def test_what_each_adapter_uses_is_stated_per_surface() -> None:
    uses = {name: {surface: u.names() for surface, u in record.uses.items()} for name, record in adapters.ADAPTERS.items()}
    assert uses["fresh"] == {"adapt": ["returns"], "play": ["partner_actions", "game_model"]}
    assert uses["pick"] == {"adapt": ["returns"]}
    assert uses["posterior"]["adapt"] == [
        "partner_actions",
        "partner_situation",
        "returns",
        "training_policies",
        "situation_keys",
        "game_model",
    ]
    assert "returns" not in uses["posterior"]["play"]
    assert uses["guard"] == {"adapt": ["returns"]}
    # The controls: the posterior's evidence without its Bayes, its planner without its evidence; none reads the returns.
    assert uses["lookup"] == {"adapt": ["partner_actions", "situation_keys"]}
    assert uses["counts-planner"] == {"adapt": ["partner_actions", "game_model"]}
    assert uses["prior-planner"] == {"adapt": ["training_policies", "game_model"]}
    # PLASTIC: the partners' moves against the training partners' policies, each seat's situation rebuilt by the rules.
    assert uses["plastic"] == {"adapt": ["partner_actions", "training_policies", "game_model"]}
    # Known seats: told which members it trained with, then PPO as the fresh head.
    assert uses["known-seats"] == {"adapt": ["returns", "partner_identities"]}
    assert [a.name for a in adapters.ADAPTERS.values() if a.in_paper] == ["fresh"]


def test_a_trained_ego_with_one_shared_head_can_adapt_only_from_a_fresh_head() -> None:
    registry.check_trained_ego("fresh", method("agg"), "'run'")
    registry.check_trained_ego("posterior", method("modular"), "'run'")
    for start in ("pick", "posterior", "plastic"):
        with pytest.raises(
            ValueError,
            match=f"head_init '{start}' needs one head per training partner, but the ego in 'run' was trained with method 'agg'",
        ):
            registry.check_trained_ego(start, method("agg"), "'run'")


@pytest.mark.parametrize("game", ["bandit", "blocks", "hanabi"])
def test_the_shipped_plans_name_adapters_of_the_vocabulary(game: str) -> None:
    plan = yaml.safe_load(config_file(f"plan_{game}.yaml").read_text())
    for label, variant in plan["adapt_variants"].items():
        settings = variant.get("settings", {})
        if "head_init" in settings:
            assert settings["head_init"] in adapters.names(role="start"), label
        if settings.get("guard"):
            assert settings.get("head_init", adapters.FRESH) in adapters.adapter(adapters.GUARD).guards, label
