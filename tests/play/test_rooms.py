"""Rooms: the study's schedule, hidden picks, turn checks, bad requests, and recordings that never break."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rllib_conv.common.user_study_table import DEFAULT_PATH, USER_STUDY_GOOD_ARMS, load_user_study
from rllib_conv.envs.bandit import user_study_prizes
from rllib_conv.partners.blocks import PermutationPartner
from rllib_conv.play import recording
from rllib_conv.play.agent import bandit_oracle_prior, uniform_prior
from rllib_conv.play.bandit_room import BanditRoom
from rllib_conv.play.lobby import Lobby
from rllib_conv.play.recording import BLOCKS_COLUMNS, CsvLog, SessionRecorder
from rllib_conv.play.room import AgentSettings, PlayError

PRIORS = {"train": bandit_oracle_prior(user_study_prizes(False)), "test": bandit_oracle_prior(user_study_prizes(True))}
SCHEDULE = [(task, c, t) for task in ("train", "test") for c in "ABC" for t in range(1, 6)]


def good(task: str, context: str) -> tuple[int, ...]:
    """1-based good arms of a study context."""
    return tuple(a + 1 for a in USER_STUDY_GOOD_ARMS[task]["ABC".index(context)])


@pytest.fixture
def out(tmp_path: Path) -> Path:
    return tmp_path / "sessions"


@pytest.fixture
def lobby(out: Path) -> Lobby:
    return Lobby("bandit", SessionRecorder(out))


@pytest.fixture
def agent_lobby(out: Path) -> Lobby:
    return Lobby("bandit", SessionRecorder(out), AgentSettings(priors=PRIORS, ego_seat=1, greedy=True, seed=0))


def human_pair(lobby: Lobby) -> tuple[BanditRoom, str, str]:
    room, t1, seat1 = lobby.create("human")
    _, t2, seat2 = lobby.join(room.code.lower())  # codes are case-insensitive
    assert (seat1, seat2) == (1, 2)
    return room, t1, t2


def test_two_people_play_the_whole_study_and_it_is_recorded_in_the_user_study_format(lobby: Lobby, out: Path) -> None:
    room, t1, t2 = human_pair(lobby)
    picks = []
    for i, (task, context, attempt) in enumerate(SCHEDULE):
        view = room.view(t1)
        assert (view["task"], view["context"], view["try"], view["played"]) == (task, context, attempt, i)
        if (task, context, attempt) == ("test", "A", 1):
            assert view["status"].startswith("The Test task starts: the green arms have changed.")
        assert [a["prize"] > 0 for a in view["arms"]] == [a in good(task, context) for a in range(1, 5)]
        a1 = good(task, context)[0]
        a2 = good(task, context)[-1] if attempt == 1 else a1  # they disagree on try 1 of symmetric contexts
        room.move(t1, {"arm": a1})
        after = room.move(t2, {"arm": a2})
        picks.append((a1, a2))
        prize = 1.0 if a1 == a2 else 0.0
        assert after["last"] == {"task": task, "context": context, "try": attempt, "you": a2, "partner": a1, "prize": prize}
    final = room.view(t2)
    assert final["phase"] == "finished" and "Session finished" in final["status"] and final["played"] == 30
    assert final["score"] == sum(a == b for a, b in picks)

    df = load_user_study(out / "bandit_human_human.csv")
    assert list(zip(df["task"], df["context"], df["try"])) == SCHEDULE
    assert list(zip(df["action_1"], df["action_2"])) == picks
    assert (df["pair"] == room.pair).all() and room.pair == 1
    assert df["coordinated"].sum() == final["score"]
    assert not (out / "bandit_human_agent.csv").exists()
    session = json.loads((out / "sessions.jsonl").read_text())
    assert session["pair"] == 1 and session["mode"] == "human" and session["room"] == room.code


def test_a_pick_stays_hidden_until_both_have_picked(lobby: Lobby) -> None:
    room, t1, t2 = human_pair(lobby)
    mine = room.move(t1, {"arm": 3})
    assert mine["your_choice"] == 3 and mine["phase"] == "waiting" and "Waiting for your partner" in mine["status"]
    theirs = room.view(t2)
    assert theirs["partner_chose"] is True and theirs["your_choice"] is None and theirs["phase"] == "choose"
    assert theirs["last"] is None and theirs["history"] == []
    assert "3" not in json.dumps({k: v for k, v in theirs.items() if k not in ("arms", "version", "tries", "total", "pair", "room")})


def snapshot(room: BanditRoom, out: Path) -> tuple:
    csv = out / "bandit_human_human.csv"
    return room.version, room.step, dict(room.picks), csv.read_bytes() if csv.exists() else None


@pytest.mark.parametrize(
    "request_, status, message",
    [
        (lambda lb, r, t1, t2: lb.room("ZZZZ"), 404, "no room with code 'ZZZZ'"),
        (lambda lb, r, t1, t2: lb.join("QQ"), 404, "no room with code 'QQ'"),
        (lambda lb, r, t1, t2: r.move("not-a-token", {"arm": 1}), 403, "not a player of room"),
        (lambda lb, r, t1, t2: r.move(None, {"arm": 1}), 403, "not a player of room"),
        (lambda lb, r, t1, t2: r.move(t1, {"arm": 0}), 400, "arm must be an integer from 1 to 4, got 0"),
        (lambda lb, r, t1, t2: r.move(t1, {"arm": 5}), 400, "arm must be an integer from 1 to 4, got 5"),
        (lambda lb, r, t1, t2: r.move(t1, {"arm": "two"}), 400, "got 'two'"),
        (lambda lb, r, t1, t2: r.move(t1, {"arm": 2.5}), 400, "got 2.5"),
        (lambda lb, r, t1, t2: r.move(t1, {"arm": True}), 400, "got True"),
        (lambda lb, r, t1, t2: r.move(t1, {}), 400, "got None"),
        (lambda lb, r, t1, t2: r.move(t1, {"arm": 2}), 409, "you already picked arm 1 for this try"),
        (lambda lb, r, t1, t2: lb.join(r.code), 409, "is full"),
        (lambda lb, r, t1, t2: lb.create("robot"), 400, "mode must be 'agent'"),
        (lambda lb, r, t1, t2: lb.create("agent", 1), 409, "has no trained agent"),
    ],
)
def test_bad_requests_are_refused_clearly_and_change_nothing(lobby: Lobby, out: Path, request_, status: int, message: str) -> None:
    room, t1, t2 = human_pair(lobby)
    room.move(t1, {"arm": 2})
    room.move(t2, {"arm": 2})  # one try recorded
    room.move(t1, {"arm": 1})  # player 1 has picked in try 2
    before = snapshot(room, out)
    with pytest.raises(PlayError) as err:
        request_(lobby, room, t1, t2)
    assert err.value.status == status and message in err.value.message
    assert snapshot(room, out) == before
    assert load_user_study(out / "bandit_human_human.csv")["try"].tolist() == [1]


def test_no_move_before_the_partner_joins_and_none_after_the_end(lobby: Lobby, out: Path) -> None:
    room, t1, _ = lobby.create("human")
    with pytest.raises(PlayError, match=f"partner has not joined yet: give them the room code {room.code}"):
        room.move(t1, {"arm": 1})
    assert room.view(t1)["phase"] == "waiting_for_partner"
    _, t2, _ = lobby.join(room.code)
    for _ in SCHEDULE:
        room.move(t1, {"arm": 1})
        room.move(t2, {"arm": 1})
    with pytest.raises(PlayError, match="the session is over: all 30 tries") as err:
        room.move(t1, {"arm": 1})
    assert err.value.status == 409
    assert len(load_user_study(out / "bandit_human_human.csv")) == 30


def test_a_failed_recording_plays_nothing_and_leaves_the_file_whole(lobby: Lobby, out: Path, monkeypatch) -> None:
    room, t1, t2 = human_pair(lobby)
    room.move(t1, {"arm": 1})
    room.move(t2, {"arm": 1})
    csv = out / "bandit_human_human.csv"
    before = csv.read_bytes()

    def crash(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(recording.os, "replace", crash)
    room.move(t1, {"arm": 1})
    with pytest.raises(PlayError, match="could not record this try .*No space left.*pick again") as err:
        room.move(t2, {"arm": 1})
    assert err.value.status == 500
    assert csv.read_bytes() == before and not list(out.glob(".*.tmp"))  # no half row, no litter
    assert room.step == 1 and room.picks == {1: 0, 2: None}  # player 2 picks again
    monkeypatch.undo()
    room.move(t2, {"arm": 1})
    assert load_user_study(csv)["try"].tolist() == [1, 2]


def test_an_invalid_row_never_reaches_the_file(tmp_path: Path) -> None:
    log = CsvLog(tmp_path / "s.csv", ("pair", "task", "context", "try", "action_1", "action_2"), recording.validate_user_study)
    log.append([{"pair": 1, "task": "train", "context": "A", "try": 1, "action_1": 1, "action_2": 1}])
    before = log.path.read_bytes()
    with pytest.raises(ValueError, match="action_2"):
        log.append([{"pair": 1, "task": "train", "context": "A", "try": 2, "action_1": 1, "action_2": 9}])
    with pytest.raises(ValueError, match="exactly the columns"):
        log.append([{"pair": 1, "task": "train"}])
    with pytest.raises(ValueError, match="repeats pair 1"):
        log.append([{"pair": 1, "task": "train", "context": "A", "try": 1, "action_1": 2, "action_2": 2}])
    assert log.path.read_bytes() == before


def test_pairs_continue_after_existing_recordings_and_foreign_files_are_refused(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    out.mkdir()
    shutil.copy(DEFAULT_PATH, out / "bandit_human_human.csv")  # the paper's 23 pairs
    lobby = Lobby("bandit", SessionRecorder(out))
    room, t1, t2 = human_pair(lobby)
    assert room.pair == 24
    room.move(t1, {"arm": 1})
    room.move(t2, {"arm": 1})
    assert Lobby("bandit", SessionRecorder(out)).create("human")[0].pair == 25  # a restarted server too
    assert set(load_user_study(out / "bandit_human_human.csv")["pair"]) == set(range(1, 25))

    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "bandit_human_agent.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="bandit_human_agent.csv.*has columns \\['a', 'b'\\]"):
        SessionRecorder(bad)
    (bad / "bandit_human_agent.csv").write_text("pair,task,context,try,action_1,action_2\n1,train,Z,1,1,1\n")
    with pytest.raises(ValueError, match="is not valid: .*column 'context'"):
        SessionRecorder(bad)


def test_agent_commits_first_adapts_to_the_person_and_carries_conventions_to_the_test_task(agent_lobby: Lobby, out: Path) -> None:
    room, token, seat = agent_lobby.create("agent", 2)
    assert seat == 2 and room.agent_seat == 1
    person = {c: good("train", c)[-1] for c in "ABC"}  # the person's conventions: the right-most good arm
    person["test"] = {"A": good("test", "A")[0], "B": good("test", "B")[0], "C": person["C"]}  # Test-C keeps Train-C's
    for task, context, _ in SCHEDULE:
        view = room.view(token)
        assert view["partner_chose"] is True and view["partner"] == "agent"  # the agent picked before the person
        arm = person[context] if task == "train" else person["test"][context]
        room.move(token, {"arm": arm})
    df = load_user_study(out / "bandit_human_agent.csv")
    assert (df["action_2"] == [person[c] if t == "train" else person["test"][c] for t, c in zip(df["task"], df["context"])]).all()
    by = df.set_index(["task", "context", "try"])["coordinated"]
    # A greedy agent with the true marginals: rules from the start, the person's convention from try 2.
    assert all(by["train", c, t] == 1 for c in "ABC" for t in range(2, 6))
    assert by["train", "A", 1] == 1 and by["test", "A", 1] == 1
    assert by["test", "C", 1] == 1  # Train-C's convention reused at once on the same symmetry
    assert all(by["test", "B", t] == 1 for t in range(2, 6))


def test_agent_rooms_pick_seats_and_refuse_bad_ones(agent_lobby: Lobby) -> None:
    room, token, seat = agent_lobby.create("agent", None)
    assert seat == 2 and room.agent_seat == 1  # default: the seat opposite the trained ego
    room, token, seat = agent_lobby.create("agent", 1)
    assert room.agent_seat == 2 and room.kinds == {1: "person", 2: "agent"}
    with pytest.raises(PlayError, match="seat must be an integer from 1 to 2, got 3"):
        agent_lobby.create("agent", 3)
    with pytest.raises(PlayError, match="only two-person rooms can be joined") as err:
        agent_lobby.join(room.code)
    assert err.value.status == 409


# --- blocks ----------------------------------------------------------------------------


def test_blocks_turns_hidden_goal_and_recording(out: Path) -> None:
    lobby = Lobby("blocks", SessionRecorder(out), games=2, seed=3)
    room, t1, _ = lobby.create("human")
    _, t2, _ = lobby.join(room.code)
    assert room.view(t1)["goal"] is not None and room.view(t2)["goal"] is None  # only P1 sees the goal
    with pytest.raises(PlayError, match="not your turn: move 1 is P1's") as err:
        room.move(t2, {"action": 0})
    assert err.value.status == 409
    with pytest.raises(PlayError, match="action must be an integer from 0 to 5, got 6"):
        room.move(t1, {"action": 6})
    assert room.moves == [] and room.version == 2
    red, blue = room.env.goal
    for token, action in [(t1, red), (t2, blue), (t1, 5), (t2, 5), (t1, 5)]:
        room.move(token, {"action": action})
        assert room.view(t2)["moves"][-1]["move"] == len(room.moves)  # each move shown as it happens
    assert not (out / "blocks" / "human_human.csv").exists()
    after = room.move(t2, {"action": 5})
    assert after["played"] == 1 and after["score"] == 20.0
    assert after["last"]["goal"] == room.results[0]["goal"] and after["last"]["score"] == 20.0  # revealed to P2
    rows = (out / "blocks" / "human_human.csv").read_text().splitlines()
    assert rows[0] == ",".join(BLOCKS_COLUMNS) and len(rows) == 7
    assert rows[1] == f"{room.pair},train,1,1,1,{red},{red},{blue},20"
    assert after["game_no"] == 2 and after["moves"] == []


def test_blocks_agent_p1_moves_first_and_learns_the_persons_answer(out: Path) -> None:
    lobby = Lobby("blocks", SessionRecorder(out), AgentSettings(priors={"task": uniform_prior}, ego_seat=1, seed=0), games=12, agent_delay=0)
    room, token, seat = lobby.create("agent", 2)
    assert seat == 2 and len(room.moves) == 1 and room.moves[0][0] == 1  # the agent (P1) opened
    person = PermutationPartner("person", [1, 3, 0, 2])
    for _ in range(12 * 3):
        obs = room.env.observe("player_1")
        view = room.move(token, {"action": person.act(obs["observation"], obs["action_mask"])})
    assert view["phase"] == "finished" and len(room.results) == 12
    assert len(room.agent.partner) > 0  # the agent learnt signals from the person's answers
    with pytest.raises(PlayError, match="the session is over"):
        room.move(token, {"action": 5})


def test_blocks_person_as_p1_gets_the_responder(out: Path) -> None:
    lobby = Lobby("blocks", SessionRecorder(out), AgentSettings(priors={"task": uniform_prior}, ego_seat=1, seed=0), games=1, agent_delay=0)
    room, token, seat = lobby.create("agent", 1)
    assert seat == 1 and room.moves == []  # the person is P1 and opens
    room.move(token, {"action": 2})
    assert room.moves[1][0] == 2 and room.moves[1][1] in (0, 1, 3)  # blue on a cell without red
    room.move(token, {"action": 5})
    assert room.moves[3] == (2, 5)  # then it passes
    view = room.move(token, {"action": 5})
    assert view["phase"] == "finished" and len((out / "blocks" / "human_agent.csv").read_text().splitlines()) == 7


def test_blocks_agent_moves_after_a_delay_and_stale_timers_do_nothing(out: Path) -> None:
    import time

    lobby = Lobby("blocks", SessionRecorder(out), AgentSettings(priors={"task": uniform_prior}, ego_seat=1, seed=0), games=1, agent_delay=0.05)
    room, token, _ = lobby.create("agent", 2)
    assert room.moves == [] and room.view(token)["phase"] == "their_turn"
    version = room.version
    room.wait_for_change(version, timeout=5)  # the agent's move wakes long polls
    assert len(room.moves) == 1 and room.version > version
    room._agent_move(room.game_no, 0)  # a late duplicate of the first timer
    assert len(room.moves) == 1
    lobby.close()
    time.sleep(0.01)


def test_blocks_failed_recording_undoes_the_last_move(out: Path, monkeypatch) -> None:
    lobby = Lobby("blocks", SessionRecorder(out), games=1, seed=1)
    room, t1, _ = lobby.create("human")
    _, t2, _ = lobby.join(room.code)
    for token in (t1, t2, t1, t2, t1):
        room.move(token, {"action": 5})
    grid, version = room.env.grid.copy(), room.version

    def crash(src, dst):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(recording.os, "replace", crash)
    with pytest.raises(PlayError, match="could not record this game .*Input/output error.*play it again") as err:
        room.move(t2, {"action": 2})
    assert err.value.status == 500
    assert len(room.moves) == 5 and room.env.move == 5 and room.turn == 2 and (room.env.grid == grid).all()
    assert room.version == version and room.results == [] and not (out / "blocks" / "human_human.csv").exists()
    monkeypatch.undo()
    assert room.move(t2, {"action": 2})["phase"] == "finished"
    assert len((out / "blocks" / "human_human.csv").read_text().splitlines()) == 7
