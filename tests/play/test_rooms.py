"""Rooms: the study's schedule, hidden picks, turn and step checks, writes before memory, replay after a restart."""

from __future__ import annotations

import io
import json
import sqlite3
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rllib_conv.common.user_study_table import USER_STUDY_GOOD_ARMS, load_user_study
from rllib_conv.envs.bandit import user_study_prizes
from rllib_conv.envs.bandit.keys import bandit_context
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.blocks import TEST_PERMUTATIONS, TRAIN_PERMUTATIONS, PermutationPartner
from rllib_conv.play.agent import AdaptiveAgent, bandit_oracle_prior, responder_prior, uniform_prior
from rllib_conv.play.bandit_room import BanditRoom
from rllib_conv.play.blocks_room import BlocksRoom
from rllib_conv.play.convention_agent import ConventionSource
from rllib_conv.play.export import BLOCKS_COLUMNS, table_csv
from rllib_conv.play.room import PlayError
from rllib_conv.play.store import DB_FILE, Participant, Store

PRIORS = {"train": bandit_oracle_prior(user_study_prizes(False)), "test": bandit_oracle_prior(user_study_prizes(True))}
SCHEDULE = [(task, c, t) for task in ("train", "test") for c in "ABC" for t in range(1, 6)]


def good(task: str, context: str) -> tuple[int, ...]:
    """1-based good arms of a study context."""
    return tuple(a + 1 for a in USER_STUDY_GOOD_ARMS[task]["ABC".index(context)])


def open_store(path: Path, game: str = "bandit") -> Store:
    store = Store(path / DB_FILE)
    store.check_settings({"game": game}, {"human": ("human", "people"), "agent": ("agent", "oracle")})
    return store


def seat_pair(store: Store, condition: str = "human", agent_seat: int | None = None, game: str = "bandit") -> int:
    """A stored room with its participants (the database's foreign keys want both); its pair number."""
    n = len(store.participants())
    seats = {1: f"p{n}", 2: f"p{n + 1}"} if agent_seat is None else {3 - agent_seat: f"p{n}"}
    for pid in seats.values():
        store.add_participant(Participant(pid, "t" + pid, condition, created=0.0, updated=0.0))
    return store.open_room(game, condition, agent_seat, seats, 0.0)


def exported(store: Store) -> pd.DataFrame:
    """The study's tries as the export writes them, read back by the analysis' reader."""
    path = store.path.parent / "export.csv"
    path.write_text(table_csv(store))
    return load_user_study(path)


@pytest.fixture
def store(tmp_path: Path):
    s = open_store(tmp_path)
    yield s
    s.close()


@pytest.fixture
def room(store: Store) -> BanditRoom:
    r = BanditRoom(seat_pair(store), store)
    r.start()
    return r


def agent_room(store: Store, seed: int = 0, greedy: bool = True) -> BanditRoom:
    pair = seat_pair(store, "agent", agent_seat=1)
    r = BanditRoom(pair, store, AdaptiveAgent(PRIORS["train"], greedy=greedy, seed=seed), 1, PRIORS)
    r.start()
    return r


def test_two_people_play_the_whole_study_and_it_is_stored_in_the_user_study_format(room: BanditRoom, store: Store) -> None:
    picks = []
    for i, (task, context, attempt) in enumerate(SCHEDULE):
        view = room.view(1)
        assert (view["task"], view["context"], view["try"], view["played"], view["step"]) == (task, context, attempt, i, i)
        if (task, context, attempt) == ("test", "A", 1):
            assert view["status"].startswith("Part 2 starts: the green arms have changed.")  # lay words, not "Test task"
        assert [a["prize"] > 0 for a in view["arms"]] == [a in good(task, context) for a in range(1, 5)]
        a1 = good(task, context)[0]
        a2 = good(task, context)[-1] if attempt == 1 else a1  # they disagree on try 1 of symmetric contexts
        room.move(1, {"arm": a1, "step": i})
        after = room.move(2, {"arm": a2, "step": i})
        picks.append((a1, a2))
        prize = 1.0 if a1 == a2 else 0.0
        assert after["last"] == {"task": task, "context": context, "try": attempt, "you": a2, "partner": a1, "prize": prize}
    final = room.view(2)
    assert final["phase"] == "finished" and "Session finished" in final["status"] and final["played"] == 30
    assert final["score"] == sum(a == b for a, b in picks)

    df = exported(store)
    assert list(zip(df["task"], df["context"], df["try"])) == SCHEDULE
    assert list(zip(df["action_1"], df["action_2"])) == picks
    assert (df["pair"] == room.pair).all() and (df["condition"] == "human").all()
    assert df["coordinated"].sum() == final["score"]


