"""The participant flow: consent, ids, balanced assignment, pairing, completion codes, timeouts, restarts, export."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rllib_conv.cli import main
from rllib_conv.common.user_study_table import load_user_study
from rllib_conv.play.agent import uniform_prior
from rllib_conv.play.conditions import Condition, StudySettings, build_settings, parse_named
from rllib_conv.play.convention_agent import ConventionAgent, ConventionSource
from rllib_conv.play.export import export, participants_csv
from rllib_conv.play.room import AgentSettings, PlayError
from rllib_conv.play.store import DB_FILE, Store
from rllib_conv.play.study import Study


class Clock:
    """A clock the test moves by hand."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def settings(conditions: str = "agent,human", **options) -> StudySettings:
    agents = ["agent=oracle"] if "agent" in conditions.split(",") else []
    return build_settings(agents=agents, conditions=conditions, greedy=True, **options)


@pytest.fixture
def clock() -> Clock:
    return Clock()


@pytest.fixture
def make(tmp_path: Path, clock: Clock):
    """Open studies on tmp_path's database (closing the previous one: a restart)."""
    opened: list[Store] = []

    def open_study(s: StudySettings | None = None) -> Study:
        for store in opened:
            store.close()
        opened.clear()
        opened.append(Store(tmp_path / DB_FILE))
        return Study(s or settings(), opened[0], clock=clock)

    yield open_study
    for store in opened:
        store.close()


def play_out(study: Study, token: str, arm: int = 1) -> dict:
    """Play a participant of an agent condition to the end; their last view."""
    view = study.view(study.participant(token))
    while view["phase"] == "choose":
        view = study.move(token, {"arm": arm, "step": view["step"]})
    return view


def test_consent_and_ids_are_checked(make) -> None:
    study = make()
    for consent in (None, False, "yes", 1):
        with pytest.raises(PlayError, match="consent must be true") as err:
            study.enrol("p1", consent)
        assert err.value.status == 400
    for bad in ("", "a b", "x" * 65, 42, ["p"], "é", "p1\n", "\np1"):  # a trailing newline slipped past `$`
        with pytest.raises(PlayError, match="participant must be an id of 1-64 letters") as err:
            study.enrol(bad, True)
        assert err.value.status == 400
    p = study.enrol("5f1e2d3c4b5a69788796a5b4", True)  # a Prolific id
    assert p.id == "5f1e2d3c4b5a69788796a5b4" and study.participant(p.token) is p
    generated = study.enrol(None, True)
    assert generated.id.startswith("anon-") and generated.token != p.token
    assert study.enrol(p.id, True, token=p.token) is p  # the same id with its token resumes, never a second enrolment
    with pytest.raises(PlayError, match="unknown or missing participant token") as err:
        study.participant("forged")
    assert err.value.status == 403


def test_assignment_is_balanced_at_every_arrival(make) -> None:
    three = build_settings(agents=["agent=oracle", "second=oracle"], conditions="agent,human,second")
    study = make(three)
    counts = {"agent": 0, "human": 0, "second": 0}
    firsts = []
    for i in range(30):
        p = study.enrol(f"p{i}", True)
        counts[p.condition] += 1
        assert max(counts.values()) - min(counts.values()) <= 1
        if i % 3 == 0:
            firsts.append(p.condition)
    assert counts == {"agent": 10, "human": 10, "second": 10}
    assert len(set(firsts)) > 1  # ties are broken at random, not always in the listed order


def test_people_of_the_human_condition_are_paired_when_both_are_connected(make, clock: Clock) -> None:
    study = make(settings("human"))
    a, b, c = (study.enrol(x, True) for x in ("a", "b", "c"))
    assert study.view(a)["phase"] == "waiting_for_partner" and study.view(a)["partner"] == "nobody"
    pushed: list[str] = []
    _, leave_a = study.connect(a.token, lambda: pushed.append("a"))
    assert a.state == "waiting"  # alone: nobody to pair with
    _, leave_c = study.connect(c.token, lambda: pushed.append("c"))
    assert (a.state, a.seat, c.state, c.seat, a.pair) == ("playing", 1, "playing", 2, c.pair)  # b never opened a page
    assert sorted(pushed) == ["a", "c"] and b.state == "waiting"
    with pytest.raises(PlayError, match="you have no partner yet") as err:
        study.move(b.token, {"arm": 1, "step": 0})
    assert err.value.status == 409
    study.move(a.token, {"arm": 1, "step": 0})
    assert pushed.count("c") == 2  # the partner's page hears of the pick at once
    leave_a()
    leave_c()


