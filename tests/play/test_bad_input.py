"""Bad input: a fuzzed set of malformed requests, each answered 4xx in JSON (never 500, never a hung connection), the server still serving."""

from __future__ import annotations

import asyncio
import json
import logging
import socket
import time

import httpx
import pytest
import websockets

from rllib_conv.play.limits import MAX_BODY
from rllib_conv.play.server import StudyServer
from tests.play.servers import oracle_study

TIMEOUT_S = 1.0  # the server's request deadline in these tests (10 s when serving a study)


@pytest.fixture
def server(serve) -> StudyServer:
    return serve(oracle_study("agent"), request_timeout_s=TIMEOUT_S)


def exchange(server: StudyServer, data: bytes, pause_s: float = 0.0, more: bytes = b"") -> tuple[int | None, dict | None, float]:
    """Send raw bytes (then, after `pause_s`, `more`); return (status, JSON body, seconds until the server closed)."""
    start = time.monotonic()
    with socket.create_connection(server.sock.getsockname()[:2], timeout=10) as s:
        try:
            s.sendall(data)
            if pause_s:
                time.sleep(pause_s)
                s.sendall(more)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server answered and closed before taking everything
        answer = b""
        try:
            while chunk := s.recv(65536):
                answer += chunk
        except ConnectionResetError:
            pass
    seconds = time.monotonic() - start
    if not answer:
        return None, None, seconds
    head, _, body = answer.partition(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1])
    return status, json.loads(body) if body else None, seconds


def request(method: str, path: str, body: bytes = b"", headers: dict[str, str] | None = None) -> bytes:
    # Connection: close, so that the server hangs up once it has answered (the test reads until then).
    lines = [
        f"{method} {path} HTTP/1.1",
        "Host: 127.0.0.1",
        "Connection: close",
        *(f"{k}: {v}" for k, v in (headers or {}).items()),
    ]
    return ("\r\n".join(lines) + "\r\n\r\n").encode() + body


JSON = {"Content-Type": "application/json"}

MALFORMED_HTTP = [
    # (what, bytes, expected status, words in the error)
    (
        "negative Content-Length",
        request("POST", "/api/move", headers=JSON | {"Content-Length": "-5"}),
        400,
        "malformed HTTP request",
    ),
    (
        "Content-Length not a number",
        request("POST", "/api/move", headers=JSON | {"Content-Length": "ten"}),
        400,
        "malformed HTTP request",
    ),
    (
        "two different Content-Lengths",
        request("POST", "/api/move", b"{}", JSON | {"Content-Length": "2", "content-length": "3"}),
        400,
        "malformed",
    ),
    ("huge Content-Length", request("POST", "/api/move", headers=JSON | {"Content-Length": str(10**12)}), 413, "at most 16384"),
    ("a request line that is not HTTP", b"HELLO THERE\r\n\r\n", 400, "malformed HTTP request"),
    ("a binary request", bytes(range(256)) * 4, 400, "malformed HTTP request"),
    ("a non-ASCII path", b"GET /caf\xc3\xa9 HTTP/1.1\r\nHost: x\r\n\r\n", 400, "malformed HTTP request"),
    ("headers over the limit", request("GET", "/api/info", headers={"X-Big": "x" * 20000}), 431, "at most 16384"),
    ("headers over the limit, trickled", request("GET", "/api/info", headers={"X-Big": "x" * 20000})[:-4], 431, "at most 16384"),
    ("a 1 MiB header", request("GET", "/api/info", headers={"X-Big": "x" * 2**20}), 431, "at most 16384"),
    ("PUT", request("PUT", "/api/move", b"{}", JSON | {"Content-Length": "2"}), 405, "PUT is not allowed"),
    ("DELETE", request("DELETE", "/api/participants"), 405, "DELETE is not allowed"),
    ("PATCH on a page", request("PATCH", "/", b"{}", JSON | {"Content-Length": "2"}), 405, "PATCH is not allowed"),
    ("OPTIONS", request("OPTIONS", "/api/info"), 405, "OPTIONS is not allowed"),
    ("an unknown path", request("GET", "/etc/passwd"), 404, "no page"),
    ("a path escaping static", request("GET", "/static/..%2f..%2fserver.py"), 404, "no page"),
    (
        "a form instead of JSON",
        request(
            "POST",
            "/api/participants",
            b"consent=1",
            {"Content-Type": "application/x-www-form-urlencoded", "Content-Length": "9"},
        ),
        415,
        "must be JSON",
    ),
    ("no Content-Type", request("POST", "/api/participants", b"{}", {"Content-Length": "2"}), 415, "must be JSON"),
]


