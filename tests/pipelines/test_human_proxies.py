"""Human proxies (`pipelines.human_proxies`, `partners.overcooked`): trained into a cache, named as built-in populations.

The slow test trains on the 2019 human data cut short in a temporary cache (the
`short_human_cache` fixture, fetched through pip: without the registry it fails, it does not
skip); nothing derived from the data is written outside the test's temporary folders.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rllib_conv import partners
from rllib_conv.envs.overcooked import OvercookedEnv
from rllib_conv.envs.overcooked import human_data as hd
from rllib_conv.partners.overcooked import population_name, proxies_folder, proxy_population
from rllib_conv.partners.trained import TrainedPolicyPartner
from rllib_conv.pipelines import human_proxies
from rllib_conv.training.behaviour_cloning import BCSettings


def test_proxies_not_trained_yet_are_not_listed_and_name_the_command_that_trains_them(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(hd.CACHE_ENV, str(tmp_path))
    assert not [name for name in partners.names() if name.endswith(("-bc", "-hproxy"))]
    expected = r"run `rllib-conv human-proxies overcooked --layouts coordination_ring` first"
    with pytest.raises(ValueError, match=expected):
        partners.get("overcooked-coordination_ring-hproxy")
    with pytest.raises(ValueError, match="'overcooked-cramped_room-bc': no trained human proxies"):
        proxy_population("cramped_room", "bc", tmp_path)


def test_a_layout_without_human_data_or_an_unknown_kind_is_refused() -> None:
    with pytest.raises(ValueError, match="layouts with human data"):
        proxies_folder("large_room", "bc")
    with pytest.raises(ValueError, match="proxy kind must be one of bc, hproxy"):
        proxies_folder("cramped_room", "ppo")


@pytest.mark.parametrize(
    "layouts, seeds, episodes, message",
    [
        (["large_room"], [0], 2, "have no human data"),
        (["cramped_room"], [], 2, "seeds must be a non-empty list"),
        (["cramped_room"], [0, 0], 2, "seeds must be distinct"),
        (["cramped_room"], [0], 3, "episodes must be an even integer"),
    ],
)
def test_bad_arguments_are_one_clear_error_before_any_data_is_read(tmp_path, layouts, seeds, episodes, message) -> None:
    with pytest.raises(ValueError, match=message):
        human_proxies.run(layouts, seeds, tmp_path, episodes=episodes)
    assert not any(tmp_path.iterdir())


def test_the_human_return_is_the_logged_reward_per_horizon_steps_counted_once_per_step() -> None:
    frame = pd.DataFrame({"seat": [0, 0, 0, 0, 1, 1, 1, 1], "reward": [0.0, 20.0, 0.0, 0.0] * 2})
    assert human_proxies.human_return(frame, horizon=400) == 2000.0


@pytest.mark.slow  # fetches the data (pip), converts it, trains 4 short proxies: 5-30 s on 2 cores
def test_trained_proxies_resolve_by_name_and_play_either_seat(short_human_cache: Path, monkeypatch) -> None:
    short_cache = short_human_cache
    table = human_proxies.run(["cramped_room"], [0], short_cache, BCSettings(epochs=3), episodes=2)
    assert len(table) == 1
    row = table.iloc[0]
    for column in ("bc_accuracy_test_split", "hproxy_accuracy_train_split", "return_bc_hproxy", "return_bc_bc"):
        assert np.isfinite(row[column]), column
    assert 0.0 <= row["bc_accuracy_moves_test_split"] <= 1.0
    assert (short_cache / "proxies" / human_proxies.REPORT_FILE).is_file()
    # The built-in names resolve to the cache that RLLIB_CONV_CACHE points at (`<root>/overcooked`).
    root = short_cache.parent / "root"
    (root).mkdir()
    (root / "overcooked").symlink_to(short_cache)
    monkeypatch.setenv(hd.CACHE_ENV, str(root))
    listed = {population_name("cramped_room", "bc"), population_name("cramped_room", "hproxy")}
    assert listed <= set(partners.names()) and population_name("coordination_ring", "bc") not in partners.names()
    bc_pop, hproxy_pop = (partners.get(population_name("cramped_room", kind)) for kind in ("bc", "hproxy"))
    assert [e.split for e in bc_pop.partners] == ["train"] and [e.split for e in hproxy_pop.partners] == ["test"]
    assert bc_pop.env == "overcooked" and bc_pop.env_config == {"layout": "cramped_room"}
    bc_player, hproxy_player = bc_pop.build()[0], hproxy_pop.build()[0]
    assert isinstance(bc_player, TrainedPolicyPartner) and not bc_player.greedy
    env = OvercookedEnv("cramped_room", horizon=20)
    for seats in ((bc_player, hproxy_player), (hproxy_player, bc_player)):
        scores = partners.play_episodes(env, dict(zip(env.possible_agents, seats)), 1)
        assert np.isfinite(scores).all()
    # Same seed, same data: the same weights again (the checkpoint is rewritten, not appended to).
    again = human_proxies.run(["cramped_room"], [0], short_cache, BCSettings(epochs=3), episodes=2)
    assert again["bc_accuracy_test_split"].iloc[0] == row["bc_accuracy_test_split"]
