"""Adapters on equal information: none reads what the ego's seat does not observe.

The convention posterior judges the new partner's moves in the situation the partner saw
(its observation). That is fair only where the partner's observation follows from what the
ego itself has observed and done; a game where it shows more declares what
(`GameRecord.partner_sees`), and there such adapters are refused before anything runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.adaptation.registry import ADAPTERS, CONTROLS, PLASTIC, check_game, check_information
from rllib_conv.envs.blocks.env import HIDDEN, decode_observations
from rllib_conv.envs.rllib_adapter import RLLIB_OBS_KEY, PettingZooMultiAgentEnv
from rllib_conv.envs.seat_views import seat_view
from rllib_conv.pipelines.plans import GAMES as PLAN_GAMES
from rllib_conv.pipelines.plans import plan_for, shipped_plan
from rllib_conv.play.room import GAMES as STUDY_GAMES

EGO, PARTNER = "player_0", "player_1"  # the seats every built-in population leaves to the ego and its partner


def _key(observation: Any) -> bytes:
    return np.asarray(observation["observation"] if isinstance(observation, dict) else observation).tobytes()


def _legal(rng: np.random.Generator, observation: Any, space) -> int:
    mask = observation.get("action_mask") if isinstance(observation, dict) else None
    return int(rng.choice(np.flatnonzero(mask))) if mask is not None else int(space.sample())


def partner_views(env, episodes: int, seed: int) -> list[tuple[tuple, bytes]]:
    """(what the ego has observed and done so far, what the partner observes) at each of the partner's moves."""
    rng, pairs = np.random.default_rng(seed), []
    for episode in range(episodes):
        history: list = []
        if hasattr(env, "agent_iter"):  # AEC: one mover at a time
            env.reset(seed=seed * 10_000 + episode)
            for agent in env.agent_iter():
                observation, _, terminated, truncated, _ = env.last()
                if terminated or truncated:
                    env.step(None)
                    continue
                action = _legal(rng, observation, env.action_space(agent))
                if agent == EGO:
                    history += [_key(observation), action]
                else:
                    pairs.append((tuple(history), _key(observation)))
                env.step(action)
        else:  # parallel: both move at once, each on its own observation of the same step
            observations, _ = env.reset(seed=seed * 10_000 + episode)
            while env.agents:
                history.append(_key(observations[EGO]))
                pairs.append((tuple(history), _key(observations[PARTNER])))
                actions = {a: _legal(rng, observations[a], env.action_space(a)) for a in env.agents}
                history.append(actions[EGO])
                observations, *_ = env.step(actions)
    return pairs


def first_disagreement(pairs: list[tuple[tuple, bytes]]) -> tuple | None:
    """An ego history seen with two different partner observations, if any."""
    seen: dict[tuple, bytes] = {}
    for history, partner in pairs:
        if seen.setdefault(history, partner) != partner:
            return history
    return None


@pytest.mark.parametrize("game", ["bandit", "blocks", "overcooked"])
def test_the_partners_observation_follows_from_what_the_ego_has_seen_and_done(game: str) -> None:
    assert envs.game(game).partner_sees is None
    config = {"layout": "cramped_room", "horizon": 20} if game == "overcooked" else {}
    pairs = partner_views(envs.make(game, **config), episodes=200, seed=0)
    # Histories must repeat for the check to bite (on Overcooked at least the fixed start does).
    histories = [h for h, _ in pairs]
    assert len(set(histories)) < len(histories)
    assert first_disagreement(pairs) is None


def test_hanabis_partner_sees_the_egos_hand_so_the_declaration_is_needed() -> None:
    assert envs.game("hanabi").partner_sees is not None
    # Deals with the same partner hand but another ego hand: the ego's first view is the same, the partner's not.
    assert first_disagreement(partner_views(envs.make("hanabi"), episodes=200, seed=0)) is not None


@pytest.mark.parametrize("game", envs.names())
@pytest.mark.parametrize("name", [a for a, rec in ADAPTERS.items() if "adapt" in rec.uses and rec.role == "start"])
def test_an_adapter_reading_the_partners_situation_is_refused_exactly_where_the_partner_sees_more(game, name) -> None:
    reads_it = ADAPTERS[name].uses["adapt"].partner_situation
    if reads_it and envs.game(game).partner_sees is not None:
        with pytest.raises(ValueError, match=f"in {game!r} shows .*information the ego does not have"):
            check_information(name, game)
    else:
        check_information(name, game)


