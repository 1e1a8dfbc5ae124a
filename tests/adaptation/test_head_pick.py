"""Picking the head to adapt from (`head_init: pick`, not in the paper): the picker by hand, then through adaptation."""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path

import pytest
import yaml

from rllib_conv import envs
from rllib_conv.adaptation.head_pick import pick_head
from rllib_conv.common.config_files import checked
from rllib_conv.common.sealed import seal_file
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.blocks import BlocksLeader, PermutationPartner, derangements
from rllib_conv.partners.episodes import episode_stream
from rllib_conv.pipelines.adapt import adapt_curve, run_adaptation
from rllib_conv.pipelines.adapt_config import AdaptConfig

PARTNER_ARMS = [0, 1, 2, 3]  # bandit, symmetric 2: contexts 0 and 1 are symmetric (arm c or c + 4)


def bandit_players() -> dict[str, BanditConventionPartner]:
    return {
        "half": BanditConventionPartner("half", [4, 1, 2, 3]),  # agrees in 3 of 4 contexts
        "right": BanditConventionPartner("right", PARTNER_ARMS),
        "wrong": BanditConventionPartner("wrong", [4, 5, 2, 3]),  # agrees in 2 of 4
    }


def test_episodes_count_env_steps_as_rllib_does() -> None:
    bandit = envs.make("bandit", symmetric=2)
    seats = {"player_0": BanditConventionPartner("a", PARTNER_ARMS), "player_1": BanditConventionPartner("b", PARTNER_ARMS)}
    assert list(itertools.islice(episode_stream(bandit, seats), 3)) == [(1.0, 1)] * 3  # one joint step per episode
    perm = list(derangements()[0])
    blocks = envs.make("blocks")
    seats = {"player_0": BlocksLeader("l", perm), "player_1": PermutationPartner("p", perm)}
    assert list(itertools.islice(episode_stream(blocks, seats), 3)) == [(20.0, 6)] * 3  # six moves, one step each


def test_pick_plays_whole_rounds_within_the_budget_and_takes_the_best() -> None:
    def make_env():
        return envs.make("bandit", symmetric=2)

    def make_partner():
        return BanditConventionPartner("p", PARTNER_ARMS)

    pick = pick_head(make_env, bandit_players(), make_partner, "player_0", "player_1", budget=64, seed=3)
    assert pick.chosen == "right" and pick.returns["right"] == 1.0
    assert pick.steps == 63  # 21 rounds of 3 one-step episodes; a 22nd would need 66
    assert pick.returns["half"] < 1.0 and pick.returns["wrong"] < pick.returns["half"]
    assert pick_head(make_env, bandit_players(), make_partner, "player_0", "player_1", budget=64, seed=3) == pick  # seeded

    tiny = pick_head(make_env, bandit_players(), make_partner, "player_0", "player_1", budget=1, seed=3)
    assert tiny.steps == 3  # the first round is played even when it overruns the budget

    same = {"first": BanditConventionPartner("first", PARTNER_ARMS), "second": BanditConventionPartner("second", PARTNER_ARMS)}
    assert (
        pick_head(make_env, same, make_partner, "player_0", "player_1", budget=20, seed=0).chosen == "first"
    )  # ties: the earlier


def test_pick_compares_candidates_on_the_same_blocks_goals() -> None:
    perms = [list(p) for p in derangements()]
    players = {f"leader{i}": BlocksLeader(f"leader{i}", p) for i, p in enumerate(perms[:4])}
    pick = pick_head(
        lambda: envs.make("blocks"),
        players,
        lambda: PermutationPartner("p", perms[2]),
        "player_0",
        "player_1",
        budget=640,
        seed=0,
    )
    assert pick.chosen == "leader2" and pick.returns["leader2"] == 20.0
    assert pick.steps == 624  # 26 rounds of 4 six-move episodes; a 27th would need 648


@pytest.mark.slow
def test_pick_is_refused_without_per_partner_heads(bandit_egos, tmp_path) -> None:
    with pytest.raises(ValueError, match="method 'scratch' starts from a fresh network"):
        AdaptConfig(runs=["r"], method="scratch", head_init="pick")
    with pytest.raises(ValueError, match="set head_init: pick"):
        AdaptConfig(runs=["r"], pick_steps=64)
    trial = tmp_path / "trial"
    shutil.copytree(bandit_egos["bandit-s2-hand"].path, trial)
    trained = yaml.safe_load((trial / "config.yaml").read_text())
    (trial / "config.yaml").write_text(yaml.safe_dump({**trained, "method": "agg", "lam": 0.0}))
    seal_file(trial / "config.yaml")  # edited on purpose: sealed again, as training writes it
    with pytest.raises(ValueError, match="one head per training partner.*'agg'"):
        adapt_curve(AdaptConfig(runs=[str(trial)], head_init="pick"), str(trial), "hand-test-1")


@pytest.mark.slow
def test_adapting_to_a_known_convention_picks_its_head(bandit_egos, tmp_path) -> None:
    # A training partner's convention: its own head scores 1 at once; the fresh head plays the marginals (3/4).
    trial = Path(bandit_egos["bandit-s2-hand"].path)
    raw = {
        "name": "p",
        "runs": [str(trial)],
        "split": "train",
        "partners": ["hand-train-2"],
        "head_init": "pick",
        "pick_steps": 64,
        "steps": 96,
    }
    curves = run_adaptation(checked(raw, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    assert curves["steps"].tolist() == [0, 64, 80, 96]  # picking is charged as env steps
    assert abs(curves["exact_return"].iloc[0] - 0.75) < 0.05
    assert curves["exact_return"].iloc[1] >= 0.95  # right after picking, before any update
