"""The study's web app (Starlette, ASGI): pages, the participants' JSON API, live views, the admin API.

    GET  /                        the participants' page (consent, instructions, play, completion code)
    GET  /admin                   the admin page (asks for the admin token)
    GET  /static/NAME             the pages' scripts and styles (only the files in STATIC_FILES)
    GET  /api/info                the game and the consent text
    GET  /favicon.ico             the pages' icon (browsers ask for it)
    POST /api/participants        {"consent": true, "participant": ID?, "token": T?} -> {participant, token, view}
                                  (an ID seen before resumes only with its token T, which the
                                  page keeps; without it: 409, never that participant's token;
                                  at most `enrol_limit` per client address a minute, then 429)
    GET  /api/session?token=T     the participant's view
    POST /api/move                {"token": T, "step": N, "arm": 1..4} (bandit) or {..., "action": 0..5} (blocks)
    WS   /api/live?token=T        the participant's view, pushed after every change that concerns them
    GET  /api/admin/status        counts per condition, with descriptions      (admin token:
    GET  /api/admin/export.csv    the user-study CSV (?condition=NAME)          "Authorization: Bearer
    GET  /api/admin/participants.csv  every participant and completion code     TOKEN" or ?token=)

Every error is `{"error": "<sentence>"}` with its status: 400 (malformed: not JSON, wrong
types or values), 401/403 (no or a wrong token), 404 (no such page), 405 (wrong method),
408/413/431 (a body too slow or too large, headers too large, `limits.py`), 409 (not now:
out of turn, already played, session over, an id enrolled in another browser), 415 (a body
that is not JSON), 429 (too many enrolments from one address), 503 (the database could not
be written: nothing was played). Nothing in a participant's page or answer names a
condition or describes an agent: that is the admin API's.

Requests run on one event loop and change the study synchronously (a few hundred
microseconds, most of it SQLite's commit), so they are serialised without locks and an
answer is sent only after its write is committed.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import secrets
from importlib import resources
from typing import Any, AsyncIterator

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from rllib_conv.play.export import participants_csv, table_csv
from rllib_conv.play.limits import REQUEST_TIMEOUT_S, BodyLimits
from rllib_conv.play.rate_limit import RateLimit
from rllib_conv.play.room import PlayError
from rllib_conv.play.study import Study

log = logging.getLogger(__name__)

STATIC_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
}
STATIC_FILES = ("index.html", "admin.html", "app.js", "admin.js", "style.css", "favicon.svg")
# The pages load nothing from elsewhere; no referrer carries the participant id in the URL away.
PAGE_HEADERS = {
    "Cache-Control": "no-store",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Content-Security-Policy": "default-src 'self'; connect-src 'self'; frame-ancestors 'none'",
}
SWEEP_S = 5.0
MIN_ADMIN_TOKEN = 8
DEFAULT_ENROL_LIMIT = 20  # enrolments per client address per minute (`--enrol-limit`)


def static_file(name: str) -> bytes:
    """The bytes of packaged static file `name` (one of STATIC_FILES)."""
    return (resources.files("rllib_conv.play") / "static" / name).read_bytes()


def error(status: int, message: str, headers: dict[str, str] | None = None) -> JSONResponse:
    """The JSON answer of every refused request."""
    return JSONResponse({"error": message}, status_code=status, headers={**PAGE_HEADERS, **(headers or {})})


def ok(payload: dict[str, Any]) -> JSONResponse:
    """The JSON answer of every accepted request."""
    return JSONResponse(payload, headers=PAGE_HEADERS)


async def json_body(request: Request) -> dict[str, Any]:
    """The request's JSON object; PlayError 415 (not JSON) or 400 (not an object) otherwise."""
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        raise PlayError(
            415, f"the request body must be JSON sent as Content-Type: application/json, got {kind or 'no Content-Type'!r}"
        )
    try:
        body = json.loads(await request.body())
    except (ValueError, RecursionError):  # JSONDecodeError, UnicodeDecodeError, and ints past Python's digit limit
        raise PlayError(400, "the request body must be a JSON object (numbers of at most 4300 digits)") from None
    if not isinstance(body, dict):
        raise PlayError(400, f"the request body must be a JSON object, got {type(body).__name__}")
    return body