def test_a_pick_stays_hidden_until_both_have_picked(room: BanditRoom) -> None:
    mine = room.move(1, {"arm": 3, "step": 0})
    assert mine["your_choice"] == 3 and mine["phase"] == "waiting" and "Waiting for your partner" in mine["status"]
    theirs = room.view(2)
    assert theirs["partner_chose"] is True and theirs["your_choice"] is None and theirs["phase"] == "choose"
    assert theirs["last"] is None and theirs["history"] == []
    assert "3" not in json.dumps({k: v for k, v in theirs.items() if k not in ("arms", "version", "tries", "total")})


def snapshot(room: BanditRoom, store: Store) -> tuple:
    return (
        room.version,
        room.step,
        dict(room.picks),
        [tuple(r) for r in store.tries(room.pair)],
        [tuple(r) for r in store.picks(room.pair)],
    )


@pytest.mark.parametrize(
    "seat, payload, status, message",
    [
        (1, {"arm": 0, "step": 1}, 400, "arm must be an integer from 1 to 4, got 0"),
        (1, {"arm": 5, "step": 1}, 400, "arm must be an integer from 1 to 4, got 5"),
        (1, {"arm": "two", "step": 1}, 400, "got 'two'"),
        (1, {"arm": 2.5, "step": 1}, 400, "got 2.5"),
        (1, {"arm": True, "step": 1}, 400, "got True"),
        (1, {"arm": [1], "step": 1}, 400, "got [1]"),
        (1, {"step": 1}, 400, "got None"),
        (1, {"arm": "9" * 400, "step": 1}, 400, "got '9999"),
        (2, {"arm": 1}, 400, "step must be an integer from 0 to"),
        (2, {"arm": 1, "step": "x"}, 400, "step must be an integer"),
        (2, {"arm": 1, "step": 0}, 409, "this move answers try 1, but the session is at try 2: it was already played"),
        (2, {"arm": 1, "step": 5}, 409, "answers try 6, but the session is at try 2"),
        (1, {"arm": 2, "step": 1}, 409, "you already picked arm 1 for this try"),
    ],
)
def test_bad_moves_are_refused_clearly_and_change_nothing(
    room: BanditRoom, store: Store, seat: int, payload: dict, status: int, message: str
) -> None:
    room.move(1, {"arm": 2, "step": 0})
    room.move(2, {"arm": 2, "step": 0})  # one try stored
    room.move(1, {"arm": 1, "step": 1})  # player 1 has picked in try 2
    before = snapshot(room, store)
    with pytest.raises(PlayError) as err:
        room.move(seat, payload)
    assert err.value.status == status and message in err.value.message
    assert snapshot(room, store) == before


def test_no_move_after_the_end(room: BanditRoom, store: Store) -> None:
    for i in range(len(SCHEDULE)):
        room.move(1, {"arm": 1, "step": i})
        room.move(2, {"arm": 1, "step": i})
    with pytest.raises(PlayError, match="the session is over: all 30 tries") as err:
        room.move(1, {"arm": 1, "step": 30})
    assert err.value.status == 409
    assert len(store.tries(room.pair)) == 30


def test_a_failed_write_plays_nothing_and_the_pick_can_be_made_again(room: BanditRoom, store: Store) -> None:
    room.move(1, {"arm": 1, "step": 0})
    before = snapshot(room, store)
    store._db.execute("PRAGMA query_only = 1")  # every write now fails inside SQLite
    with pytest.raises(PlayError, match="could not record your pick .*readonly.*please pick again") as err:
        room.move(2, {"arm": 1, "step": 0})
    assert err.value.status == 503
    assert snapshot(room, store) == before and room.picks == {1: 0, 2: None}  # player 2 picks again
    store._db.execute("PRAGMA query_only = 0")
    room.move(2, {"arm": 1, "step": 0})
    assert [r["step"] for r in store.tries(room.pair)] == [0]


def test_a_room_replays_from_the_database_after_a_restart(room: BanditRoom, store: Store, tmp_path: Path) -> None:
    for i in range(7):
        room.move(1, {"arm": 2, "step": i})
        room.move(2, {"arm": 3 if i % 2 else 2, "step": i})
    room.move(2, {"arm": 4, "step": 7})  # a pick waiting for the partner's
    store.close()
    reopened = open_store(tmp_path)
    again = BanditRoom(room.pair, reopened)
    again.restore()
    again.start()
    for seat in (1, 2):
        assert {k: v for k, v in again.view(seat).items() if k != "version"} == {
            k: v for k, v in room.view(seat).items() if k != "version"
        }
    after = again.move(1, {"arm": 4, "step": 7})
    assert after["last"]["prize"] == 1.0 and after["played"] == 8  # the stored pick met its answer
    reopened.close()


