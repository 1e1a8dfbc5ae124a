"""Serving a study: uvicorn running the app of `app.py` on one socket, one process, one event loop.

`StudyServer(settings, db, host=..., port=...)` opens the database and binds the socket
at once (a busy port or a bad database is a ValueError before anything is served);
`run()` serves until SIGINT/SIGTERM (graceful: open answers finish, live pages are
closed), `start()`/`stop()` serve from a background thread (tests). One process per
database: the rooms live in its memory, SQLite holds what they replay from.
"""

from __future__ import annotations

import asyncio
import secrets
import socket
import sys
import threading
from pathlib import Path

import uvicorn

from rllib_conv.play.app import DEFAULT_ENROL_LIMIT, MIN_ADMIN_TOKEN, build_app
from rllib_conv.play.conditions import StudySettings
from rllib_conv.play.limits import MAX_HEADER_BYTES, REQUEST_TIMEOUT_S, LimitedH11Protocol
from rllib_conv.play.store import Store
from rllib_conv.play.study import Study

HOST = "127.0.0.1"
MAX_CONNECTIONS = 1000  # beyond this uvicorn answers 503 at once
WS_MAX_MESSAGE = 4096  # the page sends no messages; anything bigger closes the socket
START_TIMEOUT_S = 60.0


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on host:port (0: a free port); ValueError naming --host/--port if it cannot be had."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise ValueError(f"--host {host!r}: not an address of this machine ({exc})") from None
    family, kind, proto, _, address = infos[0]
    # The protocol number matters: asyncio sets TCP_NODELAY only on IPPROTO_TCP sockets, and
    # without it every answer waits 40 ms for a delayed ACK between its head and body.
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # a restart may reuse the port at once
    try:
        sock.bind(address)
        sock.listen(1024)
    except OSError as exc:
        sock.close()
        raise ValueError(
            f"--port {port}: cannot listen on {host}:{port} ({exc.strerror or exc}); choose another port (0 picks a free one)"
        ) from None
    sock.setblocking(False)
    return sock


class StudyServer:
    """One study served on host:port from database `db` (module docstring).

    `admin_token` None draws one; `request_timeout_s` bounds how long a client may take to
    send a request's headers, and its body; `enrol_limit` is how many enrolments one client
    address may ask for per minute (0: no limit).
    """

    def __init__(
        self,
        settings: StudySettings,
        db: str | Path,
        *,
        host: str = HOST,
        port: int = 8000,
        admin_token: str | None = None,
        verbose: bool = False,
        request_timeout_s: float = REQUEST_TIMEOUT_S,
        enrol_limit: int = DEFAULT_ENROL_LIMIT,
    ) -> None:
        self.settings = settings
        self.request_timeout_s = request_timeout_s
        self.enrol_limit = enrol_limit
        if admin_token is not None and len(admin_token) < MIN_ADMIN_TOKEN:  # before the database: a refusal writes nothing
            raise ValueError(f"--admin-token must be at least {MIN_ADMIN_TOKEN} characters")
        self.sock = bind(host, port)  # first: a busy port creates no study folder
        try:
            self.store = Store(db)
        except ValueError:
            self.sock.close()
            raise
        self.admin_token = admin_token or secrets.token_urlsafe(16)
        self.verbose = verbose
        self.study: Study | None = None
        self._server: uvicorn.Server | None = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The participants' address, e.g. http://127.0.0.1:8000/."""
        host, port = self.sock.getsockname()[:2]
        return f"http://{host if ':' not in host else f'[{host}]'}:{port}/"

    @property
    def admin_url(self) -> str:
        """The admin page's address with its token."""
        return f"{self.url}admin?token={self.admin_token}"

    async def serve(self) -> None:
        """Build the study (restoring open rooms) on the running loop and serve until told to stop."""
        loop = asyncio.get_running_loop()
        self.study = Study(self.settings, self.store, call_later=loop.call_later)
        config = uvicorn.Config(
            build_app(self.study, self.admin_token, request_timeout_s=self.request_timeout_s, enrol_limit=self.enrol_limit),
            http=type("StudyH11Protocol", (LimitedH11Protocol,), {"header_timeout_s": self.request_timeout_s}),
            ws_max_size=WS_MAX_MESSAGE,
            h11_max_incomplete_event_size=MAX_HEADER_BYTES,
            limit_concurrency=MAX_CONNECTIONS,
            timeout_keep_alive=5,
            timeout_graceful_shutdown=5,
            log_level="info" if self.verbose else "warning",
            access_log=self.verbose,
            lifespan="on",
        )
        self._server = uvicorn.Server(config)
        await self._server.serve(sockets=[self.sock])

    def run(self) -> None:
        """Serve in this thread until SIGINT or SIGTERM."""
        if "torch" in sys.modules:
            import torch

            torch.set_num_threads(1)  # one request at a time; torch's thread pool would only compete
        try:
            asyncio.run(self.serve())
        finally:
            self.store.close()

    def start(self) -> None:
        """Serve from a background thread; return once the server answers (or raise what stopped it)."""
        failed: list[BaseException] = []

        def target() -> None:
            try:
                asyncio.run(self.serve())
            except BaseException as exc:  # handed to the caller of start()
                failed.append(exc)

        self._thread = threading.Thread(target=target, name="study-server", daemon=True)
        self._thread.start()
        while not (self._server is not None and self._server.started) and self._thread.is_alive():
            self._thread.join(0.02)
        if failed:
            raise failed[0]
        if not self._thread.is_alive():
            raise RuntimeError("the study server stopped while starting")

    def stop(self) -> None:
        """Stop a server `start`ed in the background and close the database."""
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(START_TIMEOUT_S)
            self._thread = None
        self.sock.close()
        self.store.close()
