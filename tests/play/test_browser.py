"""End to end in headless Chromium: consent to completion code in both conditions, the admin page, restarts, blocks,
the pages a participant sees when something goes wrong (a session ended early, a damaged study link).

Each page is screenshotted under the test's tmp_path (agent_session.png, person_1.png, ended_early.png, ...).
"""

from __future__ import annotations

import re
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Page, expect

from rllib_conv.common.user_study_table import load_user_study
from rllib_conv.play.conditions import build_settings
from rllib_conv.play.export import table_csv
from rllib_conv.play.room import CELL_NAMES
from rllib_conv.play.server import StudyServer
from rllib_conv.play.store import DB_FILE
from tests.play.servers import ADMIN_TOKEN, oracle_study

SCHEDULE = [(task, c, t) for task in ("train", "test") for c in "ABC" for t in range(1, 6)]
TIMEOUT_MS = 15_000
INTERNALS = ("modular", "lam 0.5", "EgoTrainable", "bandit-user-study", "oracle", "step size", "condition")
RESEARCHER_WORDS = ("Train task", "Test task", "context", "participant must be", "token")  # never in a participant's visible text
expect.set_options(timeout=TIMEOUT_MS)  # the machine has 2 busy cores


@pytest.fixture
def pages(browser):
    """New pages, each in its own browser context (two people = two browsers); JS errors and failed requests are collected."""
    contexts, errors, failed, console = [], [], [], []

    def new_page() -> Page:
        context = browser.new_context(viewport={"width": 1000, "height": 900}, accept_downloads=True)
        contexts.append(context)
        page = context.new_page()
        page.set_default_timeout(TIMEOUT_MS)
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        # Every answer >= 400 the page got (a favicon's 404 shows in the console as an unexplained error).
        page.on("response", lambda r: r.status >= 400 and failed.append(f"{r.status} {r.url}"))
        # The console sees what `response` does not: the browser's own favicon.ico request.
        page.on("console", lambda m: m.type == "error" and console.append(f"{m.text} {m.location.get('url', '')}"))
        return page

    new_page.errors = errors
    new_page.failed = failed
    new_page.console = console
    yield new_page
    for context in contexts:
        context.close()


def good_arms(page: Page) -> list[int]:
    return [int(a) for a in page.locator(".arm.good").evaluate_all("els => els.map(e => e.dataset.arm)")]


def wait_played(page: Page, n: int) -> None:
    page.wait_for_selector(f'body[data-played="{n}"]', state="attached")


def consent_and_start(page: Page, url: str) -> None:
    """Open the study link, agree to the consent form, read the instructions, start."""
    page.goto(url)
    expect(page.locator("#consent")).to_be_visible()
    expect(page.locator("#to-instructions")).to_be_disabled()  # not before agreeing
    page.check("#agree")
    page.click("#to-instructions")
    expect(page.locator("#rules")).to_contain_text("green arms")
    page.click("#start")
    expect(page.locator("#game")).to_be_visible()


def assert_no_internals(page: Page) -> None:
    text = page.content()
    assert not [w for w in INTERNALS if w in text], [w for w in INTERNALS if w in text]


def assert_lay_words(page: Page) -> None:
    """What a participant reads (the visible text, the history table included) is free of researchers' words."""
    page.evaluate("document.getElementById('history-box').open = true")
    text = page.locator("body").inner_text()
    assert not [w for w in RESEARCHER_WORDS if w.lower() in text.lower()], [
        w for w in RESEARCHER_WORDS if w.lower() in text.lower()
    ]


@pytest.mark.slow
def test_a_participant_plays_the_agent_from_consent_to_completion_code(study_ego: Path, serve, pages, tmp_path: Path) -> None:
    srv = serve(build_settings(study_ego, consent="Study ABC.\n\nWe record your choices only."))
    page = pages()
    consent_and_start(page, srv.url + "?PROLIFIC_PID=5f1e2d3c4b5a69788796a5b4&STUDY_ID=x")
    expect(page.locator("#status")).to_have_text("Your turn: pick an arm.")
    expect(page.locator("#where")).to_have_text("Part 1 of 2 · situation A · try 1 of 5")
    expect(page.locator("#partner")).to_have_text("an AI agent")
    expect(page.locator("#last")).to_have_text("No try played yet.")

    picks = []
    for i, (task, context, attempt) in enumerate(SCHEDULE):
        page.wait_for_selector('body[data-phase="choose"]', state="attached")
        expect(page.locator("#where")).to_have_text(
            f"Part {1 if task == 'train' else 2} of 2 · situation {context} · try {attempt} of 5"
        )
        arm = good_arms(page)[0]  # a consistent person: the left-most green arm
        page.click(f'.arm[data-arm="{arm}"]')
        wait_played(page, i + 1)
        assert (
            f"situation {context}, try {attempt}): you pulled arm {arm}, the agent pulled arm"
            in page.locator("#last").inner_text()
        )
        picks.append(arm)
        if i in (0, 15):  # Part 1, and Part 2 as it starts
            assert_no_internals(page)
            assert_lay_words(page)
    expect(page.locator("#status")).to_contain_text("Session finished")
    expect(page.locator("#done")).to_be_visible()
    code = page.locator("#completion-code").inner_text()
    assert re.fullmatch(r"[A-Z2-9]{8}", code)
    expect(page.locator("#arms .arm")).to_have_count(0)
    assert_no_internals(page)
    shot = tmp_path / "agent_session.png"
    page.screenshot(path=shot, full_page=True)
    assert shot.stat().st_size > 10_000

    page.reload()  # the same browser comes back: no consent again, the same code
    expect(page.locator("#completion-code")).to_have_text(code)
    assert pages.errors == []
    df = load_user_study_from(srv)
    assert list(zip(df["task"], df["context"], df["try"])) == SCHEDULE
    assert df["action_2"].tolist() == picks and (df["pair"] == 1).all()
    score = page.locator("#score").inner_text()
    assert score.startswith(f"Score: {int(df['coordinated'].sum())}") and "30 of 30 tries played" in score


