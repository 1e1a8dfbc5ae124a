"""The study API under generated input (Hypothesis): every endpoint's fields, never a 500, the server still serving.

Bounded: MAX_EXAMPLES requests in all over the two games, each within DEADLINE_MS, derandomised
(the same inputs every run, so a failure reproduces) and with no example database (nothing is
written beside the tests). Values mix JSON's types with what broke the server before: integers
past Python's 4300-digit limit and past float's range written as literals, 1e400, Unicode
digits, NaN, deep nesting, text of any script.
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass
from typing import Any, Iterator
from urllib.parse import quote

import httpx
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from websockets.exceptions import InvalidStatus, WebSocketException
from websockets.sync.client import connect

from rllib_conv.play.server import StudyServer
from rllib_conv.play.store import DB_FILE
from tests.play.servers import ADMIN_TOKEN, oracle_study

MAX_EXAMPLES = 200
DEADLINE_MS = 5_000  # one request on 2 busy cores; a hang fails long before the test's own timeout


@dataclass(frozen=True)
class Raw:
    """JSON text sent as it is: numbers Python's json module would refuse to write (huge literals, 1e400)."""

    text: str


def encode(value: Any) -> str:
    """`value` as JSON text, `Raw` parts verbatim (NaN and Infinity as Python writes them)."""
    if isinstance(value, Raw):
        return value.text
    if isinstance(value, dict):
        return "{" + ",".join(f"{json.dumps(str(k))}:{encode(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ",".join(encode(v) for v in value) + "]"
    return json.dumps(value, allow_nan=True)


big_literals = st.builds(
    lambda sign, lead, n: Raw(sign + lead + "0" * n),
    st.sampled_from(["", "-"]),
    st.sampled_from("123456789"),
    st.integers(300, 6000),
)
tricky = st.sampled_from(["²", "١", "߁", "1e400", " 3 ", "-0", "0x1", "NaN", "", "\x00", "1" * 25, "3\n", "⁴", "\ud800"])
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.integers(-2, 40),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=80),
    tricky,
    big_literals,
    st.sampled_from([Raw("1e400"), Raw("-1e400"), Raw("1E99999"), Raw("[" * 3000 + "]" * 3000)]),
)
values = st.recursive(
    scalars, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3), max_leaves=6
)


@dataclass
class Study:
    """A running study server and tokens of participants enrolled in it."""

    server: StudyServer
    tokens: list[str]


@pytest.fixture(scope="module")
def studies(tmp_path_factory) -> Iterator[dict[str, Study]]:
    """A bandit study (agent and human conditions) and a blocks study of two people, unlimited enrolment, a few participants each.

    The blocks pair is seated (their live pages stay open), so that its moves reach the room's checks.
    """
    out: dict[str, Study] = {}
    live = contextlib.ExitStack()
    for game, settings_ in (("bandit", oracle_study("agent,human")), ("blocks", oracle_study("human", game="blocks", games=1))):
        db = tmp_path_factory.mktemp(f"fuzz-{game}") / DB_FILE
        srv = StudyServer(settings_, db, port=0, admin_token=ADMIN_TOKEN, enrol_limit=0, request_timeout_s=2.0)
        srv.start()
        with httpx.Client(base_url=srv.url, timeout=10) as c:
            tokens = [
                c.post("/api/participants", json={"consent": True, "participant": f"{game}-{i}"}).json()["token"]
                for i in range(4)
            ]
        if game == "blocks":
            for t in tokens[:2]:
                live.enter_context(connect(srv.url.replace("http://", "ws://") + f"api/live?token={t}", open_timeout=5))
        out[game] = Study(srv, tokens)
    yield out
    live.close()
    for study in out.values():
        study.server.stop()


def field(good: st.SearchStrategy) -> st.SearchStrategy:
    """A field's value: often a plausible one, else anything."""
    return st.one_of(good, values)