def test_agent_commits_first_adapts_to_the_person_and_carries_conventions_to_the_test_task(store: Store) -> None:
    room = agent_room(store)
    person = {c: good("train", c)[-1] for c in "ABC"}  # the person's conventions: the right-most good arm
    person["test"] = {"A": good("test", "A")[0], "B": good("test", "B")[0], "C": person["C"]}  # Test-C keeps Train-C's
    for i, (task, context, _) in enumerate(SCHEDULE):
        view = room.view(2)
        assert view["partner_chose"] is True and view["partner"] == "agent"  # the agent picked before the person
        arm = person[context] if task == "train" else person["test"][context]
        room.move(2, {"arm": arm, "step": i})
    df = exported(store)
    assert (df["action_2"] == [person[c] if t == "train" else person["test"][c] for t, c in zip(df["task"], df["context"])]).all()
    by = df.set_index(["task", "context", "try"])["coordinated"]
    # A greedy agent with the true marginals: rules from the start, the person's convention from try 2.
    assert all(by["train", c, t] == 1 for c in "ABC" for t in range(2, 6))
    assert by["train", "A", 1] == 1 and by["test", "A", 1] == 1
    assert by["test", "C", 1] == 1  # Train-C's convention reused at once on the same symmetry
    assert all(by["test", "B", t] == 1 for t in range(2, 6))


def test_a_convention_agent_recognises_a_training_partners_convention_before_the_context_it_next_meets(store: Store) -> None:
    # `--adapter posterior` (not in the paper). Training partners "low" and "high" (each other's opposite in
    # B and C); the person follows "high". After B's tries the posterior names "high", so the greedy agent
    # picks its arm in C at the first try; the table alone would still split C's two good arms 1/2, 1/2.
    low, high = BanditConventionPartner("low", [0, 2, 1]), BanditConventionPartner("high", [0, 3, 3])
    source = ConventionSource(models=[low, high], known=[low, high], key=bandit_context)
    pair = seat_pair(store, "agent", agent_seat=1)
    room = BanditRoom(
        pair, store, source.agent(AdaptiveAgent(PRIORS["train"], greedy=True, seed=0), PRIORS["train"], seed=0), 1, PRIORS
    )
    room.start()
    for i, (_, context, _) in enumerate(SCHEDULE[:15]):
        room.move(2, {"arm": high.arms["ABC".index(context)] + 1, "step": i})  # the page counts arms from 1
    by = exported(store).set_index(["task", "context", "try"])["coordinated"]
    assert by["train", "C", 1] == 1 and all(by["train", "B", t] == 1 for t in range(2, 6))


