"""End to end in a real headless browser: scripted people play through the page; the CSVs must follow.

Each page is screenshotted under the test's tmp_path (agent_session.png, person_1.png, ...).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from rllib_conv.common.user_study_table import load_user_study
from rllib_conv.play.lobby import Lobby
from rllib_conv.play.recording import SessionRecorder
from rllib_conv.play.room import CELL_NAMES
from rllib_conv.play.server import PlayServer, build_lobby

SCHEDULE = [(task, c, t) for task in ("train", "test") for c in "ABC" for t in range(1, 6)]
TIMEOUT_MS = 15_000
expect.set_options(timeout=TIMEOUT_MS)  # the machine has 2 busy cores


@pytest.fixture
def serve():
    """Start servers for a test; stop them (after its pages are closed) at the end."""
    servers: list[PlayServer] = []

    def start(lobby: Lobby) -> PlayServer:
        srv = PlayServer(lobby, port=0)
        srv.start()
        servers.append(srv)
        return srv

    yield start
    for srv in servers:
        srv.stop()


@pytest.fixture
def pages(browser):
    """New pages, each in its own browser context (two people = two browsers); JS errors are collected."""
    contexts, errors = [], []

    def new_page() -> Page:
        context = browser.new_context(viewport={"width": 1000, "height": 900})
        contexts.append(context)
        page = context.new_page()
        page.set_default_timeout(TIMEOUT_MS)
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        return page

    new_page.errors = errors
    yield new_page
    for context in contexts:
        context.close()


def good_arms(page: Page) -> list[int]:
    return [int(a) for a in page.locator(".arm.good").evaluate_all("els => els.map(e => e.dataset.arm)")]


def room_code(page: Page) -> str:
    """The room code once the page shows it (it is filled in when the server answers)."""
    expect(page.locator("#room-code")).to_have_text(re.compile(r"^[A-Z2-9]{4}$"))
    return page.locator("#room-code").inner_text()


def wait_played(page: Page, n: int) -> None:
    page.wait_for_selector(f'body[data-played="{n}"]', state="attached")


def test_person_plays_a_full_study_session_with_the_agent(study_ego: Path, serve, pages, tmp_path: Path) -> None:
    out = tmp_path / "rec"
    srv = serve(build_lobby(study_ego, out=out, agent_delay=0))
    page = pages()
    page.goto(srv.url)
    expect(page.locator("#agent-card")).to_be_visible()
    expect(page.locator("#agent-desc")).to_contain_text("modular ego (lam 0.5) trained with bandit-user-study")
    page.check("input[name=seat][value='2']")
    page.click("#start-agent")
    expect(page.locator("#status")).to_have_text("Your turn: pick an arm.")
    expect(page.locator("#where")).to_have_text("Train task · context A · try 1 of 5")
    expect(page.locator("#you")).to_have_text("Player 2")
    expect(page.locator("#last")).to_have_text("No try played yet.")

    picks = []
    for i, (task, context, attempt) in enumerate(SCHEDULE):
        page.wait_for_selector('body[data-phase="choose"]', state="attached")
        expect(page.locator("#where")).to_have_text(f"{'Train' if task == 'train' else 'Test'} task · context {context} · try {attempt} of 5")
        arm = good_arms(page)[0]  # a consistent person: the left-most green arm
        page.click(f'.arm[data-arm="{arm}"]')
        wait_played(page, i + 1)
        last = page.locator("#last").inner_text()
        assert f"context {context}, try {attempt}): you pulled arm {arm}, the agent pulled arm" in last
        picks.append(arm)
    expect(page.locator("#status")).to_contain_text("Session finished")
    expect(page.locator("#arms .arm")).to_have_count(0)
    shot = tmp_path / "agent_session.png"
    page.screenshot(path=shot, full_page=True)
    assert shot.stat().st_size > 10_000
    assert pages.errors == []

    df = load_user_study(out / "bandit_human_agent.csv")
    assert list(zip(df["task"], df["context"], df["try"])) == SCHEDULE
    assert df["action_2"].tolist() == picks and (df["pair"] == 1).all()
    score = page.locator("#score").inner_text()
    assert score.startswith(f"Score: {int(df['coordinated'].sum())}") and "30 of 30 tries played" in score


def test_two_people_play_a_session_in_one_room(serve, pages, tmp_path: Path) -> None:
    out = tmp_path / "rec"
    srv = serve(Lobby("bandit", SessionRecorder(out)))
    one, two = pages(), pages()
    one.goto(srv.url)
    expect(one.locator("#agent-card")).to_be_hidden()  # no RUN: people only
    one.click("#create-room")
    expect(one.locator("#status")).to_contain_text("Waiting for your partner to join")
    code = room_code(one)
    two.goto(srv.url)
    two.fill("#join-code", code.lower())
    two.click("#join-room")
    expect(one.locator("#partner")).to_have_text("another person")  # player 1's page learns it by itself

    picks = []
    for i, (_, _, attempt) in enumerate(SCHEDULE):
        for page in (one, two):
            page.wait_for_selector('body[data-phase="choose"]', state="attached")
        a1 = good_arms(one)[-1]
        a2 = good_arms(two)[0] if attempt == 1 else a1  # they settle on player 1's arm after try 1
        one.click(f'.arm[data-arm="{a1}"]')
        expect(one.locator("#status")).to_have_text(f"You picked arm {a1}. Waiting for your partner to pick.")
        expect(two.locator(f'.arm[data-arm="{a1}"]')).not_to_have_class("arm good chosen")  # nothing of it shows on page 2
        two.click(f'.arm[data-arm="{a2}"]')
        for page in (one, two):
            wait_played(page, i + 1)
        assert f"you pulled arm {a2}, your partner pulled arm {a1}" in two.locator("#last").inner_text()
        assert f"you pulled arm {a1}, your partner pulled arm {a2}" in one.locator("#last").inner_text()
        picks.append((a1, a2))
    for n, page in enumerate((one, two), start=1):
        expect(page.locator("#status")).to_contain_text("Session finished")
        shot = tmp_path / f"person_{n}.png"
        page.screenshot(path=shot, full_page=True)
        assert shot.stat().st_size > 10_000
    assert pages.errors == []

    df = load_user_study(out / "bandit_human_human.csv")
    assert list(zip(df["action_1"], df["action_2"])) == picks
    assert list(zip(df["task"], df["context"], df["try"])) == SCHEDULE


def test_bad_requests_show_a_clear_error_in_the_page_and_record_nothing(serve, pages, tmp_path: Path) -> None:
    out = tmp_path / "rec"
    srv = serve(Lobby("bandit", SessionRecorder(out)))
    one, two = pages(), pages()
    one.goto(srv.url)
    one.fill("#join-code", "QQQQ")
    one.click("#join-room")
    expect(one.locator("#error")).to_have_text("no room with code 'QQQQ': check the code your partner gave you")
    expect(one.locator("#lobby")).to_be_visible()

    one.click("#create-room")
    expect(one.locator("#error")).to_be_hidden()  # a new action clears the old error
    code = room_code(one)
    one.evaluate("play.sendMove({arm: 1})")
    expect(one.locator("#error")).to_have_text(f"your partner has not joined yet: give them the room code {code}")
    two.goto(srv.url)
    two.fill("#join-code", code)
    two.click("#join-room")
    expect(two.locator("#status")).to_have_text("Your turn: pick an arm.")
    two.evaluate("play.sendMove({arm: 7})")
    expect(two.locator("#error")).to_have_text("arm must be an integer from 1 to 4, got 7")
    one.click('.arm[data-arm="1"]')
    one.evaluate("play.sendMove({arm: 2})")  # out of turn: a second pick in the same try
    expect(one.locator("#error")).to_have_text("you already picked arm 1 for this try; wait for your partner's pick")
    one.screenshot(path=tmp_path / "error.png", full_page=True)
    assert not (out / "bandit_human_human.csv").exists()  # no try completed, nothing recorded

    two.click('.arm[data-arm="4"]')
    wait_played(one, 1)
    df = load_user_study(out / "bandit_human_human.csv")
    assert df[["try", "action_1", "action_2"]].values.tolist() == [[1, 1, 4]]
    assert pages.errors == []


def test_two_people_play_blocks_and_see_moves_as_they_happen(serve, pages, tmp_path: Path) -> None:
    out = tmp_path / "rec"
    srv = serve(Lobby("blocks", SessionRecorder(out), games=1, seed=5))
    p1, p2 = pages(), pages()
    p1.goto(srv.url)
    expect(p1.locator("#title")).to_have_text("Block placing")
    p1.click("#create-room")
    code = room_code(p1)
    p2.goto(srv.url)
    p2.fill("#join-code", code)
    p2.click("#join-room")
    expect(p1.locator("#status")).to_have_text("Your turn (P1, red): move 1 of 6.")
    expect(p2.locator("#status")).to_have_text("Waiting for your partner (P1): move 1 of 6.")
    expect(p2.locator("#goal .cell.hidden")).to_have_count(4)  # P2 never sees the goal in play
    goal = p1.locator("#goal .cell").evaluate_all("els => els.map(e => e.className)")
    red, blue = next(i for i, c in enumerate(goal) if "red" in c), next(i for i, c in enumerate(goal) if "blue" in c)

    p2.evaluate("play.sendMove({action: 0})")
    expect(p2.locator("#error")).to_have_text("not your turn: move 1 is P1's (your partner)")
    p1.click(f'#board .cell[data-cell="{red}"]')
    expect(p2.locator("#moves li")).to_have_count(1)  # P2's page shows P1's move by itself
    expect(p2.locator(f'#board .cell[data-cell="{red}"]')).to_have_class("cell red")
    expect(p2.locator("#moves li")).to_have_text([f"P1 red on {CELL_NAMES[red]} (partner)"])
    for n, page in enumerate((p1, p2), start=1):
        page.screenshot(path=tmp_path / f"blocks_p{n}_move2.png", full_page=True)
    p2.click(f'#board .cell[data-cell="{blue}"]')
    for _ in range(2):
        p1.click("#pass")
        p2.wait_for_selector('body[data-phase="your_turn"]', state="attached")
        p2.click("#pass")
        if _ == 0:
            p1.wait_for_selector('body[data-phase="your_turn"]', state="attached")
    for n, page in enumerate((p1, p2), start=1):
        expect(page.locator("#status")).to_have_text("Session finished: 20 points in 1 game. Thank you!")
        page.screenshot(path=tmp_path / f"blocks_p{n}.png", full_page=True)
    expect(p2.locator("#last .cell.red")).to_have_count(2)  # the goal is revealed to P2 once the game is over
    rows = (out / "blocks" / "human_human.csv").read_text().splitlines()
    assert len(rows) == 7 and rows[-1].endswith(",20")
    assert pages.errors == []
