"""The web layer on a real uvicorn: pages, the JSON API and its errors, live views, the admin API, the command line."""

from __future__ import annotations

import asyncio
import contextlib
import csv
import io
import json
from pathlib import Path

import httpx
import pytest
import websockets

from rllib_conv.cli import main
from rllib_conv.play.server import StudyServer
from tests.play.servers import ADMIN_TOKEN, oracle_study


@pytest.fixture
def server(serve) -> StudyServer:
    return serve(oracle_study("agent,human"))


@pytest.fixture
def client(server: StudyServer):
    with httpx.Client(base_url=server.url, timeout=10) as c:
        yield c


def enrol(client: httpx.Client, pid: str, token: str | None = None) -> dict:
    r = client.post("/api/participants", json={"consent": True, "participant": pid} | ({"token": token} if token else {}))
    assert r.status_code == 200, r.text
    return r.json()


def test_pages_and_static_files_are_served_with_safe_headers(client: httpx.Client) -> None:
    pages = [
        ("/", "text/html", 'id="consent"'),
        ("/admin", "text/html", 'id="conditions"'),
        ("/static/app.js", "text/javascript", "WebSocket"),
        ("/static/style.css", "text/css", ".arm"),
        ("/favicon.ico", "image/svg+xml", "<svg"),  # browsers ask for it: no 404 in the console
        ("/static/favicon.svg", "image/svg+xml", "<svg"),
    ]
    for path, kind, marker in pages:
        r = client.get(path)
        assert r.status_code == 200 and r.headers["content-type"].startswith(kind) and marker in r.text, path
        assert r.headers["x-content-type-options"] == "nosniff" and r.headers["referrer-policy"] == "no-referrer"
        assert "default-src 'self'" in r.headers["content-security-policy"]
    for path in ("/static/secret.txt", "/static/../server.py", "/static/%2e%2e%2fstore.py"):
        r = client.get(path)
        assert r.status_code == 404 and r.json()["error"].startswith("no page"), path
    assert client.head("/").status_code == 200


def test_api_errors_are_json_sentences_with_the_right_status(client: httpx.Client) -> None:
    assert client.get("/api/info").json()["game"] == "bandit"
    cases = [
        (
            client.post("/api/participants", content=b"{not json", headers={"content-type": "application/json"}),
            400,
            "the request body must be a JSON object",
        ),
        (client.post("/api/participants", json=[1, 2]), 400, "must be a JSON object, got list"),
        (
            client.post(
                "/api/participants", content=b"consent=true", headers={"content-type": "application/x-www-form-urlencoded"}
            ),
            415,
            "must be JSON",
        ),
        (client.post("/api/participants", json={"participant": "p1"}), 400, "consent must be true"),
        (client.post("/api/participants", json={"consent": True, "participant": {"id": 1}}), 400, "participant must be an id"),
        (client.post("/api/move", json={"token": "forged", "arm": 1, "step": 0}), 403, "unknown or missing participant token"),
        (client.get("/api/session"), 403, "unknown or missing participant token"),
        (client.get("/api/whatever"), 404, "no page '/api/whatever'"),
        (client.put("/api/move", json={}), 405, "PUT is not allowed on /api/move; use POST"),
        (client.delete("/api/participants"), 405, "use POST"),
        (client.get("/api/move"), 405, "GET is not allowed"),
    ]
    for r, status, message in cases:
        assert r.status_code == status and message in r.json()["error"], (r.request.method, r.request.url, r.text)
    assert cases[8][0].headers["allow"] == "POST"


def test_a_session_over_http_with_retries_that_never_play_twice(client: httpx.Client) -> None:
    p = None
    for i in range(4):  # balanced: two of four in the agent condition
        p = enrol(client, f"p{i}")
        if p["view"]["partner"] == "agent":
            break
    token, view = p["token"], p["view"]
    assert view["phase"] == "choose" and view["step"] == 0
    first = client.post("/api/move", json={"token": token, "step": 0, "arm": 1})
    assert first.status_code == 200 and first.json()["played"] == 1
    again = client.post("/api/move", json={"token": token, "step": 0, "arm": 1})  # the retry of a lost answer
    assert again.status_code == 409 and "already played" in again.json()["error"]
    assert client.get(f"/api/session?token={token}").json()["played"] == 1
    assert enrol(client, p["participant"], token)["token"] == token  # enrolling again with the page's token resumes


def test_live_views_are_pushed_and_strangers_are_refused(server: StudyServer, client: httpx.Client) -> None:
    people = [enrol(client, f"h{i}") for i in range(4)]
    a, b = [p for p in people if p["view"]["phase"] == "waiting_for_partner"]
    live = server.url.replace("http://", "ws://") + "api/live?token="

    async def talk() -> list[str]:
        async with websockets.connect(live + a["token"]) as wa:
            seen = [json.loads(await wa.recv())["phase"]]  # the view at once
            async with websockets.connect(live + b["token"]) as wb:
                seen.append(json.loads(await wa.recv())["phase"])  # a is told it has a partner
                await wb.recv()
                await asyncio.to_thread(client.post, "/api/move", json={"token": b["token"], "step": 0, "arm": 3})
                view = json.loads(await wa.recv())
                seen.append(f"partner_chose={view['partner_chose']}")
        with pytest.raises(websockets.InvalidStatus) as err:
            async with websockets.connect(live + "forged"):
                pass
        seen.append(str(err.value.response.status_code))
        return seen

    assert asyncio.run(talk()) == ["waiting_for_partner", "choose", "partner_chose=True", "403"]