def load_user_study_from(srv: StudyServer):
    path = srv.store.path.parent / "export.csv"
    path.write_text(table_csv(srv.store))
    return load_user_study(path)


def test_two_participants_are_paired_and_play_to_their_codes(serve, pages, tmp_path: Path) -> None:
    srv = serve(oracle_study("human"))
    one, two = pages(), pages()
    consent_and_start(one, srv.url + "?participant=alice")
    expect(one.locator("#status")).to_contain_text("Waiting for another participant to join")
    expect(one.locator("#partner")).to_have_text("not yet found")
    consent_and_start(two, srv.url + "?participant=bob")
    expect(one.locator("#partner")).to_have_text("another participant")  # alice's page learns it by itself
    expect(one.locator("#you")).to_have_text("Player 1")

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
        picks.append((a1, a2))
    codes = []
    for n, page in enumerate((one, two), start=1):
        expect(page.locator("#status")).to_contain_text("Session finished")
        codes.append(page.locator("#completion-code").inner_text())
        page.screenshot(path=tmp_path / f"person_{n}.png", full_page=True)
    assert codes[0] != codes[1] and all(re.fullmatch(r"[A-Z2-9]{8}", c) for c in codes)
    assert pages.errors == []
    df = load_user_study_from(srv)
    assert list(zip(df["action_1"], df["action_2"])) == picks
    assert list(zip(df["task"], df["context"], df["try"])) == SCHEDULE


def test_the_page_shows_refused_moves_and_survives_a_server_restart(serve, pages, tmp_path: Path) -> None:
    settings = oracle_study("agent")
    db = tmp_path / "restart" / DB_FILE
    srv = serve(settings, db)
    page = pages()
    consent_and_start(page, srv.url + "?participant=carol")
    page.evaluate("play.sendMove({arm: 7})")
    expect(page.locator("#error")).to_have_text("arm must be an integer from 1 to 4, got 7")
    page.click('.arm[data-arm="1"]')
    wait_played(page, 1)
    expect(page.locator("#error")).to_be_hidden()  # a new action clears the old error
    port = srv.sock.getsockname()[1]
    srv.stop()  # the server goes away with the page open
    expect(page.locator("#offline")).to_be_visible()
    again = StudyServer(settings, db, port=port, admin_token=ADMIN_TOKEN)
    again.start()
    try:
        expect(page.locator("#offline")).to_be_hidden()
        page.click('.arm[data-arm="1"]')
        wait_played(page, 2)
        assert "situation A, try 2" in page.locator("#last").inner_text()
    finally:
        again.stop()
    assert pages.errors == []


def test_the_admin_page_needs_the_token_and_shows_live_counts(serve, pages, tmp_path: Path) -> None:
    srv = serve(build_settings(agents=["ours=oracle", "baseline=oracle"], conditions="ours,baseline"))
    page = pages()
    page.goto(srv.url + "admin")
    expect(page.locator("#login")).to_be_visible()
    page.fill("#token", "wrong-token")
    page.click("#login button")
    expect(page.locator("#error")).to_have_text("wrong admin token")
    page.fill("#token", ADMIN_TOKEN)
    page.click("#login button")
    expect(page.locator("#conditions tbody tr")).to_have_count(2)
    expect(page.locator("#summary")).to_contain_text("0 participants")
    with httpx.Client(base_url=srv.url, timeout=10) as c:
        for i in range(3):
            p = c.post("/api/participants", json={"consent": True, "participant": f"p{i}"}).json()
            c.post("/api/move", json={"token": p["token"], "step": 0, "arm": 1})
    expect(page.locator("#summary")).to_contain_text("3 participants")  # live: the page polls
    rows = page.locator("#conditions tbody tr").evaluate_all("rows => rows.map(r => [...r.cells].map(c => c.textContent))")
    assert sorted(r[3] for r in rows) == ["1", "2"] and all("oracle task module" in r[-1] for r in rows)  # playing, description
    with page.expect_download() as download:
        page.click("#downloads a >> nth=0")
    saved = tmp_path / "export.csv"
    download.value.save_as(saved)
    assert len(load_user_study(saved)) == 3
    page.screenshot(path=tmp_path / "admin.png", full_page=True)
    assert pages.errors == []