def requests(tokens: list[str]) -> st.SearchStrategy:
    """(method, path, body text or None, headers) over every endpoint and its fields."""
    token = field(st.sampled_from(tokens))
    query_token = st.one_of(st.sampled_from(tokens), st.text(max_size=40))
    enrol = st.fixed_dictionaries(
        {},
        optional={
            "consent": field(st.just(True)),
            "participant": field(st.from_regex(r"\A[A-Za-z0-9._-]{1,64}\Z")),
            "token": token,
        },
    )
    move = st.fixed_dictionaries(
        {},
        optional={
            "token": token,
            "step": field(st.integers(0, 31)),
            "arm": field(st.integers(0, 5)),
            "action": field(st.integers(-1, 7)),
        },
    )
    bodies = st.one_of(enrol, move, values)  # either endpoint may get the other's fields, or anything
    admin_token = st.one_of(st.just(ADMIN_TOKEN), st.text(max_size=30))
    return st.one_of(
        st.tuples(st.just("POST"), st.just("/api/participants"), bodies.map(encode), st.just({})),
        st.tuples(st.just("POST"), st.just("/api/move"), bodies.map(encode), st.just({})),
        st.tuples(
            st.sampled_from(["POST"]),
            st.sampled_from(["/api/participants", "/api/move"]),
            st.binary(max_size=200).map(lambda b: b.decode("latin-1")),
            st.just({}),
        ),
        st.tuples(st.just("GET"), query_token.map(lambda t: f"/api/session?token={quote(t)}"), st.none(), st.just({})),
        st.tuples(
            st.just("GET"),
            st.tuples(st.sampled_from(["status", "export.csv", "participants.csv"]), st.text(max_size=20)).map(
                lambda x: f"/api/admin/{x[0]}?condition={quote(x[1])}"
            ),
            st.none(),
            admin_token.map(lambda t: {"Authorization": "Bearer " + quote(t)}),
        ),
        st.tuples(st.just("GET"), st.text(max_size=30).map(lambda name: f"/static/{quote(name)}"), st.none(), st.just({})),
        st.tuples(st.just("WS"), query_token.map(lambda t: f"/api/live?token={quote(t)}"), st.none(), st.just({})),
        st.tuples(st.just("GET"), st.just("/api/info"), st.none(), st.just({})),
    )


def send(srv: StudyServer, method: str, path: str, body: str | None, headers: dict[str, str]) -> int:
    """Make one request; its HTTP status (a WebSocket: 101 when accepted, else the refusal's status)."""
    if method == "WS":
        try:
            with connect(srv.url.replace("http://", "ws://").rstrip("/") + path, open_timeout=5, close_timeout=1) as ws:
                json.loads(ws.recv(timeout=5))  # the view, at once
            return 101
        except InvalidStatus as err:
            return err.response.status_code
        except (WebSocketException, TimeoutError, OSError) as err:
            raise AssertionError(f"the live view {path} failed: {err!r}") from err
    content = None if body is None else body.encode("utf-8", "surrogatepass")
    with httpx.Client(base_url=srv.url, timeout=10) as c:
        r = c.request(
            method,
            path,
            content=content,
            headers={"Content-Type": "application/json", **headers} if body is not None else headers,
        )
    if r.status_code >= 400:
        assert r.json()["error"], r.text  # every refusal is a JSON sentence
    return r.status_code


@pytest.mark.parametrize("game", ["bandit", "blocks"])
def test_generated_requests_never_get_a_500_and_the_server_still_serves(studies: dict[str, Study], game: str) -> None:
    study = studies[game]
    statuses: list[int] = []

    @settings(
        max_examples=MAX_EXAMPLES // 2,
        deadline=DEADLINE_MS,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )
    @given(requests(study.tokens))
    def one(request: tuple[str, str, str | None, dict[str, str]]) -> None:
        status = send(study.server, *request)
        statuses.append(status)
        assert status < 500, request

    one()
    assert len(statuses) >= MAX_EXAMPLES // 4 and any(s == 200 for s in statuses) and any(400 <= s < 500 for s in statuses)
    with httpx.Client(base_url=study.server.url, timeout=10) as c:  # still serving: a new participant plays a move
        p = c.post("/api/participants", json={"consent": True, "participant": f"after-{game}"}).json()
        view = p["view"]
        move = {"arm": 1} if game == "bandit" else {"action": 5}
        if view["phase"] in ("choose", "your_turn"):
            view = c.post("/api/move", json={"token": p["token"], "step": view["step"], **move}).json()
        assert view["played"] >= 0 and "error" not in view
        assert c.get("/api/admin/status", headers={"Authorization": f"Bearer {ADMIN_TOKEN}"}).status_code == 200


def test_the_raw_encoder_writes_what_json_cannot() -> None:
    assert encode({"a": [Raw("1" + "0" * 5000), None, float("nan")]}) == '{"a":[1' + "0" * 5000 + ",null,NaN]}"