def test_sessions_end_with_a_completion_code(make) -> None:
    study = make(settings("agent"))
    p = study.enrol("p1", True)
    view = play_out(study, p.token)
    assert view["phase"] == "finished" and len(view["completion_code"]) == 8 and view["completion_code"] == p.completion_code
    assert view["history"] and view["score"] > 0  # the page keeps the whole session to show
    with pytest.raises(PlayError, match="your session is over"):
        study.move(p.token, {"arm": 1, "step": 30})
    fixed = make(settings("agent", completion_code="C1A2B3"))
    q = fixed.enrol("p2", True)
    assert play_out(fixed, q.token)["completion_code"] == "C1A2B3"
    codes = participants_csv(fixed.store)
    assert "p1,agent,1,2,finished,," in codes and "p2,agent,2,2,finished,,C1A2B3" in codes


def test_waiting_and_idle_sessions_end_early_with_a_code(make, clock: Clock) -> None:
    study = make(settings("agent,human", pair_timeout=60, idle_timeout=120))
    first, second = study.enrol("a", True), study.enrol("b", True)
    alone = first if first.condition == "human" else second
    player = second if alone is first else first
    study.connect(alone.token, lambda: None)
    clock.now += 61
    study.sweep()
    view = study.view(alone)
    assert view["phase"] == "ended" and "no other participant arrived in time" in view["status"] and view["completion_code"]
    study.move(player.token, {"arm": 1, "step": 0})
    clock.now += 100
    study.sweep()
    assert player.state == "playing"  # 100 s after its last move: still on
    clock.now += 21
    study.sweep()
    assert player.state == "ended" and player.end_reason == "idle" and study.view(player)["phase"] == "ended"
    assert [(s["name"], s["ended"]) for s in study.status()["conditions"]] == [("agent", 1), ("human", 1)]


def test_a_restarted_study_resumes_everyone_by_id(make) -> None:
    study = make()
    people = {pid: study.enrol(pid, True) for pid in ("a", "b", "c", "d")}
    humans = [p for p in people.values() if p.condition == "human"]
    agents = [p for p in people.values() if p.condition == "agent"]
    for p in humans:
        study.connect(p.token, lambda: None)
    for i in range(3):
        for p in agents:
            study.move(p.token, {"arm": 1, "step": i})
    study.move(humans[0].token, {"arm": 2, "step": 0})  # half a try
    before = {pid: study.view(p) for pid, p in people.items()}

    again = make()  # the server was killed and started on the same database
    for pid, p in people.items():
        resumed = again.enrol(pid, True, token=p.token)  # the token the page kept
        assert (resumed.token, resumed.condition, resumed.pair, resumed.seat) == (p.token, p.condition, p.pair, p.seat)
        view = again.view(resumed)
        for key in ("phase", "step", "history", "score", "your_choice", "partner_chose", "partner"):
            assert view[key] == before[pid][key], (pid, key)
    done = again.move(humans[1].token, {"arm": 2, "step": 0})
    assert done["last"]["prize"] == 0 and done["played"] == 1  # arm 2 is not good in Train-A


def test_a_restart_with_other_conditions_is_refused_while_sessions_are_open(make) -> None:
    study = make()
    study.enrol("a", True)
    study.enrol("b", True)
    with pytest.raises(ValueError, match="condition 'human' .* has 1 unfinished session"):
        make(settings("agent"))
    with pytest.raises(ValueError, match="was started with seed 0, not 3"):
        make(build_settings(agents=["agent=oracle"], conditions="agent,human", greedy=True, seed=3))


def test_participants_never_see_conditions_or_agent_descriptions(make) -> None:
    ours = build_settings(agents=["ours=oracle", "baseline=oracle"], conditions="ours,baseline", step_size=2.0)
    study = make(ours)
    secrets_ = ["ours", "baseline", "oracle", "step size", "marginals", "lam"]
    for i in range(4):
        p = study.enrol(f"p{i}", True)
        views = [study.view(p), study.move(p.token, {"arm": 1, "step": 0})]
        views.append(play_out(study, p.token))
        text = json.dumps(views)
        assert not [s for s in secrets_ if s in text], text
    status = json.dumps(study.status())
    assert "ours" in status and "oracle task module" in status  # the admin sees them


