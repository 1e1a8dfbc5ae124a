"""`rllib-conv play` on the command line: where the database goes, refused commands that write nothing, what is printed."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from rllib_conv.cli import main
from rllib_conv.play.command import ADMIN_TOKEN_ENV
from rllib_conv.play.server import StudyServer
from rllib_conv.play.store import DB_FILE, SCHEMA_VERSION, Store
from tests.play.servers import ADMIN_TOKEN

TOKEN = ["--admin-token", ADMIN_TOKEN, "--port", "0"]


@pytest.fixture
def started(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> list[StudyServer]:
    """`play` in this process, in tmp_path, whose server stops at once instead of serving; the servers it built."""
    monkeypatch.chdir(tmp_path)
    servers: list[StudyServer] = []

    def run(self: StudyServer) -> None:
        servers.append(self)
        self.served_url = self.url  # before the socket closes
        self.sock.close()
        self.store.close()

    monkeypatch.setattr(StudyServer, "run", run)
    return servers


def folder(path: Path) -> dict[str, bytes]:
    """Every file under `path` (relative name -> bytes): a refused command must leave it byte for byte."""
    return {str(f.relative_to(path)): f.read_bytes() for f in sorted(path.rglob("*")) if f.is_file()}


@pytest.mark.parametrize(
    "argv",
    [
        ["--agent", "agent=oracle", "--db", "{db}"],  # the form docs/play.md shows
        ["--db", "{db}", "oracle"],  # before RUN
        ["oracle", "--db", "{db}"],  # after RUN
        ["--db", "{db}", "--agent", "agent=oracle", "--conditions", "agent,human"],
    ],
    ids=["option-only", "db-before-run", "db-after-run", "db-first"],
)
def test_db_is_honoured_in_every_order(started: list[StudyServer], tmp_path: Path, capsys, argv: list[str]) -> None:
    db = tmp_path / "elsewhere" / "mine.sqlite3"
    assert main(["play", *[a.format(db=db) for a in argv], *TOKEN]) == 0, capsys.readouterr().err
    assert f"database {db}" in capsys.readouterr().out
    assert started[0].store.path == db and db.is_file()
    assert not (tmp_path / "play_sessions").exists()  # not the default folder


def test_a_second_positional_when_serving_is_refused(started: list[StudyServer], tmp_path: Path, capsys) -> None:
    assert main(["play", "oracle", "extra.sqlite3", *TOKEN]) == 2
    assert "unexpected argument 'extra.sqlite3' after RUN" in capsys.readouterr().err
    assert folder(tmp_path) == {} and not started


def test_a_short_admin_token_is_refused_before_anything_is_written(
    started: list[StudyServer], tmp_path: Path, capsys, monkeypatch
) -> None:
    assert main(["play", "--agent", "a=oracle", "--admin-token", "abc"]) == 2
    assert "--admin-token must be at least 8 characters" in capsys.readouterr().err
    monkeypatch.setenv(ADMIN_TOKEN_ENV, "short")
    assert main(["play", "--agent", "a=oracle"]) == 2
    assert f"${ADMIN_TOKEN_ENV} must be at least 8 characters" in capsys.readouterr().err
    assert folder(tmp_path) == {} and not started  # no play_sessions/study.sqlite3


def newer_schema_db(path: Path, wal: bool) -> None:
    """A study database as a later release would write it (schema version SCHEMA_VERSION + 1)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    db = sqlite3.connect(path)
    if wal:
        db.execute("PRAGMA journal_mode = WAL")
    db.execute("CREATE TABLE future (x INTEGER)")
    db.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    db.commit()
    db.close()  # the last connection folds the WAL into the file and removes -wal/-shm


