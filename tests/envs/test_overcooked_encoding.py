"""Our Overcooked grid encoding: exact channel values on hand-built states, and the package's own layers on random play."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from overcooked.mdp.actions import Direction
from overcooked.mdp.overcooked_mdp import ObjectState, OvercookedState, PlayerState, SoupState

from rllib_conv.envs.overcooked import CHANNEL, CHANNELS, CLASSIC_LAYOUTS, NUM_CHANNELS, OvercookedEnv
from rllib_conv.envs.spaces import OBS_KEY

# cramped_room: XXPXX / O  2O / X1  X / XDXSX (x right, y down); grids are indexed [channel, y, x].


def grids(make_state: Callable[[], OvercookedState]) -> tuple[np.ndarray, np.ndarray]:
    """Both seats' observations of the state `make_state()` builds in cramped_room, as [channel, y, x].

    The env comes first: the package configures its recipes (which a cooked soup needs) when it builds an MDP.
    """
    env = OvercookedEnv("cramped_room")
    obs, _ = env.reset(options={"state": make_state()})
    return tuple(env.encoder.unflatten(obs[agent][OBS_KEY]) for agent in ("player_0", "player_1"))


def at(grid: np.ndarray, channel: str, x: int, y: int) -> float:
    return float(grid[CHANNEL[channel], y, x])


def kitchen(**state) -> OvercookedState:
    """player_0 at (1, 2) facing west holding an onion; player_1 at (3, 1) facing north holding a cooked soup;
    two onions in the pot; a dish on the counter (0, 0)."""
    players = [
        PlayerState((1, 2), Direction.WEST, ObjectState("onion", (1, 2))),
        PlayerState((3, 1), Direction.NORTH, SoupState.get_soup((3, 1), num_onions=3, finished=True)),
    ]
    objects = {(2, 0): SoupState.get_soup((2, 0), num_onions=2), (0, 0): ObjectState("dish", (0, 0))}
    return OvercookedState(players, objects, **state)


def test_the_channels_are_carrolls_26_layers_in_order() -> None:
    assert NUM_CHANNELS == 26 and CHANNELS[:2] == ("ego_position", "partner_position") and CHANNELS[-1] == "urgency"
    env = OvercookedEnv("cramped_room")
    assert env.encoder.shape == (26, 4, 5) and env.observation_space("player_0")[OBS_KEY].shape == (520,)


def test_each_seat_sees_itself_first() -> None:
    first, second = grids(kitchen)
    assert at(first, "ego_position", 1, 2) == 1 and at(first, "partner_position", 3, 1) == 1
    assert at(first, "ego_facing_west", 1, 2) == 1 and at(first, "partner_facing_north", 3, 1) == 1
    assert at(second, "ego_position", 3, 1) == 1 and at(second, "partner_position", 1, 2) == 1
    assert at(second, "ego_facing_north", 3, 1) == 1 and at(second, "partner_facing_west", 1, 2) == 1
    for grid in (first, second):  # one cell each, nothing else on the player channels
        assert grid[: CHANNEL["pot"]].sum() == 4
    # Beyond the players' channels both seats see the same kitchen.
    np.testing.assert_array_equal(first[CHANNEL["pot"] :], second[CHANNEL["pot"] :])


def test_terrain_objects_and_held_items_exact_values() -> None:
    grid, _ = grids(kitchen)
    assert at(grid, "pot", 2, 0) == 1 and grid[CHANNEL["pot"]].sum() == 1
    assert at(grid, "onion_dispenser", 0, 1) == at(grid, "onion_dispenser", 4, 1) == 1
    assert at(grid, "dish_dispenser", 1, 3) == 1 and at(grid, "serving", 3, 3) == 1
    assert grid[CHANNEL["counter"]].sum() == 9 and at(grid, "counter", 0, 0) == 1 and at(grid, "counter", 2, 0) == 0
    assert grid[CHANNEL["tomato_dispenser"]].sum() == 0
    assert at(grid, "onions_in_pot", 2, 0) == pytest.approx(2 / 3)  # two of three onions, not cooking
    assert grid[CHANNEL["onions_in_soup"]].sum() == 1 and at(grid, "onions_in_soup", 3, 1) == 1  # the held soup
    assert at(grid, "soup_done", 3, 1) == 1 and grid[CHANNEL["soup_done"]].sum() == 1
    assert at(grid, "onions", 1, 2) == 1 and grid[CHANNEL["onions"]].sum() == 1  # the held onion, on its holder's cell
    assert at(grid, "dishes", 0, 0) == 1 and grid[CHANNEL["dishes"]].sum() == 1
    assert grid[CHANNEL["soup_cook_time_remaining"]].sum() == 0 and grid[CHANNEL["urgency"]].sum() == 0


@pytest.mark.parametrize(("tick", "left", "done"), [(5, 0.75, 0.0), (19, 0.05, 0.0), (20, 0.0, 1.0)])
def test_a_cooking_pot_shows_its_time_left(tick: int, left: float, done: float) -> None:
    players = [PlayerState((1, 2), Direction.NORTH), PlayerState((3, 1), Direction.NORTH)]
    grid, _ = grids(lambda: OvercookedState(players, {(2, 0): SoupState.get_soup((2, 0), num_onions=3, cooking_tick=tick)}))
    assert at(grid, "onions_in_soup", 2, 0) == 1 and at(grid, "onions_in_pot", 2, 0) == 0
    assert at(grid, "soup_cook_time_remaining", 2, 0) == pytest.approx(left)  # (20 - tick) / 20
    assert at(grid, "soup_done", 2, 0) == done


@pytest.mark.parametrize(("timestep", "urgent"), [(360, 0.0), (361, 1.0)])
def test_urgency_covers_the_last_40_steps(timestep: int, urgent: float) -> None:
    grid, _ = grids(lambda: kitchen(timestep=timestep))
    assert (grid[CHANNEL["urgency"]] == urgent).all()


@pytest.mark.parametrize("layout", CLASSIC_LAYOUTS)
def test_random_play_matches_the_packages_own_layers_rescaled(layout: str) -> None:
    """The package's `lossless_state_encoding` has the same 26 layers, as [x, y, channel] with raw counts.

    (Its `featurize_state` is broken in this release; its grid layers run, only slowly.)
    """
    env = OvercookedEnv(layout)
    scale = np.ones(NUM_CHANNELS, dtype=np.float32)
    scale[[CHANNEL[c] for c in ("onions_in_pot", "tomatoes_in_pot", "onions_in_soup", "tomatoes_in_soup")]] = 3.0
    scale[CHANNEL["soup_cook_time_remaining"]] = 20.0
    rng = np.random.default_rng(0)
    # The package's random start puts soups (onions and tomatoes, some cooking) in pots and in hands.
    saved = np.random.get_state()  # it draws from numpy's global generator: seeded here, put back after
    np.random.seed(CLASSIC_LAYOUTS.index(layout))
    start = env.mdp.get_random_start_state_fn(random_start_pos=True, rnd_obj_prob_thresh=0.7)()
    np.random.set_state(saved)
    obs, _ = env.reset(options={"state": start})
    seen = set()
    while env.agents:
        theirs = env.mdp.lossless_state_encoding(env.state, horizon=env.horizon)
        for agent, layers in zip(("player_0", "player_1"), theirs):
            ours = env.encoder.unflatten(obs[agent][OBS_KEY]) * scale[:, None, None]
            np.testing.assert_allclose(ours, np.transpose(layers, (2, 1, 0)), atol=1e-5)
        seen |= {o.name for o in env.state.all_objects_list}
        # Interacting half the time carries things about: onions, dishes, and pots filled.
        obs, *_ = env.step({agent: int(rng.choice(6, p=[0.1] * 5 + [0.5])) for agent in env.agents})
    assert {"onion", "soup"} <= seen, seen
