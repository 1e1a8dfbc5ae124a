"""The HTTP layer: static page, JSON API, error statuses, long polling, command-line checks."""

from __future__ import annotations

import json
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from rllib_conv.cli import build_parser, main
from rllib_conv.play.lobby import Lobby
from rllib_conv.play.recording import SessionRecorder
from rllib_conv.play.server import PlayServer, build_lobby


@pytest.fixture
def server(tmp_path: Path):
    srv = PlayServer(Lobby("bandit", SessionRecorder(tmp_path / "rec")), port=0, long_poll_s=5.0)
    srv.start()
    yield srv
    srv.stop()


def call(srv: PlayServer, method: str, path: str, body: Any = None, raw: bytes | None = None) -> tuple[int, dict[str, Any]]:
    data = raw if raw is not None else (None if body is None else json.dumps(body).encode())
    req = urllib.request.Request(srv.url.rstrip("/") + path, method=method, data=data, headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def test_page_and_static_files_are_served(server: PlayServer) -> None:
    with urllib.request.urlopen(server.url, timeout=10) as r:
        html = r.read().decode()
        assert r.headers["Content-Type"].startswith("text/html")
    assert '<script src="/static/app.js">' in html and 'id="status"' in html
    for name, kind in [("app.js", "text/javascript"), ("style.css", "text/css")]:
        with urllib.request.urlopen(server.url + "static/" + name, timeout=10) as r:
            assert r.headers["Content-Type"].startswith(kind) and len(r.read()) > 500
    status, body = call(server, "GET", "/static/../server.py")  # only the listed files, never a path
    assert status == 404 and body["error"].startswith("no page")
    assert call(server, "GET", "/static/secret.txt")[0] == 404


def test_api_errors_are_json_sentences(server: PlayServer) -> None:
    assert call(server, "GET", "/api/info")[1]["game"] == "bandit"
    status, body = call(server, "POST", "/api/rooms", raw=b"{not json")
    assert (status, body) == (400, {"error": "the request body must be a JSON object"})
    status, body = call(server, "POST", "/api/rooms", [1, 2])
    assert status == 400 and "got list" in body["error"]
    assert call(server, "POST", "/api/rooms/NOPE/move", {"token": "x", "arm": 1}) == (404, {"error": "no room with code 'NOPE': check the code your partner gave you"})
    assert call(server, "GET", "/api/whatever")[0] == 404
    _, created = call(server, "POST", "/api/rooms", {"mode": "human"})
    status, body = call(server, "GET", f"/api/rooms/{created['room']}/state?token=wrong")
    assert status == 403 and "not a player of room" in body["error"]
    status, body = call(server, "GET", f"/api/rooms/{created['room']}/state?token={created['token']}&since=x")
    assert status == 400 and "since must be an integer" in body["error"]


def test_long_poll_answers_as_soon_as_the_room_changes(server: PlayServer) -> None:
    _, created = call(server, "POST", "/api/rooms", {"mode": "human"})
    code, token, version = created["room"], created["token"], created["state"]["version"]
    answer: dict[str, Any] = {}

    def poll() -> None:
        start = time.monotonic()
        answer["state"] = call(server, "GET", f"/api/rooms/{code}/state?token={token}&since={version}")[1]
        answer["seconds"] = time.monotonic() - start

    waiter = threading.Thread(target=poll)
    waiter.start()
    time.sleep(0.3)
    assert "state" not in answer  # still waiting: nothing changed yet
    call(server, "POST", f"/api/rooms/{code}/join", {})
    waiter.join(timeout=5)
    assert answer["state"]["partner"] == "person" and answer["state"]["phase"] == "choose"
    assert 0.25 < answer["seconds"] < 3


def test_command_line_arguments_are_checked(tmp_path: Path, capsys) -> None:
    args = build_parser().parse_args(["play", "--port", "0"])
    assert args.run is None and args.test_prior == "oracle" and args.out == "play_sessions"
    assert main(["play", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "RUN " in capsys.readouterr().err
    with pytest.raises(ValueError, match="--test-run needs RUN"):
        build_lobby(None, test_run=str(tmp_path), out=tmp_path / "o")
    with pytest.raises(ValueError, match="--test-prior must be one of"):
        build_lobby(None, test_prior="psychic", out=tmp_path / "o")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="--out .* is a file"):
        build_lobby(None, out=tmp_path / "file")
    lobby = build_lobby(None, game="blocks", out=tmp_path / "o")
    assert lobby.game == "blocks" and lobby.agent is None


def test_a_busy_port_is_a_clear_error(server: PlayServer) -> None:
    port = server.server_address[1]
    with pytest.raises(ValueError, match=f"--port {port}: cannot listen"):
        PlayServer(server.lobby, port=port)
