"""Hidden-utility self-play (HSP): per-pair event weights, their wiring into the pair's env, the population's record."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from rllib_conv import partners
from rllib_conv.cli import main
from rllib_conv.common import config_files
from rllib_conv.common.seeds import pair_seed
from rllib_conv.envs.overcooked import EVENTS, STAY, OvercookedEnv
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.partners.base import Partner
from rllib_conv.pipelines import selfplay
from rllib_conv.pipelines.selfplay import train_population
from rllib_conv.pipelines.selfplay_config import HiddenUtilitySettings, SelfPlayConfig

EVENTS_USED = ["onion_pickup", "potting_onion", "dish_pickup", "soup_delivery"]


def hsp_raw(**overrides) -> dict:
    raw = config_files.load("tune_configs/selfplay_overcooked_hsp.yaml", [], schema=SelfPlayConfig)
    raw.update(overrides)
    return raw


def test_weights_are_drawn_per_pair_from_its_seed_and_never_all_zero() -> None:
    hidden = HiddenUtilitySettings(events=EVENTS_USED, values=[-1.0, 0.0, 1.0])
    draws = [hidden.draw(seed) for seed in range(20)]
    assert draws[3] == hidden.draw(3)  # the same seed, the same weights
    assert len({json.dumps(d) for d in draws}) > 10  # 81 possible draws: pairs differ
    assert all(set(d) == set(EVENTS_USED) and set(d.values()) <= {-1.0, 0.0, 1.0} for d in draws)
    assert all(any(d.values()) for d in draws)
    # Known answers: one non-zero value can only be drawn; all-zero values are kept as they are.
    assert HiddenUtilitySettings(events=["onion_pickup"], values=[0.0, 2.0]).draw(5) == {"onion_pickup": 2.0}
    assert HiddenUtilitySettings(events=["onion_pickup"], values=[0.0]).draw(5) == {"onion_pickup": 0.0}


def test_each_pair_trains_with_its_own_weights_on_the_partner_seat_only() -> None:
    cfg = SelfPlayConfig.model_validate(hsp_raw(pair=1))
    seed = pair_seed(cfg.seed, 1)
    env_config = selfplay.build_selfplay_config(cfg).env_config["game_config"]
    assert env_config == {**cfg.env_config, "hidden_utility": {"player_1": cfg.hidden_utility.draw(seed)}}
    other = SelfPlayConfig.model_validate(hsp_raw(pair=0))
    assert selfplay.build_selfplay_config(other).env_config["game_config"]["hidden_utility"]["player_1"] == (
        cfg.hidden_utility.draw(pair_seed(cfg.seed, 0))
    )
    # Without HSP the pair's env is the config's.
    plain = SelfPlayConfig.model_validate({**hsp_raw(), "hidden_utility": None})
    assert plain.pair_env_config(seed) == plain.env_config


@pytest.mark.parametrize(
    ("overrides", "match"),
    [
        ({"env": "bandit", "env_config": {}}, "game 'bandit' has no events"),
        ({"hidden_utility": {"events": ["onion_eaten"]}}, r"unknown event\(s\) \['onion_eaten'\]"),
        ({"population_entropy": 1.0}, "drop population_entropy/trajectory_diversity"),
        ({"shared_seats": True}, "drop shared_seats"),
        ({"hidden_utility": {"events": []}}, "events"),
    ],
)
def test_bad_hsp_settings_get_one_clear_error(overrides: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        SelfPlayConfig.model_validate(hsp_raw(**overrides))


def test_the_shipped_config_weighs_known_events() -> None:
    cfg = config_files.load_checked("tune_configs/selfplay_overcooked_hsp.yaml", schema=SelfPlayConfig).first
    assert cfg.hidden_utility is not None and set(cfg.hidden_utility.events) <= set(EVENTS)


@pytest.mark.slow
def test_an_hsp_population_records_each_partners_weights_and_loads(ray_session, tmp_path, capsys) -> None:
    raw = hsp_raw(train_pairs=2, test_pairs=0, run={"timesteps": 1600})
    raw["gate"] = {"score": 0.0, "episodes": 2, "check_every": 1, "check_episodes": 1}
    population, report = train_population(
        config_files.checked(raw, SelfPlayConfig), out=tmp_path / "pops", storage=tmp_path / "runs"
    )
    cfg = SelfPlayConfig.model_validate(raw)
    assert report["passed"].all()  # the gate scores the game: soups alone, never below 0
    expected = {f"sp{p:02d}": cfg.hidden_utility.draw(pair_seed(cfg.seed, p)) for p in range(2)}
    assert {e.name: e.hidden_utility for e in population.partners} == expected
    assert expected["sp00"] != expected["sp01"]
    on_disk = pd.read_csv(tmp_path / "pops" / cfg.name / "selfplay_report.csv")
    assert [json.loads(w) for w in on_disk["hidden_utility"]] == [expected["sp00"], expected["sp01"]]
    assert "HSP" in population.description
    reloaded = partners.get(str(tmp_path / "pops" / cfg.name))
    assert reloaded.partners[1].hidden_utility == expected["sp01"]
    assert reloaded.env_config == cfg.env_config  # partners are played, and scored, in the game itself
    capsys.readouterr()
    assert main(["partners", "show", str(tmp_path / "pops" / cfg.name)]) == 0
    assert json.dumps(expected["sp01"]) in capsys.readouterr().out
    # HSP's pruning keeps the pair furthest from the others, its networks copied into a folder of its own.
    assert (
        main(
            [
                "partners",
                "prune",
                str(tmp_path / "pops" / cfg.name),
                "--keep",
                "1",
                "--episodes",
                "1",
                "--out",
                str(tmp_path / "pruned"),
            ]
        )
        == 0
    )
    pruned = partners.get(str(tmp_path / "pruned" / f"{cfg.name}-pruned1"))
    (kept,) = pruned.partners
    assert kept.hidden_utility == expected[kept.name]
    assert Path(kept.checkpoint).is_relative_to(tmp_path / "pruned") and Path(
        kept.counterpart["params"]["checkpoint"]
    ).is_relative_to(tmp_path / "pruned")


def onion_pickups(partner: Partner, episodes: int = 3) -> float:
    """Onions `partner` picks up per episode in player_1's seat of cramped_room while player_0 stays put."""
    env = OvercookedEnv("cramped_room", hidden_utility={"player_1": {"onion_pickup": 1.0}})
    partner.seed(0)
    total = 0.0
    for episode in range(episodes):
        obs, _ = env.reset(seed=episode)
        while env.agents:
            seat = obs["player_1"]
            obs, rewards, _, _, _ = env.step({"player_0": STAY, "player_1": partner.act(seat[OBS_KEY], seat[MASK_KEY])})
            total += rewards["player_1"]
    return total / episodes


@pytest.mark.slow
def test_a_partner_rewarded_for_picking_onions_learns_to_pick_many_more(ray_session, tmp_path) -> None:
    # The obvious answer: the one weighted event becomes frequent (11 a 400-step episode before training, 64 after
    # 32k env steps in a trial run). FCP's snapshot before training is the untrained partner to compare with.
    raw = hsp_raw(train_pairs=1, test_pairs=0, fcp=True, run={"timesteps": 32_000})
    raw["hidden_utility"] = {"events": ["onion_pickup"], "values": [1.0]}
    raw["gate"] = {"score": 0.0, "stop": False, "episodes": 2, "check_every": 5, "check_episodes": 1}
    population, _ = train_population(config_files.checked(raw, SelfPlayConfig), out=tmp_path / "pops", storage=tmp_path / "runs")
    by_name = {e.name: e for e in population.partners}
    before, after = onion_pickups(by_name["sp00-init"].build()), onion_pickups(by_name["sp00"].build())
    assert after > 2 * before + 10, (before, after)