def test_two_people_play_blocks_and_see_moves_as_they_happen(serve, pages, tmp_path: Path) -> None:
    srv = serve(oracle_study("human", game="blocks", games=1, seed=5))
    p1, p2 = pages(), pages()
    for page, pid in ((p1, "red"), (p2, "blue")):
        page.goto(srv.url + f"?participant={pid}")
        page.check("#agree")
        page.click("#to-instructions")
        expect(page.locator("#rules")).to_contain_text("P1 (red) sees the goal grid")
        page.click("#start")
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
    p2.click(f'#board .cell[data-cell="{blue}"]')
    for _ in range(2):
        p1.wait_for_selector('body[data-phase="your_turn"]', state="attached")
        p1.click("#pass")
        p2.wait_for_selector('body[data-phase="your_turn"]', state="attached")
        p2.click("#pass")
    for n, page in enumerate((p1, p2), start=1):
        expect(page.locator("#status")).to_have_text("Session finished: 20 points in 1 game. Thank you!")
        expect(page.locator("#done")).to_be_visible()
        page.screenshot(path=tmp_path / f"blocks_p{n}.png", full_page=True)
    expect(p2.locator("#last .cell.red")).to_have_count(2)  # the goal is revealed to P2 once the game is over
    rows = table_csv(srv.store).splitlines()
    assert len(rows) == 7 and rows[-1].endswith(",20,human")
    assert pages.errors == []


def test_a_session_that_ends_early_says_so_in_plain_words(serve, pages, tmp_path: Path) -> None:
    """Nobody to pair with: the page says the session ended and gives the code, never "waiting · partner: not yet found"."""
    srv = serve(oracle_study("human", pair_timeout=0.5))  # the sweep ends it within SWEEP_S (5 s)
    page = pages()
    consent_and_start(page, srv.url + "?participant=alone")
    page.wait_for_selector('body[data-phase="ended"]', state="attached", timeout=20_000)
    expect(page.locator("#status")).to_have_text(
        "This session has ended early: no other participant arrived in time to play with you. Thank you for your time."
    )
    expect(page.locator("#done")).to_be_visible()
    page.screenshot(path=tmp_path / "ended_early.png", full_page=True)
    text = page.locator("body").inner_text()
    assert "not yet found" not in text and "waiting" not in text.lower(), text
    assert re.fullmatch(r"[A-Z2-9]{8}", page.locator("#completion-code").inner_text())
    assert_lay_words(page)
    assert pages.errors == [] and pages.failed == []


@pytest.mark.parametrize("query", ["?PROLIFIC_PID=%3Cscript%3E", "?participant=a%20b", "?workerId=" + "x" * 65])
def test_a_damaged_study_link_gets_a_plain_explanation_before_consent(serve, pages, tmp_path: Path, query: str) -> None:
    srv = serve(oracle_study("agent"))
    page = pages()
    page.goto(srv.url + query)
    expect(page.locator("#bad-link")).to_be_visible()
    expect(page.locator("#bad-link")).to_contain_text("This study link is incomplete or damaged")
    expect(page.locator("#bad-link")).to_contain_text("open the study from there again")
    for section in ("#consent", "#instructions", "#game", "#error"):
        expect(page.locator(section)).to_be_hidden()
    page.screenshot(path=tmp_path / "bad_link.png", full_page=True)
    assert_lay_words(page)
    assert pages.errors == [] and pages.failed == [] and pages.console == []
    with httpx.Client(base_url=srv.url, timeout=10) as c:
        assert c.get("/api/admin/status", headers={"Authorization": f"Bearer {ADMIN_TOKEN}"}).json()["participants"] == 0


def test_the_admin_page_with_a_wrong_token_shows_the_error_alone(serve, pages) -> None:
    srv = serve(oracle_study("agent"))
    page = pages()
    page.goto(srv.url + "admin?token=wrong-token")
    expect(page.locator("#error")).to_have_text("wrong admin token")
    expect(page.locator("#login")).to_be_visible()
    expect(page.locator("#summary")).to_have_text("Enter the admin token.")
    assert "Loading" not in page.locator("body").inner_text()
    assert pages.failed == [f"403 {srv.url}api/admin/status"]  # the refused token, and nothing else
    assert [m for m in pages.console if "api/admin/status" not in m] == []  # no favicon 404


def test_the_pages_ask_for_nothing_that_is_missing(serve, pages) -> None:
    """No unexplained 404 in the browser's console: every request of the participant's and the admin's pages is answered."""
    srv = serve(oracle_study("agent"))
    page = pages()
    consent_and_start(page, srv.url + "?participant=quiet")
    page.click('.arm[data-arm="1"]')
    wait_played(page, 1)
    page.goto(srv.url + f"admin?token={ADMIN_TOKEN}")
    expect(page.locator("#conditions tbody tr")).to_have_count(1)
    page.wait_for_timeout(500)  # a late favicon request
    assert pages.failed == [] and pages.errors == [] and pages.console == []