def test_no_shipped_plan_or_study_game_gives_an_adapter_more_than_the_ego_sees() -> None:
    for game in PLAN_GAMES:
        for quick in (False, True):
            for variant in plan_for(game, quick=quick).adapt_variants:
                check_information(variant.settings.get("head_init", "fresh"), game)
    # The study server offers the posterior in every game it serves.
    assert all(envs.game(g).partner_sees is None for g in STUDY_GAMES)


def test_a_plan_asking_for_the_posterior_on_hanabi_is_refused_before_it_runs(tmp_path) -> None:
    text = shipped_plan("hanabi").read_text()
    bad = text.replace(
        "modular-lam0.5-guarded: {base: modular-lam0.5, settings: {guard: true}}",
        "modular-lam0.5-guarded: {base: modular-lam0.5, settings: {head_init: posterior}}",
    )
    assert bad != text
    (tmp_path / "plan.yaml").write_text(bad)
    with pytest.raises(
        ValueError, match=r"plan\.yaml.*adapt_variants\.modular-lam0\.5-guarded: head_init 'posterior' .* the ego's own hand"
    ):
        plan_for("hanabi", path=tmp_path / "plan.yaml")


def test_the_posteriors_controls_never_receive_the_partners_observation() -> None:
    # Declared: none reads the partner's situation (so each is allowed in every game that has what it needs).
    for name in CONTROLS:
        assert not ADAPTERS[name].uses["adapt"].partner_situation, name
    # Done: what the game copies record for them holds only the ego's own observations. On blocks P2's observation hides
    # the goal and P1's shows it, so a recorded partner observation would be seen.
    env, rng = PettingZooMultiAgentEnv(envs.make("blocks")), np.random.default_rng(0)
    env.record_seen_moves(EGO)
    ego_views = set()
    for episode in range(30):
        observations, _ = env.reset(seed=episode)
        while env.env.agents:
            agent = env.env.agent_selection
            if agent == EGO:
                ego_views.add(observations[EGO]["observations"].tobytes())
            observations, *_ = env.step({agent: int(rng.integers(6))})
    recorded, _, moves = env.take_seen_moves()
    assert len(moves) == 30 * 3
    assert {o.tobytes() for o in recorded} <= ego_views
    assert not (decode_observations(recorded)["goal"] == HIDDEN).any()


def test_plastic_reads_every_partner_seat_only_through_the_egos_own_observation() -> None:
    pytest.importorskip("lbforaging")
    # Declared: it never reads a partner's situation (its observation), so it is allowed wherever it can rebuild one.
    assert not ADAPTERS[PLASTIC].uses["adapt"].partner_situation
    # Done: on LBF (3 players, full sight) the ego's seat records only its own observations, and the situation PLASTIC
    # judges each partner seat's move in, rebuilt from it by the game's rules, is the one that seat acted on.
    config = {"players": 3}
    env, rng = PettingZooMultiAgentEnv(envs.make("lbf", **config)), np.random.default_rng(0)
    env.record_seen_moves(EGO)
    ego_views, acted_on = set(), []
    for episode in range(5):
        observations, _ = env.reset(seed=episode)
        while env.env.agents:
            ego_views.add(observations[EGO][RLLIB_OBS_KEY].tobytes())
            acted_on += [observations[a][RLLIB_OBS_KEY] for a in ("player_1", "player_2")]  # the order moves are recorded in
            actions = {a: int(rng.choice(np.flatnonzero(o["action_mask"]))) for a, o in observations.items()}
            observations, *_ = env.step(actions)
    recorded, ego_moves, _, seats = env.take_seen_moves(seated=True)
    assert {o.tobytes() for o in recorded} <= ego_views and list(seats[:2]) == ["player_1", "player_2"]
    views = {a: seat_view("lbf", config, EGO, a) for a in ("player_1", "player_2")}
    for observation, move, seat, truth in zip(recorded, ego_moves, seats, acted_on, strict=True):
        assert not np.array_equal(observation, truth)  # the partner's own vector is another one...
        assert np.array_equal(views[seat](observation, int(move))[0], truth)  # ...that the ego's determines
    # With partial sight the ego's observation does not determine a partner's: PLASTIC is refused before anything runs.
    with pytest.raises(ValueError, match="it does not show the situation of 'player_1'"):
        check_game(PLASTIC, "lbf", {"players": 3, "sight": 2}, EGO)