def build_app(
    study: Study,
    admin_token: str,
    sweep_s: float = SWEEP_S,
    request_timeout_s: float = REQUEST_TIMEOUT_S,
    enrol_limit: int = DEFAULT_ENROL_LIMIT,
) -> Any:
    """The ASGI app serving `study` (module docstring), inside `limits.BodyLimits` (bodies within `request_timeout_s`).

    `enrol_limit`: enrolment requests one client address may make per minute (0: no limit).
    """
    if len(admin_token) < MIN_ADMIN_TOKEN:
        raise ValueError(f"--admin-token must be at least {MIN_ADMIN_TOKEN} characters")
    enrolments = RateLimit(enrol_limit)

    def page(name: str) -> Any:
        kind = STATIC_TYPES["." + name.rsplit(".", 1)[1]]

        async def serve(request: Request) -> Response:
            return Response(static_file(name), media_type=kind, headers=PAGE_HEADERS)

        return serve

    async def static(request: Request) -> Response:
        name = request.path_params["name"]
        if name not in STATIC_FILES:
            raise PlayError(404, f"no page {request.url.path!r}")
        return await page(name)(request)

    async def info(request: Request) -> Response:
        s = study.settings
        return ok({"game": s.game, "tries": s.tries, "games": s.games, "new_task": s.new_task, "consent": s.consent})

    async def enrol(request: Request) -> Response:
        wait = enrolments.wait(request.client.host if request.client else "")
        if wait > 0:
            seconds = max(1, round(wait))
            raise PlayError(
                429,
                f"too many enrolments from your network; please try again in {seconds} seconds",
                {"Retry-After": str(seconds)},
            )
        body = await json_body(request)
        p = study.enrol(body.get("participant"), body.get("consent"), token=body.get("token"))
        return ok({"participant": p.id, "token": p.token, "view": study.view(p)})

    async def icon(request: Request) -> Response:
        return await page("favicon.svg")(request)

    async def session(request: Request) -> Response:
        return ok(study.view(study.participant(request.query_params.get("token"))))

    async def move(request: Request) -> Response:
        body = await json_body(request)
        return ok(study.move(body.get("token"), body))

    async def live(ws: WebSocket) -> None:
        changed = asyncio.Event()
        try:
            p, disconnect = study.connect(ws.query_params.get("token"), changed.set)
        except PlayError:
            await ws.close(code=1008)  # before accept: the handshake is refused with 403
            return
        closed = False

        async def drain() -> None:
            # The page sends nothing; reading is how a closed connection is noticed.
            nonlocal closed
            try:
                while (await ws.receive())["type"] != "websocket.disconnect":
                    pass
            finally:
                closed = True
                changed.set()

        reader = None
        try:
            await ws.accept()
            reader = asyncio.ensure_future(drain())
            changed.set()
            while True:
                await changed.wait()
                changed.clear()
                if closed:
                    break
                await ws.send_json(study.view(p))
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass  # the client went away mid-send
        finally:
            disconnect()
            if reader is not None:
                reader.cancel()

    def admin(request: Request) -> None:
        given = request.headers.get("authorization", "").removeprefix("Bearer ").strip() or request.query_params.get("token", "")
        if not given:
            raise PlayError(401, "the admin API needs the admin token (Authorization: Bearer TOKEN, or ?token=TOKEN)")
        if not secrets.compare_digest(given.encode(), admin_token.encode()):
            raise PlayError(403, "wrong admin token")

    async def admin_status(request: Request) -> Response:
        admin(request)
        return ok(study.status())

    async def admin_export(request: Request) -> Response:
        admin(request)
        condition = request.query_params.get("condition") or None
        if condition is not None and condition not in study.store.condition_descriptions():
            raise PlayError(400, f"condition must be one of {list(study.store.condition_descriptions())}, got {condition!r}")
        name = f"{study.settings.game}{'_' + condition if condition else ''}.csv"
        return csv_response(table_csv(study.store, condition), name)

    async def admin_participants(request: Request) -> Response:
        admin(request)
        return csv_response(participants_csv(study.store), "participants.csv")

    def csv_response(text: str, name: str) -> Response:
        return Response(
            text,
            media_type="text/csv; charset=utf-8",
            headers={**PAGE_HEADERS, "Content-Disposition": f'attachment; filename="{name}"'},
        )

    async def play_error(request: Request, exc: PlayError) -> Response:
        return error(exc.status, exc.message, exc.headers)

    async def http_error(request: Request, exc: HTTPException) -> Response:
        if exc.status_code == 404:
            return error(404, f"no page {request.url.path!r}")
        if exc.status_code == 405:
            return error(
                405,
                f"{request.method} is not allowed on {request.url.path}; use {exc.headers.get('Allow', '') if exc.headers else ''}",
                exc.headers,
            )
        return error(exc.status_code, str(exc.detail))

    async def bug(request: Request, exc: Exception) -> Response:
        log.exception("internal error on %s %s", request.method, request.url.path)
        return error(500, f"internal error ({type(exc).__name__}); the request changed nothing it had not committed")

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        async def sweeper() -> None:
            while True:
                await asyncio.sleep(sweep_s)
                study.sweep()

        task = asyncio.ensure_future(sweeper())
        try:
            yield
        finally:
            task.cancel()
            study.close()

    routes = [
        Route("/", page("index.html")),
        Route("/admin", page("admin.html")),
        Route("/favicon.ico", icon),
        Route("/static/{name}", static),
        Route("/api/info", info),
        Route("/api/participants", enrol, methods=["POST"]),
        Route("/api/session", session),
        Route("/api/move", move, methods=["POST"]),
        WebSocketRoute("/api/live", live),
        Route("/api/admin/status", admin_status),
        Route("/api/admin/export.csv", admin_export),
        Route("/api/admin/participants.csv", admin_participants),
    ]
    handlers = {PlayError: play_error, HTTPException: http_error, Exception: bug}
    app = Starlette(routes=routes, exception_handlers=handlers, lifespan=lifespan)
    return BodyLimits(app, timeout_s=request_timeout_s)
