"""Scripted Overcooked cooks: conventions that matter, a policy that says what it draws from, seeded play."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv import partners
from rllib_conv.envs.overcooked.env import NUM_ACTIONS, STAY, OvercookedEnv
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.partners.kinds import gives_action_probs, partner_from_spec
from rllib_conv.partners.overcooked_cooks import COOK_LAYOUTS, ConventionCook, conventions


def _score(layout: str, a: ConventionCook | None, b: ConventionCook | None, seed: int = 0) -> float:
    """Sparse score of one 400-step episode (None: a player who always stays)."""
    for p in (a, b):
        if p is not None:
            p.seed(seed)
    env = OvercookedEnv(layout=layout, shaping=0.0)
    obs, _ = env.reset(seed=seed)
    total = 0.0
    while env.agents:
        actions = {
            agent: STAY if p is None else p.act(obs[agent][OBS_KEY], obs[agent][MASK_KEY])
            for agent, p in zip(env.possible_agents, (a, b))
        }
        obs, _, _, _, infos = env.step(actions)
        total += infos["player_0"]["sparse_reward"]
    return total


def test_a_cook_who_does_everything_delivers_soups_alone() -> None:
    # Known answer: beside a partner who always stays, a "both" cook fills the pot, plates and serves on its own.
    assert _score("cramped_room", ConventionCook("c", "cramped_room", role="both", onions=0), None) >= 60


def test_only_onion_cooks_never_deliver_and_an_onion_and_a_dish_cook_do() -> None:
    onions, dishes = (ConventionCook(r, "cramped_room", role=r, onions=0) for r in ("onions", "dishes"))
    assert _score("cramped_room", onions, ConventionCook("o2", "cramped_room", role="onions", onions=1)) == 0
    assert _score("cramped_room", onions, dishes) > 0


def test_cooks_faithful_to_different_pots_score_nothing_together() -> None:
    # coordination_ring has two pots: an onion cook filling pot 0 and a dish cook plating from pot 1 never meet.
    a = ConventionCook("a", "coordination_ring", role="onions", pot=0, onions=0)
    assert _score("coordination_ring", a, ConventionCook("b", "coordination_ring", role="dishes", pot=1)) == 0
    assert _score("coordination_ring", a, ConventionCook("c", "coordination_ring", role="dishes", pot=0)) > 0


def test_action_probs_are_one_hot_where_scripted_and_act_draws_from_them() -> None:
    cook = ConventionCook("c", "cramped_room", role="both")
    env = OvercookedEnv(layout="cramped_room")
    obs, _ = env.reset()
    rows = np.stack([obs[a][OBS_KEY] for a in env.possible_agents])
    masks = np.stack([obs[a][MASK_KEY] for a in env.possible_agents])
    probs = cook.action_probs(rows, masks)
    assert probs.shape == (2, NUM_ACTIONS) and np.allclose(probs.sum(1), 1.0)
    assert gives_action_probs(ConventionCook.kind)
    for row, mask, p in zip(rows, masks, probs):
        if p.max() == 1.0:
            assert cook.act(row, mask) == int(np.argmax(p))


def test_the_same_seed_plays_the_same_episode() -> None:
    make = lambda: (ConventionCook("a", "cramped_room", role="both"), ConventionCook("b", "cramped_room", role="both", onions=1))  # noqa: E731
    assert _score("cramped_room", *make(), seed=3) == _score("cramped_room", *make(), seed=3)


@pytest.mark.parametrize("layout", COOK_LAYOUTS)
def test_each_layout_has_a_population_of_its_conventions_with_held_out_cooks(layout: str) -> None:
    pop = partners.get(f"overcooked-{layout}-cooks")
    train, test = ([e for e in pop.partners if e.split == s] for s in ("train", "test"))
    assert len(train) + len(test) == len(conventions(layout)) and test and len(train) > len(test)
    assert pop.env == "overcooked" and pop.env_config == {"layout": layout}
    rebuilt = partner_from_spec(pop.partners[0].model_dump(include={"name", "kind", "params"}))
    assert isinstance(rebuilt, ConventionCook) and rebuilt.params() == pop.partners[0].params


def test_bad_conventions_are_refused_naming_the_choice() -> None:
    with pytest.raises(ValueError, match="role"):
        ConventionCook("c", "cramped_room", role="chef")
    with pytest.raises(ValueError, match="pot must be -1 .* or 0..0"):
        ConventionCook("c", "cramped_room", pot=1)
    with pytest.raises(ValueError, match="unknown Overcooked layout"):
        ConventionCook("c", "kitchen")
