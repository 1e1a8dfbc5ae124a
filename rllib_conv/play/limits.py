"""Limits on what a client may send, and JSON answers when it sends something else.

Two layers, because uvicorn parses HTTP before the app sees a request:

- `LimitedH11Protocol` (uvicorn's h11 protocol, three changes): a request that is not
  HTTP (a negative or garbled Content-Length, a bad request line, a non-ASCII path) gets a
  JSON 400 instead of plain text or a traceback, and headers still arriving past
  `MAX_HEADER_BYTES` a JSON 431 (h11's own hint, which uvicorn drops); a client that opens a connection and does not finish its request line and
  headers within `REQUEST_TIMEOUT_S` gets 408 and is disconnected (a slow client holds a
  socket for seconds, never forever).
- `BodyLimits` (ASGI middleware): headers over `MAX_HEADER_BYTES` get 431; the body is
  read whole before the app runs, at most `MAX_BODY` bytes (413, at once when
  Content-Length says more) within `REQUEST_TIMEOUT_S` (408: a body shorter than its
  Content-Length, or one trickled in).

Both answer `{"error": "<sentence>"}` and close the connection.
"""

from __future__ import annotations

import asyncio
import json
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

MAX_BODY = 16_384
MAX_HEADER_BYTES = 16_384
REQUEST_TIMEOUT_S = 10.0
REASONS = {400: "Bad Request", 408: "Request Timeout", 413: "Content Too Large", 431: "Request Header Fields Too Large"}


def error_body(message: str) -> bytes:
    """The JSON body of every error answer."""
    return json.dumps({"error": message}).encode()


def raw_response(status: int, message: str) -> bytes:
    """A complete HTTP/1.1 error response that closes the connection (for when no request was parsed)."""
    body = error_body(message)
    head = f"HTTP/1.1 {status} {REASONS[status]}\r\ncontent-type: application/json\r\ncontent-length: {len(body)}\r\nconnection: close\r\n\r\n"
    return head.encode() + body


class LimitedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with JSON 400s and a deadline for the request line and headers (module docstring)."""

    header_timeout_s = REQUEST_TIMEOUT_S

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._deadline: asyncio.TimerHandle | None = None
        self._refusal: h11.RemoteProtocolError | None = None
        parse = self.conn.next_event

        def next_event() -> Any:
            # uvicorn answers every h11 refusal with 400; keep it, to answer 431 where h11 says so.
            try:
                return parse()
            except h11.RemoteProtocolError as exc:
                self._refusal = exc
                raise

        self.conn.next_event = next_event  # type: ignore[method-assign]
        self._arm()

    def _arm(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
        self._deadline = self.loop.call_later(self.header_timeout_s, self._request_deadline)

    def _request_deadline(self) -> None:
        # Between requests (h11 IDLE, no response pending) for the whole deadline: a request
        # line and headers that never finish, or a connection that never sent one.
        if self.transport.is_closing() or self.conn.their_state is not h11.IDLE:
            return
        if self.cycle is not None and not self.cycle.response_complete:
            return
        if self.conn.trailing_data[0]:
            self.transport.write(
                raw_response(408, f"the request line and headers did not arrive within {self.header_timeout_s:g} s")
            )
        self.transport.close()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if not self.transport.is_closing():
            self._arm()

    def connection_lost(self, exc: Exception | None) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
        super().connection_lost(exc)

    def handle_events(self) -> None:
        try:
            super().handle_events()
        except UnicodeDecodeError:  # uvicorn decodes the path as ASCII
            self.send_400_response("the request path must be ASCII (percent-encode other characters)")

    def handle_websocket_upgrade(self, event: h11.Request) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
        super().handle_websocket_upgrade(event)

    def send_400_response(self, msg: str) -> None:
        if self.transport.is_closing():
            return
        if self._refusal is not None and self._refusal.error_status_hint == 431:
            self.transport.write(
                raw_response(
                    431, f"the request headers are over {MAX_HEADER_BYTES} bytes; at most {MAX_HEADER_BYTES} are accepted"
                )
            )
        else:
            self.transport.write(raw_response(400, f"malformed HTTP request: {msg.rstrip('.')}"))
        self.transport.close()


class BodyLimits:
    """ASGI middleware: read each HTTP request's body whole, bounded in size and time, before the app runs."""

    def __init__(self, app: Any, max_body: int = MAX_BODY, timeout_s: float = REQUEST_TIMEOUT_S) -> None:
        self.app = app
        self.max_body = max_body
        self.timeout_s = timeout_s

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        header_bytes = sum(len(k) + len(v) for k, v in scope["headers"])
        if header_bytes > MAX_HEADER_BYTES:  # h11 bounds headers still arriving; this, headers that came at once
            return await self._refuse(
                send, 431, f"the request headers are {header_bytes} bytes; at most {MAX_HEADER_BYTES} are accepted"
            )
        length = next((v for k, v in scope["headers"] if k == b"content-length"), None)
        if length is not None and int(length) > self.max_body:  # h11 has refused lengths that are not integers
            return await self._refuse(send, 413, f"the request body is {int(length)} bytes; at most {self.max_body} are accepted")
        chunks: list[bytes] = []
        size = 0
        try:
            async with asyncio.timeout(self.timeout_s):
                while True:
                    message = await receive()
                    if message["type"] == "http.disconnect":
                        return  # the client went away: nobody to answer
                    size += len(message.get("body", b""))
                    if size > self.max_body:
                        return await self._refuse(send, 413, f"the request body is over {self.max_body} bytes")
                    chunks.append(message.get("body", b""))
                    if not message.get("more_body", False):
                        break
        except TimeoutError:
            return await self._refuse(
                send, 408, f"the request body did not arrive within {self.timeout_s:g} s (shorter than its Content-Length?)"
            )
        body = b"".join(chunks)
        replayed = False

        async def replay() -> dict:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)

    @staticmethod
    async def _refuse(send: Any, status: int, message: str) -> None:
        body = error_body(message)
        headers = [
            (b"content-type", b"application/json"),
            (b"content-length", str(len(body)).encode()),
            (b"connection", b"close"),
        ]
        await send({"type": "http.response.start", "status": status, "headers": headers})
        await send({"type": "http.response.body", "body": body})