def test_a_restored_agent_has_learnt_exactly_what_it_had(store: Store, tmp_path: Path) -> None:
    room = agent_room(store, greedy=False)
    for i in range(12):
        room.move(2, {"arm": good(*["train", "ABC"[(i // 5) % 3]])[-1], "step": i})
    store.close()
    reopened = open_store(tmp_path)
    again = BanditRoom(room.pair, reopened, AdaptiveAgent(PRIORS["train"], greedy=False, seed=99), 1, PRIORS)
    again.restore()
    again.start()
    for context in range(3):
        obs = np.eye(3, dtype=np.float32)[context]
        assert np.allclose(again.agent.policy(obs, np.ones(4)), room.agent.policy(obs, np.ones(4)))
    assert again.step == 12 and again.picks[1] is not None and again.picks[2] is None  # its hidden pick drawn again
    reopened.close()


def test_an_agent_room_needs_a_seat_and_both_priors(store: Store) -> None:
    agent = AdaptiveAgent(uniform_prior)
    with pytest.raises(ValueError, match="agent_seat must be 1 or 2, got 3"):
        BanditRoom(1, store, agent, 3, PRIORS)
    with pytest.raises(ValueError, match="agent_seat must be 1 or 2, got None"):
        BlocksRoom(1, store, agent, None)
    with pytest.raises(ValueError, match="a prior per task \\['train', 'test'\\], got \\['train'\\]"):
        BanditRoom(1, store, agent, 1, {"train": uniform_prior})


# --- blocks ----------------------------------------------------------------------------


@pytest.fixture
def blocks_store(tmp_path: Path):
    s = open_store(tmp_path / "blocks", "blocks")
    yield s
    s.close()


def blocks_rows(store: Store) -> list[str]:
    return table_csv(store).splitlines()


def test_blocks_turns_hidden_goal_and_recording(blocks_store: Store) -> None:
    room = BlocksRoom(seat_pair(blocks_store, game="blocks"), blocks_store, games=2, seed=3)
    room.start()
    assert room.view(1)["goal"] is not None and room.view(2)["goal"] is None  # only P1 sees the goal
    with pytest.raises(PlayError, match="not your turn: move 1 is P1's \\(your partner\\)") as err:
        room.move(2, {"action": 0, "step": 0})
    assert err.value.status == 409
    with pytest.raises(PlayError, match="action must be an integer from 0 to 5, got 6"):
        room.move(1, {"action": 6, "step": 0})
    with pytest.raises(PlayError, match="answers move 2, but the session is at move 1"):
        room.move(1, {"action": 0, "step": 1})
    assert room.moves == [] and room.version == 0 and blocks_store.moves() == []
    red, blue = room.env.goal
    for step, (seat, action) in enumerate([(1, red), (2, blue), (1, 5), (2, 5), (1, 5)]):
        room.move(seat, {"action": action, "step": step})
        assert room.view(2)["moves"][-1]["move"] == len(room.moves)  # each move shown as it happens
    assert len(blocks_store.moves()) == 5 and blocks_rows(blocks_store) == [
        ",".join((*BLOCKS_COLUMNS, "condition"))
    ]  # no finished game yet
    after = room.move(2, {"action": 5, "step": 5})
    assert after["played"] == 1 and after["score"] == 20.0
    assert after["last"]["goal"] == room.results[0]["goal"] and after["last"]["score"] == 20.0  # revealed to P2
    rows = blocks_rows(blocks_store)
    assert len(rows) == 7 and rows[1] == f"{room.pair},train,1,1,1,{red},{red},{blue},20,human"
    assert after["game_no"] == 2 and after["moves"] == []


def test_blocks_replays_from_the_database(blocks_store: Store, tmp_path: Path) -> None:
    pair = seat_pair(blocks_store, "agent", agent_seat=1, game="blocks")
    room = BlocksRoom(pair, blocks_store, AdaptiveAgent(uniform_prior, seed=0), 1, games=3, seed=4)
    room.start()
    person = PermutationPartner("person", [1, 3, 0, 2])
    while room.step < 15:
        obs = room.env.observe("player_1")
        room.move(2, {"action": person.act(obs["observation"], obs["action_mask"]), "step": room.step})
    blocks_store.close()
    reopened = open_store(tmp_path / "blocks", "blocks")
    again = BlocksRoom(pair, reopened, AdaptiveAgent(uniform_prior, seed=5), 1, games=3, seed=4)
    again.restore()
    assert {k: v for k, v in again.view(2).items() if k != "version"} == {k: v for k, v in room.view(2).items() if k != "version"}
    assert len(again.agent.partner) == len(room.agent.partner) > 0  # the same signals learnt from the same games
    again.start()
    assert again.step == 15 and again.turn == 2  # the person's move, then the agent answers as before
    obs = again.env.observe("player_1")
    assert again.move(2, {"action": person.act(obs["observation"], obs["action_mask"]), "step": 15})["step"] == 17
    reopened.close()


def test_blocks_agent_p1_moves_first_and_learns_the_persons_answer(blocks_store: Store) -> None:
    pair = seat_pair(blocks_store, "agent", agent_seat=1, game="blocks")
    room = BlocksRoom(pair, blocks_store, AdaptiveAgent(uniform_prior, seed=0), 1, games=12)
    room.start()
    assert len(room.moves) == 1 and room.moves[0][0] == 1  # the agent (P1) opened
    person = PermutationPartner("person", [1, 3, 0, 2])
    for _ in range(12 * 3):
        obs = room.env.observe("player_1")
        view = room.move(2, {"action": person.act(obs["observation"], obs["action_mask"]), "step": room.step})
    assert view["phase"] == "finished" and len(room.results) == 12
    assert len(room.agent.partner) > 0  # the agent learnt signals from the person's answers
    with pytest.raises(PlayError, match="the session is over"):
        room.move(2, {"action": 5, "step": room.step})


@pytest.mark.parametrize("perm, known_from", [(TRAIN_PERMUTATIONS[1], 1), (TEST_PERMUTATIONS[0], 2)])
def test_a_blocks_convention_agent_plans_against_the_persons_moves(
    tmp_path: Path, blocks_conventions: ConventionSource, perm: tuple[int, ...], known_from: int
) -> None:
    # `--adapter posterior` on blocks (not in the paper): the training partners are the 3 training
    # permutations, the heads their leaders. A person following a training permutation is met on every
    # goal from game 2 on (one answer names it); one recombining them cell by cell from game 3 on (with
    # these goals, its answers to the red cells that matter are in by then). The paper's table agent on
    # a uniform prior, fed the same hindsight targets, is still far from it.
    person = PermutationPartner("person", list(perm))
    scores = {}
    for adapter in ("table", "posterior"):
        store = open_store(tmp_path / adapter, "blocks")  # room 1 of each: the same goals
        pair = seat_pair(store, "agent", agent_seat=1, game="blocks")
        agent = AdaptiveAgent(uniform_prior, seed=0)
        room = BlocksRoom(
            pair,
            store,
            agent if adapter == "table" else blocks_conventions.agent(agent, uniform_prior, seed=0),
            1,
            games=12,
            seed=0,
        )
        room.start()
        while len(room.results) < 12:
            obs = room.env.observe("player_1")
            room.move(2, {"action": person.act(obs["observation"], obs["action_mask"]), "step": room.step})
        scores[adapter] = [r["score"] for r in room.results]
        store.close()
    assert scores["posterior"][known_from:] == [20.0] * (12 - known_from)
    assert scores["posterior"][:known_from] != [20.0] * known_from  # before the evidence it is not met for certain
    assert sum(scores["table"]) <= sum(scores["posterior"]) - 100


def test_blocks_person_as_p1_gets_the_responder(blocks_store: Store) -> None:
    pair = seat_pair(blocks_store, "agent", agent_seat=2, game="blocks")
    room = BlocksRoom(pair, blocks_store, AdaptiveAgent(responder_prior, seed=0), 2, games=1)
    room.start()
    assert room.moves == []  # the person is P1 and opens
    room.move(1, {"action": 2, "step": 0})
    assert room.moves[1][0] == 2 and room.moves[1][1] in (0, 1, 3)  # blue on a cell without red
    room.move(1, {"action": 5, "step": 2})
    assert room.moves[3] == (2, 5)  # then it passes
    view = room.move(1, {"action": 5, "step": 4})
    assert view["phase"] == "finished" and len(blocks_rows(blocks_store)) == 7


def test_blocks_agent_moves_after_a_delay_and_stale_timers_do_nothing(blocks_store: Store) -> None:
    pair = seat_pair(blocks_store, "agent", agent_seat=1, game="blocks")
    room = BlocksRoom(pair, blocks_store, AdaptiveAgent(uniform_prior, seed=0), 1, games=1, agent_delay=0.05)
    changes = []
    room.on_change = lambda r: changes.append(r.version)
    room.start()
    assert room.moves == [] and room.view(2)["phase"] == "their_turn"
    deadline = time.monotonic() + 5
    while not changes and time.monotonic() < deadline:
        time.sleep(0.01)
    assert len(room.moves) == 1 and changes == [1]  # the agent's move is announced
    room._agent_move(0)  # a late duplicate of the first timer
    assert len(room.moves) == 1 and len(blocks_store.moves()) == 1
    room.close()


def test_blocks_failed_write_undoes_the_move(blocks_store: Store) -> None:
    room = BlocksRoom(seat_pair(blocks_store, game="blocks"), blocks_store, games=1, seed=1)
    for step, seat in enumerate((1, 2, 1, 2, 1)):
        room.move(seat, {"action": 5, "step": step})
    grid, version = room.env.grid.copy(), room.version
    blocks_store._db.execute("PRAGMA query_only = 1")
    with pytest.raises(PlayError, match="could not record your move .*readonly.*play it again") as err:
        room.move(2, {"action": 2, "step": 5})
    assert err.value.status == 503
    assert len(room.moves) == 5 and room.env.move == 5 and room.turn == 2 and (room.env.grid == grid).all()
    assert room.version == version and room.results == [] and len(blocks_store.moves()) == 5
    blocks_store._db.execute("PRAGMA query_only = 0")
    assert room.move(2, {"action": 2, "step": 5})["phase"] == "finished"
    assert len(pd.read_csv(io.StringIO(table_csv(blocks_store)))) == 6


def test_a_stored_try_is_never_written_twice(store: Store) -> None:
    pair = seat_pair(store)
    row = {"task": "train", "context": "A", "try": 1, "action_1": 1, "action_2": 1}
    store.add_try(pair, 0, row, 1.0, 0.0)
    with pytest.raises(sqlite3.IntegrityError):
        store.add_try(pair, 0, row, 1.0, 0.0)