@pytest.mark.parametrize("wal", [False, True], ids=["rollback-journal", "wal"])
def test_a_newer_schema_is_refused_by_play_and_export_leaving_the_folder_byte_identical(
    started: list[StudyServer], tmp_path: Path, capsys, wal: bool
) -> None:
    study = tmp_path / "study"
    newer_schema_db(study / DB_FILE, wal)
    before = folder(tmp_path)
    assert set(before) == {f"study/{DB_FILE}"}
    assert main(["play", "--agent", "agent=oracle", "--out", str(study), *TOKEN]) == 2
    assert f"has schema version {SCHEMA_VERSION + 1}, newer than this release's" in capsys.readouterr().err
    assert folder(tmp_path) == before and not started
    assert main(["play", "export", str(study)]) == 2
    assert f"has schema version {SCHEMA_VERSION + 1}" in capsys.readouterr().err
    assert folder(tmp_path) == before  # no -wal/-shm, no CSV
    with pytest.raises(ValueError, match="newer than this release's"):
        Store(study / DB_FILE)
    assert folder(tmp_path) == before


def test_a_file_that_is_not_sqlite_is_refused_unchanged(tmp_path: Path) -> None:
    path = tmp_path / DB_FILE
    path.write_bytes(b"not a database, just text that is long enough to look like a header" * 3)
    before = folder(tmp_path)
    for readonly in (False, True):
        with pytest.raises(ValueError, match="is not a study database"):
            Store(path, readonly=readonly)
    assert folder(tmp_path) == before


def test_export_takes_db_as_the_positional_or_as_db(tmp_path: Path, capsys) -> None:
    Store(tmp_path / DB_FILE).close()
    assert main(["play", "export", "--db", str(tmp_path / DB_FILE), "--out", str(tmp_path / "a.csv")]) == 0
    assert main(["play", "export", str(tmp_path), "--out", str(tmp_path / "b.csv")]) == 0
    assert (tmp_path / "a.csv").is_file() and (tmp_path / "b.csv").is_file()
    assert main(["play", "export", str(tmp_path), "--db", str(tmp_path / "other.sqlite3")]) == 2
    assert "differ; give the database once" in capsys.readouterr().err


def test_an_admin_token_from_the_environment_is_not_printed(
    started: list[StudyServer], tmp_path: Path, capsys, monkeypatch
) -> None:
    secret = "from-the-environment-1234"
    monkeypatch.setenv(ADMIN_TOKEN_ENV, secret)
    assert main(["play", "--agent", "agent=oracle", "--port", "0"]) == 0
    out = capsys.readouterr()
    assert secret not in out.out + out.err and f"admin page: {started[0].served_url}admin (token: ${ADMIN_TOKEN_ENV})" in out.out
    assert started[0].admin_token == secret
    assert main(["play", "--agent", "agent=oracle", "--port", "0", "--admin-token", "given-on-the-command-line"]) == 0
    assert "admin?token=given-on-the-command-line" in capsys.readouterr().out  # typed by the user: shown back as the link


def test_the_enrol_limit_must_not_be_negative(started: list[StudyServer], tmp_path: Path, capsys) -> None:
    assert main(["play", "--agent", "agent=oracle", "--enrol-limit", "-1", *TOKEN]) == 2
    assert "--enrol-limit must be 0 (no limit) or more, got -1" in capsys.readouterr().err
    assert folder(tmp_path) == {}


def test_no_deprecation_warning_on_start_or_before_an_error(tmp_path: Path) -> None:
    """The real command in a fresh process: Python's and RLlib's DeprecationWarnings stay out of its output."""
    code = (
        "import logging, sys\n"
        "from rllib_conv.play import command\n"
        "from rllib_conv.cli import main\n"
        # What RLlib does while rebuilding a checkpoint's module: a WARNING record from its own logger.
        "def noisy(*a, **k):\n"
        "    logging.getLogger('ray.rllib.core.rl_module.rl_module').warning('DeprecationWarning: `RLModule(config=...)` has been deprecated.')\n"
        "    raise ValueError('RUN: refused after loading')\n"
        "import rllib_conv.play.conditions as c\n"
        "c.build_settings = noisy\n"
        "sys.exit(main(['play', 'some-run', '--admin-token', 'abcdefghij', '--port', '0']))\n"
    )
    logging_setup = "import logging; logging.basicConfig()\n"  # a handler, as Ray installs one for its loggers
    done = subprocess.run([sys.executable, "-c", logging_setup + code], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "RUN: refused after loading" in done.stderr and "Deprecation" not in done.stdout + done.stderr, done.stderr