def test_the_admin_api_needs_the_token_and_serves_counts_and_exports(server: StudyServer, client: httpx.Client) -> None:
    for i in range(4):
        p = enrol(client, f"p{i}")
        if p["view"]["partner"] == "agent":
            client.post("/api/move", json={"token": p["token"], "step": 0, "arm": 1})
    r = client.get("/api/admin/status")
    assert r.status_code == 401 and "needs the admin token" in r.json()["error"]
    assert client.get("/api/admin/status", headers={"Authorization": "Bearer wrong-token"}).status_code == 403
    status = client.get("/api/admin/status", headers={"Authorization": f"Bearer {ADMIN_TOKEN}"}).json()
    by = {c["name"]: c for c in status["conditions"]}
    assert (by["agent"]["playing"], by["agent"]["tries"], by["human"]["waiting"]) == (2, 2, 2)
    assert "oracle task module" in by["agent"]["description"] and status["participants"] == 4
    r = client.get(f"/api/admin/export.csv?token={ADMIN_TOKEN}&condition=agent")
    assert r.headers["content-disposition"] == 'attachment; filename="bandit_agent.csv"'
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert len(rows) == 2 and {row["condition"] for row in rows} == {"agent"}
    assert client.get(f"/api/admin/export.csv?token={ADMIN_TOKEN}&condition=robots").status_code == 400
    people = list(csv.DictReader(io.StringIO(client.get(f"/api/admin/participants.csv?token={ADMIN_TOKEN}").text)))
    assert sorted(p["id"] for p in people) == ["p0", "p1", "p2", "p3"]


def test_command_line_arguments_are_checked(tmp_path: Path, capsys, server: StudyServer) -> None:
    bad = [
        (["play", str(tmp_path / "missing"), "--out", str(tmp_path / "o")], "RUN "),
        (["play", "--conditions", "ours,human", "--out", str(tmp_path / "o")], "--conditions: 'ours' is neither"),
        (["play", "--agent", "agent=oracle", "--test-prior", "psychic"], "invalid choice"),
        (["play", "--agent", "agent=oracle", "--consent", str(tmp_path / "nope.txt"), "--out", str(tmp_path / "o")], "--consent"),
        (["play", "--condition", "agent", "--out", str(tmp_path / "o")], "--condition is for `play export DB`"),
        (["play", "--port", str(server.sock.getsockname()[1]), "--out", str(tmp_path / "o")], "--port"),
    ]
    for argv, message in bad:
        with pytest.raises(SystemExit) if "invalid choice" in message else contextlib.nullcontext():
            assert main(argv) == 2, argv
        assert message in capsys.readouterr().err, argv
    (tmp_path / "file").write_text("x")
    assert main(["play", "--out", str(tmp_path / "file")]) == 2
    assert "is a file; expected the study folder" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing was created by a refused start


def test_an_id_without_its_token_gets_409_and_never_the_token(server: StudyServer, client: httpx.Client) -> None:
    first = enrol(client, "5f1e2d3c4b5a69788796a5b4")
    for body in ({}, {"token": "guess"}, {"token": None}):
        r = client.post("/api/participants", json={"consent": True, "participant": first["participant"], **body})
        assert r.status_code == 409 and first["token"] not in r.text and "another browser" in r.json()["error"], r.text
    lone_surrogate = b'{"consent": true, "participant": "%s", "token": "\\ud800"}' % first["participant"].encode()
    r = client.post("/api/participants", content=lone_surrogate, headers={"content-type": "application/json"})
    assert r.status_code == 409, r.text  # not a 500 from encoding the token
    taken = client.post("/api/move", json={"token": first["token"], "step": 0, "arm": 1})  # the owner still plays
    assert taken.status_code in (200, 409), taken.text
    status = client.get("/api/admin/status", headers={"Authorization": f"Bearer {ADMIN_TOKEN}"}).json()
    assert status["refused_resumes"] == 4 and status["recent_refused"] == [first["participant"]] * 4
    assert status["participants"] == 1
    assert enrol(client, first["participant"], first["token"])["token"] == first["token"]


def test_enrolment_is_rate_limited_per_client(serve) -> None:
    srv = serve(oracle_study("agent"), enrol_limit=3)
    with httpx.Client(base_url=srv.url, timeout=10) as c:
        answers = [c.post("/api/participants", json={"consent": True}) for _ in range(5)]
        assert [r.status_code for r in answers] == [200, 200, 200, 429, 429]
        assert "too many enrolments" in answers[3].json()["error"] and 1 <= int(answers[3].headers["retry-after"]) <= 60
        assert c.get("/api/info").status_code == 200  # only enrolment is limited
        status = c.get("/api/admin/status", headers={"Authorization": f"Bearer {ADMIN_TOKEN}"}).json()
    assert status["participants"] == 3
    unlimited = serve(oracle_study("agent"), enrol_limit=0)
    with httpx.Client(base_url=unlimited.url, timeout=10) as c:
        assert {c.post("/api/participants", json={"consent": True}).status_code for _ in range(30)} == {200}