@pytest.mark.parametrize("what, data, status, words", MALFORMED_HTTP, ids=[m[0] for m in MALFORMED_HTTP])
def test_malformed_http_gets_a_json_4xx(server: StudyServer, what: str, data: bytes, status: int, words: str) -> None:
    got, body, _ = exchange(server, data)
    assert got == status and words in body["error"], (what, got, body)


BAD_JSON = [
    (b"{not json", 400, "must be a JSON object"),
    (b"", 400, "must be a JSON object"),
    (b"\xff\xfe{}", 400, "must be a JSON object"),
    (b"[" * 8000 + b"]" * 8000, 400, "must be a JSON object"),  # deeper than the parser recurses
    (b'"a string"', 400, "got str"),
    (b"null", 400, "got NoneType"),
    (b'{"consent": "true"}', 400, "consent must be true"),
    (b'{"consent": true, "participant": 12}', 400, "participant must be an id"),
    (b'{"consent": true, "participant": "../../etc"}', 400, "participant must be an id"),
    (b'{"consent": true, "participant": "' + b"a" * 5000 + b'"}', 400, "participant must be an id"),
]


@pytest.mark.parametrize("body, status, words", BAD_JSON)
def test_bad_json_and_wrong_types_get_400(server: StudyServer, body: bytes, status: int, words: str) -> None:
    r = httpx.post(server.url + "api/participants", content=body, headers=JSON, timeout=10)
    assert r.status_code == status and words in r.json()["error"], r.text


def test_bad_moves_and_unknown_ids_get_4xx_and_change_nothing(server: StudyServer) -> None:
    with httpx.Client(base_url=server.url, timeout=10) as c:
        p = c.post("/api/participants", json={"consent": True, "participant": "fuzz"}).json()
        token = p["token"]
        moves = [
            ({"token": token, "step": 0, "arm": "NaN"}, 400),
            ({"token": token, "step": 0, "arm": float("inf")}, 400),
            ({"token": token, "step": 0, "arm": 10**100}, 400),
            ({"token": token, "step": 0, "arm": -1}, 400),
            ({"token": token, "step": 0, "arm": {"$gt": 0}}, 400),
            ({"token": token, "step": -1, "arm": 1}, 400),
            ({"token": token, "step": 10**30, "arm": 1}, 400),
            ({"token": token, "step": 3, "arm": 1}, 409),
            ({"token": token, "arm": 1}, 400),
            ({"token": token + "x", "step": 0, "arm": 1}, 403),
            ({"token": 7, "step": 0, "arm": 1}, 403),
            ({"step": 0, "arm": 1}, 403),
        ]
        for body, status in moves:
            raw = json.dumps(body, allow_nan=True).encode()
            r = c.post("/api/move", content=raw, headers=JSON)
            assert r.status_code == status, (body, r.text)
        for path in ("/api/session?token=nobody", "/api/session?token=", "/api/session?token=%00%ff"):
            assert c.get(path).status_code == 403, path
        assert c.get(f"/api/session?token={token}").json()["played"] == 0  # nothing was played by any of them


# The five inputs that were HTTP 500s (issue 47): Python's int-length limit, float overflow, a Unicode digit.
FORMER_500S = [
    ("step of 5000 digits", b'{"token": "%s", "step": ' + b"9" * 5000 + b', "arm": 1}', 400, "must be a JSON object"),
    (
        "step = 1e400 as an integer",
        b'{"token": "%s", "step": 1' + b"0" * 400 + b', "arm": 1}',
        400,
        "step must be an integer from 0 to",
    ),
    (
        "arm = 1e400 as an integer",
        b'{"token": "%s", "step": 0, "arm": 1' + b"0" * 400 + b"}",
        400,
        "arm must be an integer from 1 to 4",
    ),
    ("arm = 1e400", b'{"token": "%s", "step": 0, "arm": 1e400}', 400, "arm must be an integer from 1 to 4"),
    (
        "arm a superscript two",
        '{"token": "%s", "step": 0, "arm": "²"}'.encode(),
        400,
        "arm must be an integer from 1 to 4, got '²'",
    ),
    ("step a superscript two", '{"token": "%s", "step": "²", "arm": 1}'.encode(), 400, "step must be an integer from 0 to"),
    (
        "arm an Arabic-Indic digit",
        '{"token": "%s", "step": 0, "arm": "\u0661"}'.encode(),
        400,
        "arm must be an integer from 1 to 4",
    ),
    ("consent of 4000 digits", b'{"consent": ' + b"7" * 4000 + b"}", 400, "consent must be true"),
    ("participant of 4000 digits", b'{"consent": true, "participant": ' + b"7" * 4000 + b"}", 400, "participant must be an id"),
]


