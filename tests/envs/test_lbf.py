"""Level-Based Foraging: PettingZoo API, determinism under a seed, loading and rewards on hand-built states, errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from rllib_conv import envs
from rllib_conv.envs.lbf import LOAD, NONE, LBFEnv, observation_size, read_observation
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv

CONFIGS = [
    {"players": 2},
    {"players": 3},
    {"players": 4, "size": 6, "food": 2, "sight": 2},
    {"players": 3, "coop": True, "shared_reward": False, "horizon": 20},
]


def random_play(env: LBFEnv, seed: int, steps: int) -> list[tuple]:
    """Legal actions drawn from a generator seeded `seed`, episodes seeded `seed, seed+1, ...`: every step's outcome."""
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    trace, episode = [], 0
    for _ in range(steps):
        actions = {a: int(rng.choice(np.flatnonzero(obs[a]["action_mask"]))) for a in env.agents}
        obs, rewards, terms, truncs, _ = env.step(actions)
        trace.append((actions, {a: o["observation"].tolist() for a, o in obs.items()}, rewards, terms, truncs))
        if not env.agents:
            episode += 1
            obs, _ = env.reset(seed=seed + episode)
    return trace


def place(env: LBFEnv, players: list[tuple[int, int, int]], food: dict[tuple[int, int], int]) -> dict:
    """Start an episode on a field set by hand: each seat's (row, col, level) and the food levels by cell; return its observations."""
    env.reset(seed=0)
    forage = env.forage
    forage.field = np.zeros((env.size, env.size), np.int32)
    for (row, col), level in food.items():
        forage.field[row, col] = level
    forage._food_spawned = float(forage.field.sum())  # the package normalises rewards by the food on the field
    for player, (row, col, level) in zip(forage.players, players):
        player.position, player.level = (row, col), level
    return env.observe()


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: "-".join(f"{k}{v}" for k, v in c.items()))
def test_pettingzoo_api(config: dict) -> None:
    parallel_api_test(envs.make("lbf", **config), num_cycles=120)  # crosses the 50-step horizon


@pytest.mark.parametrize("config", CONFIGS[:3], ids=lambda c: f"players{c['players']}")
def test_one_seed_one_game_whatever_the_env_instance(config: dict) -> None:
    # PettingZoo's parallel_seed_test draws actions without the mask, which this env refuses: the same check, masked.
    first = random_play(envs.make("lbf", **config), seed=7, steps=300)
    assert first == random_play(envs.make("lbf", **config), seed=7, steps=300)
    assert first != random_play(envs.make("lbf", **config), seed=8, steps=300)


def test_reset_with_a_seed_spawns_the_same_field_and_without_one_goes_on() -> None:
    env = envs.make("lbf", players=3)
    first, _ = env.reset(seed=11)
    second, _ = env.reset()
    again, _ = env.reset(seed=11)
    assert all((first[a]["observation"] == again[a]["observation"]).all() for a in env.possible_agents)
    assert any((first[a]["observation"] != second[a]["observation"]).any() for a in env.possible_agents)


def test_observation_layout_food_then_self_then_the_others() -> None:
    env = envs.make("lbf", players=3, size=8, food=2)
    obs = place(env, [(3, 3, 1), (6, 6, 2), (0, 7, 1)], {(2, 5): 2, (5, 1): 3})
    assert env.observation_space("player_0")["observation"].shape == (observation_size(3, 2),)
    seen = read_observation(obs["player_1"]["observation"], food=2, players=3)
    assert seen.food.tolist() == [[2, 5, 2], [5, 1, 3]]  # reading order
    assert seen.players.tolist() == [[6, 6, 2], [3, 3, 1], [0, 7, 1]]  # itself first, then seat order
    # Partial sight: 1 cell around (3, 3) is rows/cols 2..4, in window coordinates; nothing else is in view.
    near = envs.make("lbf", players=3, size=8, food=2, sight=1)
    obs = place(near, [(3, 3, 1), (6, 6, 2), (0, 7, 1)], {(2, 4): 2, (5, 1): 3})
    seen = read_observation(obs["player_0"]["observation"], food=2, players=3)
    assert seen.food.tolist() == [[0, 2, 2]] and seen.players.tolist() == [[1, 1, 1]]


def test_two_level_one_players_load_a_level_two_food_together_and_share_the_reward() -> None:
    env = envs.make("lbf", players=2, size=8, food=1)
    obs = place(env, [(3, 2, 1), (3, 4, 1)], {(3, 3): 2})
    assert obs["player_0"]["action_mask"][LOAD] == 1
    _, rewards, terms, _, infos = env.step({"player_0": LOAD, "player_1": NONE})  # alone: too weak
    assert rewards == {"player_0": 0.0, "player_1": 0.0} and not any(terms.values())
    _, rewards, terms, truncs, infos = env.step({"player_0": LOAD, "player_1": LOAD})
    assert rewards == {"player_0": 1.0, "player_1": 1.0}  # every food collected: the team scores 1
    assert [infos[a]["own_reward"] for a in env.possible_agents] == [0.5, 0.5]  # the package's shares, by level
    assert all(terms.values()) and not any(truncs.values()) and env.agents == []


