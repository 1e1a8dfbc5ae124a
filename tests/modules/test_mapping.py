"""PartnerMapping: one partner per episode and partner seat, in turn; ego to its head, partners to their modules."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from rllib_conv.modules import AGG_HEAD_ID, PartnerMapping
from rllib_conv.modules.partner_schedule import PartnerFunction, WeightedPartners
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig


def ep(i: int) -> SimpleNamespace:
    return SimpleNamespace(id_=f"episode-{i}")


def test_round_robin_and_consistent_within_an_episode() -> None:
    m = PartnerMapping(["a", "b", "c"], "player_0", "player_1")
    got = []
    for i in range(7):
        got.append((m("player_1", ep(i)), m("player_0", ep(i))))
    assert got == [
        ("partner@a", "ego@a"),
        ("partner@b", "ego@b"),
        ("partner@c", "ego@c"),
        ("partner@a", "ego@a"),
        ("partner@b", "ego@b"),
        ("partner@c", "ego@c"),
        ("partner@a", "ego@a"),
    ]


def test_shared_head_for_agg_and_unknown_agents() -> None:
    m = PartnerMapping(["a", "b"], "player_0", "player_1", shared_head=True)
    assert m("player_0", ep(0)) == AGG_HEAD_ID and m("player_1", ep(0)) == "partner@a"
    with pytest.raises(ValueError, match="neither the ego"):
        m("player_2", ep(0))
    with pytest.raises(ValueError, match="at least one partner"):
        PartnerMapping([], "player_0", "player_1")


def _partners_played(m: PartnerMapping, episodes: int, replica: int | None = None) -> list[str]:
    agent = "player_1" if replica is None else f"player_1#{replica}"
    return [m(agent, ep(i)).split("@", 1)[1].split("#")[0] for i in range(episodes)]


def test_weighted_partners_are_drawn_with_their_weights_reproducibly() -> None:
    def mapping(seed: int) -> PartnerMapping:
        return PartnerMapping(["a", "b", "c"], "player_0", "player_1", schedule=WeightedPartners({"a": 3.0, "b": 1.0}, [seed]))

    played = _partners_played(mapping(0), 4000)
    assert abs(played.count("a") / 4000 - 0.75) < 0.03 and abs(played.count("b") / 4000 - 0.25) < 0.03 and "c" not in played
    assert _partners_played(mapping(0), 50) == played[:50] and _partners_played(mapping(1), 50) != played[:50]


def test_a_replica_draws_its_partners_as_it_would_alone() -> None:
    names = ["a", "b", "c"]
    alone = PartnerMapping(names, "player_0", "player_1", schedule=WeightedPartners({"a": 1.0, "b": 1.0, "c": 1.0}, [7]))
    packed = PartnerMapping(
        names,
        "player_0",
        "player_1",
        replica_partners=[names] * 3,
        schedule=WeightedPartners({"a": 1.0, "b": 1.0, "c": 1.0}, [5, 7, 9]),
    )
    assert _partners_played(packed, 40, replica=1) == _partners_played(alone, 40)
    assert _partners_played(packed, 40, replica=0) != _partners_played(packed, 40, replica=1)


def test_a_users_function_chooses_the_partner_of_each_episode() -> None:
    m = PartnerMapping(
        ["a", "b", "c"],
        "player_0",
        "player_1",
        schedule=PartnerFunction("tests.modules.mapping_functions:alternate_first_two", [0]),
    )
    assert _partners_played(m, 5) == ["a", "b", "a", "b", "a"]
    assert m("player_0", ep(1)) == "ego@b"
    state = m.get_state()
    restored = PartnerMapping(
        ["a", "b", "c"],
        "player_0",
        "player_1",
        schedule=PartnerFunction("tests.modules.mapping_functions:alternate_first_two", [0]),
    )
    restored.set_state(state)
    assert _partners_played(restored, 7)[5:] == ["b", "a"]  # it goes on counting episodes where it stopped
    wrong = PartnerMapping(
        ["a", "b"], "player_0", "player_1", schedule=PartnerFunction("tests.modules.mapping_functions:nobody", [0])
    )
    with pytest.raises(ValueError, match="returned 'nobody' for episode 0; expected one of \\['a', 'b'\\]"):
        wrong("player_0", ep(0))


def test_three_seats_go_through_every_team_in_turn_and_the_ego_plays_its_teams_head() -> None:
    m = PartnerMapping(["a", "b", "c"], "player_0", ["player_1", "player_2"])
    teams = [(m("player_1", ep(i)), m("player_2", ep(i)), m("player_0", ep(i))) for i in range(10)]
    assert teams[:4] == [
        ("partner@a", "partner@a", "ego@a+a"),
        ("partner@b", "partner@a", "ego@b+a"),
        ("partner@c", "partner@a", "ego@c+a"),
        ("partner@a", "partner@b", "ego@a+b"),
    ]
    assert len(set(teams[:9])) == 9 and teams[9] == teams[0]  # all 3 x 3 teams, each once, then again
    assert (m("player_2", ep(5)), m("player_1", ep(5)), m("player_0", ep(5))) == (
        "partner@b",
        "partner@c",
        "ego@c+b",
    )  # asked again
    shared = PartnerMapping(["a", "b"], "player_0", ["player_1", "player_2"], shared_head=True)
    assert shared("player_0", ep(0)) == AGG_HEAD_ID
    with pytest.raises(ValueError, match="neither the ego \\('player_0'\\) nor a partner \\('player_1', 'player_2'\\)"):
        m("player_3", ep(0))


def test_three_seats_state_round_trips_and_an_old_one_seat_state_still_loads() -> None:
    m = PartnerMapping(["a", "b"], "player_0", ["player_1", "player_2"])
    played = [m("player_0", ep(i)) for i in range(3)]
    restored = PartnerMapping(["a", "b"], "player_0", ["player_1", "player_2"])
    restored.set_state(m.get_state())
    assert [restored("player_0", ep(i)) for i in range(4)] == [*played, "ego@b+b"]  # remembered, then goes on
    old = PartnerMapping(["a", "b"], "player_0", "player_1")
    old.set_state({"next": 1, "assigned": [["episode-0", [1]]], "focus": None, "schedule": {}})  # one int per replica
    assert old("player_1", ep(0)) == "partner@b" and old("player_1", ep(1)) == "partner@b"


def test_three_seats_with_weights_draw_each_seat_and_focus_fills_every_seat() -> None:
    m = PartnerMapping(["a", "b"], "player_0", ["player_1", "player_2"], schedule=WeightedPartners({"a": 1.0, "b": 1.0}, [3]))
    teams = [m("player_0", ep(i)) for i in range(2000)]
    assert sorted(set(teams)) == [f"ego@{t}" for t in ("a+a", "a+b", "b+a", "b+b")]
    assert all(abs(teams.count(t) / 2000 - 0.25) < 0.04 for t in set(teams))  # each seat drawn on its own, 1/2 each
    m.focus("b")
    assert (m("player_1", ep(2000)), m("player_2", ep(2000))) == ("partner@b", "partner@b")


def test_three_seats_refuse_a_mapping_function_and_bad_seats() -> None:
    m = PartnerMapping(
        ["a", "b"],
        "player_0",
        ["player_1", "player_2"],
        schedule=PartnerFunction("tests.modules.mapping_functions:alternate_first_two", [0]),
    )
    with pytest.raises(ValueError, match="chooses the partner of one partner seat"):
        m("player_0", ep(0))
    for seats in ([], ["player_1", "player_1"], ["player_0", "player_1"]):
        with pytest.raises(ValueError, match="distinct partner agents besides the ego"):
            PartnerMapping(["a"], "player_0", seats)


@pytest.mark.parametrize(
    ("path", "match"),
    [
        ("tests.modules.mapping_functions:missing", "cannot be loaded"),
        ("no_such_module_xyz:f", "cannot be loaded"),
        ("tests.modules.mapping_functions:NOT_CALLABLE", "is not callable"),
        ("nodots", "expected 'package.module:function'"),
    ],
)
def test_a_bad_function_path_is_refused_when_the_experiment_resolves(path: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        resolve(ExperimentConfig(population="bandit-s2-hand", mapping={"kind": "function", "function": path}))


def test_mapping_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="mapping.weights is for kind 'weighted'"):
        ExperimentConfig(population="bandit-s2-hand", mapping={"kind": "weighted"})
    with pytest.raises(ValueError, match="mapping.function is for kind 'function'"):
        ExperimentConfig(population="bandit-s2-hand", mapping={"function": "a:b"})
    with pytest.raises(ValueError, match=r"mapping.weights: \['hand-test-0'\] are not training partners"):
        resolve(ExperimentConfig(population="bandit-s2-hand", mapping={"kind": "weighted", "weights": {"hand-test-0": 1.0}}))
    with pytest.raises(ValueError, match="positive weight"):
        ExperimentConfig(population="bandit-s2-hand", mapping={"kind": "weighted", "weights": {"hand-train-0": 0.0}})


@pytest.mark.parametrize(
    ("mapping", "played"),
    [
        ({"kind": "weighted", "weights": {"hand-train-1": 1.0}}, {"hand-train-1"}),
        ({"kind": "function", "function": "tests.modules.mapping_functions:last_partner"}, {"hand-train-3"}),
        ({}, {f"hand-train-{k}" for k in range(4)}),
    ],
)
@pytest.mark.slow
def test_training_plays_the_partners_the_mapping_chooses(ray_session, mapping: dict, played: set[str]) -> None:
    exp = ExperimentConfig(
        population="bandit-s2-hand", model={"hidden": 8}, ppo={"rollout_per_partner": 16, "num_epochs": 1}, mapping=mapping
    )
    algo = build_ppo_config(resolve(exp)).build_algo()
    try:
        sampled = algo.train()["env_runners"]["num_module_steps_sampled_lifetime"]
    finally:
        algo.stop()
    partners = {mid.split("@", 1)[1].split("#")[0] for mid, n in sampled.items() if mid.startswith("partner@") and n > 0}
    assert partners == played