@pytest.mark.parametrize("what, body, status, words", FORMER_500S, ids=[c[0] for c in FORMER_500S])
def test_huge_and_unicode_numbers_get_400_not_500(server: StudyServer, what: str, body: bytes, status: int, words: str) -> None:
    with httpx.Client(base_url=server.url, timeout=10) as c:
        token = c.post("/api/participants", json={"consent": True}).json()["token"]
        path = "/api/participants" if b"consent" in body else "/api/move"
        r = c.post(path, content=body.replace(b"%s", token.encode()), headers=JSON)
        assert r.status_code == status and words in r.json()["error"], (what, r.status_code, r.text)
        assert c.get(f"/api/session?token={token}").json()["played"] == 0  # nothing played, and the server still serves


def test_slow_and_truncated_requests_get_408_within_the_deadline(server: StudyServer) -> None:
    head = request("POST", "/api/participants", headers=JSON | {"Content-Length": "100"})
    status, body, seconds = exchange(server, head + b'{"consent": true')  # 16 of the 100 bytes
    assert status == 408 and "did not arrive within 1 s" in body["error"] and seconds < TIMEOUT_S + 3
    status, body, seconds = exchange(server, b"GET /api/info HTTP/1.1\r\nHost: 127.0")  # headers that never end
    assert status == 408 and "request line and headers" in body["error"] and seconds < TIMEOUT_S + 3
    status, _, seconds = exchange(server, b"")  # a connection that never says anything is closed
    assert status is None and seconds < 5 + 3
    chunks = b"".join(b"%x\r\n%s\r\n" % (4000, b"x" * 4000) for _ in range(5)) + b"0\r\n\r\n"
    chunked = request("POST", "/api/participants", headers=JSON | {"Transfer-Encoding": "chunked"})
    status, body, _ = exchange(server, chunked + chunks)  # no Content-Length, but over the limit as it streams
    assert status == 413 and f"over {MAX_BODY} bytes" in body["error"]


def test_websockets_refuse_strangers_and_oversized_messages(server: StudyServer) -> None:
    token = httpx.post(server.url + "api/participants", json={"consent": True, "participant": "ws"}, timeout=10).json()["token"]
    live = server.url.replace("http://", "ws://") + "api/live?token="

    async def probe() -> tuple[int, int | None]:
        try:
            async with websockets.connect(live + "forged"):
                pass
        except websockets.InvalidStatus as err:
            refused = err.response.status_code
        async with websockets.connect(live + token, max_size=None) as ws:
            await ws.recv()
            await ws.send("x" * 100_000)
            try:
                await asyncio.wait_for(ws.recv(), 5)
            except websockets.ConnectionClosed as closed:
                return refused, closed.rcvd.code if closed.rcvd else None
        return refused, None

    assert asyncio.run(probe()) == (403, 1009)  # 1009: message too big


def test_after_all_of_it_the_server_still_serves_a_whole_session(server: StudyServer, caplog) -> None:
    caplog.set_level(logging.WARNING)
    for _, data, _, _ in MALFORMED_HTTP:
        exchange(server, data)
    with httpx.Client(base_url=server.url, timeout=10) as c:
        p = c.post("/api/participants", json={"consent": True, "participant": "after"}).json()
        view = p["view"]
        while view["phase"] == "choose":
            view = c.post("/api/move", json={"token": p["token"], "step": view["step"], "arm": 1}).json()
    assert view["phase"] == "finished" and view["played"] == 30 and view["completion_code"]
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR], [r.getMessage() for r in caplog.records]
