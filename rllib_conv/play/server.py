"""`rllib-conv play`: a small web server (standard library only) for people to play the games.

Serves the page (`static/index.html`, `app.js`, `style.css`) and a JSON API on 127.0.0.1:

    GET  /api/info                                   game, whether an agent is available, seat names
    POST /api/rooms          {"mode": "agent"|"human", "seat": 1|2}   -> {room, token, you, state}
    POST /api/rooms/CODE/join                        -> {room, token, you, state}
    GET  /api/rooms/CODE/state?token=T&since=V       the player's view; waits (long poll, up to
                                                     20 s) until the room changes past version V
    POST /api/rooms/CODE/move  {"token": T, "arm": 1..4} (bandit) or {"token": T, "action": 0..5} (blocks)

Errors answer `{"error": "<sentence for the page>"}` with status 400 (bad value), 403 (not
a player of that room), 404 (no such room or path), 409 (not now: out of turn, already
picked, room full, session over) or 500 (recording failed; nothing was played).

`build_lobby` turns the command-line arguments into a `lobby.Lobby` (loading the trained
egos), `serve` runs the server until Ctrl-C.
"""

from __future__ import annotations

import json
import sys
import threading
import traceback
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from rllib_conv.envs.bandit import user_study_prizes
from rllib_conv.play.agent import bandit_oracle_prior, uniform_prior
from rllib_conv.play.ego_run import load_run, require_user_study
from rllib_conv.play.lobby import Lobby
from rllib_conv.play.recording import SessionRecorder
from rllib_conv.play.room import DEFAULT_GAMES, GAMES, TRIES, AgentSettings, PlayError

HOST = "127.0.0.1"
LONG_POLL_S = 20.0
MAX_BODY = 16_384
STATIC_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8"}
STATIC_FILES = ("index.html", "app.js", "style.css")
TEST_PRIORS = ("oracle", "uniform")


def static_file(name: str) -> bytes:
    """The bytes of packaged static file `name` (one of STATIC_FILES)."""
    return (resources.files("rllib_conv.play") / "static" / name).read_bytes()


class PlayHandler(BaseHTTPRequestHandler):
    """One HTTP request: static files or the JSON API of `server.lobby`."""

    server: "PlayServer"
    protocol_version = "HTTP/1.0"  # one request per connection: long polls never block a kept-alive socket

    # -- plumbing -------------------------------------------------------------------
    def log_message(self, format: str, *args: Any) -> None:
        if self.server.verbose:
            super().log_message(format, *args)

    def _send(self, status: int, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, payload: dict[str, Any]) -> None:
        self._send(status, json.dumps(payload).encode(), "application/json")

    def _body(self) -> dict[str, Any]:
        try:
            length = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise PlayError(400, "bad Content-Length header") from None
        if length > MAX_BODY:
            raise PlayError(400, f"request body too large ({length} bytes; at most {MAX_BODY})")
        raw = self.rfile.read(length) if length else b"{}"
        try:
            body = json.loads(raw or b"{}")
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise PlayError(400, "the request body must be a JSON object") from None
        if not isinstance(body, dict):
            raise PlayError(400, f"the request body must be a JSON object, got {type(body).__name__}")
        return body

    def _route(self, method: str) -> None:
        url = urlsplit(self.path)
        parts = [p for p in url.path.split("/") if p]
        query = {k: v[-1] for k, v in parse_qs(url.query).items()}
        try:
            if method == "GET" and not parts:
                return self._send(200, static_file("index.html"), STATIC_TYPES[".html"])
            if method == "GET" and len(parts) == 2 and parts[0] == "static" and parts[1] in STATIC_FILES:
                return self._send(200, static_file(parts[1]), STATIC_TYPES[Path(parts[1]).suffix])
            if parts[:1] != ["api"]:
                raise PlayError(404, f"no page {url.path!r}")
            self._json(200, self._api(method, parts[1:], query))
        except PlayError as err:
            self._json(err.status, {"error": err.message})
        except Exception as exc:  # a bug must not kill the server; the page shows a sentence, stderr the trace
            traceback.print_exc(file=sys.stderr)
            self._json(500, {"error": f"internal error: {type(exc).__name__}: {exc}"})

    def _api(self, method: str, parts: list[str], query: dict[str, str]) -> dict[str, Any]:
        lobby = self.server.lobby
        if method == "GET" and parts == ["info"]:
            return lobby.info()
        if method == "POST" and parts == ["rooms"]:
            body = self._body()
            room, token, seat = lobby.create(body.get("mode"), body.get("seat"))
            return {"room": room.code, "token": token, "you": seat, "state": room.view(token)}
        if len(parts) == 3 and parts[0] == "rooms":
            room = lobby.room(parts[1])
            if method == "POST" and parts[2] == "join":
                self._body()
                room, token, seat = lobby.join(parts[1])
                return {"room": room.code, "token": token, "you": seat, "state": room.view(token)}
            if method == "GET" and parts[2] == "state":
                token = query.get("token")
                room.seat_of(token)  # refuse strangers before waiting
                if "since" in query:
                    try:
                        since = int(query["since"])
                    except ValueError:
                        raise PlayError(400, f"since must be an integer version, got {query['since']!r}") from None
                    room.wait_for_change(since, self.server.long_poll_s)
                return room.view(token)
            if method == "POST" and parts[2] == "move":
                body = self._body()
                return room.move(body.get("token"), body)
        raise PlayError(404, f"no API endpoint {method} /api/{'/'.join(parts)}")

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        self._route("GET")

    def do_HEAD(self) -> None:  # noqa: N802
        self._route("GET")

    def do_POST(self) -> None:  # noqa: N802
        self._route("POST")


