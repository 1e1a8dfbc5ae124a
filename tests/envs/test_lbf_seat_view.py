"""Level-Based Foraging's seat views: a partner's observation and legal moves rebuilt from the ego's, checked against the env."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.envs.seat_views import seat_view

pytest.importorskip("lbforaging")


@pytest.mark.parametrize(("config", "ego"), [({"players": 3}, "player_0"), ({"players": 4, "size": 6}, "player_2")])
def test_every_partners_view_rebuilt_from_the_egos_observation_is_the_one_the_env_gives_it(config, ego: str) -> None:
    env, rng, checked = envs.make("lbf", **config), np.random.default_rng(0), 0
    views = {agent: seat_view("lbf", config, ego, agent) for agent in env.possible_agents if agent != ego}
    loads = 0
    for episode in range(15):
        observations, _ = env.reset(seed=episode)
        while env.agents:
            for agent, view in views.items():
                vector, mask = view(observations[ego]["observation"], -1)
                assert np.array_equal(vector, observations[agent]["observation"]), (episode, agent)
                assert np.array_equal(mask, observations[agent]["action_mask"]), (episode, agent)
                loads += int(mask[5])
                checked += 1
            # Mostly loads where legal, so food is collected and the field changes over the episode.
            actions = {}
            for agent in env.agents:
                legal = np.flatnonzero(observations[agent]["action_mask"])
                actions[agent] = 5 if 5 in legal and rng.random() < 0.8 else int(rng.choice(legal))
            observations, *_ = env.step(actions)
    assert checked > 500 and loads > 10  # the masks were checked next to food too


def test_with_partial_sight_there_is_no_view_and_other_games_have_none() -> None:
    assert seat_view("lbf", {"players": 3, "sight": 2}, "player_0", "player_1") is None
    assert seat_view("lbf", {"players": 3, "sight": 8}, "player_0", "player_1") is not None
    assert seat_view("blocks", {}, "player_0", "player_1") is None