def test_own_rewards_when_not_shared_and_truncation_at_the_horizon() -> None:
    env = envs.make("lbf", players=2, size=8, food=2, horizon=2, shared_reward=False)
    place(env, [(3, 2, 1), (6, 6, 1)], {(3, 3): 1, (1, 6): 1})
    _, rewards, terms, truncs, _ = env.step({"player_0": LOAD, "player_1": NONE})
    assert rewards == {"player_0": 0.5, "player_1": 0.0} and not any(truncs.values())
    _, rewards, terms, truncs, _ = env.step({"player_0": NONE, "player_1": NONE})
    assert not any(terms.values()) and all(truncs.values()) and env.agents == []


@pytest.mark.parametrize("first", [0, 1])
def test_a_contested_load_resolves_in_seat_order(first: int) -> None:
    # A (at 3,4) loads food X (3,3, level 2); B (at 3,2) is next to X and to Y (2,2, level 1) and looks north first.
    # Resolving A first, X takes both (A + B = 2) and Y stays; B first, Y is B's alone and A fails on X.
    env = envs.make("lbf", players=2, size=8, food=2, shared_reward=False)
    a, b = (3, 4, 1), (3, 2, 1)
    place(env, [a, b] if first == 0 else [b, a], {(3, 3): 2, (2, 2): 1})
    env.step({"player_0": LOAD, "player_1": LOAD})
    left = {cell for cell in [(3, 3), (2, 2)] if env.forage.field[cell] > 0}
    assert left == ({(2, 2)} if first == 0 else {(3, 3)})


def test_masked_actions_raise_and_moves_into_food_or_walls_are_masked() -> None:
    env = envs.make("lbf", players=2, size=8, food=1)
    obs = place(env, [(0, 0, 1), (5, 5, 1)], {(1, 0): 1})
    # At the top-left corner with food to the south: no north, west or south; nothing adjacent to player_1.
    assert obs["player_0"]["action_mask"].tolist() == [1, 0, 0, 0, 1, 1]
    assert obs["player_1"]["action_mask"].tolist() == [1, 1, 1, 1, 1, 0]
    with pytest.raises(ValueError, match="action 5 is not legal for player_1"):
        env.step({"player_0": NONE, "player_1": LOAD})
    with pytest.raises(ValueError, match="no action for player_1"):
        env.step({"player_0": NONE})


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ({"players": 5}, r"players must be an integer in \[2, 4\], got 5"),
        ({"players": 1}, r"players must be an integer in \[2, 4\]"),
        ({"size": 4}, r"size must be an integer >= 5"),
        ({"sight": 9}, r"sight must be an integer in \[1, 8\]"),
        ({"food": 0}, r"food must be an integer in \[1, 9\]"),
        ({"coop": 1}, r"coop must be true or false"),
        ({"render_mode": "human"}, r"render_mode must be one of"),
    ],
)
def test_bad_settings_name_the_argument(config: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        envs.make("lbf", **config)


def test_rllib_sees_every_seat_with_its_mask() -> None:
    # RLlib's check_multiagent_environments draws actions without the mask, which this env refuses: stepped masked here.
    env = PettingZooMultiAgentEnv(envs.make("lbf", players=3))
    obs, _ = env.reset(seed=0)
    assert sorted(obs) == ["player_0", "player_1", "player_2"]
    assert obs["player_2"]["observations"].shape == (observation_size(3, 3),)
    for _ in range(60):  # past the 50-step horizon: every seat acts each step until the episode ends for all
        actions = {a: int(np.flatnonzero(o["action_mask"])[-1]) for a, o in obs.items()}
        obs, rewards, terms, truncs, _ = env.step(actions)
        if terms["__all__"] or truncs["__all__"]:
            break
        assert sorted(obs) == sorted(rewards) == ["player_0", "player_1", "player_2"]
    assert terms["__all__"] or truncs["__all__"]


def test_render_shows_food_levels_and_players_by_letter() -> None:
    env = envs.make("lbf", players=2, size=5, food=1, render_mode="ansi")
    place(env, [(0, 0, 1), (4, 4, 2)], {(2, 2): 3})
    assert env.render() == "A....\n.....\n..3..\n.....\n....B"


def test_without_the_extra_the_name_says_how_to_install_it() -> None:
    hide = (
        "import importlib.util; real = importlib.util.find_spec; "
        "importlib.util.find_spec = lambda name, *a: None if name == 'lbforaging' else real(name, *a); "
        "from rllib_conv import envs\n"
        "try:\n    envs.game('lbf')\nexcept ValueError as exc:\n    print(exc)\n"
        "print('lbf' in envs.names())"
    )
    out = subprocess.run([sys.executable, "-c", hide], capture_output=True, text=True, check=True).stdout
    assert "pip install 'rllib-conv[lbf]'" in out and out.strip().endswith("False")