class PlayServer(ThreadingHTTPServer):
    """The HTTP server of one lobby; one thread per request, none of them keeps the process alive."""

    daemon_threads = True
    block_on_close = False  # long polls must not delay shutdown

    def __init__(self, lobby: Lobby, port: int = 8000, host: str = HOST, verbose: bool = False, long_poll_s: float = LONG_POLL_S) -> None:
        self.lobby = lobby
        self.verbose = verbose
        self.long_poll_s = long_poll_s
        try:
            super().__init__((host, port), PlayHandler)
        except OSError as exc:
            raise ValueError(f"--port {port}: cannot listen on {host}:{port} ({exc.strerror or exc}); choose another port (0 picks a free one)") from None

    @property
    def url(self) -> str:
        """The address people open, e.g. http://127.0.0.1:8000/."""
        host, port = self.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> threading.Thread:
        """Serve in a background thread (tests); stop with `stop()`."""
        self._thread = threading.Thread(target=self.serve_forever, name="play-server", daemon=True)
        self._thread.start()
        return self._thread

    def stop(self) -> None:
        """Stop serving (if `start`ed), wake long polls, close the socket."""
        self.lobby.close()
        if getattr(self, "_thread", None) is not None:
            self.shutdown()  # only valid while serve_forever runs in another thread
            self._thread = None
        self.server_close()


def build_lobby(
    run: str | Path | None = None,
    *,
    game: str | None = None,
    test_run: str | Path | None = None,
    test_prior: str = "oracle",
    out: str | Path = "play_sessions",
    step_size: float = 3.0,
    greedy: bool = False,
    seed: int = 0,
    games: int = DEFAULT_GAMES,
    tries: int = TRIES,
    agent_delay: float = 0.6,
) -> Lobby:
    """The lobby for `rllib-conv play` (see its --help); ValueError naming the bad argument.

    Bandit: `run` must be an ego trained on the user-study Train task; its task module is
    the agent's prior there. On the Test task the prior is `test_run`'s task module (an ego
    trained on the Test task), or without it `test_prior`: "oracle" = the Test task's true
    marginals (uniform over each context's good arms: the rules the person sees on the page),
    "uniform" = uniform over the 4 arms (an agent that learns the new rules only from the person).
    Blocks: `run` is an ego trained on blocks; its task (original or new) is the session's.
    Without `run` only two-person rooms are offered.
    """
    if game is not None and game not in GAMES:
        raise ValueError(f"--game must be one of {list(GAMES)}, got {game!r}")
    if test_prior not in TEST_PRIORS:
        raise ValueError(f"--test-prior must be one of {list(TEST_PRIORS)}, got {test_prior!r}")
    if games < 1:
        raise ValueError(f"--games must be at least 1, got {games}")
    if test_run is not None and run is None:
        raise ValueError("--test-run needs RUN (the Train-task ego) as well")
    recorder = SessionRecorder(out)
    if run is None:
        return Lobby(game or "bandit", recorder, None, games=games, tries=tries, seed=seed, agent_delay=agent_delay)

    ego = load_run(run, "RUN")
    game = game or ego.game
    if ego.game != game:
        raise ValueError(f"RUN {str(ego.trial)!r} was trained on {ego.game!r}, but --game is {game!r}")
    if game not in GAMES:
        raise ValueError(f"RUN {str(ego.trial)!r} was trained on {game!r}; play supports {list(GAMES)}")
    info: dict[str, Any] = {"run": str(ego.trial), "method": ego.exp.method, "lam": ego.exp.lam, "population": ego.population.name}
    new_task = False
    if game == "bandit":
        require_user_study(ego, new_task=False, what="RUN")
        if test_run is not None:
            test_ego = load_run(test_run, "--test-run")
            require_user_study(test_ego, new_task=True, what="--test-run")
            test = test_ego.prior
            info["test_run"] = str(test_ego.trial)
        else:
            test = bandit_oracle_prior(user_study_prizes(new_task=True)) if test_prior == "oracle" else uniform_prior
            info["test_prior"] = test_prior
        priors = {"train": ego.prior, "test": test}
    else:
        if test_run is not None:
            raise ValueError("--test-run is for the bandit's Test task; a blocks session plays RUN's own task")
        new_task = bool(ego.env_config.get("new_task", False))
        priors = {"task": ego.prior}
    info.update({"step_size": step_size, "greedy": greedy, "seed": seed})
    settings = AgentSettings(priors=priors, ego_seat=ego.ego_seat, step_size=step_size, greedy=greedy, seed=seed, description=ego.describe())
    return Lobby(game, recorder, settings, new_task=new_task, games=games, tries=tries, seed=seed, agent_delay=agent_delay, run_info=info)


def serve(lobby: Lobby, port: int = 8000, verbose: bool = False) -> None:
    """Serve `lobby` on 127.0.0.1:`port` until Ctrl-C, printing the address first."""
    import torch

    torch.set_num_threads(1)  # one request at a time per thread; torch's pool would only compete
    server = PlayServer(lobby, port, verbose=verbose)
    mode = "with the agent or two people" if lobby.agent else "two people (no RUN: no agent)"
    print(f"rllib-conv play: {lobby.game}, {mode}; recording to {lobby.recorder.out}/", flush=True)
    print(f"open {server.url} in a browser (Ctrl-C stops)", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()  # serve_forever has returned here: stop() only closes