def test_settings_are_checked_naming_the_argument(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--conditions: 'ours' is neither 'human' nor an agent"):
        build_settings(conditions="ours,human")
    with pytest.raises(ValueError, match="--conditions agent leaves out the agent\\(s\\) \\['b'\\]"):
        build_settings(agents=["agent=oracle", "b=oracle"], conditions="agent")
    with pytest.raises(ValueError, match="--agent expects NAME=VALUE"):
        build_settings(agents=["oracle"])
    with pytest.raises(ValueError, match="'human' is the two-person condition"):
        build_settings(agents=["human=oracle"])
    with pytest.raises(ValueError, match="--agent: condition name 'Ours!'"):
        build_settings(agents=["Ours!=oracle"])
    with pytest.raises(ValueError, match="--test-run b: no agent 'b'"):
        build_settings(agents=["agent=oracle"], test_runs=["b=somewhere"])
    with pytest.raises(ValueError, match="the oracle agent is the bandit's"):
        build_settings(agents=["agent=oracle"], game="blocks")
    with pytest.raises(ValueError, match="--test-prior must be one of"):
        build_settings(test_prior="psychic")
    with pytest.raises(ValueError, match="--conditions lists a condition twice"):
        build_settings(conditions="human,human")
    with pytest.raises(ValueError, match="--pair-timeout must be a positive number"):
        build_settings(pair_timeout=0)
    with pytest.raises(ValueError, match="--completion-code must be 1-64 letters"):
        build_settings(completion_code="no spaces")
    with pytest.raises(ValueError, match="RUN .* does not exist"):
        build_settings(tmp_path / "missing")
    assert parse_named(["runs/x/seed=0"], "--test-run", "agent") == {"agent": "runs/x/seed=0"}  # '=' in a path
    assert parse_named(["b=runs/y/seed=1"], "--test-run", "agent") == {"b": "runs/y/seed=1"}
    assert [c.name for c in build_settings().conditions] == ["human"]
    assert build_settings(game="blocks").game == "blocks"
    with pytest.raises(ValueError, match="--game must be one of"):
        StudySettings(game="chess", conditions=[Condition("human", None, "")])


def test_the_export_is_the_user_study_format_and_the_report_reads_it(make, tmp_path: Path, capsys) -> None:
    study = make()
    people = [study.enrol(pid, True) for pid in ("a", "b", "c", "d")]
    for p in people:
        if p.condition == "human":
            study.connect(p.token, lambda: None)
    humans = [p for p in people if p.condition == "human"]
    for i in range(30):
        for p in humans:
            study.move(p.token, {"arm": 1, "step": i})
    for p in people:
        if p.condition == "agent":
            play_out(study, p.token)
    study.store.close()

    path, rows = export(tmp_path)  # the study folder: its study.sqlite3
    assert path == tmp_path / "user_study.csv" and rows == 90
    df = load_user_study(path)
    assert sorted(df.groupby("condition")["pair"].nunique().items()) == [("agent", 2), ("human", 1)]
    assert (df.groupby("pair").size() == 30).all()
    assert main(["play", "export", str(tmp_path / DB_FILE), "--out", str(tmp_path / "human.csv"), "--condition", "human"]) == 0
    assert "wrote 30 rows to" in capsys.readouterr().out
    assert set(load_user_study(tmp_path / "human.csv")["condition"]) == {"human"}
    assert main(["play", "export", str(tmp_path), "--condition", "robots"]) == 2
    assert "--condition 'robots'" in capsys.readouterr().err
    assert main(["play", "export"]) == 2 and "play export needs DB" in capsys.readouterr().err
    assert main(["play", "export", str(tmp_path / "nothing.sqlite3")]) == 2

    # `rllib-conv report ROOT --user-study exported.csv`: the paper's section gains the recorded sessions.
    from analysis.report import build_report

    root = tmp_path / "root"
    (root / "bandit").mkdir(parents=True)
    (root / "bandit" / "plan.json").write_text("{}")
    report = build_report(root, user_study=[path]).read_text()
    assert "### Recorded sessions (3 pairs in 1 file(s))" in report


@pytest.mark.parametrize("person_seat, wrapped", [(2, True), (1, False)])
def test_a_blocks_posterior_agent_sits_only_in_the_trained_seat(
    make, blocks_conventions: ConventionSource, person_seat: int, wrapped: bool
) -> None:
    # `--adapter posterior` on blocks: the heads and the plan are P1's (the trained seat); a person who
    # takes P1 gets the scripted responder, the paper's table agent, as with `--adapter table`.
    agent = AgentSettings(priors={"task": uniform_prior}, ego_seat=1, greedy=True, conventions=blocks_conventions)
    study = make(
        StudySettings(game="blocks", conditions=[Condition("agent", agent, "a blocks posterior agent")], person_seat=person_seat)
    )
    participant = study.enrol("p1", True)
    room = study.rooms[participant.pair]
    assert isinstance(room.agent, ConventionAgent) is wrapped and room.agent_seat == 3 - person_seat


def test_an_id_alone_never_takes_over_a_session(make) -> None:
    """Ids travel in URLs others see: re-enrolling with one needs the token its enrolment gave, else 409, counted for the admin."""
    study = make()
    p = study.enrol("5f1e2d3c4b5a69788796a5b4", True)
    for token in (None, "", "forged", p.token[:-1], 42, ["x"]):
        with pytest.raises(PlayError, match="already been used to start a session in another browser") as err:
            study.enrol(p.id, True, token=token)
        assert err.value.status == 409 and p.token not in err.value.message
    other = study.enrol("someone-else", True)
    with pytest.raises(PlayError):
        study.enrol(p.id, True, token=other.token)  # another participant's token is not this one's
    assert study.enrol(p.id, True, token=p.token) is p
    status = study.status()
    assert status["refused_resumes"] == 7 and status["recent_refused"] == [p.id] * 7 and status["participants"] == 2
    assert make().status()["refused_resumes"] == 7  # kept in the database across restarts
